"""Cost of the full-order field output against the vertex output, per output step.

The ``dfg-cylinder`` example's mesh (DFG 2D-1 channel, h = 0.0125 at the cylinder graded to
0.04, curved cells) with each element pair: the time to build the full-order fields
(:func:`fluidem.io.full_order_fields`: lattice numbering and basis evaluation) and the vertex
fields (:func:`fluidem.io.fluid_point_data`), the time to write each VTU file and its size.
Medians of 5 rounds, one BLAS thread; written to ``benchmarks/results/output.{md,json}``.

Run (about a minute)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_output.py --benchmark-only -p no:cacheprovider
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.scenes import example_scene  # noqa: E402
from fluidem.io import OutputWriter, fluid_point_data, full_order_fields  # noqa: E402
from fluidem.scene import Scene  # noqa: E402
from fluidem.simulation import Simulation, _ccw  # noqa: E402

ELEMENTS = ("th", "p3", "p2b", "mini")
ROUNDS = 5


def _median(f, rounds=ROUNDS):
    out, ts = None, []
    for _ in range(rounds):
        t0 = time.perf_counter()
        out = f()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), out


def measure() -> list:
    rows = []
    for el in ELEMENTS:
        d = example_scene("dfg-cylinder").to_dict()
        d["fluid"]["element"] = el
        sim = Simulation(Scene.from_dict(d))
        space, m = sim.flow.space, sim.flow.mesh
        x = np.random.default_rng(0).standard_normal(space.n_dofs)
        t_full, full = _median(lambda: full_order_fields(space, x))
        t_vert, vert = _median(lambda: fluid_point_data(space, x))
        with tempfile.TemporaryDirectory() as tmp:
            w = OutputWriter(tmp)
            tw_full, p_full = _median(lambda: w.fields_full(0, 0.0, *full))
            tw_vert, p_vert = _median(lambda: w.fields(0, 0.0, m.p[:, :m.nvertices].T, _ccw(m), vert))
            size_full, size_vert = Path(p_full).stat().st_size, Path(p_vert).stat().st_size
            w.close()
        rows.append({"element": el, "dofs": int(space.n_dofs), "triangles": int(m.t.shape[1]),
                     "cells": full[1][0][0], "points_full": len(full[0]), "points_vertex": int(m.nvertices),
                     "build_full_s": t_full, "build_vertex_s": t_vert, "write_full_s": tw_full,
                     "write_vertex_s": tw_vert, "bytes_full": size_full, "bytes_vertex": size_vert})
    return rows


def write(rows: list) -> None:
    machine = machine_description()
    write_json("output", machine, rows)
    lines = ["# Full-order field output against vertex output, per output step", "", f"Machine: {machine}.", "",
             "The `dfg-cylinder` mesh (curved cells) with random coefficients (`benchmarks/bench_output.py`); "
             f"medians of {ROUNDS} rounds.", "",
             "| element | DOFs | triangles | full cells | points full / vertex | build full ms | build vertex ms | "
             "write full ms | write vertex ms | file full kB | file vertex kB |", "|---" * 11 + "|"]
    for r in rows:
        lines.append(f"| {r['element']} | {r['dofs']} | {r['triangles']} | {r['cells']} | {r['points_full']} / "
                     f"{r['points_vertex']} | {1e3 * r['build_full_s']:.1f} | {1e3 * r['build_vertex_s']:.2f} | "
                     f"{1e3 * r['write_full_s']:.1f} | {1e3 * r['write_vertex_s']:.1f} | "
                     f"{r['bytes_full'] / 1e3:.0f} | {r['bytes_vertex'] / 1e3:.0f} |")
    (RESULTS / "output.md").write_text("\n".join(lines) + "\n")


def test_output_cost(benchmark):
    rows = benchmark.pedantic(measure, rounds=1, iterations=1)
    write(rows)
    assert all(r["points_full"] > r["points_vertex"] for r in rows)


if __name__ == "__main__":
    write(measure())
    print((RESULTS / "output.md").read_text())
