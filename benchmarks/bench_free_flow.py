"""Cost of the coupled fluid–body step against the prescribed-motion moving-mesh step.

Disks of radius 0.05 (48 sides) in a closed box, Navier–Stokes (ν = 0.01, P2+bubble/P1dc, the
default element), BDF2 semi-implicit, solver ``auto`` (lagged LU), h = 0.02 near the bodies,
dt = 0.005:

* ``free``: the disks settle from rest at ρ_s/ρ_f = 1.5 under g = (0, −1) (one coupled solve
  per step, :class:`fluidem.coupling.free_flow.FreeBodyFlow`);
* ``prescribed``: the same disks moving down at a constant 0.05 (about the settling speed
  reached) on the same moving mesh (:class:`fluidem.coupling.moving_flow.MovingMeshFlow`).

Both in one run, one BLAS thread, medians over the steps after the first (its LU) with
re-triangulations included.  For 1, 10 and 100 bodies (the box grows with the number of
bodies, the resolution per body stays), written to ``benchmarks/results/free_flow.{md,json}``.
Target: coupled step ≤ 1.3 × the prescribed step at the same DOFs; mesh layer ≤ 20 % of a step.

Run (a few minutes)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_free_flow.py --benchmark-only -p no:cacheprovider
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.scene import Scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

PARTS = ("mesh", "rebuild", "assembly", "solve", "coupling", "loads")
BODIES = {1: (1, 12), 10: (10, 12), 100: (100, 6)}
if os.environ.get("FLUIDEM_BENCH_QUICK"):
    BODIES = {1: (1, 6)}  # bodies: (n, steps)


def scene(n: int, free: bool, steps: int, dt: float = 0.005) -> Scene:
    """``n`` disks on a square lattice (spacing 0.25) in a box with a margin of 0.3."""
    k = int(np.ceil(np.sqrt(n)))
    L = 0.25 * k + 0.6
    bodies = []
    for i in range(n):
        ix, iy = divmod(i, k)
        b = {"shape": "disk", "radius": 0.05, "segments": 48, "position": [0.425 + 0.25 * ix, 0.425 + 0.25 * iy],
             "density": 1.5}
        if not free:
            b.update(motion="prescribed", velocity=[0.0, -0.05])
        bodies.append(b)
    return Scene.from_dict({
        "gravity": [0.0, -1.0], "fluid": {"model": "navier-stokes", "viscosity": 0.01, "density": 1.0},
        "domain": {"box": [0.0, L, 0.0, L]}, "bodies": bodies,
        "mesh": {"h": 0.02, "grading": {"growth": 1.15, "h_max": 0.06}},
        "time": {"dt": dt, "t_end": dt * steps}})


def run_steps(sc: Scene) -> dict:
    sim = Simulation(sc)
    costs = []
    sim.run(out_dir=None, progress=lambda k, n, t, c: costs.append(c))
    costs = costs[1:]
    tot = np.array([c.total for c in costs])
    out = {"dofs": int(sim.flow.dofs), "steps": len(costs), "median_s": float(np.median(tot)),
           "mean_s": float(tot.mean()), "triangulations": sim.counters["triangulations"]}
    for p in PARTS:
        out[p] = float(np.mean([c.parts.get(p, 0.0) for c in costs]))
    return out


def measure() -> list:
    rows = []
    for n, (nb, steps) in BODIES.items():
        r = {"bodies": nb}
        for kind in ("free", "prescribed"):
            r[kind] = run_steps(scene(nb, kind == "free", steps))
        r["ratio_median"] = r["free"]["median_s"] / r["prescribed"]["median_s"]
        r["ratio_mean"] = r["free"]["mean_s"] / r["prescribed"]["mean_s"]
        rows.append(r)
    return rows


def write(rows: list) -> None:
    machine = machine_description()
    write_json("free_flow", machine, rows)
    lines = ["# Coupled fluid–body step against the prescribed-motion step", "", f"Machine: {machine}.", "",
             "Disks r = 0.05 settling at ρ_s/ρ_f = 1.5 (free) or moving down at 0.05 (prescribed), NS ν = 0.01, "
             "P2+bubble/P1dc, h = 0.02, dt = 0.005 (`benchmarks/bench_free_flow.py`); means of the split over the "
             "steps after the first.", "",
             "| bodies | DOFs | free median s | prescribed median s | ratio (median) | ratio (mean) | free: mesh | "
             "rebuild | assembly | solve | coupling | per body s |", "|---" * 12 + "|"]
    for r in rows:
        f, p = r["free"], r["prescribed"]
        lines.append(f"| {r['bodies']} | {f['dofs']} | {f['median_s']:.3f} | {p['median_s']:.3f} | "
                     f"{r['ratio_median']:.2f} | {r['ratio_mean']:.2f} | {f['mesh']:.3f} | {f['rebuild']:.3f} | "
                     f"{f['assembly']:.3f} | {f['solve']:.3f} | {f['coupling']:.3f} | "
                     f"{f['median_s'] / r['bodies']:.4f} |")
    (RESULTS / "free_flow.md").write_text("\n".join(lines) + "\n")


def test_free_flow_step_cost(benchmark):
    rows = benchmark.pedantic(measure, rounds=1, iterations=1)
    write(rows)
    assert all(r["free"]["dofs"] == r["prescribed"]["dofs"] or abs(r["free"]["dofs"] / r["prescribed"]["dofs"] - 1)
               < 0.05 for r in rows)


if __name__ == "__main__":
    rows = measure()
    write(rows)
    print((RESULTS / "free_flow.md").read_text())
