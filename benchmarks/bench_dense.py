"""Cost of a settling, piling suspension: the contacts' share of a step, per body and per step.

Polygons (disks, rectangles, triangles, hexagons; equal-area radius 0.025–0.04; ρ_s/ρ_f = 2,
ν = 0.01, g = 9.81) drawn by :func:`fluidem.scene.fill` at an area fraction of 0.35 in the lower
part of a closed box, so that they touch the floor and each other within the first steps;
Navier–Stokes, P2+bubble/P1dc, the contact law of the dense repro scenes (``E = 1e4``, μ = 0.3,
γ = 0.3) with the default lubrication and repulsion, h = 0.012 (about a third of the mean radius),
dt = 0.01.  Each case runs in its own process (peak memory), one BLAS thread; per step: wall
seconds, the DEM's share (``dem`` of :class:`fluidem.cost.CostSplit`: the contact sub-steps of
:class:`fluidem.coupling.contacts.FluidContacts`), DEM sub-steps and passes, re-triangulations.
Medians over the steps after the first.

Target (issue "Hundreds of bodies in fluid"): the DEM's share of a dense step ≤ 25 %.

Run (tens of minutes)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dense.py [--before PATH] [N ...]
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dense.py --apart [N]   # a dense step against the same bodies apart
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dense.py --lu [N ...]   # SuperLU against PARDISO, at once

    python benchmarks/bench_dense.py --log OUT_DIR RUN.LOG [PEAK_MIB] [--steps A B] [--name NAME]   # a long run
    python benchmarks/bench_dense.py --narrow N [--before PATH]   # the short-range models' gaps of N bodies
    python benchmarks/bench_dense.py --groups N   # one DEM pass of N bodies: grouped sub-steps against one group
    python benchmarks/bench_dense.py --continue OUT_DIR SCENE.toml STEP K --before PATH [--name NAME]   # twice
    python benchmarks/bench_dense.py --continue OUT_DIR SCENE.toml STEP K --repair [--name NAME]   # repair on/off

writes ``benchmarks/results/dense.{md,json}`` (``--lu``: ``dense_lu.{md,json}``; the ``pardiso`` extra
installed, MKL pinned to one thread).  ``--before PATH`` also runs every case, side by side,
with the fluidem package found at ``PATH`` (a checkout of an earlier version; keys it does not know
are left out of its scene).  ``python benchmarks/bench_dense.py --scene N FILE.toml`` writes the scene
of ``N`` bodies.

``--narrow`` times :func:`fluidem.dem.repulsion.pair_gaps`, the narrow phase of the repulsion and the
lubrication that runs at every DEM sub-step, on the pairs of the scene of ``N`` bodies whose bounding
circles are within ``h`` (their outlines padded to the most vertices of any body, as in the DEM), the
median of 15 calls, with ``--before`` also with an earlier checkout, each in its own process, one right
after the other; writes ``dense_narrow.{md,json}``.

``--groups`` times one contact pass (:meth:`fluidem.coupling.contacts.FluidContacts.mean_load`) of the scene
of ``N`` bodies at its start, with random velocities (seeded; 0.05 and 1.7 rad/s rms, about the settling
speed) that bring some pairs within the repulsion's range: each group of bodies out of each other's reach
at its own sub-steps (:meth:`~fluidem.coupling.contacts.FluidContacts.sub_step_groups`) against every body at
the sub-steps of the stiffest (as before groups), median of 5, alternating in one process; the groups, body
sub-steps and how far the loads differ; writes ``dense_groups.{md,json}``.

``--continue`` continues the run in ``OUT_DIR`` (of ``SCENE.toml``, with a checkpoint of step ``STEP``) by ``K``
steps twice at once, in two copies of ``OUT_DIR``: with this version and with the package at ``PATH``
(``fluidem run --restart -v``); medians of the ordinary steps, the mean step, the DEM's time and share, its
sub-steps and passes, the re-triangulations, and how far the bodies of the two ended apart (``history.csv``);
writes ``dense_continue.{md,json}`` (``--name``: ``NAME.{md,json}``).  With ``--repair`` instead of
``--before``: this version twice, the second with the node repair of ``[mesh] repair = true``
switched on from the checkpoint on (a restart refuses a changed scene, so the moving mesh's
``repair_sweeps`` is set on the restored mesh, ``--continue-repaired``), and the drag change of each
kind of step (ordinary, repaired, re-triangulated): Σ|ΔF_y| / Σ|F_y| over the bodies.

``--log`` reads a run of such a scene too long for a benchmark session (``fluidem run FILE.toml -v
> RUN.LOG``, continued with ``--restart`` as often as needed): the verbose lines of ``RUN.LOG`` (each
step's cost split) and the re-triangulations of ``OUT_DIR/events.log``, and writes
``dense_run.{md,json}`` (``--name``: ``NAME.{md,json}``; ``--steps A B``: steps A to B only): medians of
ordinary and re-triangulation steps, each part's share of the
wall time, the DEM's sub-steps and passes, LUs, the re-triangulation cadence and the force change
at them.  ``PEAK_MIB``: the run process's peak resident memory, if measured (``VmHWM`` in
``/proc/PID/status`` on Linux).
"""

from __future__ import annotations

import json
import os
import re
import resource
import subprocess
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json, write_results  # noqa: E402

