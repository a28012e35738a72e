"""The dragged mesh in dense settling suspensions: how often it is re-triangulated, why, at what
cost, and how much the body forces jump at a re-triangulation.

Scenes: ``benchmarks/scenes/{dense12,packed12,loose20}.toml`` (12–20 polygons settling onto
the floor of a closed box, h = 0.02, E = 10⁴) and the built-in ``suspension`` example (105
bodies, expensive: about 10 s a step).  For each scene and each source tree given (``--src``:
the package to import, e.g. this checkout and an older copy of it, so that before and after
run side by side on one machine in one session) a worker process steps the scene and records
per step: the wall-clock time, whether the mesh was re-triangulated and why
(:class:`fluidem.mesh.MeshEvent` ``reason``), and the fluid forces on the bodies.  The force
jump at a re-triangulation, |F_k − F_{k−1}| / |F_{k−1}| over all bodies, is set against the
same change between ordinary steps (median and 90th percentile).

Writes ``benchmarks/results/dense_mesh.{md,json}`` (``--out``).  Run (about 20 minutes with two
trees; the suspension over 100 steps another 20)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dense_mesh.py --src before=/path/to/old --src after=.
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dense_mesh.py --src before=/path/to/old --src after=. \
        --scenes suspension --steps 100 --out dense_mesh_suspension
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

HERE = pathlib.Path(__file__).resolve().parent
SCENES = {"dense12": HERE / "scenes" / "dense12.toml", "packed12": HERE / "scenes" / "packed12.toml",
          "loose20": HERE / "scenes" / "loose20.toml", "suspension": "suspension"}
STEPS = {"dense12": 100, "packed12": 100, "loose20": 100, "suspension": 30}


def worker(scene: str, n_steps: int) -> dict:
    """Step ``scene`` ``n_steps`` times with the ``fluidem`` on ``sys.path``; the per-step rows."""
    import numpy as np

    import fluidem
    from fluidem.cases.scenes import example_scene

    sys.path.insert(0, str(HERE))
    from results_io import step_recorder

    path = example_scene(scene) if scene == "suspension" else scene
    sim = fluidem.Simulation(path)

    def extra(sim, cost):
        f = sim.flow.__dict__.get("_forces_now")
        return {"mesh_seconds": float(getattr(cost, "mesh", 0.0) or 0.0),
                "forces": None if f is None else np.asarray(f[1], float).tolist()}

    rows, progress = step_recorder(sim, extra)

    status = "finished"
    with tempfile.TemporaryDirectory() as out:
        try:
            sim.run(out, n_steps=n_steps, overwrite=True, progress=progress)
        except Exception as exc:  # a stopped run is a result too (its message goes in the table)
            status = f"stopped: {str(exc).splitlines()[0][:160]}"
    return {"file": fluidem.__file__, "status": status, "rows": rows}


def summary(rows: list) -> dict:
    """Re-triangulations per 100 steps and their reasons, step cost, force jumps."""
    import numpy as np

    n = len(rows)
    retri = [r for r in rows if r["retriangulated"]]
    reasons = {}
    for r in retri:
        reasons[r["reason"]] = reasons.get(r["reason"], 0) + 1
    change, at_retri = [], []
    for a, b in zip(rows[:-1], rows[1:]):
        if a["forces"] is None or b["forces"] is None:
            continue
        fa, fb = np.asarray(a["forces"]), np.asarray(b["forces"])
        c = float(np.linalg.norm(fb - fa) / max(np.linalg.norm(fa), 1e-300))
        (at_retri if b["retriangulated"] else change).append(c)
    sec = np.array([r["seconds"] for r in rows]) if rows else np.zeros(1)
    sec_r = [r["seconds"] for r in retri]
    sec_o = [r["seconds"] for r in rows if not r["retriangulated"]]
    return {"steps": n, "retriangulations": len(retri), "per_100": 100.0 * len(retri) / max(n, 1),
            "reasons": reasons, "mean_step_s": float(sec.mean()),
            "retri_step_s": float(np.mean(sec_r)) if sec_r else float("nan"),
            "ordinary_step_s": float(np.mean(sec_o)) if sec_o else float("nan"),
            "force_change_median": float(np.median(change)) if change else float("nan"),
            "force_change_p90": float(np.percentile(change, 90)) if change else float("nan"),
            "force_jump_median": float(np.median(at_retri)) if at_retri else float("nan"),
            "force_jump_max": float(np.max(at_retri)) if at_retri else float("nan")}


def run_worker(src: str, scene: str, n_steps: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(pathlib.Path(src).resolve()), OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, __file__, "--worker", str(SCENES[scene]), str(n_steps)], env=env,
                         capture_output=True, text=True, check=False)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if not lines:
        return {"file": src, "status": f"worker failed: {out.stderr.strip().splitlines()[-1:]}", "rows": []}
    return json.loads(lines[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", action="append", default=[], help="label=path of a source tree (repeatable)")
    ap.add_argument("--scenes", default="dense12,packed12,loose20,suspension")
    ap.add_argument("--steps", type=int, default=None, help="steps per scene (default: 100, suspension 30)")
    ap.add_argument("--out", default="dense_mesh", help="results name (benchmarks/results/NAME.{md,json})")
    ap.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker[0], int(args.worker[1]))))
        return
    sys.path.insert(0, str(HERE))
    from results_io import RESULTS, machine_description, write_json

    trees = [s.split("=", 1) for s in (args.src or [f"after={HERE.parent}"])]
    results = []
    for scene in args.scenes.split(","):
        n = args.steps or STEPS[scene]
        for label, src in trees:
            t0 = time.perf_counter()
            res = run_worker(src, scene, n)
            s = summary(res["rows"])
            s.update(scene=scene, tree=label, status=res["status"], wall_s=time.perf_counter() - t0)
            results.append(s)
            print(f"{scene:10s} {label:7s} {s['steps']:4d} steps, {s['retriangulations']:3d} re-triangulations "
                  f"{s['reasons']}, {s['mean_step_s']:.2f} s/step, force jump {s['force_jump_median']:.3g} vs "
                  f"change {s['force_change_median']:.3g}; {res['status']}", flush=True)
    machine = machine_description()
    write_json(args.out, machine, results)
    lines = ["# Dense settling suspensions: re-triangulations of the dragged mesh", "",
             f"Machine: {machine}.  `benchmarks/bench_dense_mesh.py`; trees: "
             + ", ".join(f"{lab} = `{src}`" for lab, src in trees) + ".", "",
             "Force change: |F_k − F_{k−1}| / |F_{k−1}| over all bodies between consecutive steps; "
             "*jump* at re-triangulation steps, *change* between ordinary ones (median, 90th percentile).", "",
             "| scene | tree | steps | re-tri. / 100 steps | reasons | s/step (mean, ordinary, re-tri.) "
             "| force change median / p90 | force jump median / max | status |",
             "|---|---|---|---|---|---|---|---|---|"]
    for s in results:
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(s["reasons"].items())) or "–"
        lines.append(f"| {s['scene']} | {s['tree']} | {s['steps']} | {s['per_100']:.1f} | {reasons} | "
                     f"{s['mean_step_s']:.2f}, {s['ordinary_step_s']:.2f}, {s['retri_step_s']:.2f} | "
                     f"{s['force_change_median']:.3g} / {s['force_change_p90']:.3g} | "
                     f"{s['force_jump_median']:.3g} / {s['force_jump_max']:.3g} | {s['status']} |")
    (RESULTS / f"{args.out}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
