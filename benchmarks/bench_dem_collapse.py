"""Dry granular column collapse against Lube et al. (2005) (:mod:`fluidem.cases.collapse`).

Columns of random convex polygons (5–7 corners, sizes 0.8–1 cm, ρ = 10 kg/m², E = 2000 N/m,
γ = 1, μ = 0.5 for every contact, seed 1) settled for 1 s behind a gate from a loose lattice,
released onto a rough floor and left to flow for 3 s, at the requested aspect ratios
a = 0.5, 1, 2 and 4, with at least 10 grains across the smaller side (L0 = max(10, 10/a) D).
For each: the measured a = H0/L0, (L∞ − L0)/L0, Lube's 1.2 a (a ≤ 2.3) or 1.9 a^(2/3), their
ratio, the number of grains, the solid fraction of the settled column, the 99th-percentile
grain motion in the last 0.05 s, the wall seconds and the load average.  Written (after
each column, so a partial run keeps its rows) to ``benchmarks/results/column_collapse.{md,json}``.

Run (about 20 min of CPU; one BLAS thread)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dem_collapse.py [a ...]

or ``python -m pytest benchmarks/bench_dem_collapse.py -p no:cacheprovider -q -s``.
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.collapse import D, MU, collapse, lube  # noqa: E402

ASPECTS = (0.5, 1.0, 2.0, 4.0)
SEED = 1


def width_grains(aspect: float) -> int:
    """Column width in grains: at least 10 grains across the smaller side."""
    return int(round(max(10, 10 / aspect)))


def measure_one(aspect: float) -> dict:
    t0 = time.perf_counter()
    a, runout, sim, t_flow = collapse(aspect, width_grains=width_grains(aspect), seed=SEED, mu=MU)
    wall = time.perf_counter() - t0
    col = sim.column
    return {"aspect_requested": aspect, "a": a, "runout": runout, "lube": lube(a), "ratio": runout / lube(a),
            "grains": col["grains"], "width_grains": width_grains(aspect), "L0_m": col["L0"], "H0_m": col["H0"],
            "packing_fraction": col["packing_fraction"], "mu": MU, "seed": SEED, "flow_time_s": t_flow,
            "last_move_D": sim.last_move / D, "steps": int(sim.cost.steps), "wall_s": wall,
            "load_average": os.getloadavg()[0]}


def write(rows: list) -> None:
    machine = machine_description()
    write_json("column_collapse", machine, rows)
    lines = ["| a (requested) | a = H0/L0 | (L∞−L0)/L0 | Lube | ratio | grains (L0) | packing fraction | μ | "
             "99 % move in last 0.05 s | wall s | load average |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['aspect_requested']:g} | {r['a']:.2f} | {r['runout']:.2f} | {r['lube']:.2f} | "
                     f"{r['ratio']:.2f} | {r['grains']} ({r['width_grains']} D) | {r['packing_fraction']:.3f} | "
                     f"{r['mu']:g} | {r['last_move_D']:.1e} D | {r['wall_s']:.0f} | {r['load_average']:.1f} |")
    (RESULTS / "column_collapse.md").write_text(
        f"Machine: {machine}.\n\n"
        "Dry column collapse (`fluidem.cases.collapse.collapse`, seed 1): random convex polygons (5–7 corners, "
        "sizes 0.8–1 cm, elongation 1–1.4, ρ = 10 kg/m²), E = 2000 N/m, γ = 1, μ = 0.5 grain–grain, grain–floor "
        "and grain–wall, rough floor of fixed grains.  Initial packing: a loose square lattice (spacing 1.05 D) "
        "settled for 1 s behind the gate; packing fraction = solid area fraction of the settled column between "
        "the floor top and one grain below the column top.  a = H0/L0 measured on the settled column; "
        "flow for 3 s after opening the gate; runout front = rightmost point of a grain touching another.  "
        "Lube et al. (2005, J. Fluid Mech. 508): (L∞−L0)/L0 ≈ 1.2 a for a ≤ 2.3, 1.9 a^(2/3) above.\n\n"
        + "\n".join(lines) + "\n")


def measure(aspects=ASPECTS) -> list:
    rows = []
    for aspect in aspects:
        rows.append(measure_one(aspect))
        write(rows)
        r = rows[-1]
        print(f"a = {r['a']:.2f}: (L_inf - L0)/L0 = {r['runout']:.2f}, Lube {r['lube']:.2f}, ratio {r['ratio']:.2f}, "
              f"{r['grains']} grains, phi = {r['packing_fraction']:.3f}, {r['wall_s']:.0f} s", flush=True)
    return rows


def test_column_collapse():
    rows = measure()
    assert len(rows) == len(ASPECTS)
    assert all(0.5 < r["ratio"] < 2.0 for r in rows)


if __name__ == "__main__":
    measure(tuple(float(s) for s in sys.argv[1:]) or ASPECTS)
    print((RESULTS / "column_collapse.md").read_text())
