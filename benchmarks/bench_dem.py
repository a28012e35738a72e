"""Benchmarks of one DEM step on settled packings of 1 000 and 10 000 polygons.

The packing: random convex polygons (5–8 corners, sizes 0.8–1 cm, elongation 1–1.5,
ρ = 10 kg/m²) dropped from a loose lattice into a box 28 cm wide and settled under
gravity (E = 1e4 N/m, μ = 0.4, γ = 0.3) until the kinetic energy is below 1e-5 of the
potential energy drop; it is cached in the temporary directory (it takes a few minutes
the first time).  10 000 polygons are ten copies of it side by side in a box ten times
as wide.  One round is one ``DEM.step(dt_max)``.

Run (one BLAS thread; wall-clock, so noisy on a shared machine)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_dem.py --benchmark-only \
        --benchmark-columns=median,min,rounds -p no:cacheprovider

``extra_info`` holds the contacts per step, the split of a step into broad phase,
narrow phase, forces and integration (ms) and the cost per contact (µs).
"""

from __future__ import annotations

import os
import tempfile

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from fluidem.dem import Body, ContactModel, DEM  # noqa: E402

D = 0.01
N1 = 1000
MODEL = ContactModel(E=1e4, mu=0.4, gamma=0.3)
CACHE = os.path.join(tempfile.gettempdir(), "fluidem_bench_dem_packing_v1.npz")


def _bodies(n_copies=1):
    nx = int(np.sqrt(N1) * 0.8)
    width = nx * 1.1 * D
    base = Body.random_packing(N1, (0, width, 0, 10 * width), sizes=(0.8 * D, D),
                               n_vertices=(5, 8), elongation=(1.0, 1.5), rng=1, density=10.0)
    return base, width


def settled_packing():
    """State (N1, 6): x, y, angle, vx, vy, omega of the settled 1 000-polygon packing."""
    if os.path.exists(CACHE):
        return np.load(CACHE)["state"]
    base, width = _bodies()
    sim = DEM(base, walls=(0, width, 0, 10 * width), contact=MODEL)
    dt = sim.dt_max
    pe0 = sim.potential_energy()
    for _ in range(100):
        sim.run(sim.time + 500 * dt, dt)
        if sim.kinetic_energy() < 1e-5 * (pe0 - sim.potential_energy()) and sim.time > 0.2:
            break
    state = np.column_stack([sim.positions, sim.angles, sim.velocities, sim.omegas])
    np.savez(CACHE, state=state)
    return state


def make_sim(n_copies):
    state = settled_packing()
    base, width = _bodies()
    bodies = []
    for c in range(n_copies):
        for b, s in zip(base, state):
            bodies.append(Body.polygon(b.vertices, density=b.density,
                                       position=(s[0] + c * width, s[1]), angle=s[2],
                                       velocity=s[3:5], omega=s[5]))
    return DEM(bodies, walls=(0, n_copies * width, 0, 10 * width), contact=MODEL,
               overlap_tolerance=0.05)


@pytest.mark.parametrize("n_copies", [1, 10], ids=["1k", "10k"])
def test_dem_step(benchmark, n_copies):
    sim = make_sim(n_copies)
    dt = sim.dt_max
    for _ in range(3):
        sim.step(dt)
    sim.reset_cost()
    benchmark.pedantic(sim.step, args=(dt,), rounds=40 if n_copies == 1 else 10, iterations=1,
                       warmup_rounds=1)
    p = sim.cost_per_step()
    benchmark.extra_info.update(
        n_bodies=sim.n, contacts_per_step=round(p["contacts_per_step"]),
        coordination=round(sim.coordination_number(), 2),
        broad_ms=round(1e3 * p["broad"], 3), narrow_ms=round(1e3 * p["narrow"], 3),
        forces_ms=round(1e3 * p["forces"], 3), integrate_ms=round(1e3 * p["integrate"], 3),
        us_per_contact=round(1e6 * p["per_contact"], 2))
    print(f"\n{sim.n} bodies, {sim.cost.steps} steps: {1e3 * p['total']:.3f} ms/step = broad "
          f"{1e3 * p['broad']:.3f} + narrow {1e3 * p['narrow']:.3f} + forces {1e3 * p['forces']:.3f} + "
          f"integrate {1e3 * p['integrate']:.3f}; {p['contacts_per_step']:.0f} contacts, "
          f"{1e6 * p['per_contact']:.2f} µs/contact")
