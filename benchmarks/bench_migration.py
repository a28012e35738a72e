"""Inertial migration of a neutrally buoyant disk in plane Couette flow at Re = 40 (Feng, Hu & Joseph 1994).

Set-up :func:`fluidem.cases.migration.migration_scene`: walls W = 1 apart moving at ∓1/2, ν = 1/40, a
free disk of radius W/8 and the fluid's density released at rest W/4 from the bottom wall, channel
periodic along the walls over 4 W, uniform moving mesh of size h, P2+bubble/P1dc, BDF2, to t = 60 W/ΔU.
Compared: the distance of the centre from the wall against Feng, Hu & Joseph's figure
(:data:`fluidem.cases.migration.FENG_HU_JOSEPH`, read to about ±0.01 W).

The disk is carried along at up to ΔU/4 and crosses the periodic sides (bent sides, the default)
several times.  Per run also: the re-triangulations per 100 steps and their reasons, and how
smooth the motion is through the crossings: the largest step-to-step change of the disk's
velocities (the kink of u, v, ω) while its outline straddles a periodic side, against the largest at
steps away from the sides, both without and with a re-triangulation in the step or the 3 before (after t = 5,
past the start from rest).

Writes ``benchmarks/results/migration.{md,json,png}``; runs at other (h, dt) stored there are kept.

Run (about 15–30 minutes per resolution on one core)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_migration.py [h:dt ...]   # default 0.05:0.05 0.04:0.05
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_migration.py report       # redraw from the JSON
    python benchmarks/bench_migration.py from-run OUT h:dt    # store the output OUT of `fluidem run` of the same
                                                              # scene (history_every = 1) as the run at (h, dt)
"""

from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, markdown_table  # noqa: E402

from fluidem.cases.migration import (FENG_HU_JOSEPH, PERIOD, crossing_kinks, migration_scene,  # noqa: E402
                                     wall_distance)
from fluidem.simulation import Simulation  # noqa: E402

NAME = "migration"
DEFAULT = ((0.05, 0.05), (0.04, 0.05))
T_END = 60.0
KINK_GROUPS = ("crossing", "away", "re-triangulated crossing", "re-triangulated away")


