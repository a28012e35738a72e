"""Force history of a translating and turning plate through re-triangulations (moving mesh).

The case: a tilted 0.3 × 0.1 plate (angle 0.3 rad at start, centre (0.8, 0.5)) translating at
U = (1, 0) and turning at 0.5 rad per time unit through a closed channel [0, 3] × [0, 1],
ν = 0.01 (Re = U·0.3/ν = 30), P2+bubble/P1dc (the default element), h = 0.04, dt = 0.01,
strategy ``drag`` with the default schedule, 150 steps (the plate travels 1.5).

Per step the drag and lift (kinematic, per unit depth), whether the mesh was re-triangulated
and why, and the node count are recorded.  The figures of merit:

* re-triangulations per 100 steps, by reason;
* the force jump ratio: the largest step-to-step change of the drag at a re-triangulation
  step over the median change at ordinary steps (1 would be no visible jump), and the mean
  relative drag change |ΔF|/|F| at re-triangulation steps;
* the node-count drift (last over first) over the run;
* the interpolation noise of the field transfer per re-triangulation (the relative L2 change
  of u^n it makes, ``MeshEvent.transfer_change``) and the relative force change of that step
  (``MeshEvent.force_change``), where the run logs them (not before the ALE transfer).

Writes ``benchmarks/results/plate_history.{md,json,png}``.  Run (about a minute)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_plate_history.py [label]
    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_plate_history.py --benchmark-only
"""

from __future__ import annotations

import json
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description  # noqa: E402

from fluidem.scene import Scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

STEPS = 150


def plate_scene(steps: int = STEPS, omega: float = 0.5, dt: float = 0.01, h: float = 0.04) -> Scene:
    """The plate case of this benchmark."""
    return Scene.from_dict({
        "fluid": {"model": "navier-stokes", "viscosity": 0.01},
        "domain": {"box": [0.0, 3.0, 0.0, 1.0]},
        "bodies": [{"shape": "rectangle", "width": 0.3, "height": 0.1, "position": [0.8, 0.5], "angle": 0.3,
                    "motion": "prescribed", "velocity": [1.0, 0.0], "omega": omega}],
        "mesh": {"h": h, "strategy": "drag"},
        "time": {"dt": dt, "t_end": dt * steps}})


def _num(v) -> float:
    return float("nan") if v is None else float(v)


def force_history(scene: Scene) -> dict:
    """Run ``scene``; per-step time, drag, lift, re-triangulation reason ('' if none), nodes, noise."""
    sim = Simulation(scene)
    rows = []

    def record(k, n, t, cost):
        F, _ = sim.last_loads
        ev = sim.flow.last_event
        rows.append({"step": k, "t": t, "drag": float(F[0, 0]), "lift": float(F[0, 1]),
                     "reason": ev.reason if ev.retriangulated else "", "nodes": int(ev.n_nodes),
                     "noise": _num(getattr(ev, "transfer_change", None)) if ev.retriangulated else float("nan"),
                     "force_change": _num(getattr(ev, "force_change", None)) if ev.retriangulated else float("nan"),
                     "seconds": cost.total})

    sim.run(out_dir=None, progress=record)
    return {"rows": rows, "dofs": int(sim.flow.dofs)}


def figures(rows: list) -> dict:
    """Re-triangulation counts, force jump ratio and node drift of one history (first 5 steps skipped:
    the impulsive start)."""
    drag = np.array([r["drag"] for r in rows])
    reason = [r["reason"] for r in rows]
    d = np.abs(np.diff(drag))  # change from step k to k+1, attributed to step k+1
    retri = np.array([bool(r) for r in reason[1:]])
    keep = np.arange(1, len(rows)) >= 5
    ordinary = d[keep & ~retri]
    at = d[keep & retri]
    med = float(np.median(ordinary))
    by_reason = {}
    for r in reason:
        if r:
            by_reason[r] = by_reason.get(r, 0) + 1
    n = len(rows)
    noise = np.array([r["noise"] for r in rows if r["reason"]])
    return {"steps": n, "retriangulations": int(sum(bool(r) for r in reason)),
            "per_100_steps": 100.0 * sum(bool(r) for r in reason) / n, "by_reason": by_reason,
            "median_ordinary_change": med, "max_change_at_retriangulation": float(at.max()) if len(at) else 0.0,
            "jump_ratio": float(at.max() / med) if len(at) else 0.0,
            "mean_relative_jump": float(np.mean(at / np.abs(drag[1:][keep & retri]))) if len(at) else 0.0,
            "nodes_first": rows[0]["nodes"], "nodes_last": rows[-1]["nodes"],
            "node_drift": rows[-1]["nodes"] / rows[0]["nodes"] - 1.0,
            "median_noise": float(np.nanmedian(noise)) if len(noise) and np.isfinite(noise).any() else None,
            "median_step_s": float(np.median([r["seconds"] for r in rows[1:]]))}


