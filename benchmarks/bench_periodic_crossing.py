"""Navier–Stokes forces of a disk crossing a periodic side: moving mesh (lab frame) against the
body-frame solution on a fixed mesh, with bent and with straight periodic sides.

The case of the Galilean check of ``tests/test_periodic.py``: a disk (R = 0.15, 48 sides)
translating at U = 1 along a channel [0, 4] × [0, 1] periodic in x between walls at rest,
ν = 0.01 (Re = U·2R/ν = 30), Taylor–Hood, BDF2, h = 0.05; the body frame holds the disk on a
fixed mesh with both walls moving at −U and the fluid starting at −U.  Here the disk starts near
the right side, so that it crosses it: at x = 3.3 with U Δt = h/5 (Δt = 0.01, 120 steps, to
x = 4.5) and at x = 3.55 with U Δt = h/20 (Δt = 0.0025, 320 steps, to x = 4.35).  Both frames
solve the same problem, so the relative difference of the drag, |F_lab − F_body| / |F_body|,
and of the lift over the drag are the errors of the moving mesh.  They are reported over

* the *crossing* steps: the outline cuts the side line (centre within R of it);
* the steps *near* the side: centre within R + 2h;
* the steps *away*: centre farther than R + 4h from the side;

all after the first 5 steps (the impulsive start), beside the ordinary step-to-step change of the
drag of the body-frame run (after step 20) and the re-triangulations with their reasons.
``seams = "bend"`` is the default; ``"clip"`` (straight sides, the seam nodes slide along them)
is given to the lab frame's moving mesh when it is built (the scene has no key for it).

Writes ``benchmarks/results/periodic_crossing.{md,json}``.  Run (about 15 minutes on a quiet
2-core machine; ``--report`` rebuilds the tables from the stored rows)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_periodic_crossing.py [--case i | --report]
"""

from __future__ import annotations

import collections
import json
import os
import sys
import time
import types
from unittest import mock

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, markdown_table, run_or_report, write_json  # noqa: E402

H, U, R, NU, L = 0.05, 1.0, 0.15, 0.01, 4.0
#: (seams, U Δt / h, start x, steps)
CASES = [("bend", 1 / 5, 3.3, 120), ("clip", 1 / 5, 3.3, 120), ("bend", 1 / 20, 3.55, 320)]


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
    fl, fb, reasons = [], [], []
    t0 = time.perf_counter()
    for _ in range(n):
        lab.step(dt)
        body.step(dt)
        fl.append(lab.loads()[0][0, :2].tolist())
        fb.append(body.loads()[0][0, :2].tolist())
        ev = lab.last_event
        reasons.append(ev.reason if ev.retriangulated else "")
    return {"seams": seams, "frac": frac, "dt": dt, "x0": x0, "steps": n, "lab": fl, "body": fb,
            "reasons": reasons, "wall_s": time.perf_counter() - t0}


def summary(r: dict) -> dict:
    """The figures of the module docstring for one run."""
    k = np.arange(1, r["steps"] + 1)
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
           "step_change": float(np.median(np.abs(np.diff(fb[:, 0]))[19:] / drag[20:]))}
    for name, m in (("crossing", dseam < R), ("near", dseam < R + 2 * H), ("away", dseam > R + 4 * H)):
        m = m & start
        out[name] = {"steps": int(m.sum()), "drag": float(e_drag[m].max()), "drag_median": float(np.median(e_drag[m])),
                     "lift": float(e_lift[m].max())}
    worst = int(np.argmax(np.where(start, e_drag, 0)))
    out["worst"] = {"step": int(k[worst]), "x": float(x[worst]), "drag": float(e_drag[worst]),
                    "retriangulated": bool(r["reasons"][worst])}
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
                   f"{s['steps']} ({s['crossing']['steps']} / {s['near']['steps']} / {s['away']['steps']})",
                   f"{s['crossing']['drag']:.2e}", f"{s['near']['drag']:.2e}", f"{s['away']['drag']:.2e}",
                   f"{s['crossing']['lift']:.2e}", f"{s['away']['lift']:.2e}",
                   f"{s['worst']['step']} ({s['worst']['x']:.2f}{', re-tri.' if s['worst']['retriangulated'] else ''})",
                   f"{s['step_change']:.2e}",
                   ", ".join(f"{n} {k}" for k, n in sorted(s["retriangulations"].items())) or "0",
                   f"{s['wall_s']:.0f}"] for s in ss])]
    (RESULTS / "periodic_crossing.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main() -> None:
    """``--report``: the tables from the stored rows; ``--case i``: run ``CASES[i]`` alone and store it
    with the other stored rows (the cases are independent: two can run side by side); no argument:
    every case, one after the other."""
    path = RESULTS / "periodic_crossing.json"
    if sys.argv[1:2] == ["--case"]:
        case = CASES[int(sys.argv[2])]
        row = run_case(*case)
        rows = json.loads(path.read_text())["rows"] if path.exists() else []
        rows = [r for r in rows if (r["seams"], r["frac"]) != (row["seams"], row["frac"])] + [row]
        rows.sort(key=lambda r: [(c[0], c[1]) for c in CASES].index((r["seams"], r["frac"])))
        write_json("periodic_crossing", machine_description(), rows)
        report(rows, machine_description())
        return
    run_or_report("periodic_crossing", lambda: [run_case(*c) for c in CASES], report)


if __name__ == "__main__":
    main()