CASES = {10: 60, 40: 40, 100: 20, 300: 20}  # bodies: steps
#: scene keys of this version an earlier one may not know (left out of the scene ``--before`` runs)
NEW_KEYS = ("zero_net_flux", "rheology_window")
H, DT = 0.012, 0.01


#: gap between the bodies of the "apart" variant (:func:`scene_dict`): 2.5 h, beyond the lubrication range h
APART_GAP = 0.03


def scene_dict(n: int, steps: int, apart: bool = False) -> dict:
    """``n`` polygons at area fraction 0.35 in the lower part of a closed box (width ∝ √n); ``apart``: the same
    polygons (the same draws of shapes and sizes) over the whole box with gaps of :data:`APART_GAP`."""
    from fluidem.scene.fill import fill

    mean_area = np.pi * 0.0325**2
    width = float(np.sqrt(n * mean_area / 0.35 / 0.8))  # the bed region is 0.8 as tall as wide
    region = (0.0, width, 0.0, (1.3 if apart else 0.8) * width)
    gap = APART_GAP if apart else 0.004
    p = fill(region, n=n, shapes=("disk", "rectangle", "triangle", "hexagon"), radius=(0.025, 0.04), seed=2,
             min_gap=gap, **({"side_gap": gap} if apart else {}))
    bodies = [dict(b, density=2.0) for b in p.bodies]
    return {"name": f"dense-{n}", "gravity": [0.0, -9.81],
            "fluid": {"density": 1.0, "viscosity": 0.01, "element": "p2b"},
            "domain": {"box": [0.0, width, 0.0, 1.3 * width]}, "bodies": bodies,
            "contact": {"E": 1e4, "mu": 0.3, "gamma": 0.3}, "mesh": {"h": H},
            "time": {"dt": DT, "t_end": steps * DT}, "output": {"every": 100000, "fields": False}}


