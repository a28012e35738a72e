"""Sheared suspensions of free disks in a periodic Stokes shear cell: effective viscosity against
the literature, and what bodies crossing the periodic sides cost.

The cell is the built-in ``sheared-suspension`` example's: the box [0, 2] × [−0.5, 0.5],
periodic in x, walls moving at ∓1 (shear rate γ̇ = 2), Stokes, Taylor–Hood, 20 free neutrally
buoyant disks placed by ``fluidem fill`` (``periodic="x"``, so bodies start across the sides
too) with gaps ≥ h, dt = 0.02, 5 strain units (t = 2.5); μ_eff/μ is the run's ``rheology``
(mean wall shear stress over μ γ̇ in the window t ∈ [1, 2.5], the last 3 strain units, with
its blocking standard error).  Mesh size h = min(0.04, r/1.4): at φ = 0.1 the example's h;
h = 0.025 there moved μ_eff/μ by 0.3 % (1.241 → 1.237, one seed).

Two parts (``--part``):

* ``viscosity``: φ = 0.05, 0.10, 0.15 over three seeds, and φ = 0.2, 0.3 (one seed each by
  default); each φ's mean over seeds with the standard error across seeds, beside Bystricky et
  al. (2D boundary integrals in Taylor–Couette flow: 1.12, 1.22, 1.42 at φ = 0.05, 0.10, 0.15),
  Einstein's 2D dilute law 1 + 2φ and a Krieger–Dougherty curve (1 − φ/φ_m)^(−[η] φ_m) with
  [η] = 2 and φ_m = 0.8 (≈ 1.58 and 2.12 at φ = 0.2 and 0.3).  Reported, not tuned: the cell
  has walls (a layer of bodies next to each wall) and only 20 bodies.
* ``cost``: the cost of seams.  Re-triangulations: the same 20 disks at φ = 0.1 (same seed) (i)
  spread over the whole cell, across the seams (the ``viscosity`` part's run), and (ii) in the
  middle of a box 8 long, periodic, with the same walls (same γ̇), for the same 125 steps, in
  which no body comes within the moving mesh's image margin of a side (checked: the run records
  the images it meshed); seeds 1…``--cost-seeds``.  Time per step in the same 2 × 1 box: (i)
  against (iii) the disks filled into the band x ∈ [0.4, 1.6] (local fraction 0.17) and run for
  10 steps, too few for a rate of re-triangulations.  And within each run (i): where its
  re-triangulations fired (``MeshEvent.fired_at``), near the seam against away from it, in bands
  of equal width across the period (the shear flow is the same at every x).
* ``resolution``: φ = 0.1 and 0.3 (seed 1) again at h = 0.025.  Per step: wall time
  (median over steps 2…), re-triangulations per 100 steps and their reasons; run one after the
  other in one session (the load is in the machine line).

Writes ``benchmarks/results/shear_cell.{md,json}``.  Run (about 40 minutes on a quiet 2-core
machine; ``--seeds 1`` and ``--phis 0.1`` for a quick look)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_shear_cell.py
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

HERE = pathlib.Path(__file__).resolve().parent
N_BODIES = 20
#: the cost part's cell without seams: the bodies start in this band of x
BAND = (0.4, 1.6)
#: the cost part's cell without seams for the re-triangulation rate: the same disks in the middle
#: of a box this long (no disk reaches a side in 5 strain units: the fastest moves about 2)
LONG = 8.0
BOX = (0.0, 2.0, -0.5, 0.5)
#: bands across the period in which the cost part places the re-triangulations of a 2 × 1 run (the
#: first centred on the seam, half a band ≈ the image margin)
N_BANDS = 6
SHEAR_RATE = 2.0
#: Bystricky et al. (2D boundary integrals, Taylor–Couette), the issue's reference values
BYSTRICKY = {0.05: 1.12, 0.10: 1.22, 0.15: 1.42}
#: Krieger–Dougherty with [η] = 2 (Einstein's 2D coefficient) and φ_m = 0.8 (2D random close packing)
KD_INTRINSIC, KD_MAX = 2.0, 0.8


def krieger_dougherty(phi: float) -> float:
    """μ_eff/μ = (1 − φ/φ_m)^(−[η] φ_m) (Krieger & Dougherty 1959), [η] = 2, φ_m = 0.8."""
    return (1.0 - phi / KD_MAX) ** (-KD_INTRINSIC * KD_MAX)


def radius_of(phi: float) -> float:
    """Radius of ``N_BODIES`` equal disks covering ``phi`` of the box."""
    x0, x1, y0, y1 = BOX
    return math.sqrt(phi * (x1 - x0) * (y1 - y0) / (N_BODIES * math.pi))


def scene_dict(phi: float, seed: int, t_end: float, band=None, h=None, length=None) -> dict:
    """The shear cell with 20 free disks at area fraction ``phi`` (of the box), placed by
    :func:`fluidem.scene.fill.fill` over the whole periodic cell or inside ``band`` (x0, x1);
    mesh size ``h`` (default min(0.04, r/1.4)).  ``length``: the same disks as over the whole
    cell (same seed), in the middle of a box ``length`` long (periodic, same walls, same γ̇)."""
    from fluidem.scene.fill import fill

    r = radius_of(phi)
    h = min(0.04, r / 1.4) if h is None else h
    x0, x1, y0, y1 = box = BOX
    if band is None:
        p = fill(BOX, n=N_BODIES, radius=r, periodic="x", min_gap=h, side_gap=h, seed=seed)
    else:
        p = fill((band[0], band[1], y0, y1), n=N_BODIES, radius=r, min_gap=h, side_gap=h, seed=seed)
    bodies = [dict(b, motion="free") for b in p.bodies]
    if length is not None:
        shift = 0.5 * (length - (x1 - x0)) - x0
        bodies = [dict(b, position=[b["position"][0] + shift, b["position"][1]]) for b in bodies]
        box = (0.0, float(length), y0, y1)
    return {"name": f"shear-{phi:g}-{seed}", "gravity": [0.0, 0.0],
            "fluid": {"model": "stokes", "viscosity": 1.0, "element": "th"},
            "domain": {"box": list(box), "left": "periodic", "right": "periodic",
                       "bottom": {"type": "moving-wall", "velocity": [-1.0, 0.0]},
                       "top": {"type": "moving-wall", "velocity": [1.0, 0.0]}},
            "bodies": bodies, "contact": {}, "mesh": {"h": h},
            "time": {"dt": 0.02, "t_end": t_end},
            "output": {"every": 1000, "history_every": 1, "rheology_window": [min(1.0, 0.4 * t_end), t_end]}}


def worker(spec: dict) -> dict:
    """Run one cell; per-step wall time, re-triangulations and images; the run's rheology."""
    import numpy as np

    import fluidem
    from fluidem.scene import Scene

    sys.path.insert(0, str(HERE))
    from results_io import step_recorder

    sc = scene_dict(spec["phi"], spec["seed"], spec["t_end"], spec.get("band"), spec.get("h"),
                    spec.get("length"))
    sim = fluidem.Simulation(Scene.from_dict(sc))
    period = sc["domain"]["box"][1] - sc["domain"]["box"][0]

    def extra(sim, cost):
        ev = sim.flow.last_event
        row = {"images": int(sim.flow.mm.n_bodies - sim.flow.mm.n_real)}
        if ev is not None and ev.retriangulated:  # where it fired, x in [0, period)
            row["fired_x"] = sorted({round(float(x), 4) for x in np.mod(ev.fired_at[:, 0], period)})
        return row

    rows, progress = step_recorder(sim, extra)

    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        sim.run(out, overwrite=True, progress=progress)
        wall = time.perf_counter() - t0
        run = json.loads((pathlib.Path(out) / "run.json").read_text())
    return {"rows": rows, "wall_s": wall, "rheology": run.get("rheology"), "h": sc["mesh"]["h"], "period": period,
            "radius": radius_of(spec["phi"])}


