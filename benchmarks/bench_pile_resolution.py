"""Force jumps at re-triangulations of a settling pile against the mesh size at the outlines.

The pile of 100 polygons of ``bench_dense.py`` (equal-area radius a = 0.025–0.04, h = 0.012: a/h ≈
2.1–3.3), 300 steps of dt = 0.01 with the node repair on, run as a user runs it (``fluidem run -v``),
and the same pile with the size ``H`` at the outlines graded ×1.2 to 0.012 (``[mesh] grading = {region
= "bodies"}``): ``bench_gap_triangulation.py`` measured the force in a narrow gap varying 1.07–2.29×
the exact one between triangulations at a/h = 2.5 and within 2 % at a/h = 5.

Per run, over the steps of a window (the bed: 200–300 by default): the relative change of all the
bodies' hydrodynamic forces from one step to the next, ‖F(k) − F(k−1)‖ / ‖F(k−1)‖ (``history.csv``;
what ``events.log`` reports as "force change" at a re-triangulation), its median over the ordinary
steps (neither re-triangulated nor right after one) and at each re-triangulation as a multiple of
that median; the cost per step (the verbose log's split), the DEM's share of it and its sub-steps
(``dem`` and "DEM n sub-steps" of the verbose lines), and the DOFs.

Run (an hour or more; the runs may go side by side: give their load in words with ``--load``)::

    python benchmarks/bench_pile_resolution.py --scene H FILE.toml      # the pile, size H at the outlines
    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 fluidem run FILE.toml --out OUT -v > RUN.LOG
    python benchmarks/bench_pile_resolution.py OUT RUN.LOG [OUT RUN.LOG ...] [--steps A B] [--load "IN WORDS"]

writes ``benchmarks/results/pile_resolution.{md,json}``.

A dense step in the bed against the same bodies apart (the target "a dense step costs at most 2× a step of the
same bodies apart", which ``bench_dense.py --apart`` measures over the first 12 steps, before a bed forms): the
pile continued from a checkpoint in the bed and the bodies of ``bench_dense.py --apart`` (spread over the box,
gaps 2.5 h), 40 steps, run at the same time::

    python benchmarks/bench_pile_resolution.py --apart-scene APART.toml
    fluidem run SCENE.toml --out BED --restart BED/checkpoints/ckpt_0000270.npz -v > BED.LOG &
    fluidem run APART.toml --out APART -v > APART.LOG
    python benchmarks/bench_pile_resolution.py --bed BED BED.LOG APART APART.LOG ["LOAD IN WORDS"]

writes ``benchmarks/results/pile_bed_apart.{md,json}``: medians and means of the steps after the first.
"""

from __future__ import annotations

import csv
import json
import pathlib
import sys

import numpy as np
from bench_dense import H, parse_run_log, scene_dict
from results_io import write_results

BODIES, STEPS = 100, 300
WINDOW = (200, 300)


def pile_scene(h_outline: float) -> dict:
    """The pile of ``bench_dense.py`` with the node repair, history every step and the size ``h_outline``
    at the outlines (graded ×1.2 to the pile's h where smaller)."""
    d = scene_dict(BODIES, STEPS)
    d["mesh"]["repair"] = True
    if h_outline < H:
        d["mesh"].update(h=h_outline, grading={"region": "bodies", "growth": 1.2, "h_max": H})
    d["output"] = {"every": 1, "fields": False}
    return d


def force_history(out_dir) -> dict:
    """``{step: (n_bodies, 2) hydrodynamic forces}`` from ``history.csv`` (bodies in id order)."""
    per_step: dict = {}
    with open(pathlib.Path(out_dir) / "history.csv") as f:
        for r in csv.DictReader(f):
            per_step.setdefault(int(r["step"]), []).append((int(r["id"]), float(r["fx"]), float(r["fy"])))
    return {k: np.array(sorted(v))[:, 1:] for k, v in per_step.items()}


