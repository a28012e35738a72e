"""Navier–Stokes forces of a disk crossing a periodic side: moving mesh (lab frame) against the
body-frame solution on a fixed mesh, with bent and with straight periodic sides.

The case of the Galilean check of ``tests/test_periodic.py``: a disk (R = 0.15, 48 sides)
translating at U = 1 along a channel [0, 4] × [0, 1] periodic in x between walls at rest,
ν = 0.01 (Re = U·2R/ν = 30), Taylor–Hood, BDF2, h = 0.05; the body frame holds the disk on a
fixed mesh with both walls moving at −U and the fluid starting at −U.  Here the disk starts near
the right side, so that it crosses it: at x = 3.3 with U Δt = h/5 (Δt = 0.01, 120 steps, to
x = 4.5) and at x = 3.55 with U Δt = h/20 (Δt = 0.0025, 320 steps, to x = 4.35); the fourth
case runs the first for three periods (1200 steps from x = 3.3 to 15.3, through the side at x = 4,
8 and 12).  Both frames solve the same problem, so the relative difference of the drag,
|F_lab − F_body| / |F_body|,
and of the lift over the drag are the errors of the moving mesh.  They are reported over

* the *crossing* steps: the outline cuts the side line (centre within R of it);
* the steps *near* the side: centre within R + 2h;
* the steps *away*: centre farther than R + 4h from the side;

all after the first 5 steps (the impulsive start), beside the ordinary step-to-step change of the
drag of the body-frame run (after step 20) and the re-triangulations with their reasons.  A run
through several sides is also reported per crossing (its crossing and near steps, the largest change
of the lab drag from one step to the next over its crossing steps against the change of the
body-frame drag over the same steps, its re-triangulations) and per stretch between two sides (the
median error over its away steps, to see a drift from period to period), with the median seconds a
step and the load average over the run.  SIGTERM stops a run: the steps done are stored and reported
as a stopped run.
``seams = "bend"`` is the default; ``"clip"`` (straight sides, the seam nodes slide along them)
is given to the lab frame's moving mesh when it is built (the scene has no key for it).

Writes ``benchmarks/results/periodic_crossing.{md,json}``.  Run (about 15 minutes on a quiet
2-core machine for the first three cases, 20 to 30 more for the fourth, ``--case 3``; ``--report``
rebuilds the tables from the stored rows)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_periodic_crossing.py [--case i | --report]
"""

from __future__ import annotations

import collections
import json
import os
import signal
import sys
import time
import types
from unittest import mock

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, markdown_table, run_or_report, write_json  # noqa: E402

from fluidem.diagnostics import recently_retriangulated  # noqa: E402

H, U, R, NU, L = 0.05, 1.0, 0.15, 0.01, 4.0
#: (seams, U Δt / h, start x, steps)
CASES = [("bend", 1 / 5, 3.3, 120), ("clip", 1 / 5, 3.3, 120), ("bend", 1 / 20, 3.55, 320),
         ("bend", 1 / 5, 3.3, 1200)]


def _key(r) -> tuple:
    """What tells the cases apart: the sides, the step, the start and the number of steps."""
    return (r[0], r[1], r[2], r[3]) if isinstance(r, tuple) else (r["seams"], r["frac"], r["x0"], r["steps"])


class _Stopped(Exception):
    """SIGTERM during a run: the steps done so far are kept, the row marked partial."""


def _stop(signum, frame):
    raise _Stopped


def _scene(lab: bool, x0: float, dt: float, n: int):
    from fluidem.scene import Scene

    wall = {"type": "moving-wall", "velocity": [-U, 0.0]}
    dom = {"box": [0.0, L, 0.0, 1.0], "left": "periodic", "right": "periodic"}
    if not lab:
        dom.update(top=wall, bottom=wall)
    body = {"shape": "disk", "radius": R, "position": [x0 if lab else 1.0, 0.5], "segments": 48,
            "motion": "prescribed" if lab else "fixed", "velocity": [U if lab else 0.0, 0.0]}
    return Scene.from_dict({"fluid": {"model": "navier-stokes", "viscosity": NU, "element": "th", "solver": "direct"},
                            "domain": dom, "bodies": [body], "mesh": {"h": H},
                            "time": {"dt": dt, "t_end": n * dt, "scheme": "bdf2"}})


