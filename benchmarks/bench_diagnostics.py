"""What the run diagnostics cost (:mod:`fluidem.diagnostics`): the condition estimates at every LU.

The diagnostics are on by default; their only work of size is the 1-norm condition estimate of each LU
(about 8 solves with the factors and their transpose), the rest is bookkeeping of numbers the solvers
report.  Measured per scene, one BLAS thread:

* ``estimate_s``: seconds inside the estimates (timed by :class:`fluidem.diagnostics.RunDiagnostics`);
* ``share``: ``estimate_s`` over the steps' wall seconds (the run's cost split, the first step included);
* ``off_s``: the same steps with ``sim.diagnostics.enabled = False``, for comparison (a noisier figure:
  two runs on a shared machine).

Scenes: the ``settling-disk`` example (one free disk, 12.8k DOFs) and the 10 settling disks of
``bench_free_flow.py`` (re-triangulating every few steps, so an LU every few steps).  Written to
``benchmarks/results/diagnostics.{md,json}``.

Run (about a minute)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_diagnostics.py --benchmark-only -p no:cacheprovider
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import warnings  # noqa: E402

from bench_free_flow import scene as free_flow_scene  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.scenes import example_scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

STEPS = {"settling-disk": 40, "10 disks": 30}


def _scenes():
    yield "settling-disk", example_scene("settling-disk")
    yield "10 disks", free_flow_scene(10, True, STEPS["10 disks"])


def _run(sc, steps: int, enabled: bool) -> tuple:
    sim = Simulation(sc)
    sim.diagnostics.enabled = enabled
    costs = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim.run(out_dir=None, n_steps=steps, progress=lambda k, n, t, c: costs.append(c))
    return sim, sum(c.total for c in costs)


def measure() -> list:
    rows = []
    for name, sc in _scenes():
        steps = STEPS[name]
        sim, wall = _run(sc, steps, True)
        _, off = _run(sc, steps, False)
        rec = sim.diagnostics.record()
        rows.append({"scene": name, "dofs": int(sim.flow.dofs), "steps": steps,
                     "estimates": rec["condition"]["estimates"], "estimate_s": rec["seconds"], "steps_s": wall,
                     "share": rec["seconds"] / wall, "off_s": off, "growth": rec["condition"]["growth"]})
    return rows


def write(rows: list) -> None:
    machine = machine_description()
    write_json("diagnostics", machine, rows)
    lines = ["# Cost of the run diagnostics (condition estimates at every LU)", "", f"Machine: {machine}.", "",
             "`benchmarks/bench_diagnostics.py`: seconds inside the estimates against the steps' wall seconds; "
             "`off` is a second run with the diagnostics off.", "",
             "| scene | DOFs | steps | LUs estimated | estimates s | steps s | share | steps s (off) | κ₁ growth |",
             "|---" * 9 + "|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['dofs']} | {r['steps']} | {r['estimates']} | {r['estimate_s']:.3f} | "
                     f"{r['steps_s']:.2f} | {100 * r['share']:.1f} % | {r['off_s']:.2f} | {r['growth']:.3g} |")
    (RESULTS / "diagnostics.md").write_text("\n".join(lines) + "\n")


def test_diagnostics_cost(benchmark):
    rows = benchmark.pedantic(measure, rounds=1, iterations=1)
    write(rows)
    assert all(r["estimates"] >= 1 for r in rows)


if __name__ == "__main__":
    rows = measure()
    write(rows)
    print((RESULTS / "diagnostics.md").read_text())
