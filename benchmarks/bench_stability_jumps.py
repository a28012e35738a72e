"""The force jump at a re-triangulation against the ordinary step change (turning and settling ellipses).

:mod:`fluidem.cases.jumps`: a prescribed ellipse translating and turning at Re 30 and a free
ellipse settling and turning in a channel, Navier–Stokes on the dragged moving mesh (defaults:
``strategy = "drag"``, ``min_angle_margin = 0``), at mesh sizes where the outline has 12–80 mesh
edges; for the 40-edge runs also with a 3° smallest-angle trigger margin.  Per run: the median
and 90th percentile of the relative force change between ordinary steps, the relative force
change at each re-triangulation step, their ratio, the interpolation noise of the transfer
(relative L2 change of u^n), and the same against the rms force with second differences.

Writes ``benchmarks/results/stability_jumps.{md,json}``.  Run (about 16 minutes on one core)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_stability_jumps.py [--report] [label ...]
"""

from __future__ import annotations

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, markdown_table  # noqa: E402

from fluidem.cases.jumps import (jump_figures, jump_run, settling_ellipse_scene,  # noqa: E402
                                 switch_ingredient, turning_ellipse_scene)

TURN_STEPS = 120
SETTLE_STEPS = 150

#: label -> (case, h, min_angle_margin or None)
RUNS = {
    "turn h=0.04": ("turn", 0.04, None),
    "turn h=0.018": ("turn", 0.018, None),
    "turn h=0.012": ("turn", 0.012, None),
    "turn h=0.009": ("turn", 0.009, None),
    "turn h=0.018, margin 3°": ("turn", 0.018, 3.0),
    "turn h=0.04, ellipse shape, uniform mesh": ("plain", 0.04, None),
    "settle h=0.04": ("settle", 0.04, None),
    "settle h=0.012": ("settle", 0.012, None),
    "settle h=0.008": ("settle", 0.008, None),
    "settle h=0.012, margin 3°": ("settle", 0.012, 3.0),
}

OUT = RESULTS / "stability_jumps.json"


#: label -> (base run, switch, what it changes)
ABLATIONS = {
    "turn h=0.018, L2 projection": ("turn h=0.018", "l2", "u^n, u^{n−1} by L2 projection"),
    "turn h=0.018, BDF1 restart": ("turn h=0.018", "bdf1", "BDF1 at the re-triangulation step"),
    "turn h=0.018, first-order w": ("turn h=0.018", "first-order-w",
                                    "mesh velocity of the last displacement (new nodes: neighbours' mean) "
                                    "at the re-triangulation step"),
    "turn h=0.018, Stokes": ("turn h=0.018", "stokes", "no history: quasi-steady Stokes, the geometry alone"),
    "turn h=0.04, L2 projection": ("turn h=0.04", "l2", "u^n, u^{n−1} by L2 projection"),
    "turn h=0.04, Stokes": ("turn h=0.04", "stokes", "no history: quasi-steady Stokes, the geometry alone"),
    "turn h=0.018, dt = 0.02": ("turn h=0.018", "dt", "twice the time step, the same 1.2 time units"),
    "turn h=0.018, 80-gon": ("turn h=0.018", "80", "the 80-sided polygon of the h = 0.009 run"),
    "turn h=0.012, 80-gon": ("turn h=0.012", "80", "the 80-sided polygon of the h = 0.009 run"),
}


