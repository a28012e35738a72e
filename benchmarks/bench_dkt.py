"""Drafting–kissing–tumbling (Glowinski et al. 2001) to t = 6 s: event times, trajectories, cost.

The set-up of :mod:`fluidem.cases.dkt` (CGS: box 2 × 8 cm, disks d = 0.2 cm, ρ_s/ρ_f = 1.01,
ν = 0.01 cm²/s), P2+bubble/P1dc, h = 0.02 cm at the disks (graded ×1.2 to 0.16), dt = 0.005 s,
implicit coupling, the default contact model (:mod:`fluidem.coupling.contacts`: the squeeze-film
lubrication correction below h, the short-range repulsion as a backstop below 0.01 h).  Written to
``benchmarks/results/dkt.{md,json,png}``: the event times, the positions at the kiss, the
trajectories, DOFs, steps, wall time and the cost split per step.  Also a short run with
``fluid.coupling = "explicit"`` at the same ratio, to show where staggering fails.

Target (issue): to t = 6 s in at most 15 minutes on this machine, one BLAS thread.

Run (about 10–15 minutes on a quiet machine)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dkt.py            # run and write
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dkt.py report     # redraw from the JSON
"""

from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.dkt import D, dkt_events, dkt_scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

COLUMNS = ("t", "x_lead", "y_lead", "x_trail", "y_trail", "v_lead", "v_trail", "gap", "wall_s")


def run(h=0.02, dt=0.005, t_end=6.0, coupling="implicit", element="p2b", log=sys.stderr) -> dict:
    """One run; returns the result record (rows of :data:`COLUMNS`, events, cost split)."""
    t0 = time.perf_counter()
    sim = Simulation(dkt_scene(h=h, dt=dt, t_end=t_end, element=element, coupling=coupling))
    fl = sim.flow
    rows, parts = [], {}

    def step(k, n, t, cost):
        P, V = fl.poses, fl.body_velocities
        rows.append([fl.t, *P[0, :2], *P[1, :2], V[0, 1], V[1, 1], float(np.hypot(*(P[1, :2] - P[0, :2])) - D),
                     time.perf_counter() - t0])
        for name, s in cost.parts.items():
            parts[name] = parts.get(name, 0.0) + s
        if log is not None and k % 50 == 0:
            print(f"step {k}/{n} t = {t:.3f} gap {rows[-1][7]:.4f} {rows[-1][8]:.0f} s", file=log, flush=True)

    status = "complete"
    try:
        sim.run(out_dir=None, progress=step)
    except Exception as exc:  # the explicit mode is expected to fail: record how
        status = f"failed at step {len(rows) + 1}: {str(exc).splitlines()[0]}"
    R = np.array(rows)
    rec = {"h": h, "dt": dt, "t_end": t_end, "coupling": coupling, "element": element, "dofs": int(fl.dofs),
           "steps": len(rows), "wall_s": time.perf_counter() - t0, "status": status,
           "cost_per_step_s": {k: v / max(len(rows), 1) for k, v in parts.items()},
           "triangulations": int(sim.counters["triangulations"]), "rows": R.tolist()}
    if fl.contacts is not None and len(R):
        rec["contact_substeps"] = int(fl.contacts.substeps)
        rec["contact_passes"] = int(fl.contacts.dem_calls)
        rec["events"] = dkt_events(R[:, 0], R[:, 1:3], R[:, 3:5], R[:, 5], R[:, 6], h)
    return rec


def report(recs: list) -> None:
    """Markdown and figure from the stored records."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    main = recs[0]
    R = np.array(main["rows"])
    ev = main.get("events", {})
    lines = ["# DKT (Glowinski et al. 2001): two disks, ρ_s/ρ_f = 1.01, box 2 × 8 cm", "",
             f"Machine: {json.loads((RESULTS / 'dkt.json').read_text())['machine']}", "",
             "| run | DOFs | h | dt | steps | wall s | s/step | t_draft | t_kiss | t_tumble | min gap | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        e = r.get("events", {})

        def f(k, e=e):
            return f"{e[k]:.3f}" if k in e and np.isfinite(e[k]) else "–"

        lines.append(f"| {r['coupling']} {r['element']} | {r['dofs']} | {r['h']} | {r['dt']} | {r['steps']} | "
                     f"{r['wall_s']:.0f} | {r['wall_s'] / max(r['steps'], 1):.2f} | {f('t_draft')} | {f('t_kiss')} | "
                     f"{f('t_tumble')} | {e.get('min_gap', float('nan')):.4f} | {r['status']} |")
    split = ", ".join(f"{k} {v:.3f}" for k, v in main["cost_per_step_s"].items() if v > 0)
    lines += ["", f"Cost per step (s, implicit run): {split}.",
              f"Positions at the kiss: leading {ev.get('kiss_leading')}, trailing {ev.get('kiss_trailing')}.", ""]
    (RESULTS / "dkt.md").write_text("\n".join(lines) + "\n")
    fig, ax = plt.subplots(1, 3, figsize=(11, 4.2), gridspec_kw={"width_ratios": [1, 2, 2]})
    ax[0].plot(R[:, 1], R[:, 2], label="leading")
    ax[0].plot(R[:, 3], R[:, 4], label="trailing")
    ax[0].set(xlim=(0, 2), ylim=(0, 8), aspect="equal", xlabel="x [cm]", ylabel="y [cm]", title="trajectories")
    ax[0].legend(fontsize=7)
    for k, name in ((2, "leading"), (4, "trailing")):
        ax[1].plot(R[:, 0], R[:, k], label=f"y {name}")
        ax[1].plot(R[:, 0], R[:, k - 1], "--", label=f"x {name}")
    ax[1].set(xlabel="t [s]", ylabel="centre [cm]", title="positions")
    ax[1].legend(fontsize=7)
    ax[2].semilogy(R[:, 0], np.maximum(R[:, 7], 1e-5))
    ax[2].axhline(main["h"], color="k", lw=0.6, ls=":")
    for k in ("t_draft", "t_kiss", "t_tumble"):
        if k in ev and np.isfinite(ev[k]):
            ax[2].axvline(ev[k], color="gray", lw=0.6)
            ax[2].text(ev[k], 1.5, k[2:], rotation=90, fontsize=7, va="bottom")
    ax[2].set(xlabel="t [s]", ylabel="gap between outlines [cm]", title="gap (dotted: h, the kissing gap)")
    fig.tight_layout()
    fig.savefig(RESULTS / "dkt.png", dpi=110)


if __name__ == "__main__":
    if sys.argv[1:] == ["report"]:
        report(json.loads((RESULTS / "dkt.json").read_text())["rows"])
    else:
        recs = [run(), run(t_end=0.25, coupling="explicit")]
        write_json("dkt", machine_description(), recs)
        report(recs)