def run(h: float, dt: float, t_end: float = T_END) -> dict:
    """One run: per step t, the centre (x in the box, y), the velocities (u, v, ω), whether the mesh was
    re-triangulated and why, and the step's wall seconds."""
    sim = Simulation(migration_scene(h=h, dt=dt, t_end=t_end))
    fl = sim.flow
    steps, last = [], [time.perf_counter()]

    def progress(k, n, t, cost):
        now = time.perf_counter()
        ev = fl.last_event
        steps.append([float(fl.t), float(fl.poses[0, 0] % PERIOD), float(fl.poses[0, 1]),
                      *map(float, fl.body_velocities[0]), bool(ev is not None and ev.retriangulated),
                      ev.reason if ev is not None and ev.retriangulated else "", now - last[0]])
        if k % max(1, n // 20) == 0:
            print(f"h = {h:g}, dt = {dt:g}: step {k}/{n}, t = {t:.2f}, y = {fl.poses[0, 1]:.4f}", flush=True)
        last[0] = time.perf_counter()

    t0 = time.perf_counter()
    sim.run(out_dir=None, progress=progress)
    return {"h": h, "dt": dt, "t_end": t_end, "dofs": int(fl.dofs), "wall_s": time.perf_counter() - t0,
            "steps": steps}


def from_run(out_dir: str, h: float, dt: float) -> dict:
    """The rows of :func:`run` from the output of ``fluidem run`` of the same scene (``history.csv`` with
    every step, ``events.log``, ``run.json``); each step's seconds is the run's mean."""
    import re

    d = np.genfromtxt(os.path.join(out_dir, "history.csv"), delimiter=",", names=True)[1:]
    events = open(os.path.join(out_dir, "events.log")).read()
    why = {int(k): r for k, r in re.findall(r"step=(\d+) t=\S+ retriangulation reason=(\w+)", events)}
    info = json.loads(open(os.path.join(out_dir, "run.json")).read())["summary"]
    wall = float(info["wall_s"])
    steps = [[float(r["t"]), float(r["x"] % PERIOD), float(r["y"]), float(r["vx"]), float(r["vy"]), float(r["omega"]),
              int(r["step"]) in why, why.get(int(r["step"]), ""), wall / len(d)] for r in d]
    return {"h": h, "dt": dt, "t_end": float(d["t"][-1]), "dofs": int(info["dofs"]), "wall_s": wall,
            "steps": steps}


def summary(r: dict) -> dict:
    """The figures of a run: distances at the reference times, re-triangulations, smoothness through the
    periodic sides."""
    s = r["steps"]
    t, x, y = (np.array([row[k] for row in s]) for k in range(3))
    vel = np.array([row[3:6] for row in s])
    retri = np.array([row[6] for row in s])
    reasons: dict = {}
    for row in s:
        if row[6]:
            reasons[row[7]] = reasons.get(row[7], 0) + 1
    t_ref = [tr for tr in FENG_HU_JOSEPH if tr <= t[-1] + 1e-9]
    ts = np.r_[0.0, t]
    ys = np.r_[0.25, y]
    dist = wall_distance(ts, ys, t_ref) if t_ref else np.array([])
    kinks = crossing_kinks(t, x, vel, retri)
    crossings = kinks.pop("crossings")
    return {"h": r["h"], "dt": r["dt"], "dofs": r["dofs"], "n": len(s), "t_end": float(t[-1]),
            "distance": {f"{tr:g}": float(d) for tr, d in zip(t_ref, dist)},
            "retriangulations_per_100": 100.0 * retri.sum() / len(s), "reasons": reasons,
            "crossings": crossings, "kinks": kinks,
            "s_per_step": float(np.median([row[8] for row in s[1:]])), "wall_s": r["wall_s"]}


def report(runs: list, machine: str) -> None:
    rows, header = [], ["h", "dt", "DOFs", "steps"] + [f"y/W at t = {tr:g} (FHJ {v:.2f})" for tr, v in
                                                     FENG_HU_JOSEPH.items() if tr <= T_END] + [
        "re-tri. / 100 steps (reasons)", "side crossings", "s/step (median)", "wall s"]
    sums = [summary(r) for r in runs]
    for m in sums:
        d = [f"{m['distance'][f'{tr:g}']:.4f}" if f"{tr:g}" in m["distance"] else "–"
             for tr in FENG_HU_JOSEPH if tr <= T_END]
        rows.append([f"{m['h']:g}", f"{m['dt']:g}", str(m["dofs"]), str(m["n"]), *d,
                     f"{m['retriangulations_per_100']:.1f} ({json.dumps(m['reasons'])})", str(m["crossings"]),
                     f"{m['s_per_step']:.2f}", f"{m['wall_s']:.0f}"])
    # rows stored from a `fluidem run` output (from_run) have each step at the run's mean seconds
    lines = ["# Inertial migration in plane Couette flow, Re = 40 (Feng, Hu & Joseph 1994)", "",
             f"Machine: {machine}; one BLAS thread.  `benchmarks/bench_migration.py`: a neutrally buoyant free disk of "
             "radius W/8 released at rest W/4 from the bottom wall, walls at ∓ΔU/2, Re = ΔU W/ν = 40, channel "
             f"periodic over {PERIOD:g} W (bent sides), uniform moving mesh of size h, P2+bubble/P1dc, BDF2.  "
             "y/W: the centre's distance from the bottom wall at t (W/ΔU); Feng, Hu & Joseph's values are read "
             "from their figure (±0.01 W).", "",
             *markdown_table(header, rows), "",
             "Smoothness through the periodic sides: the largest kink of the disk's velocities, "
             "|(V_k − V_k−1) − (V_k−1 − V_k−2)| for V = u, v, ω, after t = 5 (past the start from rest), "
             "at the steps where its outline straddles "
             "a periodic side (crossing) or not (away), without a re-triangulation in the step or the 3 before, "
             "and with one.  The disk moves at u ≈ −0.1 to −0.25 and turns at ω ≈ −0.5.  A row stored from the "
             "output of `fluidem run` (`from-run`) has the run's mean seconds a step, not the median.", "",
             *markdown_table(["h", "dt"] + [f"{g}: u / v / ω" for g in KINK_GROUPS],
                             [[f"{m['h']:g}", f"{m['dt']:g}"] + [
                                 "–" if m["kinks"][g] is None else " / ".join(f"{a:.1e}" for a in m["kinks"][g])
                                 for g in KINK_GROUPS] for m in sums])]
    (RESULTS / f"{NAME}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    _plot(runs)


def _plot(runs: list) -> None:
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for r in runs:
        s = np.array([row[:3] for row in r["steps"]])
        ax.plot(s[:, 0], s[:, 2], label=f"fluidem, h = {r['h']:g}, dt = {r['dt']:g}")
    ax.plot(list(FENG_HU_JOSEPH), list(FENG_HU_JOSEPH.values()), "ko", label="Feng, Hu & Joseph (1994)")
    ax.set_xlim(0, T_END)
    ax.set_xlabel("t ΔU / W")
    ax.set_ylabel("distance from the wall / W")
    ax.axhline(0.5, color="0.7", lw=0.8)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{NAME}.png", dpi=120)


def main(argv: list) -> None:
    path = RESULTS / f"{NAME}.json"
    stored = json.loads(path.read_text())["rows"] if path.exists() else []
    if argv[:1] == ["from-run"]:          # from-run DIR h:dt
        h, dt = map(float, argv[2].split(":"))
        argv, imported = [argv[2]], from_run(argv[1], h, dt)
    else:
        imported = None
    if argv != ["report"]:
        for arg in argv or [f"{h}:{dt}" for h, dt in DEFAULT]:
            h, dt = map(float, arg.split(":"))
            r = imported if imported is not None else run(h, dt)
            stored = [s for s in stored if (s["h"], s["dt"]) != (h, dt)] + [r]
            stored.sort(key=lambda s: (-s["h"], -s["dt"]))
            RESULTS.mkdir(exist_ok=True)
            path.write_text(json.dumps({"machine": machine_description(), "rows": stored}))
    report(stored, json.loads(path.read_text())["machine"] if path.exists() else machine_description())


if __name__ == "__main__":
    main(sys.argv[1:])
