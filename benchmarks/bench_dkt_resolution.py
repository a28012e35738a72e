"""Resolution check for the drafting–kissing–tumbling (DKT) set-up: one disk in the DKT box.

The Glowinski et al. (2001) DKT set-up in CGS units: box 2 × 8 cm (here [−1, 1] × [0, 8], the
disk on the centre line x = 0), fluid ρ_f = 1 g/cm³, ν = 0.01 cm²/s, g = 980 cm/s², disks of
diameter d = 0.2 cm (regular 64-gons) at ρ_s = 1.01 g/cm³, P2+bubble/P1dc, mesh size h at the
disk graded (growth 1.2) to 8 h, dt = 0.005 s.  The question: at which h is the single-disk
terminal velocity of the coupled lab-frame run within 1 % of an independent steady reference?

* ``reference``: :func:`fluidem.cases.settling.steady_terminal_velocity` (steady Navier–Stokes
  in the disk's frame, walls and inflow at U, secant on U until the drag equals the buoyant
  weight) for h = 0.03, 0.02, 0.015 and frame half-lengths 3, 6, 10 (the wake at Re ≈ 20–40 is
  long, so the length is checked);
* ``lab``: the free disk released at rest at y = 7 cm (:func:`fluidem.cases.settling.settling_scene`)
  run until t_end (it must stay clear of the floor), the settling speed recorded every step;
  the terminal speed is Aitken's Δ² limit of the last three samples 0.25 s apart, and the
  time to terminal speed the first time after which the speed stays within 1e-3 of it.

Reynolds numbers: Re = U d / ν (fluid density, the usual definition) and Re_s = ρ_s U d / μ
(with the particle density; μ = ρ_f ν), both printed.  Results go to
``benchmarks/results/dkt_resolution.{md,json}``, rewritten after every row so an interrupted run
keeps what it measured.

Run (an hour or more on a loaded two-core machine)::

    OPENBLAS_NUM_THREADS=1 nice python -m pytest benchmarks/bench_dkt_resolution.py --benchmark-only -p no:cacheprovider
    # or: nice python benchmarks/bench_dkt_resolution.py [lab|reference] [h ...]
"""

from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.settling import settling_scene, steady_terminal_velocity  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

A, L, HEIGHT, START, RHO_S, NU, G, SEG, DT = 0.1, 1.0, 8.0, 7.0, 1.01, 0.01, 980.0, 64, 0.005
LAB = {0.02: 6.0, 0.015: 6.0, 0.03: 6.0}  # h: t_end (s), the runs stop earlier
REF = [(0.02, 6.0), (0.03, 3.0), (0.03, 6.0), (0.03, 10.0), (0.02, 10.0), (0.015, 10.0), (0.02, 3.0)]  # (h, length)
if os.environ.get("FLUIDEM_BENCH_QUICK"):
    LAB, REF = {0.03: 0.75}, [(0.03, 3.0)]
SAMPLE = 0.25  # s between the samples the Aitken limit uses


def reynolds(U: float) -> dict:
    """Re with the fluid density (U d / ν) and with the particle density (ρ_s U d / (ρ_f ν))."""
    return {"Re": U * 2 * A / NU, "Re_particle_density": RHO_S * U * 2 * A / NU}


def reference(h: float, length: float) -> dict:
    t0 = time.perf_counter()
    r = steady_terminal_velocity(a=A, half_width=L, density=RHO_S, nu=NU, g=G, h=h, segments=SEG,
                                 length=length, element="p2b")
    return {"h": h, "length": length, "U": r["U"], "drag": r["drag"], "weight": r["weight"],
            "iterations": r["iterations"], "dofs": int(r["dofs"]), "seconds": time.perf_counter() - t0,
            **reynolds(r["U"])}


def aitken(v) -> float:
    """Aitken's Δ² limit of the last three (equally spaced) terms."""
    a, b, c = v[-3:]
    d = (c - b) - (b - a)
    return float(c if d == 0 else c - (c - b) ** 2 / d)