def run_case(seams: str, frac: float, x0: float, n: int) -> dict:
    """Drag and lift of both frames per step, and the re-triangulations of the lab frame."""
    import fluidem.mesh
    from fluidem.build import body_frame_flow, moving_mesh_flow

    class SeamsMesh(fluidem.mesh.MovingMesh):  # the scene has no key for seams: the flow's mesh gets it here
        def __init__(self, *args, **kw):
            super().__init__(*args, seams=seams, **kw)

    dt = frac * H / U
    with mock.patch.object(fluidem.mesh, "MovingMesh", SeamsMesh):
        lab = moving_mesh_flow(_scene(True, x0, dt, n), types.SimpleNamespace(counters=collections.Counter()))
    assert lab.mm.params.seams == seams
    body = body_frame_flow(_scene(False, x0, dt, n), (-U, 0.0), types.SimpleNamespace(counters=collections.Counter()))
    fl, fb, reasons, step_s, load = [], [], [], [], []
    t0 = time.perf_counter()
    previous = signal.signal(signal.SIGTERM, _stop)
    try:
        for _ in range(n):
            ts = time.perf_counter()
            lab.step(dt)
            body.step(dt)
            f_lab, f_body = lab.loads()[0][0, :2].tolist(), body.loads()[0][0, :2].tolist()
            ev = lab.last_event
            fl.append(f_lab)
            fb.append(f_body)
            reasons.append(ev.reason if ev.retriangulated else "")
            step_s.append(time.perf_counter() - ts)
            load.append(os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan"))
    except _Stopped:
        done = min(map(len, (fl, fb, reasons, step_s, load)))  # a step cut between its records is dropped
        for a in (fl, fb, reasons, step_s, load):
            del a[done:]
        print(f"stopped after {done} of {n} steps", file=sys.stderr)
    finally:
        signal.signal(signal.SIGTERM, previous)
    return {"seams": seams, "frac": frac, "dt": dt, "x0": x0, "steps": n, "steps_run": len(fl), "lab": fl,
            "body": fb, "reasons": reasons, "wall_s": time.perf_counter() - t0, "step_s": step_s, "load": load}


def _max(a) -> float:
    return float(np.max(a)) if len(a) else float("nan")  # nan: no step of the kind (a run stopped early)


def _median(a) -> float:
    return float(np.median(a)) if len(a) else float("nan")


def summary(r: dict) -> dict:
    """The figures of the module docstring for one run."""
    k = np.arange(1, len(r["lab"]) + 1)  # the steps run (fewer than planned in a stopped run)
    x = r["x0"] + U * r["dt"] * k
    fl, fb = np.array(r["lab"]), np.array(r["body"])
    drag = np.abs(fb[:, 0])
    e_drag = np.abs(fl[:, 0] - fb[:, 0]) / drag
    e_lift = np.abs(fl[:, 1] - fb[:, 1]) / drag
    dseam = np.abs((x + L / 2) % L - L / 2)
    start = k > 5
    out = {"seams": r["seams"], "frac": r["frac"], "steps": r["steps"], "wall_s": r["wall_s"],
           "retriangulations": collections.Counter(s for s in r["reasons"] if s),
           "retriangulated_at": [int(i) for i in k[[bool(s) for s in r["reasons"]]]],
           "step_change": _median(np.abs(np.diff(fb[:, 0]))[19:] / drag[20:])}
    for name, m in (("crossing", dseam < R), ("near", dseam < R + 2 * H), ("away", dseam > R + 4 * H)):
        m = m & start
        out[name] = {"steps": int(m.sum()), "drag": _max(e_drag[m]), "drag_median": _median(e_drag[m]),
                     "lift": _max(e_lift[m])}
    worst = int(np.argmax(np.where(start, e_drag, 0)))
    out["worst"] = {"step": int(k[worst]), "x": float(x[worst]), "drag": float(e_drag[worst]),
                    "retriangulated": bool(r["reasons"][worst])}
    out["steps_run"] = len(k)
    out["machine"] = r.get("machine")  # a row run alone with --case
    if "step_s" in r:  # the rows stored before the step times and the load were recorded have neither
        out["step_s"] = float(np.median(r["step_s"]))
        out["load"] = [float(np.min(r["load"])), float(np.median(r["load"])), float(np.max(r["load"]))]
    out["per_100_steps"] = 100 * len(out["retriangulated_at"]) / len(k)
    out["crossings"] = _crossings(k, x, fl, fb, e_drag, e_lift, r["reasons"], start)
    out["laps"] = _laps(k, x, e_drag, e_lift, r["reasons"], start)
    return out


def _crossings(k, x, fl, fb, e_drag, e_lift, reasons, start) -> list:
    """Per crossing of a side (at x = L, 2L, …): the errors ``e_drag``, ``e_lift`` (of :func:`summary`)
    over its crossing and near steps, the largest step-to-step change of the lab drag over its crossing
    steps against the change of the body-frame drag over the same steps, and the re-triangulations of its
    near steps."""
    drag = np.abs(fb[:, 0])
    d_lab = np.r_[np.nan, np.abs(np.diff(fl[:, 0]))] / drag  # change into step k from step k − 1
    d_body = np.r_[np.nan, np.abs(np.diff(fb[:, 0]))] / drag
    side = np.round(x / L)
    dseam = np.abs(x - side * L)
    recent = recently_retriangulated([bool(s) for s in reasons], 4)  # in the step or the 3 before
    out = []
    for m in np.unique(side[(dseam < R) & start]):
        c, near = (dseam < R) & (side == m) & start, (dseam < R + 2 * H) & (side == m) & start
        j = np.flatnonzero(c)[np.nanargmax(d_lab[c])]
        jn = np.flatnonzero(near)[np.nanargmax(d_lab[near])]
        q = c & ~recent
        out.append({"side": float(m * L), "steps": int(c.sum()), "near_steps": int(near.sum()),
                    "first": int(k[c][0]), "last": int(k[c][-1]),
                    "drag": float(e_drag[c].max()), "near": float(e_drag[near].max()), "lift": float(e_lift[c].max()),
                    "jump": float(d_lab[j]), "jump_step": int(k[j]),
                    "jump_retriangulated": bool(reasons[j] or reasons[j - 1]),
                    "near_jump": float(d_lab[jn]), "near_jump_step": int(k[jn]),
                    "near_jump_retriangulated": bool(reasons[jn] or reasons[jn - 1]),
                    "quiet_jump": _max(d_lab[q]), "quiet_jump_over_body": _max(d_lab[q] / d_body[q]),
                    "body_change": float(np.nanmax(d_body[c])), "body_change_median": float(np.nanmedian(d_body[c])),
                    "jump_of_difference": float(np.nanmax(np.abs(np.r_[np.nan, np.diff(fl[:, 0] - fb[:, 0])])[c]
                                                          / drag[c])),
                    "retriangulations": collections.Counter(reasons[i] for i in np.flatnonzero(near) if reasons[i]),
                    "complete": bool(dseam[-1] >= R or side[-1] != m)})
    return out


def _laps(k, x, e_drag, e_lift, reasons, start) -> list:
    """Per stretch between two sides (x in [jL, (j + 1)L), the first and last ones partial): the drag and
    lift errors over its away steps and its re-triangulations, to see whether the error drifts."""
    lap = np.floor(x / L)
    dseam = np.abs(x - np.round(x / L) * L)
    out = []
    for j in np.unique(lap):
        inlap = lap == j
        a = inlap & (dseam > R + 4 * H) & start
        if not a.any():
            continue
        re = [reasons[i] for i in np.flatnonzero(inlap) if reasons[i]]
        out.append({"from": float(x[inlap][0]), "to": float(x[inlap][-1]), "steps": int(inlap.sum()),
                    "away_steps": int(a.sum()), "drag_median": float(np.median(e_drag[a])),
                    "drag": float(e_drag[a].max()), "lift_median": float(np.median(e_lift[a])),
                    "retriangulations": collections.Counter(re), "per_100_steps": 100 * len(re) / int(inlap.sum())})
    return out


def report(rows: list, machine: str) -> None:
    ss = [summary(r) for r in rows]
    lines = ["# Navier–Stokes forces of a disk crossing a periodic side", "",
             f"Machine: {machine}.  `benchmarks/bench_periodic_crossing.py`: a disk (R = {R:g}, 48 sides) at "
             f"U = {U:g} through the side of a channel [0, {L:g}] × [0, 1] periodic in x, Re = 30, Taylor–Hood, "
             f"BDF2, h = {H:g}; moving mesh (lab frame) against the body-frame solution on a fixed mesh.  "
             "Errors: |F_lab − F_body| / |F_body| for the drag, the lift difference over the drag; largest "
             "over the steps (after step 5) where the outline cuts the side line (crossing), the centre is "
             "within R + 2h of it (near), or farther than R + 4h (away).  Step-to-step: median relative "
             "change of the body-frame drag from one step to the next (after step 20).", "",
             *markdown_table(
                 ["sides", "U Δt", "steps (crossing / near / away)", "drag error crossing", "near", "away",
                  "lift / drag crossing", "away", "worst step (x)", "step-to-step", "re-triangulations", "wall s"],
                 [[s["seams"], f"h/{1 / s['frac']:.0f}",
                   f"{_steps(s)} ({s['crossing']['steps']} / {s['near']['steps']} / {s['away']['steps']})",
                   f"{s['crossing']['drag']:.2e}", f"{s['near']['drag']:.2e}", f"{s['away']['drag']:.2e}",
                   f"{s['crossing']['lift']:.2e}", f"{s['away']['lift']:.2e}",
                   f"{s['worst']['step']} ({s['worst']['x']:.2f}{', re-tri.' if s['worst']['retriangulated'] else ''})",
                   f"{s['step_change']:.2e}",
                   _reasons(s["retriangulations"]),
                   f"{s['wall_s']:.0f}"] for s in ss])]
    lines += [f"{_name(s)} run alone (`--case`), machine: {s['machine']}." for s in ss
              if s["machine"] and len(s["crossings"]) <= 1]
    for s in ss:
        if len(s["crossings"]) > 1:
            lines += _periods(s)
    (RESULTS / "periodic_crossing.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def _steps(s: dict) -> str:
    return str(s["steps"]) if s["steps_run"] == s["steps"] else f"{s['steps_run']} of {s['steps']} (stopped)"


def _name(s: dict) -> str:
    return f"{s['seams']} sides, U Δt = h/{1 / s['frac']:.0f}, {_steps(s)} steps"


def _reasons(c: collections.Counter) -> str:
    return ", ".join(f"{n} {k}" for k, n in sorted(c.items())) or "0"


def _periods(s: dict) -> list:
    """The section of a run through several sides: per crossing and per stretch between sides."""
    names = ["1st", "2nd", "3rd"] + [f"{i}th" for i in range(4, 20)]
    load = (f"Load average {s['load'][1]:.1f} (median; {s['load'][0]:.1f}–{s['load'][2]:.1f}) over the run, "
            f"{s['step_s']:.2f} s (median) a step of both frames" if "load" in s else "")
    stopped = ("" if s["steps_run"] == s["steps"] else
               f"  **Stopped after {s['steps_run']} of the {s['steps']} steps planned: the figures are those of "
               "the steps run.**")
    machine = f"  Machine: {s['machine']}." if s["machine"] else ""
    return ["", f"## Several periods: {_name(s)}", "",
            f"The disk crosses a side {len(s['crossings'])} times ({sum(c['complete'] for c in s['crossings'])} "
            f"completed).  Re-triangulations: {_reasons(s['retriangulations'])}, {s['per_100_steps']:.2f} per "
            f"100 steps.  {load}.{stopped}{machine}  The disk's velocity is prescribed (U = {U:g}), continuous by "
            "construction; the loads are compared.  Per crossing: errors as above over its crossing and near "
            "steps; the largest relative change |ΔF_lab| / |F_body| of the lab drag from the step before over "
            "its crossing steps (the step; r: re-triangulated in the step or the one before), against the "
            "largest and the median change of the body-frame drag over the same steps, and the largest change "
            "of the difference F_lab − F_body; the largest change of the lab drag over its near steps; over its "
            "crossing steps with no re-triangulation in the step or the 3 before, the largest change of the lab "
            "drag and the largest ratio of it to the change of the body-frame drag in the same step; the "
            "re-triangulations over its near steps.", "",
            *markdown_table(
                ["crossing", "side x", "steps (crossing / near)", "drag error crossing", "near", "lift / drag crossing",
                 "lab drag jump (step)", "body-frame change max / median", "jump of the difference",
                 "lab drag jump near (step)", "without re-tri. (/ body-frame change)", "re-triangulations near"],
                [[names[i] + ("" if c["complete"] else " (not completed)"), f"{c['side']:g}",
                  f"{c['first']}–{c['last']} ({c['steps']} / {c['near_steps']})",
                  f"{c['drag']:.2e}", f"{c['near']:.2e}", f"{c['lift']:.2e}",
                  f"{c['jump']:.2e} ({c['jump_step']}{', r' if c['jump_retriangulated'] else ''})",
                  f"{c['body_change']:.2e} / {c['body_change_median']:.2e}", f"{c['jump_of_difference']:.2e}",
                  f"{c['near_jump']:.2e} ({c['near_jump_step']}{', r' if c['near_jump_retriangulated'] else ''})",
                  f"{c['quiet_jump']:.2e} ({c['quiet_jump_over_body']:.2f})",
                  _reasons(c["retriangulations"])] for i, c in enumerate(s["crossings"])]),
            "", "Per stretch between sides (x from jL to (j + 1)L; the first and the last partial): the drag "
            "error over its away steps, median and largest, the median lift error, and its re-triangulations.",
            "", *markdown_table(
                ["x", "steps (away)", "drag error away median", "largest", "lift / drag away median",
                 "re-triangulations", "per 100 steps"],
                [[f"{a['from']:.2f}–{a['to']:.2f}", f"{a['steps']} ({a['away_steps']})", f"{a['drag_median']:.2e}",
                  f"{a['drag']:.2e}", f"{a['lift_median']:.2e}", _reasons(a["retriangulations"]),
                  f"{a['per_100_steps']:.1f}"] for a in s["laps"]])]


def main() -> None:
    """``--report``: the tables from the stored rows; ``--case i``: run ``CASES[i]`` alone and store it
    with the other stored rows (the cases are independent: two can run side by side); no argument:
    every case, one after the other."""
    path = RESULTS / "periodic_crossing.json"
    if sys.argv[1:2] == ["--case"]:
        case = CASES[int(sys.argv[2])]
        row = run_case(*case)
        row["machine"] = machine_description()  # its own: the file's machine line stays that of the other rows
        stored = json.loads(path.read_text()) if path.exists() else {"machine": row["machine"], "rows": []}
        rows = [r for r in stored["rows"] if _key(r) != _key(row)] + [row]
        rows.sort(key=lambda r: [_key(c) for c in CASES].index(_key(r)))
        write_json("periodic_crossing", stored["machine"], rows)
        report(rows, stored["machine"])
        return
    run_or_report("periodic_crossing", lambda: [run_case(*c) for c in CASES], report)


if __name__ == "__main__":
    main()
