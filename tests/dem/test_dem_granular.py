"""Granular benchmarks of the DEM: angle of repose of a poured heap, dry column collapse.

Material for both: random convex polygons (5–7 corners, sizes 0.8–1 cm, elongation
1–1.4), ρ = 10 kg/m², γ = 0.3, the same μ for grain–grain and grain–floor contacts.
E = 2000 N/m is soft on purpose (the number of steps grows as √E): E/(ρ g d) = 2000, so
the static overlap areas stay around 1 % of a grain's area (depth ~0.3 % of its size) at
the bottom of these ≤ 40-grain-high deposits, small enough for the overlap-area law.
"""

from __future__ import annotations

import numpy as np
import pytest

from fluidem.dem import Body, ContactModel, DEM

D = 0.01
RHO = 10.0
E_SOFT = 2000.0


def _grain(rng, position):
    return Body.random_convex(rng.uniform(0.8 * D, D), int(rng.integers(5, 8)), rng.uniform(1.0, 1.4),
                              rng=rng, density=RHO, position=position)


def pour_heap(mu, n=500, batch=20, seed=0, settle=0.6, every=0.04):
    """Pour ``n`` grains in batches of ``batch`` onto the floor y = 0 from just above the
    top of the heap (a nozzle that rises with it), then let the heap come to rest.

    Returns the simulation.
    """
    rng = np.random.default_rng(seed)
    model = ContactModel(E=E_SOFT, mu=mu, gamma=0.3)
    cols = 5
    sim = None
    poured = 0
    while poured < n:
        top = 0.0 if sim is None else float(np.max(sim.positions[:, 1])) + 0.5 * D
        k = min(batch, n - poured)
        new = [_grain(rng, ((c % cols - (cols - 1) / 2) * 1.1 * D + rng.uniform(-0.05, 0.05) * D,
                            top + 1.2 * D + (c // cols) * 1.1 * D)) for c in range(k)]
        if sim is None:
            sim = DEM(new, walls=(-np.inf, np.inf, 0.0, np.inf), contact=model)
        else:
            sim.add_bodies(new)
        poured += k
        dt = sim.dt_max
        sim.run(sim.time + every, dt)
    sim.run(sim.time + settle, sim.dt_max)
    return sim


def repose_angle(sim):
    """Angle of the two flanks (degrees): straight-line fit of the highest grain per
    one-grain-wide column, between 20 % and 80 % of the heap height, averaged."""
    x, y = sim.positions[:, 0], sim.positions[:, 1]
    xc = x[np.argmax(y)]
    hmax = y.max()
    angles = []
    for side in (-1, 1):
        sel = side * (x - xc) > 0
        xs, ys = side * (x[sel] - xc), y[sel]
        bins = np.floor(xs / D).astype(int)
        top = {}
        for b, yy, xx in zip(bins, ys, xs):   # small arrays: per-grain loop in analysis only
            if yy > top.get(b, (-1, 0))[0]:
                top[b] = (yy, xx)
        pts = np.array([(xx, yy) for yy, xx in top.values()])
        keep = (pts[:, 1] > 0.2 * hmax) & (pts[:, 1] < 0.8 * hmax)
        slope = np.polyfit(pts[keep, 0], pts[keep, 1], 1)[0]
        angles.append(np.degrees(np.arctan(-slope)))
    return float(np.mean(angles)), angles


#: Angle of repose (degrees) of 500 poured polygons, measured with this set-up
#: (seed 0), and the mean kinetic energy per grain at the end (J).
REPOSE_TABLE = {}


@pytest.mark.slow
def test_angle_of_repose_grows_with_friction():
    results = {}
    for mu in (0.1, 0.3, 0.6):
        sim = pour_heap(mu)
        ang, sides = repose_angle(sim)
        results[mu] = ang
        print(f"mu={mu}: angle {ang:.1f}° (flanks {sides[0]:.1f}°, {sides[1]:.1f}°), "
              f"KE/grain {sim.kinetic_energy() / sim.n:.2e} J, z = {sim.coordination_number():.2f}")
        assert sim.n == 500
        assert sim.kinetic_energy() / sim.n < 1e-7      # at rest (m g d ≈ 5e-5 J)
    a = [results[m] for m in sorted(results)]
    assert a[0] < a[1] < a[2]


def column(aspect, width_grains=10, seed=1, mu=0.5):
    """Settled column of width L0 = ``width_grains`` · D and height ≈ ``aspect`` · L0 in the
    corner x ≥ 0, y ≥ 0, built by letting a loose lattice fall into the box [0, L0]."""
    rng = np.random.default_rng(seed)
    L0 = width_grains * D
    h = 1.1 * D
    ncol = int(np.floor(L0 / h))
    grains, k = [], 0
    model = ContactModel(E=E_SOFT, mu=mu, gamma=0.3)
    # lattice rows until the settled column reaches aspect · L0 (packing fraction ~ 0.8)
    area_needed = aspect * L0 * L0 * 0.8
    area = 0.0
    while area < area_needed:
        iy, ix = divmod(k, ncol)
        g = _grain(rng, ((ix + 0.5) * L0 / ncol, (iy + 0.5) * h))
        grains.append(g)
        area += g.area
        k += 1
    sim = DEM(grains, walls=(0.0, L0, 0.0, np.inf), contact=model)
    dt = sim.dt_max
    for _ in range(200):
        sim.run(sim.time + 0.05, dt)
        if sim.kinetic_energy() < 1e-9 * sim.n:
            break
    return sim, L0


def collapse(aspect, **kw):
    """Release the settled column (remove the wall x = L0) and run until the grains stop.

    Returns (a, (L∞ − L0)/L0, simulation) with a = H0/L0 measured on the settled column
    (top of the column: mean height of the 3 highest grains)."""
    sim0, L0 = column(aspect, **kw)
    y = np.sort(sim0.positions[:, 1])
    H0 = float(np.mean(y[-3:]) + 0.5 * D)
    a = H0 / L0
    sim = sim0
    sim.walls = (0.0, np.inf, 0.0, np.inf)      # open the gate at x = L0
    dt = sim.dt_max
    for _ in range(400):
        sim.run(sim.time + 0.05, dt)
        if sim.kinetic_energy() < 1e-9 * sim.n:
            break
    # runout: front of the deposit = rightmost outline point of a grain in contact
    # (a grain that bounced away alone does not count)
    touching = np.zeros(sim.n, bool)
    touching[sim.contacts.i] = True
    touching[sim.contacts.j[sim.contacts.j >= 0]] = True
    front = max(o[:, 0].max() for k, o in enumerate(sim.outlines()) if touching[k])
    return a, (front - L0) / L0, sim


def lube(a):
    """Lube et al. (2005), dry 2D collapse: (L∞ − L0)/L0 ≈ 1.2 a (a ≲ 2.3), 1.9 a^(2/3) above."""
    return 1.2 * a if a <= 2.3 else 1.9 * a ** (2.0 / 3.0)