def run_case(path: str, steps: int) -> dict:
    """Run a scene file ``steps`` steps without output; per-step costs and counts."""
    import warnings

    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    warnings.simplefilter("ignore")
    sim = Simulation(Scene.from_toml(path))
    rows = []

    def record(k, n, t, cost):
        rows.append({"wall": cost.total, "dem": cost.parts.get("dem", 0.0), "solve": cost.parts.get("solve", 0.0),
                     "rebuild": cost.parts.get("rebuild", 0.0), "mesh": cost.parts.get("mesh", 0.0),
                     "substeps": cost.counts.get("dem_substeps", 0), "passes": cost.counts.get("dem_passes", 0),
                     "retriangulated": int(bool(getattr(sim.flow.last_event, "retriangulated", False)))})

    t0 = time.perf_counter()
    error = None
    try:
        sim.run(out_dir=None, progress=record, n_steps=steps)
    except Exception as exc:  # a stopped run is a result too
        error = str(exc).splitlines()[0][:300]
    return {"rows": rows, "seconds": time.perf_counter() - t0, "dofs": int(sim.flow.dofs), "error": error,
            "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def summary(n: int, out: dict) -> dict:
    r = out["rows"][1:] or out["rows"]
    col = {k: np.array([x[k] for x in r], float) for k in r[0]} if r else {}
    contact = col["passes"] > 0 if r else np.zeros(0, bool)
    share = col["dem"] / np.maximum(col["wall"], 1e-300) if r else np.zeros(0)
    return {"bodies": n, "steps": len(out["rows"]), "dofs": out["dofs"], "error": out["error"],
            "s_per_step": float(np.median(col["wall"])) if r else None,
            "dem_share_median": float(np.median(share)) if r else None,
            "dem_share_total": float(col["dem"].sum() / col["wall"].sum()) if r else None,
            "contact_steps": int(contact.sum()),
            "substeps_per_pass": float(col["substeps"][contact].sum() / max(col["passes"][contact].sum(), 1)),
            "passes_per_contact_step": float(np.median(col["passes"][contact])) if contact.any() else 0.0,
            "retriangulations_per_100": 100.0 * col["retriangulated"].sum() / max(len(r), 1) if r else None,
            "s_per_step_per_body": float(np.median(col["wall"])) / n if r else None,
            "peak_mib": out["peak_mib"], "seconds": out["seconds"]}


def main(argv: list[str]) -> None:
    if argv[:1] == ["--scene"]:
        from fluidem.scene import Scene

        n = int(argv[1])
        Scene.from_dict(scene_dict(n, CASES.get(n, 30))).to_toml(argv[2])
        return
    if argv[:1] == ["--case"]:
        print(json.dumps(run_case(argv[1], int(argv[2]))))
        return
    if argv[:1] == ["--apart"]:
        dense_against_apart(int(argv[1]) if len(argv) > 1 else 100)
        return
    if argv[:1] == ["--narrow-case"]:
        print(json.dumps(narrow_case(argv[1])))
        return
    if argv[:1] == ["--narrow"]:
        narrow_phase(int(argv[1]), argv[3] if argv[2:3] == ["--before"] else None)
        return
    if argv[:1] == ["--groups"]:
        grouped_pass(int(argv[1]))
        return
    if argv[:1] == ["--continue"]:
        before = argv[argv.index("--before") + 1] if "--before" in argv else None
        name = argv[argv.index("--name") + 1] if "--name" in argv else "dense_continue"
        continue_side_by_side(argv[1], argv[2], int(argv[3]), int(argv[4]), before, results=name,
                              repair="--repair" in argv)
        return
    if argv[:1] == ["--continue-repaired"]:
        continue_repaired(argv[1:])
        return
    if argv[:1] == ["--log"]:
        steps = tuple(int(a) for a in argv[argv.index("--steps") + 1:argv.index("--steps") + 3]) \
            if "--steps" in argv else None
        name = argv[argv.index("--name") + 1] if "--name" in argv else "dense_run"
        peak = argv[3] if len(argv) > 3 and not argv[3].startswith("--") else None
        summarise_run_log(argv[1], argv[2], float(peak) if peak else None, steps=steps, name=name)
        return
    if argv[:1] == ["--lu"]:
        lu_side_by_side([int(a) for a in argv[1:]] or [100])
        return
    before = None
    if argv[:1] == ["--before"]:
        before, argv = argv[1], argv[2:]
    cases = {int(a): CASES.get(int(a), 30) for a in argv} or CASES
    rows = []
    for n, steps in cases.items():
        path = RESULTS / f"dense-{n}.toml"
        RESULTS.mkdir(exist_ok=True)
        main(["--scene", str(n), str(path)])
        versions = [("this version", None)]
        if before is not None:
            old = RESULTS / f"dense-{n}-before.toml"
            old.write_text("".join(ln for ln in path.read_text().splitlines(True) if not ln.startswith(NEW_KEYS)))
            versions.insert(0, ("before", old))
        for version, scene in versions:
            env = dict(os.environ, **({"PYTHONPATH": before} if scene is not None else {}))
            out = subprocess.run([sys.executable, __file__, "--case", str(scene or path), str(steps)],
                                 capture_output=True, text=True, check=True, env=env)
            rows.append(dict(summary(n, json.loads(out.stdout.strip().splitlines()[-1])), version=version))
            print(rows[-1], flush=True)
            if scene is not None:
                scene.unlink()
        path.unlink()
    machine = machine_description()
    # keep the rows of the cases not run this time (each row says its own machine line)
    for r in rows:
        r["machine"] = machine
    old = RESULTS / "dense.json"
    if old.exists():
        kept = [r for r in json.loads(old.read_text())["rows"]
                if not any(r["bodies"] == x["bodies"] and r.get("version") == x["version"] for x in rows)]
        rows = sorted(kept + rows, key=lambda r: (r["bodies"], r.get("version") != "before"))
    write_json("dense", machine, rows)
    lines = ["# Settling suspensions: cost per step and the contacts' share", "",
             f"One BLAS thread; h = {H}, dt = {DT}; medians over the steps after the first; the versions of a "
             "case side by side, one after the other, in one session.", "",
             "| bodies | version | DOFs | steps | s/step | s/step/body | DEM share (median, total) "
             "| DEM sub-steps/pass | passes/contact step | re-triangulations/100 steps | peak MiB | stopped |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['bodies']} | {r['version']} | {r['dofs']} | {r['steps']} | {r['s_per_step']:.3g} | "
                     f"{r['s_per_step_per_body']:.3g} | {r['dem_share_median']:.1%}, {r['dem_share_total']:.1%} | "
                     f"{r['substeps_per_pass']:.1f} | {r['passes_per_contact_step']:.0f} | "
                     f"{r['retriangulations_per_100']:.0f} | {r['peak_mib']:.0f} | {r['error'] or ''} |")
    lines += ["", "Machines:"] + sorted({f"- {r['bodies']} bodies: {r.get('machine', '')}" for r in rows})
    (RESULTS / "dense.md").write_text("\n".join(lines) + "\n")


def lu_side_by_side(cases: list) -> None:
    """Each case with ``fluid.lu_backend = "superlu"`` and ``"pardiso"`` (one MKL thread), the two processes
    started together on the two cores (the faster one ends first); writes ``results/dense_lu.{md,json}``."""
    from fluidem.scene import Scene

    rows = []
    for n in cases:
        procs = {}
        for lu in ("superlu", "pardiso"):
            d = scene_dict(n, CASES.get(n, 30))
            d["fluid"]["lu_backend"] = lu
            path = RESULTS / f"dense-{n}-{lu}.toml"
            Scene.from_dict(d).to_toml(str(path))
            env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
            procs[lu] = (path, subprocess.Popen([sys.executable, __file__, "--case", str(path), str(CASES.get(n, 30))],
                                                stdout=subprocess.PIPE, text=True, env=env))
        outs = {lu: proc.communicate()[0] for lu, (_, proc) in procs.items()}
        load = os.getloadavg()[0]  # the last minute's, with both running
        for path, _ in procs.values():
            path.unlink()
        for lu, (_, proc) in procs.items():
            out = outs[lu]
            if proc.returncode:
                raise SystemExit(f"the {lu} case of {n} bodies failed (exit code {proc.returncode})")
            res = json.loads(out.strip().splitlines()[-1])
            r = res["rows"][1:]
            rows.append(dict(summary(n, res), lu=lu, solve_s=float(np.median([x["solve"] for x in r])), load=load))
            print(rows[-1], flush=True)
    notes = []
    for n in cases:
        by = {r["lu"]: r for r in rows if r["bodies"] == n}
        ratio = by["superlu"]["s_per_step"] / by["pardiso"]["s_per_step"]
        verdict = ", ".join(f"{'met' if by[k]['s_per_step'] <= 2.0 else 'missed'} with {k}" for k in by)
        notes.append(f"\n{n} bodies: SuperLU / PARDISO = {ratio:.2f} per step"
                     + (f"; the target 'at most 2 s a step for 100 bodies' is {verdict}." if n == 100 else "."))
    write_results("dense_lu", rows, "Settling suspensions: the LU backends side by side",
                  f"`benchmarks/bench_dense.py --lu`: the settling suspension of `dense.md` (h = {H}, "
                  f"dt = {DT}, P2+bubble, the lagged LU) with `fluid.lu_backend = \"superlu\"` and `\"pardiso\"` "
                  "(Intel MKL through the optional `pardiso` extra, one MKL thread), the two processes started "
                  "together on the two cores (the faster one ends first); medians over the steps after the first.",
                  ["bodies", "LU", "DOFs", "steps", "s/step", "solve s/step", "DEM share (total)",
                   "re-triangulations/100 steps", "peak MiB", "load at the end"],
                  [[str(r["bodies"]), r["lu"], str(r["dofs"]), str(r["steps"]), f"{r['s_per_step']:.3g}",
                    f"{r['solve_s']:.3g}", f"{r['dem_share_total']:.1%}", f"{r['retriangulations_per_100']:.0f}",
                    f"{r['peak_mib']:.0f}", f"{r['load']:.1f}"] for r in rows], notes)


def dense_against_apart(n: int, steps: int = 12) -> None:
    """A dense step against a step of the same bodies apart: the ``n`` polygons packed in the bed region
    (gaps 0.004, settling onto the floor and each other) and spread over the whole box with gaps of
    :data:`APART_GAP`, ``steps`` steps each, one after the other; writes ``results/dense_apart.{md,json}``."""
    from results_io import markdown_table

    rows = []
    for apart in (False, True):
        path = RESULTS / f"dense-{n}-{'apart' if apart else 'packed'}.toml"
        from fluidem.scene import Scene

        Scene.from_dict(scene_dict(n, steps, apart=apart)).to_toml(str(path))
        out = subprocess.run([sys.executable, __file__, "--case", str(path), str(steps)], capture_output=True,
                             text=True, check=True)
        path.unlink()
        res = json.loads(out.stdout.strip().splitlines()[-1])
        r = res["rows"][1:]
        contact = [x for x in r if x["passes"] > 0]
        rows.append({"bodies": n, "variant": "apart" if apart else "packed", "dofs": res["dofs"],
                     "steps": len(res["rows"]), "s_per_step": float(np.median([x["wall"] for x in r])),
                     "solve_s": float(np.median([x["solve"] for x in r])),
                     "dem_s": float(np.median([x["dem"] for x in r])),
                     "contact_steps": len(contact), "substeps_per_step": float(np.median([x["substeps"] for x in r])),
                     "retriangulations": int(sum(x["retriangulated"] for x in res["rows"])),
                     "peak_mib": res["peak_mib"], "error": res["error"], "load": os.getloadavg()[0]})
        print(rows[-1], flush=True)
    machine = machine_description()
    write_json("dense_apart", machine, rows)
    ratio = rows[0]["s_per_step"] / rows[1]["s_per_step"]
    lines = ["# A dense step against the same bodies apart", "",
             f"Machine: {machine}.  `benchmarks/bench_dense.py --apart {n}`: the {n} polygons of the settling "
             f"suspension (h = {H}, dt = {DT}, P2+bubble, the LU of `fluid.lu_backend = \"auto\"`) packed in the bed "
             f"region with gaps of 0.004 (they settle onto the floor and each other: contacts, lubrication, "
             f"repulsion) and spread over the whole box with gaps of {APART_GAP} (2.5 h: no short-range force); "
             f"{steps} steps each, one after the other; medians over the steps after the first.", "",
             *markdown_table(["variant", "DOFs", "steps", "s/step", "solve s", "DEM s", "steps with contact passes",
                              "DEM sub-steps/step", "re-triangulations", "peak MiB", "load"],
                             [[r["variant"], str(r["dofs"]), str(r["steps"]), f"{r['s_per_step']:.3g}",
                               f"{r['solve_s']:.3g}", f"{r['dem_s']:.3g}", str(r["contact_steps"]),
                               f"{r['substeps_per_step']:.0f}", str(r["retriangulations"]), f"{r['peak_mib']:.0f}",
                               f"{r['load']:.1f}"] for r in rows]),
             "", f"Dense step / apart step: {ratio:.2f} (target ≤ 2)."]
    (RESULTS / "dense_apart.md").write_text("\n".join(lines) + "\n")




#: one verbose progress line: step, then the cost split ``part ms + ... = total ms`` (fluidem.progress)
_STEP = re.compile(r"^step (\d+)/\d+ .*?  ((?:\w+ [\d.]+ \+ )*\w+ [\d.]+) = ([\d.]+) ms$")
_DEM = re.compile(r" DEM (\d+) sub-steps in (\d+) pass")
_LU = re.compile(r" LU (\d+) ")
_BODY = re.compile(r", (\d+) body sub-steps")
_RETRI = re.compile(r"^step=(\d+) .*retriangulation reason=(\w+).*?(?:force change ([\d.]+) %)?$")


def parse_run_log(log_text: str, events_text: str) -> dict:
    """The steps of a verbose run log (the last line of each step number: a restart repeats none) and the
    re-triangulations of its events.log: ``{"steps": {step: {part: s, "total": s, "substeps", "passes", "lu"}},
    "retri": {step: (reason, force change or nan)}, "dofs": int}``."""
    steps = {}
    for line in log_text.splitlines():
        m = _STEP.match(line.rstrip())
        if not m:
            continue
        parts = {k: float(v) / 1e3 for k, v in (p.rsplit(" ", 1) for p in m.group(2).split(" + "))}
        lu, dem, body = _LU.search(line), _DEM.search(line), _BODY.search(line)
        steps[int(m.group(1))] = dict(parts, total=float(m.group(3)) / 1e3, substeps=int(dem.group(1)) if dem else 0,
                                      passes=int(dem.group(2)) if dem else 0, lu=int(lu.group(1)) if lu else -1,
                                      body_substeps=int(body.group(1)) if body else None)
    retri, dofs = {}, 0
    for line in events_text.splitlines():
        m = _RETRI.match(line)
        if m:
            retri[int(m.group(1))] = (m.group(2), float(m.group(3)) if m.group(3) else float("nan"))
        d = re.search(r"initial: \d+ triangles, (\d+) DOFs", line)
        if d:
            dofs = int(d.group(1))
    return {"steps": steps, "retri": retri, "dofs": dofs}


def summarise_run_log(out_dir: str, log_path: str, peak_mib: float | None = None, steps: tuple | None = None,
                      name: str = "dense_run") -> dict:
    """Write ``NAME.{md,json}`` (``dense_run`` by default) from a long run's verbose log and events.log (module
    docstring); ``steps`` (first, last): only those."""
    import pathlib

    out = pathlib.Path(out_dir)
    run = parse_run_log(pathlib.Path(log_path).read_text(errors="replace"), (out / "events.log").read_text())
    steps_of_run, window = run["steps"], steps
    steps = {k: v for k, v in steps_of_run.items() if window is None or window[0] <= k <= window[1]}
    if not steps:
        where = f" in steps {window[0]}–{window[1]}" if window else ""
        raise SystemExit(f"{log_path}: no verbose step lines{where}")
    first = min(steps)
    keep = sorted(k for k in steps if k > first)  # the first step of a (re)start holds a fresh analysis and LU
    if not keep:
        raise SystemExit(f"{log_path}: fewer than two verbose step lines")
    at = [k for k in keep if k in run["retri"]]
    ordinary = [k for k in keep if k not in run["retri"]]
    parts = [p for p in steps[keep[0]] if p not in ("total", "substeps", "passes", "lu", "body_substeps")]
    total = sum(steps[k]["total"] for k in keep)

    def med(ks, p):
        return float(np.median([steps[k][p] for k in ks])) if ks else float("nan")

    lus = [steps[k]["lu"] for k in keep if steps[k]["lu"] >= 0]
    dem = [k for k in keep if steps[k]["passes"] > 0]
    forces = np.array([run["retri"][k][1] for k in at], float)
    reasons = {}
    for k in at:
        reasons[run["retri"][k][0]] = reasons.get(run["retri"][k][0], 0) + 1
    row = {"scene": json.loads((out / "run.json").read_text()).get("scene"), "dofs": run["dofs"],
           "steps": [keep[0], keep[-1]], "n_steps": len(keep), "n_retri": len(at), "reasons": reasons,
           "retri_per_100": 100.0 * len(at) / len(keep),
           "ordinary": {p: med(ordinary, p) for p in parts + ["total"]},
           "at_retri": {p: med(at, p) for p in parts + ["total"]},
           "mean_s_per_step": total / len(keep),
           "share": {p: sum(steps[k][p] for k in keep) / total for p in parts},
           "lus": (lus[-1] - steps[first]["lu"]) if lus and steps[first]["lu"] >= 0 else None,
           "dem_substeps_per_pass": float(sum(steps[k]["substeps"] for k in dem) / max(sum(steps[k]["passes"]
                                                                                          for k in dem), 1)),
           "dem_passes_median": float(np.median([steps[k]["passes"] for k in dem])) if dem else 0.0,
           "force_change_median_pct": float(np.nanmedian(forces)) if len(forces) else None,
           "force_change_max_pct": float(np.nanmax(forces)) if len(forces) else None,
           "peak_mib": peak_mib, "machine": machine_description()}
    write_json(name, row["machine"], [row])
    head = ["part", "ordinary step, median s", "re-triangulation step, median s", "share of the wall time"]
    table = [[p, f"{row['ordinary'][p]:.2f}", f"{row['at_retri'][p]:.2f}", f"{row['share'][p]:.1%}"] for p in parts]
    table.append(["total", f"{row['ordinary']['total']:.2f}", f"{row['at_retri']['total']:.2f}", "100 %"])
    from results_io import markdown_table

    lines = [f"# A long run of `{row['scene']}`: cost per step through settling and contact", "",
             f"Machine: {row['machine']}; one BLAS and one MKL thread. Steps {keep[0]}–{keep[-1]} of the run "
             f"({len(keep)} steps; the first step of every (re)start, which holds a fresh analysis and LU, left "
             f"out), {row['dofs']} DOFs at the start.", "",
             *markdown_table(head, table), "",
             f"- Mean {row['mean_s_per_step']:.2f} s a step (re-triangulations included).",
             f"- Re-triangulations: {len(at)} in {len(keep)} steps, {row['retri_per_100']:.1f} per 100 "
             f"({', '.join(f'{k} {v}' for k, v in sorted(reasons.items()))}); force change at them "
             + (f"median {row['force_change_median_pct']:.2f} %, largest {row['force_change_max_pct']:.2f} %."
                if row["force_change_median_pct"] is not None else "none."),
             f"- LUs: {row['lus']} in {len(keep)} steps (re-triangulations included); DEM: "
             f"{row['dem_substeps_per_pass']:.1f} sub-steps a pass, {row['dem_passes_median']:.0f} passes a contact "
             "step (median).",
             f"- Peak resident memory of the run process: {peak_mib:.0f} MiB." if peak_mib else
             "- Peak resident memory: not measured."]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    return row


def narrow_case(path: str) -> dict:
    """Median milliseconds of :func:`fluidem.dem.repulsion.pair_gaps` on the pairs within ``h`` of a scene."""
    from scipy.spatial import cKDTree

    from fluidem.dem.repulsion import pair_gaps
    from fluidem.geometry import rigid_transform
    from fluidem.scene import Scene

    sc = Scene.from_toml(path)
    verts = [b.local_vertices() for b in sc.bodies]
    K = max(len(v) for v in verts)
    V = np.stack([np.vstack([v, np.repeat(v[:1], K - len(v), axis=0)]) for v in verts])
    pos = np.array([b.position for b in sc.bodies], float)
    W = rigid_transform(V, np.column_stack([pos, [b.angle for b in sc.bodies]]))
    r = np.array([np.linalg.norm(v, axis=1).max() for v in verts])
    pairs = np.array(sorted(cKDTree(pos).query_pairs(2 * r.max() + H)), dtype=np.int64).reshape(-1, 2)
    i, j = pairs[:, 0], pairs[:, 1]
    keep = np.linalg.norm(pos[i] - pos[j], axis=1) < r[i] + r[j] + H
    i, j = i[keep], j[keep]
    times = []
    for _ in range(15):
        t0 = time.perf_counter()
        pair_gaps(W, i, j, pos, r, H)
        times.append(time.perf_counter() - t0)
    return {"median_ms": 1e3 * float(np.median(times)), "pairs": int(len(i)), "rows": int(K),
            "real_vertices": float(np.mean([len(v) for v in verts]))}


def narrow_phase(n: int, before: str | None) -> None:
    """``--narrow``: this version (and ``before``) side by side, ``dense_narrow.{md,json}``."""
    from fluidem.scene import Scene

    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"dense-{n}-narrow.toml"
    Scene.from_dict(scene_dict(n, 1)).to_toml(str(path))
    rows = []
    for version, where in ([("before", before)] if before else []) + [("this version", None)]:
        env = dict(os.environ, **({"PYTHONPATH": where} if where else {}))
        out = subprocess.run([sys.executable, __file__, "--narrow-case", str(path)], capture_output=True, text=True,
                             check=True, env=env)
        rows.append(dict(json.loads(out.stdout.strip().splitlines()[-1]), version=version, bodies=n))
        print(rows[-1], flush=True)
    path.unlink()
    notes = []
    if len(rows) == 2:
        notes = ["", f"Ratio before / this version: {rows[0]['median_ms'] / rows[1]['median_ms']:.2f}."]
    write_results("dense_narrow", rows, "The short-range models' narrow phase (`pair_gaps`) of a settling suspension",
                  f"One BLAS thread. The scene of `bench_dense.py` with {n} bodies at its start (triangles, rectangles "
                  f"and disks), the pairs whose bounding circles are within h = {H}; outlines padded to the most "
                  "vertices of any body, as in the DEM; median of 15 calls, each version in its own process, one right "
                  "after the other.",
                  ["version", "pairs", "rows per outline", "real vertices (mean)", "ms a call"],
                  [[r["version"], str(r["pairs"]), str(r["rows"]), f"{r['real_vertices']:.2f}", f"{r['median_ms']:.2f}"]
                   for r in rows], notes)


def grouped_pass(n: int, repeats: int = 5) -> None:
    """``--groups``: one contact pass of ``n`` bodies grouped and as one group, ``dense_groups.{md,json}``."""
    from fluidem.coupling.contacts import FluidContacts
    from fluidem.scene import Scene

    sc = Scene.from_dict(scene_dict(n, 1))
    bodies = sc.bodies
    free = np.arange(len(bodies))
    outlines = [np.asarray(b.local_vertices()) for b in bodies]
    poses = np.array([[*b.position, b.angle] for b in bodies])
    rng = np.random.default_rng(0)
    vel = np.column_stack([0.05 * rng.standard_normal((n, 2)), 0.05 / 0.03 * rng.standard_normal(n)])

    def contacts(least: int | None) -> FluidContacts:
        c = FluidContacts(bodies, free, outlines, [None] * n, domain=sc.domain, fluid=sc.fluid, contact=sc.contact,
                          gravity=sc.gravity, h=sc.mesh.h)
        grouped = c.sub_step_groups
        if least is None:  # every body at the sub-steps of the stiffest group, as before groups
            c.sub_step_groups = lambda dt, p, v, vc, seen=None: [(free, *c.sub_steps(dt, p, v, vc))]
        elif least > 1:  # each group at least ``least`` sub-steps: the accuracy of the others' film
            c.sub_step_groups = lambda *a, **k: [(b, max(m, least), f, by) for b, m, f, by in grouped(*a, **k)]
        return c

    runs = {"grouped": contacts(1), "grouped, at least 8": contacts(8), "grouped, at least 32": contacts(32),
            "one group": contacts(None)}
    times = {k: [] for k in runs}
    loads = {}
    for _ in range(repeats):
        for name, c in runs.items():
            before = c.body_substeps
            t0 = time.perf_counter()
            loads[name] = c.load_function(0.0, DT, poses, vel)(vel, np.zeros((n, 3)))
            times[name].append(time.perf_counter() - t0)
            runs[name].last_work = c.body_substeps - before
    groups = runs["grouped"].sub_step_groups(DT, poses, vel, vel)
    ref = loads["one group"]
    stiffest = groups[0][0]
    rows = [{"version": name, "bodies": n, "median_s": float(np.median(times[name])), "groups": len(groups) if
             name != "one group" else 1, "largest_sub_steps": int(groups[0][1]), "body_sub_steps": int(c.last_work),
             "load_difference": float(np.abs(loads[name] - ref).max() / np.abs(ref).max()),
             "stiffest_difference": float(np.abs(loads[name][stiffest] - ref[stiffest]).max() / np.abs(ref).max())}
            for name, c in runs.items()]
    print(rows, flush=True)
    write_results("dense_groups", rows, "One contact pass: each group of bodies at its own sub-steps",
                  f"One BLAS thread. The scene of `bench_dense.py` with {n} bodies at its start, random velocities "
                  f"(seed 0), dt = {DT}; median of {repeats} passes, the versions alternating in one process. Groups "
                  "(sub-steps, bodies): " + ", ".join(f"({g[1]}, {len(g[0])})" for g in groups) + ".",
                  ["version", "s a pass", "groups", "sub-steps of the stiffest", "body sub-steps",
                   "load difference from one group (of the largest load)", "in the stiffest group"],
                  [[r["version"], f"{r['median_s']:.3f}", str(r["groups"]), str(r["largest_sub_steps"]),
                    str(r["body_sub_steps"]), f"{r['load_difference']:.2g}", f"{r['stiffest_difference']:.2g}"]
                   for r in rows],
                  ["", f"Ratio one group / grouped: {rows[-1]['median_s'] / rows[0]['median_s']:.2f} (time), "
                   f"{rows[-1]['body_sub_steps'] / rows[0]['body_sub_steps']:.1f} (body sub-steps). The stiffest "
                   "group moves as in one group; the others take the sub-steps their own gaps need, and their film "
                   "(implicit, first order in the sub-step) differs from that at the stiffest group's sub-steps by "
                   "what the rows with more sub-steps show."])


def continue_repaired(argv: list[str]) -> None:
    """``fluidem run`` with ``argv``, the moving mesh's node repair switched on whatever the checkpoint
    it continues holds (``--continue --repair``)."""
    import dataclasses

    import fluidem.mesh.moving as moving
    from fluidem.cli import main as cli
    from fluidem.mesh.params import REPAIR_SWEEPS

    drag = moving.drag_step

    def repaired_drag_step(mesh, new, ev):
        if mesh.params.repair_sweeps != REPAIR_SWEEPS:
            mesh.params = dataclasses.replace(mesh.params, repair_sweeps=REPAIR_SWEEPS)
        return drag(mesh, new, ev)

    moving.drag_step = repaired_drag_step
    sys.exit(cli(argv))


def force_changes(out_dir, step: int) -> dict:
    """Median and largest Σ|ΔF_y| / Σ|F_y| over the bodies, per kind of step after ``step`` (``history.csv``,
    ``events.log``): ``ordinary``, ``repaired``, ``retriangulated``."""
    import csv
    import pathlib

    rows = [r for r in csv.DictReader(open(pathlib.Path(out_dir) / "history.csv")) if int(r["step"]) >= step]
    steps = sorted({int(r["step"]) for r in rows})
    ids = sorted({r["id"] for r in rows})
    F = np.zeros((len(steps), len(ids)))
    for r in rows:
        F[steps.index(int(r["step"])), ids.index(r["id"])] = float(r["fy"])
    change = np.abs(np.diff(F, axis=0)).sum(axis=1) / np.abs(F[:-1]).sum(axis=1)
    ev = (pathlib.Path(out_dir) / "events.log").read_text()
    repaired = {int(m) for m in re.findall(r"step=(\d+) \S+ mesh repair", ev)}
    retri = {int(m) for m in re.findall(r"step=(\d+) \S+ retriangulation", ev)}
    kind = np.array(["retriangulated" if j in retri else "repaired" if j in repaired else "ordinary"
                     for j in steps[1:]])
    return {kd: {"steps": int((kind == kd).sum()), "median": float(np.median(change[kind == kd])),
                 "max": float(change[kind == kd].max())}
            for kd in ("ordinary", "repaired", "retriangulated") if (kind == kd).any()}


def continue_side_by_side(out_dir: str, scene: str, step: int, k: int, before: str | None,
                          results: str = "dense_continue", repair: bool = False) -> None:
    """``--continue``: the run in ``out_dir`` continued from step ``step`` by ``k`` steps, this version and
    ``before`` (or, ``repair``, this version with the node repair) at once (module docstring);
    ``{results}.{md,json}``."""
    import csv
    import pathlib
    import shutil
    import tempfile

    from fluidem.scene import Scene

    sc = Scene.from_toml(scene)
    d = sc.to_dict()
    d["time"]["t_end"] = (step + k) * sc.time.dt
    work = pathlib.Path(tempfile.mkdtemp(prefix="dense_continue_"))
    path = work / "scene.toml"
    Scene.from_dict(d).to_toml(str(path))
    versions = [("this version", None)] + ([("before", before)] if before else [])
    if repair:
        versions = [("this version", None), ("with the repair", None)]
    procs = []
    for name, where in versions:
        copy = work / name.replace(" ", "_")
        shutil.copytree(out_dir, copy)
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
                   **({"PYTHONPATH": where} if where else {}))
        log = open(copy / "continue.log", "w")
        run = ["run", str(path), "--out", str(copy), "--restart", str(copy / "checkpoints" / f"ckpt_{step:07d}.npz"),
               "-v"]
        cmd = [sys.executable, __file__, "--continue-repaired"] if name == "with the repair" else \
            [sys.executable, "-m", "fluidem"]
        procs.append((name, copy, log, subprocess.Popen(cmd + run, stdout=log, stderr=subprocess.STDOUT, env=env,
                                                        cwd=where or None)))
    for _, _, log, proc in procs:
        proc.wait()
        log.close()

    def final(copy, at):
        rows = sorted((r for r in csv.DictReader(open(copy / "history.csv")) if int(r["step"]) == at),
                      key=lambda r: int(r["id"]) if r["id"].isdigit() else r["id"])
        return np.array([[float(r[c]) for c in ("x", "y", "vx", "vy")] for r in rows])

    rows = []
    for name, copy, _, proc in procs:
        run = parse_run_log((copy / "continue.log").read_text(errors="replace"), (copy / "events.log").read_text())
        st = {j: v for j, v in run["steps"].items() if j > step}
        ks = sorted(st)
        ordinary = [j for j in ks if j not in run["retri"]]
        wall = sum(st[j]["total"] for j in ks)
        dem = sum(st[j].get("dem", 0.0) for j in ks)
        rows.append({"version": name, "steps": [ks[0], ks[-1]] if ks else None, "exit": proc.returncode,
                     "ordinary_s": float(np.median([st[j]["total"] for j in ordinary])) if ordinary else None,
                     "dem_s": dem, "wall_s": wall, "dem_share": dem / wall if wall else None,
                     "substeps_per_step": float(np.mean([st[j]["substeps"] for j in ks])) if ks else None,
                     "passes_per_step": float(np.mean([st[j]["passes"] for j in ks])) if ks else None,
                     "body_substeps_per_step": (float(np.mean([st[j]["body_substeps"] for j in ks]))
                                                if ks and all(st[j]["body_substeps"] is not None for j in ks)
                                                else None),
                     "retriangulations": sum(j in run["retri"] for j in ks),
                     "force_change": force_changes(copy, step) if proc.returncode == 0 else None})
    notes = []
    if len(procs) == 2 and all(r["exit"] == 0 for r in rows):
        a, b = (final(copy, step + k) for _, copy, _, _ in procs)
        start = final(procs[0][1], step)
        moved = np.median(np.linalg.norm(a[:, :2] - start[:, :2], axis=1))
        speed = np.median(np.linalg.norm(a[:, 2:], axis=1))
        notes = ["", f"At step {step + k} the bodies of the two are {np.abs(a[:, :2] - b[:, :2]).max():.3g} apart at "
                 f"most (median displacement over the {k} steps {moved:.3g}), their velocities "
                 f"{np.abs(a[:, 2:] - b[:, 2:]).max():.3g} (median speed {speed:.3g})."]
    for r in rows:
        if r["force_change"]:
            notes.append(f"{r['version']}: drag change Σ|ΔF_y| / Σ|F_y| a step, median (largest): " + ", ".join(
                f"{kd} {v['median']:.2%} ({v['max']:.2%}, {v['steps']} steps)" for kd, v in r["force_change"].items()))
    shutil.rmtree(work)

    def cell(v, f):
        return "" if v is None else format(v, f)

    write_results(results, rows, f"`{sc.name}` continued from step {step} by {k} steps, two versions at once",
                  f"The two runs at the same time on the two cores, one BLAS and one MKL thread each; medians over the "
                  f"ordinary steps (re-triangulations left out), totals over all {k}.",
                  ["version", "steps", "ordinary step, median s", "mean step s", "DEM s (share)",
                   "DEM sub-steps a step", "passes a step", "body sub-steps a step", "re-triangulations"],
                  [[r["version"], f"{r['steps'][0]}–{r['steps'][1]}" if r["steps"] else "",
                    cell(r["ordinary_s"], ".3f"), f"{r['wall_s'] / k:.3f}",
                    f"{r['dem_s']:.1f} ({cell(r['dem_share'], '.1%')})", cell(r["substeps_per_step"], ".0f"),
                    cell(r["passes_per_step"], ".2f"), cell(r["body_substeps_per_step"], ".0f"),
                    str(r["retriangulations"])] for r in rows], notes)


if __name__ == "__main__":
    main(sys.argv[1:])
