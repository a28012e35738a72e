"""Benchmark of the ALE Navier–Stokes step on the moving mesh against the fixed-mesh step.

A tilted plate (0.3 × 0.04, at 0.4 rad) in a closed channel [0, 3] × [0, 1], Taylor–Hood,
ν = 0.01, BDF2 semi-implicit, solver ``auto`` (lagged LU), dt = 0.01 at 20k DOFs and 0.005 at
80k (the same Courant number 0.135), and 0.01 at 80k as a third case:

* moving: the plate translates at (0.5, 0) and turns at 0.3 rad per time unit (prescribed),
  strategy ``drag``; re-triangulations (periodic every 20 steps, or on quality) are included
  in the mean (amortised);
* fixed: the same plate at rest in the same channel with a parabolic inflow of 0.5 on the
  left and do-nothing outflow on the right, the mesh size chosen for the same DOFs (±2 %).

Both at about 20k and 80k DOFs in the same run, one BLAS thread; wall-clock on a possibly
shared machine (the load average is written with the results).  Per size the medians and
means of the step cost split (``mesh``, ``rebuild``, ``assembly``, ``solve``, ``loads``) go to
``benchmarks/results/moving_flow.{md,json}``.  Targets: moving step ≤ 2 × fixed step; mesh
layer (update, relaxation, amortised re-triangulation, mesh velocity) ≤ 20 % of the moving step.

Before the moving problem was reused (a new FlowSpace/FlowProblem and a fresh LU every step)
the same moving plate took 0.27 s per step at 20k DOFs and 1.42 s at 80k (dt = 0.005, no
re-triangulation in 12 steps); with reuse and the lagged LU 0.13 s and 0.52 s, same machine
and load.

Run (a few minutes)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_moving_flow.py \\
        --benchmark-only --benchmark-columns=median,min,rounds -p no:cacheprovider
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


import numpy as np  # noqa: E402
import pytest  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.scene import Scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

PARTS = ("mesh", "rebuild", "assembly", "solve", "loads")
# mesh size of the moving and of the fixed mesh (the fixed one refines along the plate, so it
# needs a larger h for the same DOFs: about 20.3k / 19.9k and 80.2k / 79.4k), time step, steps.
# The time step halves with h (the plate moves 0.135 h per step in both, a Courant number of
# 0.135); "80k-dt2" keeps dt = 0.01 at 80k (0.27 h per step) to show what a coarser step costs.
SIZES = {"20k": ((0.037, 0.05), 0.01, 40), "80k": ((0.0185, 0.025), 0.005, 32),
         "80k-dt2": ((0.0185, 0.025), 0.01, 24)}


def plate_scene(h: float, moving: bool, steps: int, dt: float = 0.01) -> Scene:
    """The plate scene of this benchmark (moving: prescribed motion, closed channel)."""
    body = {"shape": "rectangle", "width": 0.3, "height": 0.04, "position": [0.8, 0.5], "angle": 0.4,
            "motion": "fixed"}
    if moving:
        body.update(motion="prescribed", velocity=[0.5, 0.0], omega=0.3)
        domain = {"box": [0.0, 3.0, 0.0, 1.0]}
    else:
        domain = {"box": [0.0, 3.0, 0.0, 1.0], "left": "inflow", "right": "outflow",
                  "inflow_profile": {"type": "parabolic", "umax": 0.5, "ramp": 0.0}}
    return Scene.from_dict({
        "fluid": {"model": "navier-stokes", "viscosity": 0.01, "element": "th", "solver": "auto"},
        "domain": domain, "bodies": [body],
        "mesh": {"h": h, "strategy": "drag", "retriangulate_every": 20},
        "time": {"dt": dt, "t_end": dt * steps}})


def run_steps(scene: Scene, steps: int) -> dict:
    """Run ``steps`` steps; per-step CostSplits (step 1, the first LU, left out of the statistics)."""
    sim = Simulation(scene)
    costs = []
    sim.run(out_dir=None, n_steps=steps, progress=lambda k, n, t, c: costs.append(c))
    costs = costs[1:]
    tot = np.array([c.total for c in costs])
    out = {"dofs": int(sim.flow.dofs), "steps": len(costs), "median_s": float(np.median(tot)),
           "mean_s": float(tot.mean()), "triangulations": sim.counters["triangulations"],
           **sim.flow.stepper.solver_summary()}
    for p in PARTS:
        v = np.array([getattr(c, p) for c in costs])
        out[f"{p}_median_s"], out[f"{p}_mean_s"] = float(np.median(v)), float(v.mean())
    return out


class _Report:
    def __init__(self):
        self.rows = []

    def write(self):
        if not self.rows:
            return
        machine = machine_description()
        write_json("moving_flow", machine, self.rows)
        cols = ["size", "flow", "dofs", "dt", "steps", "median_s", "mean_s"] + [f"{p}_mean_s" for p in PARTS] + \
            ["factorizations", "krylov_iterations", "triangulations"]
        lines = [f"| {' | '.join(cols)} |", "|" + "---|" * len(cols)]
        for r in self.rows:
            lines.append("| " + " | ".join(f"{r[c]:.3f}" if isinstance(r[c], float) else str(r[c]) for c in cols)
                         + " |")
        summary = []
        for size in dict.fromkeys(r["size"] for r in self.rows):
            mv = next((r for r in self.rows if r["size"] == size and r["flow"] == "moving"), None)
            fx = next((r for r in self.rows if r["size"] == size and r["flow"] == "fixed"), None)
            if mv and fx:
                summary.append(f"* {size}: moving / fixed step (means, re-triangulations amortised) = "
                               f"{mv['mean_s'] / fx['mean_s']:.2f} (medians {mv['median_s'] / fx['median_s']:.2f}; "
                               f"target ≤ 2); mesh layer = {100 * mv['mesh_mean_s'] / mv['mean_s']:.1f} % of the "
                               f"moving step (target ≤ 20 %); solve "
                               f"{mv['solve_mean_s'] / fx['solve_mean_s']:.2f} × the "
                               f"fixed one: GMRES iterations per step {mv['krylov_iterations'] / mv['steps']:.1f} "
                               f"against {fx['krylov_iterations'] / fx['steps']:.1f}, LU factorisations "
                               f"{mv['factorizations']} against {fx['factorizations']} "
                               f"({mv['triangulations'] - 1} forced by re-triangulations); rebuild "
                               f"{100 * mv['rebuild_mean_s'] / mv['mean_s']:.1f} %")
        (RESULTS / "moving_flow.md").write_text(
            f"Machine: {machine}; one BLAS thread; seconds per step (median and mean over the steps after the "
            "first; parts are means).\n\n" + "\n".join(lines) + "\n\n" + "\n".join(summary) + "\n")


@pytest.fixture(scope="module")
def report():
    rep = _Report()
    yield rep
    rep.write()


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("flow", ["fixed", "moving"])
def test_step(benchmark, report, size, flow):
    (h_moving, h_fixed), dt, steps = SIZES[size]
    h = h_moving if flow == "moving" else h_fixed
    res = {"dt": dt}

    def run():
        res.update(run_steps(plate_scene(h, flow == "moving", steps, dt), steps))

    benchmark.pedantic(run, rounds=1, iterations=1)
    row = {"size": size, "flow": flow, **res}
    benchmark.extra_info.update(row)
    report.rows.append(row)