def run_worker(spec: dict) -> dict:
    env = dict(os.environ, PYTHONPATH=str(HERE.parent), OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, __file__, "--worker", json.dumps(spec)], env=env, capture_output=True,
                         text=True, check=False)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if not lines:
        return {"error": (out.stderr.strip().splitlines() or ["no output"])[-1], "rows": []}
    return json.loads(lines[-1])


def replace_row(runs: list, row: dict) -> None:
    """Append ``row`` to ``runs``, dropping an older row of the same kind, φ and seed."""
    runs[:] = [r for r in runs if (r["kind"], r["phi"], r["seed"]) != (row["kind"], row["phi"], row["seed"])]
    runs.append(row)


def step_summary(res: dict) -> dict:
    """Median step time (steps 2…), re-triangulations per 100 steps and their reasons, images met."""
    import numpy as np

    rows = res["rows"]
    sec = np.array([r["seconds"] for r in rows[1:]]) if len(rows) > 1 else np.array([np.nan])
    reasons: dict = {}
    for r in rows:
        if r["retriangulated"]:
            reasons[r["reason"]] = reasons.get(r["reason"], 0) + 1
    n = max(len(rows), 1)
    out = {"steps": len(rows), "median_step_s": float(np.median(sec)), "per_100": 100.0 * sum(reasons.values()) / n,
           "reasons": reasons, "max_images": max((r["images"] for r in rows), default=0)}
    if any("fired_x" in r for r in rows):
        out["bands"] = band_counts(rows, res.get("period", BOX[1] - BOX[0]))
    return out