def plot(histories: dict, path) -> None:
    """Drag over time for each labelled history, re-triangulation steps marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.5))
    for label, rows in histories.items():
        t = np.array([r["t"] for r in rows])
        drag = np.array([r["drag"] for r in rows])
        line, = ax.plot(t, drag, lw=1.2, label=label)
        m = np.array([bool(r["reason"]) for r in rows])
        ax.plot(t[m], drag[m], "o", ms=4, mfc="none", color=line.get_color())
    ax.set_xlabel("time t")
    ax.set_ylabel("drag F_x (kinematic, per unit depth)")
    ax.set_title("plate at Re 30 through re-triangulations (circles)")
    ax.set_ylim(*np.percentile(np.concatenate([[r["drag"] for r in rows[5:]] for rows in histories.values()]),
                               [0.5, 99.5]) * np.array([1.1, 0.9]))
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(label: str) -> dict:
    """Run the case at 0.5 rad/s, add it to ``plate_history.json`` under ``label``; rewrite md and png."""
    out = RESULTS / "plate_history.json"
    data = json.loads(out.read_text()) if out.exists() else {"runs": {}}
    h = force_history(plate_scene())
    data["runs"][label] = {"machine": machine_description(), "dofs": h["dofs"], "figures": figures(h["rows"]),
                           "rows": h["rows"]}
    RESULTS.mkdir(exist_ok=True)
    out.write_text(json.dumps(data, indent=0))
    lines = ["# Plate through re-triangulations (moving mesh, Re 30)", "",
             "0.3 × 0.1 plate, U = 1, 0.5 rad/s, closed 3 × 1 channel, ν = 0.01, P2+bubble/P1dc, h = 0.04, "
             f"dt = 0.01, {STEPS} steps (`benchmarks/bench_plate_history.py`).", "",
             "| run | DOFs | re-tri / 100 steps (reasons) | jump ratio | mean rel. jump | node drift | "
             "median noise | median step s |", "|---|---|---|---|---|---|---|---|"]
    for lab, r in data["runs"].items():
        f = r["figures"]
        why = ", ".join(f"{k} {v}" for k, v in f["by_reason"].items())
        noise = "–" if f["median_noise"] is None else f"{f['median_noise']:.2e}"
        lines.append(f"| {lab} | {r['dofs']} | {f['per_100_steps']:.1f} ({why}) | {f['jump_ratio']:.1f} | "
                     f"{100 * f['mean_relative_jump']:.1f} % | {100 * f['node_drift']:+.1f} % | {noise} | "
                     f"{f['median_step_s']:.3f} |")
    lines += ["", "Jump ratio: largest step-to-step drag change at a re-triangulation step over the median change "
              "at ordinary steps (first 5 steps left out). Machine per run in the JSON.", ""]
    last = list(data["runs"])[-1]
    ev = [r for r in data["runs"][last]["rows"] if r["reason"]]
    if ev and np.isfinite([r["noise"] for r in ev]).any():
        lines += [f"Re-triangulations of the run '{last}':", "",
                  "| step | reason | nodes | interpolation noise | force change |", "|---|---|---|---|---|"]
        lines += [f"| {r['step']} | {r['reason']} | {r['nodes']} | {100 * r['noise']:.3f} % | "
                  f"{100 * r['force_change']:.2f} % |" for r in ev]
    (RESULTS / "plate_history.md").write_text("\n".join(lines) + "\n")
    plot({lab: r["rows"] for lab, r in data["runs"].items()}, RESULTS / "plate_history.png")
    return data["runs"][label]


def test_plate_history(benchmark):
    r = benchmark.pedantic(write, args=("current",), rounds=1, iterations=1)
    assert r["figures"]["steps"] == STEPS


if __name__ == "__main__":
    r = write(sys.argv[1] if len(sys.argv) > 1 else "current")
    print(json.dumps(r["figures"], indent=1))