def lab(h: float, t_end: float, floor_gap: float = 2.0) -> dict:
    """The free disk from rest, in chunks of ``SAMPLE`` s until the speed is within 1e-3 of its
    Aitken limit, the centre comes within ``floor_gap`` cm of the floor, or ``t_end``; the
    history (t, x, y, u, v, ω) every step and the step costs."""
    sim = Simulation(settling_scene(a=A, half_width=L, height=HEIGHT, start=START, density=RHO_S, nu=NU, g=G,
                                    h=h, segments=SEG, dt=DT, t_end=t_end, element="p2b"))
    hist, costs = [], []

    def record(k, n, t, cost):
        p, v = sim.flow.poses[0], sim.flow.body_velocities[0]
        hist.append((t, p[0], p[1], v[0], v[1], v[2]))
        costs.append(cost)

    every = int(round(SAMPLE / DT))
    stop = "t_end"
    t0, c0 = time.perf_counter(), time.process_time()
    while sim.step_index < sim.plan.n_steps:
        sim.run(out_dir=None, progress=record, n_steps=min(sim.step_index + every, sim.plan.n_steps))
        sp = -np.array([r[4] for r in hist[::-1][::every][:3][::-1]])
        print(f"h={h} t={hist[-1][0]:.3f} y={hist[-1][2]:.4f} x={hist[-1][1]:.2e} speed={sp[-1]:.6f} "
              f"u={hist[-1][3]:.2e} omega={hist[-1][5]:.2e} wall={time.perf_counter() - t0:.0f}s", flush=True)
        if len(sp) == 3 and hist[-1][0] >= 1.0 and abs(sp[-1] / aitken(sp) - 1) < 1e-3:
            stop = "converged"
            break
        if hist[-1][2] < floor_gap:
            stop = "floor"
            break
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    H = np.array(hist)
    t, speed = H[:, 0], -H[:, 4]
    U = aitken(speed[::-1][::every][:3][::-1])
    far = np.abs(speed / U - 1) > 1e-3
    t_term = float(t[np.nonzero(far)[0][-1] + 1]) if not far[-1] else float("nan")
    tot = np.array([c.total for c in costs[1:]])
    parts = sorted({p for c in costs for p in c.parts})
    late = t > t[-1] - 1.0  # last second: the settled state
    return {"h": h, "stop": stop, "t_end": float(t[-1]), "steps": len(t), "dofs": int(sim.flow.dofs), "U": U,
            "u_end": float(speed[-1]), "t_terminal_1e-3": t_term, "y_end": float(H[-1, 2]),
            "fallen": float(START - H[-1, 2]), "x_max": float(np.abs(H[:, 1]).max()),
            "u_max": float(np.abs(H[:, 3]).max()), "omega_max": float(np.abs(H[:, 5]).max()),
            "u_late_max": float(np.abs(H[late, 3]).max()), "speed_late_range": float(np.ptp(speed[late])),
            "speed_max": float(speed.max()), "wall_s": wall, "cpu_s": cpu, "step_median_s": float(np.median(tot)),
            "step_mean_s": float(tot.mean()), "triangulations": sim.counters["triangulations"],
            "parts_mean_s": {p: float(np.mean([c.parts.get(p, 0.0) for c in costs[1:]])) for p in parts},
            "history": H[::10].round(7).tolist(), **reynolds(U)}


def _t_within(r: dict, tol: float) -> float:
    """First time of the recorded history (every tenth step) after which the speed stays within
    ``tol`` of the terminal speed."""
    H = np.array(r["history"])
    far = np.abs(-H[:, 4] / r["U"] - 1) > tol
    return float(H[np.nonzero(far)[0][-1] + 1, 0]) if not far[-1] else float("nan")