def band_counts(rows: list, period: float = BOX[1] - BOX[0], n_bands: int = N_BANDS) -> dict:
    """Where one run's re-triangulations fired, across the period: the period cut into ``n_bands``
    bands of equal width, band 0 centred on the seam (x = 0 ≡ ``period``); per band the
    re-triangulations with a fired element in it (one may count in several bands), a ``"seam"``
    one (an outline left its seam) in band 0; those that name no element (the schedule, a contact)
    counted apart."""
    width = period / n_bands
    per_band, unplaced = [0] * n_bands, 0
    for r in rows:
        if not r["retriangulated"]:
            continue
        bands = {int(((x + 0.5 * width) % period) // width) for x in r.get("fired_x", [])}
        if r["reason"] == "seam":
            bands.add(0)
        if not bands:
            unplaced += 1
        for b in bands:
            per_band[b] += 1
    return {"per_band": per_band, "unplaced": unplaced}


def band_lines(spread: dict) -> list:
    """The within-run comparison: re-triangulations fired near the seam (band 0) against the mean
    of the other bands, summed over the seeds of ``spread`` (seed -> row with ``bands``)."""
    from results_io import markdown_table

    seeds = [s for s in sorted(spread) if "bands" in spread[s]]
    if not seeds:
        return []
    total = [sum(spread[s]["bands"]["per_band"][b] for s in seeds) for b in range(N_BANDS)]
    steps = sum(spread[s]["steps"] for s in seeds)
    away = sum(total[1:]) / (N_BANDS - 1)
    rows = [[str(s), str(spread[s]["steps"]), *map(str, spread[s]["bands"]["per_band"]),
             str(spread[s]["bands"]["unplaced"])] for s in seeds]
    rows.append(["all", str(steps), *map(str, total), str(sum(spread[s]["bands"]["unplaced"] for s in seeds))])
    width = (BOX[1] - BOX[0]) / N_BANDS
    heads = [f"x ≈ {b * width:.2g}" + (" (seam)" if b == 0 else "") for b in range(N_BANDS)]
    ratio = total[0] / away if away else float("inf")
    return ["", "Within each 2 × 1 run, where the re-triangulations fired: the period cut into "
            f"{N_BANDS} bands {width:.3g} wide (half a band ≈ the image margin, (drag_reach + 1) h = 0.16: the "
            "strip in which a body near the seam is meshed with its image), the first centred on the seam.  "
            "A re-triangulation counts in each band holding one of its fired elements (`MeshEvent.fired_at`), "
            "one for an outline leaving its seam (`seam`) in the seam's band; scheduled and contact ones name "
            "no element (last column).  The shear flow is the same at every x, so away from numerical "
            "effects each band would see the same number.", "",
            *markdown_table(["seed", "steps", *heads, "no element"], rows), "",
            f"Re-triangulations per 100 steps fired near the seam: {100 * total[0] / steps:.1f} against "
            f"{100 * away / steps:.1f} in a band away from it (mean of the other {N_BANDS - 1}; "
            f"from {min(total[1:])} to {max(total[1:])} in {steps} steps): {ratio:.2f}× (target ≤ 2)."]


def cost_lines(runs: list) -> list:
    """The "What seams cost" section: re-triangulations of the same disks with and without seams
    per seed and summed, and the cost per step in the same box (band row)."""
    from results_io import markdown_table

    ok = [r for r in runs if r["phi"] == 0.1 and not r.get("error")]
    long = {r["seed"]: r for r in ok if r["kind"] == "long"}
    spread = {r["seed"]: r for r in ok if r["kind"] == "spread"}
    seeds = sorted(set(long) & set(spread))
    if not seeds:
        return []
    rows, n_events, n_steps = [], {"long": 0, "spread": 0}, {"long": 0, "spread": 0}
    for seed in seeds:
        for kind, label in (("long", f"{LONG:g} × 1, disks in its middle, none near a seam"),
                            ("spread", "2 × 1, crossing the seams")):
            r = (long if kind == "long" else spread)[seed]
            n_events[kind] += sum(r["reasons"].values())
            n_steps[kind] += r["steps"]
            rows.append([str(seed), label, str(r["steps"]), str(r["max_images"]), f"{r['per_100']:.1f}",
                         json.dumps(r["reasons"])])
    rate = {k: 100.0 * n_events[k] / max(n_steps[k], 1) for k in n_events}
    per_seed = ", ".join(f"{spread[s]['per_100'] / max(long[s]['per_100'], 1e-9):.2f}" for s in seeds)
    out = ["", "## What seams cost (φ = 0.1)", "",
           "The same 20 disks (same seed, same γ̇ = 2, h, dt and 125 steps) in the 2 × 1 cell, where they "
           f"cross the periodic sides, and in the middle of a box {LONG:g} long with the same walls, where "
           "no disk comes within the moving mesh's image margin of a side in the whole run (images meshed: "
           "0).  Their trajectories differ: in the long box the disks by the sides have no neighbours across "
           "them, and the layers of disks sheared apart pass each other once, in the 2 × 1 cell every "
           "period.", "",
           *markdown_table(["seed", "cell", "steps", "images meshed (most)", "re-tri. / 100 steps", "reasons"], rows),
           "", f"Re-triangulations per 100 steps over {len(seeds)} seed(s): {rate['spread']:.1f} with seams "
           f"({n_events['spread']} in {n_steps['spread']} steps) against {rate['long']:.1f} without "
           f"({n_events['long']} in {n_steps['long']}): {rate['spread'] / max(rate['long'], 1e-9):.2f}× "
           f"(target ≤ 2; per seed {per_seed})."]
    out += band_lines(spread)
    band = next((r for r in ok if r["kind"] == "band"), None)
    if band is not None and 1 in spread:
        s = spread[1]
        out += ["", "Cost per step (seed 1, same 2 × 1 box): bodies over the whole cell crossing the seams "
                f"{s['median_step_s']:.3f} s (median of {s['steps']} steps, {s['max_images']} images at most) "
                f"against {band['median_step_s']:.3f} s with the same disks filled into x ∈ [{BAND[0]:g}, "
                f"{BAND[1]:g}] and run {band['steps']} steps ({band['max_images']} images; "
                f"{json.dumps(band['reasons'])}): {s['median_step_s'] / band['median_step_s']:.2f} "
                "(target ≤ 1.3).  The 10-step band run is too short for a re-triangulation rate."]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="viscosity,cost,resolution")
    ap.add_argument("--phis", default="0.05,0.1,0.15,0.2,0.3")
    ap.add_argument("--seeds", type=int, default=3, help="seeds at phi <= 0.15 (default 3)")
    ap.add_argument("--dense-seeds", type=int, default=1, help="seeds at phi > 0.15 (default 1)")
    ap.add_argument("--t-end", type=float, default=2.5, help="end time (default 2.5: 5 strain units)")
    ap.add_argument("--cost-seeds", type=int, default=3, help="seeds of the cost part (default 3)")
    ap.add_argument("--out", default="shear_cell")
    ap.add_argument("--add", action="store_true", help="keep the rows of the last results file that this run "
                    "does not redo (same kind, phi and seed); with --part none: the tables again from that file")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return
    import numpy as np

    sys.path.insert(0, str(HERE))
    from results_io import RESULTS, machine_description, markdown_table, write_json

    parts = args.part.split(",")
    runs = []
    if args.add and (RESULTS / f"{args.out}.json").exists():
        runs = json.loads((RESULTS / f"{args.out}.json").read_text())["rows"]
    if "viscosity" in parts:
        for phi in (float(p) for p in args.phis.split(",")):
            for seed in range(1, 1 + (args.seeds if phi <= 0.15 + 1e-12 else args.dense_seeds)):
                res = run_worker({"phi": phi, "seed": seed, "t_end": args.t_end})
                s = step_summary(res)
                rh = res.get("rheology") or {}
                row = dict(kind="spread", phi=phi, seed=seed, wall_s=res.get("wall_s"), h=res.get("h"),
                           mu=rh.get("mu_eff_over_mu"), se=rh.get("standard_error"), error=res.get("error"), **s)
                replace_row(runs, row)
                write_json(args.out, machine_description(), runs)  # kept if the run stops
                print(json.dumps(row), flush=True)
    if "resolution" in parts:
        for phi in (0.1, 0.3):
            res = run_worker({"phi": phi, "seed": 1, "t_end": args.t_end, "h": 0.025})
            rh = res.get("rheology") or {}
            row = dict(kind="fine", phi=phi, seed=1, wall_s=res.get("wall_s"), h=res.get("h"),
                       mu=rh.get("mu_eff_over_mu"), se=rh.get("standard_error"), error=res.get("error"),
                       **step_summary(res))
            replace_row(runs, row)
            write_json(args.out, machine_description(), runs)  # kept if the run stops
            print(json.dumps(row), flush=True)
    if "cost" in parts:
        res = run_worker({"phi": 0.1, "seed": 1, "t_end": 0.2, "band": list(BAND)})
        row = dict(kind="band", phi=0.1, seed=1, wall_s=res.get("wall_s"), h=res.get("h"), error=res.get("error"),
                   **step_summary(res))
        replace_row(runs, row)
        write_json(args.out, machine_description(), runs)  # kept if the run stops
        print(json.dumps(row), flush=True)
        for seed in range(1, 1 + args.cost_seeds):  # the same disks without and with seams, one after the other
            res = run_worker({"phi": 0.1, "seed": seed, "t_end": args.t_end, "length": LONG})
            row = dict(kind="long", phi=0.1, seed=seed, wall_s=res.get("wall_s"), h=res.get("h"),
                       error=res.get("error"), **step_summary(res))
            replace_row(runs, row)
            write_json(args.out, machine_description(), runs)  # kept if the run stops
            print(json.dumps(row), flush=True)
            if "viscosity" not in parts or seed > args.seeds or 0.1 not in [float(f) for f in args.phis.split(",")]:
                res = run_worker({"phi": 0.1, "seed": seed, "t_end": args.t_end})
                rh = res.get("rheology") or {}
                row = dict(kind="spread", phi=0.1, seed=seed, wall_s=res.get("wall_s"), h=res.get("h"),
                           mu=rh.get("mu_eff_over_mu"), se=rh.get("standard_error"), error=res.get("error"),
                           **step_summary(res))
                replace_row(runs, row)
                write_json(args.out, machine_description(), runs)  # kept if the run stops
                print(json.dumps(row), flush=True)

    machine = machine_description()
    write_json(args.out, machine, runs)
    lines = ["# Sheared suspensions in a periodic Stokes shear cell", "",
             f"Machine: {machine}.  `benchmarks/bench_shear_cell.py`: 20 free disks, box 2 × 1 periodic in x, "
             f"walls at ∓1 (γ̇ = {SHEAR_RATE:g}), Stokes, Taylor–Hood, dt = 0.02, t_end = {args.t_end:g}; "
             "μ_eff/μ over t ∈ [1, t_end] with its blocking standard error.  The runs ran one after the other; "
             "the load average above is the machine's when the file was written (other jobs may have shared "
             "it): compare times only within a table.", ""]
    spread = sorted((r for r in runs if r["kind"] == "spread" and r.get("mu") is not None),
                    key=lambda r: (r["phi"], r["seed"]))
    if spread:
        lines += ["## Effective viscosity", "", *markdown_table(
            ["φ", "seed", "h", "μ_eff/μ", "standard error", "re-tri. / 100 steps", "s/step (median)", "wall s"],
            [[f"{r['phi']:g}", str(r["seed"]), f"{r['h']:.4g}", f"{r['mu']:.4f}", f"{r['se']:.4f}",
              f"{r['per_100']:.0f}", f"{r['median_step_s']:.2f}", f"{r['wall_s']:.0f}"] for r in spread]), ""]
        table = []
        for phi in sorted({r["phi"] for r in spread}):
            mu = np.array([r["mu"] for r in spread if r["phi"] == phi])
            err = mu.std(ddof=1) / math.sqrt(len(mu)) if len(mu) > 1 else float("nan")
            by = BYSTRICKY.get(round(phi, 2))
            table.append([f"{phi:g}", str(len(mu)), f"{mu.mean():.4f}", "–" if math.isnan(err) else f"{err:.4f}",
                          f"{1 + 2 * phi:.3f}", "–" if by is None else f"{by:.2f}", f"{krieger_dougherty(phi):.3f}"])
        lines += ["Mean over seeds (standard error across seeds):", "", *markdown_table(
            ["φ", "seeds", "μ_eff/μ", "± (seeds)", "1 + 2φ", "Bystricky et al.", "Krieger–Dougherty"], table), ""]
    fine = [r for r in runs if r["kind"] == "fine" and r.get("mu") is not None]
    if fine:
        coarse = {r["phi"]: r for r in spread if r["seed"] == 1}
        lines += ["Resolution (seed 1):", "", *markdown_table(
            ["φ", "h", "μ_eff/μ", "at the table's h", "change"],
            [[f"{r['phi']:g}", f"{r['h']:g}", f"{r['mu']:.4f}",
              f"{coarse[r['phi']]['mu']:.4f} (h = {coarse[r['phi']]['h']:.4g})" if r["phi"] in coarse else "–",
              f"{r['mu'] / coarse[r['phi']]['mu'] - 1:+.2%}" if r["phi"] in coarse else "–"] for r in fine]), ""]
    failed = [r for r in runs if r.get("error")]
    for r in failed:
        lines.append(f"* {r['kind']} φ = {r['phi']:g}, seed {r['seed']}: stopped: {r['error']}")
    lines += cost_lines(runs)
    (RESULTS / f"{args.out}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
