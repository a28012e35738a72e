"""Oscillating grids (paper Sec. 3.3, Fig. 5): regenerate-every-step against dragging.

Set-up :mod:`fluidem.cases.oscillation`: a square body of side 0.2 in the channel [−1, 2] ×
[−0.5, 0.5], uniform inflow U = 1 raised over t = 0.2, Navier–Stokes ν = 0.01 (Re 20),
P2+bubble/P1dc, h = 0.05, dt = 0.02, 40 steps; the body oscillates vertically, y = A sin(2π t/T),
A = h/4, T = 4 dt (0, A, 0, −A, ...).  Strategies: ``regenerate`` (a new mesh every step) with 20
relaxation sweeps (its default), 3 and 0; ``drag`` with 3 (its default) and 20.  Reference: the same
motion dragged on h = 0.025.  Per step: interpolation noise, condition estimate κ₁, oscillating
nodes, re-triangulations, the force on the body.

Writes ``benchmarks/results/stability_oscillation.{md,json,png}``.  Run (about 2 minutes at load 3;
``--report`` writes the tables and the figure again from the stored JSON)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_stability_oscillation.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, markdown_table, run_or_report  # noqa: E402

from fluidem.cases.oscillation import force_deviation, oscillation_run  # noqa: E402

H, H_REF, STEPS, DT = 0.05, 0.025, 40, 0.02
#: A / 0.05 and T / dt
AMPLITUDE, PERIOD_STEPS = 0.25, 4
#: (strategy, relaxation sweeps per step; None: the strategy's default)
RUNS = (("regenerate", None), ("regenerate", 3), ("regenerate", 0), ("drag", None), ("drag", 20))
#: steps left out of the force comparison: the inflow's start-up (ramp 0.2 = 10 steps)
SKIP = 10


def _kw():
    return {"amplitude": AMPLITUDE, "period_steps": PERIOD_STEPS, "steps": STEPS, "dt": DT}


def run() -> list:
    rows = [{"kind": "reference", **oscillation_run(H_REF, "drag", **_kw())}]
    print({k: rows[-1][k] for k in ("h", "strategy", "triangulations", "noise_total", "run_seconds")}, flush=True)
    for strategy, relax in RUNS:
        rows.append({"kind": "run", **oscillation_run(H, strategy, relax, **_kw())})
        print({k: rows[-1][k] for k in ("h", "strategy", "relax_iterations", "triangulations", "noise_total",
                                        "run_seconds")}, flush=True)
    return rows


def _label(r: dict) -> str:
    return f"{r['strategy']}, {r['relax_iterations']} sweeps"


def _summary(r: dict, ref: dict) -> dict:
    noise = [v for v in r["noise"] if v is not None]
    late = [v for v in r["noise"][SKIP:] if v is not None]
    cond = [v for v in r["condition"] if v is not None]
    dev = force_deviation(r, ref, skip=SKIP)
    lift = force_deviation(r, ref, skip=SKIP, component=1)
    return {"lift_rms": lift["rms"], "noise_total": r["noise_total"], "noise_late": float(sum(late)),
            "noise_median": float(np.median(noise)) if noise else None,
            "cond_min": min(cond) if cond else None, "cond_max": max(cond) if cond else None,
            "lus": len(cond), "oscillating_max": max(r["oscillating"]),
            "oscillating_steps": sum(1 for v in r["oscillating"] if v), **dev}


def figure(rows: list) -> None:
    """Noise per step, κ₁ per step and the deviation of the drag force from the reference, per strategy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = next(r for r in rows if r["kind"] == "reference")
    runs = [r for r in rows if r["kind"] == "run"]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for r in runs:
        t = np.asarray(r["t"])
        noise = np.array([np.nan if v is None else v for v in r["noise"]])
        cond = np.array([np.nan if v is None else v for v in r["condition"]])
        line, = axes[0].semilogy(t, noise, "o-", ms=3, label=_label(r))
        axes[1].semilogy(t, cond, "o", ms=3, color=line.get_color())
        dev = (np.asarray(r["force"])[:, 0] - np.asarray(ref["force"])[:, 0]) / np.abs(ref["force"][-1][0])
        axes[2].plot(t, dev, "-", color=line.get_color())
    axes[0].set_ylabel("interpolation noise ‖Δu‖ / ‖u‖")
    axes[1].set_ylabel("condition estimate κ₁ (LU steps)")
    axes[2].set_ylabel("(F_x − F_x,ref) / F_x,ref(t_end)")
    for ax in axes:
        ax.set_xlabel("t")
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=8)
    fig.suptitle(f"square body oscillating by h/4 every {PERIOD_STEPS} steps, h = {H}: "
                 "noise, condition and force error per strategy", fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.savefig(RESULTS / "stability_oscillation.png", dpi=110)
    plt.close(fig)


def _e(v) -> str:
    return "—" if v is None else f"{v:.2e}"


def report(rows: list, machine: str) -> None:
    ref = next(r for r in rows if r["kind"] == "reference")
    runs = [r for r in rows if r["kind"] == "run"]
    figure(rows)
    F_ref = np.asarray(ref["force"])[SKIP:]
    lines = ["# Oscillating grids: regenerate-every-step against dragging", "",
             f"Machine: {machine}; one BLAS thread, runs one after another in one process.  A square body of "
             "side 0.2 at the origin of the channel [−1, 2] × [−0.5, 0.5], uniform inflow U = 1 on the left "
             "(raised over t = 0.2), outflow on the right, walls top and bottom, Navier–Stokes ν = 0.01 (Re 20), "
             f"P2+bubble/P1dc, h = {H}, dt = {DT}, {STEPS} steps.  The body oscillates vertically, "
             f"y = A sin(2π t / T), A = {AMPLITUDE * 0.05:g} (h/4), T = {PERIOD_STEPS} dt: positions 0, A, 0, −A, "
             "... .  Reference: the same motion dragged on h = "
             f"{H_REF} ({ref['dofs']} DOFs, {ref['triangulations']} re-triangulation in the run).  *Noise*: the "
             "relative L2 change of u a field transfer makes at a re-triangulation (paper Fig. 5), summed over "
             f"the run and over the steps after the inflow's start-up (steps {SKIP + 1}–{STEPS}).  κ₁: the 1-norm "
             "condition estimate of the LUs computed (the default solver's lagged LU is refactorised after every "
             "re-triangulation and when its Krylov iterations rise).  *Drag error*: mean and root mean square over "
             f"steps {SKIP + 1}–{STEPS} of F_x − F_x,ref relative to the reference's mean F_x "
             f"({np.abs(F_ref[:, 0]).mean():.4f}); *drag jitter*: the root mean square of the step-to-step change "
             "of F_x − F_x,ref, same scale.  *Lift error*: root mean square of F_y − F_y,ref over the reference's "
             f"mean |F_y| ({np.abs(F_ref[:, 1]).mean():.3g}; F_y is mostly the force that moves the body).  "
             "Oscillating nodes: `OscillationDetector` (a relaxation move reversed three steps in a row; it "
             "watches the dragged nodes only, so a regenerated mesh shows none).", "",
             "## Per strategy", ""]
    body = []
    for r in runs:
        s = _summary(r, ref)
        body.append([_label(r), str(r["triangulations"]), f"{s['noise_total']:.3f}", f"{s['noise_late']:.4f}",
                     _e(s["noise_median"]), f"{s['lus']}: {_e(s['cond_min'])}–{_e(s['cond_max'])}",
                     f"{s['oscillating_max']} ({s['oscillating_steps']} steps)", f"{s['mean']:+.1e}",
                     f"{s['rms']:.1e}", f"{s['jitter']:.1e}", f"{s['lift_rms']:.1e}", f"{r['step_median']:.2f}"])
    lines += markdown_table(["strategy", "re-triangulations", "noise, sum", f"noise, steps {SKIP + 1}–{STEPS}",
                             "noise, median per transfer", "LUs: κ₁ range", "oscillating nodes, most",
                             "drag error, mean", "drag error, rms", "drag jitter", "lift error, rms",
                             "step median (s)"], body)
    ref_dev = force_deviation(ref, ref, skip=SKIP)
    lines += ["", f"The reference's own step-to-step change of F_x on this scale: {ref_dev['jitter_ref']:.1e} "
              "(the motion's physical force swing).",
              "", "## Per step (h = 0.05)", ""]
    head = ["step", "y", "reference F_x"] + [_label(r) + ": noise / κ₁ / F_x" for r in runs]
    per = []
    for n in range(STEPS):
        cells = [str(n + 1), f"{round(runs[0]['y'][n], 10) + 0.0:+.4f}", f"{ref['force'][n][0]:.4f}"]
        for r in runs:
            cells.append(f"{_e(r['noise'][n])} / {_e(r['condition'][n])} / {r['force'][n][0]:.4f}")
        per.append(cells)
    lines += markdown_table(head, per)
    lines += ["", "![noise, condition and force error per step](stability_oscillation.png)"]
    (RESULTS / "stability_oscillation.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    run_or_report("stability_oscillation", run, report)