def jumps(out_dir, log_path, window=WINDOW) -> dict:
    """The force changes and costs of one run in the steps ``window`` (module docstring)."""
    run = parse_run_log(pathlib.Path(log_path).read_text(errors="replace"),
                        (pathlib.Path(out_dir) / "events.log").read_text())
    F = force_history(out_dir)
    lo, hi = window
    change = {k: float(np.linalg.norm(F[k] - F[k - 1]) / max(np.linalg.norm(F[k - 1]), 1e-300))
              for k in F if lo <= k <= hi and k - 1 in F and k - 1 > 0}
    retri = sorted(k for k in run["retri"] if k in change)
    ordinary = np.array([c for k, c in change.items() if k not in run["retri"] and k - 1 not in run["retri"]])
    med = float(np.median(ordinary))
    at = np.array([change[k] for k in retri])
    steps = {k: v for k, v in run["steps"].items() if lo <= k <= hi}
    reasons: dict = {}
    for k in retri:
        reasons[run["retri"][k][0]] = reasons.get(run["retri"][k][0], 0) + 1
    from fluidem.scene import Scene

    mesh = Scene.from_toml(pathlib.Path(out_dir) / "scene.toml").mesh
    graded = f", graded ×{mesh.grading['growth']:g} to {mesh.grading['h_max']:g}" if mesh.grading else ""
    return {"out": str(out_dir), "scene": json.loads((pathlib.Path(out_dir) / "run.json").read_text()).get("scene"),
            "mesh": f"h = {mesh.h:g} at the outlines{graded}",
            "dofs": run["dofs"], "window": [lo, hi], "steps": len(change),
            "ordinary_median_pct": 100 * med, "ordinary_p90_over_median": float(np.percentile(ordinary, 90)) / med,
            "retriangulations": len(retri), "reasons": reasons,
            "retri_over_ordinary": [float(c / med) for c in at],
            "retri_over_ordinary_median": float(np.median(at) / med) if len(at) else None,
            "retri_median_pct": 100 * float(np.median(at)) if len(at) else None,
            "s_per_step_median": float(np.median([s["total"] for s in steps.values()])) if steps else None,
            "s_per_step_mean": float(np.mean([s["total"] for s in steps.values()])) if steps else None,
            "dem_share": (sum(s["dem"] for s in steps.values()) / sum(s["total"] for s in steps.values())
                          if steps else None),
            "dem_substeps_per_step": float(np.mean([s["substeps"] for s in steps.values()])) if steps else None}


def step_costs(out_dir, log_path) -> dict:
    """Medians and means over the steps after the first of a verbose run log: the step, its solve and DEM
    seconds, DEM sub-steps a step, re-triangulations, DOFs."""
    run = parse_run_log(pathlib.Path(log_path).read_text(errors="replace"),
                        (pathlib.Path(out_dir) / "events.log").read_text())
    keep = sorted(run["steps"])[1:]  # the first step of a (re)start holds a fresh analysis and LU
    col = {p: np.array([run["steps"][k][p] for k in keep], float) for p in ("total", "solve", "dem", "substeps")}
    return {"out": str(out_dir), "steps": [keep[0], keep[-1]], "dofs": run["dofs"],
            "median": {p: float(np.median(v)) for p, v in col.items()},
            "mean": {p: float(np.mean(v)) for p, v in col.items()},
            "retriangulations": sum(k in run["retri"] for k in keep)}