def one(label: str) -> dict:
    """Run ``RUNS[label]`` (or an ablation of ``ABLATIONS``); its figures, rows and machine line."""
    base, switch, _ = ABLATIONS.get(label, (label, None, ""))
    case, h, margin = RUNS[base]
    if switch == "dt":
        scene, switch = turning_ellipse_scene(h, steps=TURN_STEPS // 2, dt=0.02), None
    elif switch == "80":
        scene, switch = turning_ellipse_scene(h, steps=TURN_STEPS, sides=80), None
    elif case in ("turn", "plain"):
        scene = turning_ellipse_scene(h, steps=TURN_STEPS, plain=case == "plain")
    else:
        scene = settling_ellipse_scene(h, steps=SETTLE_STEPS)
    if switch == "stokes":
        d = scene.to_dict()
        d["fluid"]["model"] = "stokes"
        scene, switch = type(scene).from_dict(d), None
    t0 = time.perf_counter()
    hook = None if switch is None else (lambda flow: switch_ingredient(flow, switch))
    r = jump_run(scene, min_angle_margin=margin, flow_hook=hook)
    wall = time.perf_counter() - t0
    return {"case": case, "h": h, "min_angle_margin": margin, "dofs": r["dofs"], "edges": r["edges"],
            "steps": len(r["rows"]), "wall_seconds": wall, "machine": machine_description(),
            "figures": jump_figures(r["rows"]), "rows": r["rows"]}


def _round(v):
    """Floats to 9 significant digits (the kink is 1e-4 of the force), in nested lists and dicts."""
    if isinstance(v, float):
        return float(f"{v:.9g}")
    if isinstance(v, list):
        return [_round(x) for x in v]
    if isinstance(v, dict):
        return {k: _round(x) for k, x in v.items()}
    return v


def _write(data: dict) -> None:
    """``stability_jumps.json``: one line per run."""
    runs = ",\n".join(f"{json.dumps(k)}: {json.dumps(_round(v), separators=(',', ':'))}"
                       for k, v in data["runs"].items())
    OUT.write_text("{\"runs\": {\n" + runs + "\n}}\n")


def _noise(v) -> str:
    return "–" if v is None else f"{v:.1e}"


def report(data: dict) -> None:
    """``stability_jumps.md`` from the stored runs."""
    runs = data["runs"]
    loads = sorted(float(r["machine"].split("load average ")[1].split()[0]) for r in runs.values())
    head = ["run", "sides", "DOFs", "re-tri.", "ordinary change median / p90", "jump median / max",
            "ratio median (max) to ordinary median", "jump median / ordinary p90", "noise median",
            "largest |ΔF| at re-tri. / rms F", "2nd diff. ordinary / re-tri. median (max), of rms F", "wall s"]
    body = []
    for lab, r in runs.items():
        f = r["figures"]
        noise = "–" if f["noise_median"] is None else f"{f['noise_median']:.1e}"
        body.append([lab, str(r["edges"]), str(r["dofs"]), str(f["retriangulations"]),
                     f"{100 * f['ordinary_median']:.2f} % / {100 * f['ordinary_p90']:.2f} %",
                     f"{100 * f['jump_median']:.2f} % / {100 * f['jump_max']:.2f} %",
                     f"{f['ratio']:.2f} ({f['ratio_max']:.1f})", f"{f['ratio_p90']:.2f}", noise,
                     f"{100 * f['step_rms_jump_max']:.2f} %",
                     f"{f['d2_ordinary_median']:.1e} / {f['d2_jump_median']:.1e} ({f['d2_jump_max']:.1e})",
                     f"{r['wall_seconds']:.0f}"])
    lines = ["# Force jumps at re-triangulations: turning and settling ellipses", "",
             "`benchmarks/bench_stability_jumps.py`, cases `fluidem.cases.jumps`. Navier–Stokes, P2+bubble/P1dc, "
             "dragged mesh graded from the body (growth 1.2 up to min(8 h, 0.1)), dt = 0.01, package defaults "
             "(`min_angle_margin = 0`) unless a margin is named. *turn*: prescribed ellipse 0.15 × 0.075 "
             f"translating at U = 1 and turning at 0.5 rad/s, Re 30, {TURN_STEPS} steps. *settle*: free ellipse "
             f"0.1 × 0.05, density 2, released at angle 0.6 in a closed channel 1 × 4, g = 1, {SETTLE_STEPS} "
             "steps. The polygon has about perimeter / h sides (*sides*; each is one mesh edge on the outline).", "",
             "Relative force change |F_k − F_{k−1}| / |F_{k−1}| (force vector of the fluid on the body); "
             "*ordinary*: steps without a re-triangulation; *jump*: re-triangulation steps; first 5 steps left "
             "out. *noise*: relative L2 change of u^n by the transfer. Medians unless named.", "",
             f"Machine: {runs[next(iter(runs))]['machine'].split(', load')[0]}; one BLAS thread "
             f"(`OPENBLAS_NUM_THREADS=1`), runs one after another on 2 shared cores, load average "
             f"{loads[0]:.1f}–{loads[-1]:.1f} (per run in the JSON).", ""]
    lines += markdown_table(head, body)
    lines += ["", "Per re-triangulation (step, reason, force change, noise):", ""]
    for lab, r in runs.items():
        ev = "; ".join(f"{j['step']} {j['reason']} {100 * j['change']:.2f} % ({_noise(j['noise'])})"
                       for j in r["figures"]["jumps"])
        lines.append(f"- {lab}: {ev}")
    what = {lab.split(", ", 1)[1]: w for lab, (_, _, w) in ABLATIONS.items()}
    lines += ["", "*2nd diff.*: |F_k − 2F_{k−1} + F_{k−2}| over the rms force of the run, the kink a jump leaves "
              "(at a re-triangulation step k the larger of those at k and k + 1). The largest jumps come in the "
              "first 20 steps, where the impulsively started flow still changes by 1–5 % per step.", "",
              "Switched ingredients (label after the comma): " + "; ".join(f"*{k}*: {w}" for k, w in what.items())
              + "."]
    ref = runs.get("turn h=0.009")
    if ref is not None:
        R = np.array([r["force"] for r in ref["rows"]])
        rms = float(np.sqrt(np.mean(np.sum(R[5:] ** 2, axis=1))))
        lines += ["", "Force against the h = 0.009 run (80 sides), |F_h(t) − F_0.009(t)| over its rms force, "
                  "steps 6–120 (the mesh's discretisation error where the polygon is the same):", ""]
        rows = []
        for lab in ("turn h=0.04", "turn h=0.018", "turn h=0.012", "turn h=0.018, 80-gon", "turn h=0.012, 80-gon"):
            if lab in runs and len(runs[lab]["rows"]) == len(ref["rows"]):
                e = np.linalg.norm(np.array([r["force"] for r in runs[lab]["rows"]])[5:] - R[5:], axis=1) / rms
                f = runs[lab]["figures"]
                rows.append([lab, str(runs[lab]["edges"]), f"{np.median(e):.1e} / {e.max():.1e}",
                             f"{f['d2_jump_median']:.1e}", f"{f['noise_median']:.1e}"])
        lines += markdown_table(["run", "sides", "difference median / max", "kink at re-tri. (2nd diff., median)",
                                 "noise median"], rows)
    (RESULTS / "stability_jumps.md").write_text("\n".join(lines) + "\n")


def main(argv) -> None:
    data = json.loads(OUT.read_text()) if OUT.exists() else {"runs": {}}
    if "--report" not in argv:
        labels = [a for a in argv if not a.startswith("--")] or list(RUNS) + list(ABLATIONS)
        for lab in labels:
            r = one(lab)
            data["runs"][lab] = r
            RESULTS.mkdir(exist_ok=True)
            _write(data)
            f = r["figures"]
            print(f"{lab}: edges {r['edges']} dofs {r['dofs']} retri {f['retriangulations']} ratio "
                  f"{f['ratio']:.2f} max {f['ratio_max']:.2f} p90 {f['ratio_p90']:.2f} {r['wall_seconds']:.0f} s",
                  flush=True)
    order = list(RUNS) + list(ABLATIONS)
    data["runs"] = {k: data["runs"][k] for k in order if k in data["runs"]} | \
        {k: v for k, v in data["runs"].items() if k not in order}
    _write(data)
    report(data)


def test_stability_jumps(benchmark):
    benchmark.pedantic(main, args=([],), rounds=1, iterations=1)
    assert np.isfinite(json.loads(OUT.read_text())["runs"]["turn h=0.018"]["figures"]["ratio"])


if __name__ == "__main__":
    main(sys.argv[1:])
