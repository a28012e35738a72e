"""The stability lab in one file: the paper's three locking mechanisms, the graded mesh, the stress suite and
the force jump at a re-triangulation, each experiment's tables and figures gathered into
``benchmarks/results/stability.md``.

Every experiment has its own benchmark, which measures and writes ``results/stability_<name>.{md,json}``
(and a PNG where it draws one):

==============  =====================================  ==============================================
experiment      benchmark                              what it measures (paper, Sec.)
==============  =====================================  ==============================================
curvature       ``bench_stability_curvature.py``       element pairs between close counter-moving surfaces (3.1)
junctions       ``bench_stability_junctions.py``       cross-flow at four-body junctions, Voronoi points (3.2)
oscillation     ``bench_stability_oscillation.py``     oscillating grids: regenerating against dragging (3.3, Fig. 5)
jumps           ``bench_stability_jumps.py``           the force jump at a re-triangulation at ≥ 40 edges (3.3)
graded          ``bench_stability_graded.py``          a graded mesh against a uniform one of equal accuracy (2.3)
stress          ``bench_stability_stress.py``          moving packings at φ 0.3–0.7, enclosed fluid pockets (5)
==============  =====================================  ==============================================

Run::

    python benchmarks/bench_stability.py            # gather the stored results (seconds)
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_stability.py --run   # run every experiment first (about an hour)
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parent
RESULTS = HERE / "results"
#: (results name, benchmark script, section title), in the order of the paper
EXPERIMENTS = (
    ("curvature", "bench_stability_curvature.py", "1. Wrong element curvature (Sec. 3.1)"),
    ("junctions", "bench_stability_junctions.py", "2. Cross-flow at junctions (Sec. 3.2)"),
    ("oscillation", "bench_stability_oscillation.py", "3. Oscillating grids (Sec. 3.3, Fig. 5)"),
    ("jumps", "bench_stability_jumps.py", "3b. The force jump at a re-triangulation (Sec. 3.3)"),
    ("graded", "bench_stability_graded.py", "4. Graded mesh (Sec. 2.3)"),
    ("stress", "bench_stability_stress.py", "5. Stress suite: moving packings and fluid pockets (Sec. 5)"),
)


def gathered() -> str:
    """``results/stability.md``: every experiment's stored Markdown under its own heading (its headings one
    level down), with the script that wrote it; a missing result is named, not skipped."""
    lines = ["# The stability lab: results", "",
             "Gathered by `benchmarks/bench_stability.py` from the results each experiment's benchmark stored; "
             "the user's account of them is the documentation page *Stability*.", ""]
    for name, script, title in EXPERIMENTS:
        lines += [f"## {title}", "", f"`benchmarks/{script}` → `results/stability_{name}.md`", ""]
        path = RESULTS / f"stability_{name}.md"
        if not path.exists():
            lines += ["(not run yet)", ""]
            continue
        body = path.read_text().splitlines()
        if body and body[0].startswith("# "):
            body = body[1:]  # its title: the section heading says it
        lines += [("#" + ln) if ln.startswith("#") else ln for ln in body] + [""]
    return "\n".join(lines).rstrip() + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="store_true", help="run every experiment's benchmark first")
    a = ap.parse_args()
    if a.run:
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
        for _, script, title in EXPERIMENTS:
            print(f"{title}: {script}", flush=True)
            subprocess.run([sys.executable, str(HERE / script)], check=True, env=env, cwd=HERE.parent)
    (RESULTS / "stability.md").write_text(gathered())
    print(RESULTS / "stability.md")


if __name__ == "__main__":
    main()