def bed_against_apart(bed_out, bed_log, apart_out, apart_log, load: str | None = None) -> None:
    """``--bed``: write ``pile_bed_apart.{md,json}`` (module docstring); ``load``: the load average while the
    two ran, in words (the machine line has the one when written)."""
    rows = [dict(step_costs(bed_out, bed_log), variant="pile in its bed"),
            dict(step_costs(apart_out, apart_log), variant="apart")]
    ratio = rows[0]["median"]["total"] / rows[1]["median"]["total"]
    cells = [[r["variant"], f"{r['dofs']:,}", f"{r['steps'][0]}–{r['steps'][1]}",
              f"{r['median']['total']:.2f} / {r['mean']['total']:.2f}", f"{r['median']['solve']:.2f}",
              f"{r['median']['dem']:.2f}", f"{r['mean']['substeps']:.0f}", str(r["retriangulations"])] for r in rows]
    write_results("pile_bed_apart", rows + [{"dense_over_apart_median": ratio, "load_while_running": load}],
                  "A dense step in the bed against the same bodies apart",
                  "The 100 polygons of `bench_dense.py`: the pile of `bench_pile_resolution.py` (h = 0.012) "
                  "continued from a checkpoint in its bed, and the bodies spread over the box with gaps of 2.5 h "
                  "(`bench_dense.py --apart`), run at the same time, one BLAS and one MKL thread each"
                  + (f" ({load})" if load else "") + "; medians (and means) over the steps after the first.",
                  ["variant", "DOFs", "steps", "s a step: median / mean", "solve s", "DEM s",
                   "DEM sub-steps a step", "re-triangulations"], cells,
                  notes=["", f"Dense step / apart step (medians): {ratio:.2f} (target ≤ 2)."])


def main(argv: list[str]) -> None:
    if argv[:1] == ["--scene"]:
        from fluidem.scene import Scene

        Scene.from_dict(pile_scene(float(argv[1]))).to_toml(argv[2])
        return
    if argv[:1] == ["--apart-scene"]:
        from fluidem.scene import Scene

        d = scene_dict(BODIES, 40, apart=True)
        d["output"] = {"every": 1, "fields": False}
        Scene.from_dict(d).to_toml(argv[1])
        return
    if argv[:1] == ["--bed"]:
        bed_against_apart(*argv[1:6])
        return
    window, load = WINDOW, None
    if "--load" in argv:
        i = argv.index("--load")
        load, argv = argv[i + 1], argv[:i] + argv[i + 2:]
    if "--steps" in argv:
        i = argv.index("--steps")
        window, argv = (int(argv[i + 1]), int(argv[i + 2])), argv[:i] + argv[i + 3:]
    rows = [dict(jumps(out, log, window), load_while_running=load) for out, log in zip(argv[::2], argv[1::2])]
    cells = [[r["mesh"], f"{r['dofs']:,}", f"{r['window'][0]}–{r['window'][1]}",
              f"{r['ordinary_median_pct']:.2f} % (p90 {r['ordinary_p90_over_median']:.1f}×)",
              f"{r['retriangulations']} ({', '.join(f'{k} {v}' for k, v in sorted(r['reasons'].items()))})",
              (f"{r['retri_median_pct']:.2f} %: {r['retri_over_ordinary_median']:.1f}× "
               f"({min(r['retri_over_ordinary']):.1f}–{max(r['retri_over_ordinary']):.1f}×)")
              if r["retriangulations"] else "—",
              f"{r['s_per_step_median']:.2f} / {r['s_per_step_mean']:.2f}",
              f"{r['dem_share']:.1%} ({r['dem_substeps_per_step']:.0f})"] for r in rows]
    write_results("pile_resolution", rows, "Force jumps of a settling pile against the mesh size at the outlines",
                  "The pile of 100 polygons of `bench_dense.py` (a = 0.025–0.04), node repair on; "
                  "‖ΔF‖/‖F‖ of all bodies’ hydrodynamic forces from step to step; "
                  "one BLAS and one MKL thread per run" + (f" ({load})" if load else "")
                  + "; `benchmarks/bench_pile_resolution.py`.",
                  ["mesh", "DOFs at the start", "steps", "ordinary change, median", "re-triangulations",
                   "change at them, median: over the ordinary median (range)", "s a step: median / mean",
                   "DEM share of the time (sub-steps a step)"], cells)


if __name__ == "__main__":
    main(sys.argv[1:])