def write(refs: list, labs: list) -> None:
    """Both tables; rows on disk that this run did not measure (another process, another h) are kept,
    rows of the same h (and frame length) replaced."""
    path = RESULTS / "dkt_resolution.json"
    if path.exists():
        old = json.loads(path.read_text())["rows"]
        have = {(r["h"], r["length"]) for r in refs}
        refs = sorted([r for r in old.get("reference", []) if (r["h"], r["length"]) not in have] + refs,
                      key=lambda r: (-r["h"], r["length"]))
        have = {r["h"] for r in labs}
        labs = sorted([r for r in old.get("lab", []) if r["h"] not in have] + labs, key=lambda r: -r["h"])
    machine = machine_description()
    write_json("dkt_resolution", machine, {"reference": refs, "lab": labs})
    byh = {r["h"]: r for r in refs if r["length"] == max(x["length"] for x in refs if x["h"] == r["h"])}
    lines = ["# DKT resolution: single-disk terminal velocity in the DKT box", "", f"Machine: {machine}.", "",
             "Box 2 × 8 cm, ρ_f = 1, ν = 0.01 cm²/s, g = 980 cm/s², disk d = 0.2 cm (64-gon), ρ_s = 1.01, P2+bubble, "
             "h at the disk graded 1.2 to 8 h, dt = 0.005 s (`benchmarks/bench_dkt_resolution.py`). "
             "Re = U d/ν (fluid density); Re_s = ρ_s U d/(ρ_f ν) (particle density).", "",
             "## Steady reference (disk frame, secant on U)", "",
             "| h | half-length | U_ref cm/s | Re | Re_s | DOFs | secant its | s |", "|---" * 8 + "|"]
    for r in refs:
        lines.append(f"| {r['h']} | {r['length']} | {r['U']:.6f} | {r['Re']:.2f} | {r['Re_particle_density']:.2f} | "
                     f"{r['dofs']} | {r['iterations']} | {r['seconds']:.0f} |")
    lines += ["", "## Lab frame (free disk from rest at y = 7 cm) against the reference of the same h "
              "(longest frame)", "",
              "| h | DOFs | stop | t_end s | U_lab cm/s (Aitken) | u(t_end) | U_ref | U_lab/U_ref − 1 | "
              "vs finest U_ref | t to 1 % s | t to 1e-3 s | "
              "fallen cm | max abs x cm | max abs ω 1/s | step median s | wall s | CPU s |",
              "|---" * 17 + "|"]
    finest = byh[min(byh)] if byh else None
    for r in labs:
        ref = byh.get(r["h"])
        rel = f"{r['U'] / ref['U'] - 1:+.1e}" if ref else "–"
        uref = f"{ref['U']:.6f}" if ref else "–"
        fin = f"{r['U'] / finest['U'] - 1:+.1e}" if finest else "–"
        lines.append(f"| {r['h']} | {r['dofs']} | {r['stop']} | {r['t_end']:.2f} | {r['U']:.6f} | {r['u_end']:.6f} | "
                     f"{uref} | {rel} | {fin} | {_t_within(r, 0.01):.2f} |"
                     f" {r['t_terminal_1e-3']:.2f} | {r['fallen']:.2f} | {r['x_max']:.2e} | "
                     f"{r['omega_max']:.2e} | {r['step_median_s']:.3f} | {r['wall_s']:.0f} | "
                     + (f"{r['cpu_s']:.0f} |" if "cpu_s" in r else "– |"))
    (RESULTS / "dkt_resolution.md").write_text("\n".join(lines) + "\n")


def measure(which=("reference", "lab"), hs=None) -> tuple:
    """The lab runs and the references (of mesh sizes ``hs`` only, if given)."""
    refs, labs = [], []
    if "lab" in which:
        for h, t_end in LAB.items():
            if hs and h not in hs:
                continue
            labs.append(lab(h, t_end))
            write(refs, labs)
            print({k: v for k, v in labs[-1].items() if k != "history"}, flush=True)
    if "reference" in which:
        for h, length in REF:
            if hs and h not in hs:
                continue
            refs.append(reference(h, length))
            write(refs, labs)
            print(refs[-1], flush=True)
    return refs, labs


def test_dkt_resolution(benchmark):
    refs, labs = benchmark.pedantic(measure, rounds=1, iterations=1)
    write(refs, labs)
    assert all(abs(r["drag"] / r["weight"] - 1) < 1e-4 for r in refs)  # the secant converged
    assert all(r["fallen"] < START - 1.0 for r in labs)  # the lab runs stop clear of the floor


if __name__ == "__main__":
    which = tuple(a for a in sys.argv[1:] if a in ("reference", "lab")) or ("reference", "lab")
    hs = [float(a) for a in sys.argv[1:] if a not in ("reference", "lab")]
    refs, labs = measure(which, hs)
    write(refs, labs)
    print((RESULTS / "dkt_resolution.md").read_text())
