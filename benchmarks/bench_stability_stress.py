"""Stress suite: moving packings at area fraction 0.3, 0.5 and 0.7, and fluid pockets between touching bodies.

Set-up :mod:`fluidem.cases.stress`.  Packings: 25 bodies per run, random convex polygons (diameters
0.5–1.5) at φ = 0.3 and 0.5, hexagons (width 0.9–1.0) on a lattice at φ = 0.7, in a walled box,
gaps down to 0.01 (1 % of the mean size); every body moved by ``RandomMotion`` (translations of
std 0.02 and turns of std 0.04 rad a step, undone where a gap would fall below 0.01), prescribed on
the moving mesh, Stokes ν = 1, P2+bubble/P1dc, h = 0.25, dt = 0.1, 40 steps; four seeds per φ.  Per
run: steps, re-triangulations, the largest condition estimate κ₁ of the LUs, the largest relative
residual, the smallest angle of the mesh, the smallest gap, how the run ended.  Pockets: the frame of
four touching bars around a 0.6 × 0.6 pocket, translated, turned, or with the top bar pushed in.

Writes ``benchmarks/results/stability_stress.{md,json}``.  Run (about 3 minutes at load 4;
``--report`` writes the tables again from the stored JSON)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_stability_stress.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import warnings  # noqa: E402

from results_io import RESULTS, markdown_table, run_or_report  # noqa: E402

from fluidem.cases.stress import BOUNDS, pocket_run, stress_run  # noqa: E402
from fluidem.errors import RunWarning  # noqa: E402

PHIS = (0.3, 0.5, 0.7)
SEEDS = (0, 1, 2, 3)
N, STEPS, H = 25, 40, 0.25
POCKETS = (("translate", {}), ("rotate", {}), ("translate", {"outflow": False}), ("piston", {}))

_KEEP = ("n", "phi", "layout", "seed", "dofs", "steps", "steps_done", "retriangulations", "max_condition",
         "max_residual", "min_angle_run", "min_gap_run", "pockets_max", "ended", "error", "seconds")


def run() -> list:
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)  # few edges per small body at h = 0.25: said in the table
        for phi in PHIS:
            for seed in SEEDS:
                r = stress_run(n=N, phi=phi, seed=seed, motion_seed=seed + 100, steps=STEPS, h=H)
                rows.append({"kind": "packing", **{k: r[k] for k in _KEEP}, "condition": r["condition"]})
                print({k: r[k] for k in ("phi", "seed", "ended", "retriangulations", "max_condition", "seconds")},
                      flush=True)
        for motion, kw in POCKETS:
            r = pocket_run(motion, steps=3, **kw)
            rows.append({"kind": "pocket", "outflow": kw.get("outflow", True), **r})
            print({k: r[k] for k in ("motion", "ended", "pocket_velocity_error")}, flush=True)
    return rows


def _e(v, f="{:.2e}") -> str:
    return "—" if v is None else f.format(v)


def report(rows: list, machine: str) -> None:
    packs = [r for r in rows if r["kind"] == "packing"]
    lines = ["# Stress suite: moving packings and enclosed fluid pockets", "",
             f"Machine: {machine}; one BLAS thread (`OPENBLAS_NUM_THREADS=1`), runs one after another in one "
             f"process.  {N} bodies per run in a walled box: random convex polygons (diameters 0.5–1.5, "
             "`packing`) at φ = 0.3 and 0.5, hexagons of width 0.9–1.0 on a lattice (`hexagon_packing`; "
             "random placement jams near φ 0.55) at φ = 0.7; gaps down to 0.01, 1 % of the mean size.  Each "
             "step every body is moved by `RandomMotion` (translation std 0.02, turn std 0.04 rad, undone "
             "where a gap would fall below 0.01), prescribed on the moving mesh (drag and relax, "
             f"re-triangulation by its triggers); Stokes ν = 1, P2+bubble/P1dc, h = {H}, dt = 0.1, {STEPS} "
             "steps.  κ₁: the largest 1-norm condition estimate of the run's LUs (`fluidem.diagnostics`); "
             "residual: the largest relative residual of a solve; angle: the smallest interior angle of the "
             "mesh over the run (all elements); gap: the smallest gap between two bodies over the run.  A run "
             f"*finishes* with every field finite and κ₁ < {BOUNDS['condition']:g}, residual ≤ "
             f"{BOUNDS['residual']:g}, no degenerate or inverted element, or *stops* with fluidem's own error "
             "(its message in the last column).", ""]
    for phi in PHIS:
        sel = [r for r in packs if r["phi"] == phi]
        if not sel:
            continue
        lines += [f"## φ = {phi} ({sel[0]['layout']})", ""]
        body = [[str(r["seed"]), str(r["dofs"]), f"{r['steps_done']} / {r['steps']}", str(r["retriangulations"]),
                 _e(r["max_condition"]), _e(r["max_residual"]), _e(r["min_angle_run"], "{:.2f}°"),
                 _e(r["min_gap_run"], "{:.4f}"), str(r["pockets_max"]), r["ended"] + (f": {r['error']}" if
                                                                                     r["error"] else ""),
                 f"{r['seconds']:.1f}"] for r in sel]
        lines += markdown_table(["seed", "DOFs (start)", "steps", "re-triangulations", "largest κ₁",
                                 "largest residual", "smallest angle", "smallest gap", "pockets", "ended",
                                 "seconds"], body)
        lines.append("")
    pk = [r for r in rows if r["kind"] == "pocket"]
    if pk:
        lines += ["## Fluid pockets", "",
                  "Four 0.2-wide bars touching end to side (gaps of 1e-6, below the mesh's contact gap "
                  "1e-3 h: meshed as one closed outline) around a 0.6 × 0.6 pocket, in the 2.5 × 2.5 box with "
                  "an outflow on the right (or walls all round), h = 0.08, Stokes ν = 1, P2+bubble/P1dc, 3 steps.  "
                  "The pocket has its own pressure reference (one pin, zero mean; `fluidem.fluid.pockets`).  "
                  "Velocity error: the largest |u − u_rigid| in the pocket over the frame's speed; pressure: "
                  "L2 norm of p in the pocket over ν U / side; dA/dt: the pocket's area rate the bodies' motion "
                  "imposes.", ""]
        body = [[r["motion"], "outflow" if r["outflow"] else "walls", str(r["pockets"]),
                 _e(r["pocket_velocity_error"]), _e(r["pocket_pressure"]), _e(r["divergence"]),
                 _e(r["area_rate"]), r["ended"] + (f": {r['error']}" if r["error"] else "")] for r in pk]
        lines += markdown_table(["motion", "box", "pockets", "velocity error", "pressure", "divergence", "dA/dt",
                                 "ended"], body)
    (RESULTS / "stability_stress.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    run_or_report("stability_stress", run, report)
