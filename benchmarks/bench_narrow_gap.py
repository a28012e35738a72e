"""Narrow-gap accuracy: the resolved force on a disk approaching a wall against the exact one.

Set-up :func:`fluidem.cases.narrow_gap.wall_approach_force` (a 96-gon of radius a = 0.1, a vertex
facing the floor, Stokes, the moving mesh of the free-body runs, size h at the disk): for each
element pair and mesh size, the gap δ from h down to h/50, the resolved F⊥/(μV) against the
bipolar solution 4π/(α − tanh α) (REFERENCES.md), the resolved-film length δ_r that the
lubrication correction of :mod:`fluidem.dem.lubrication` models the mesh by, and the force with
the correction added: the default (the whole law less its value at the cut-off h) and the
deficit alone (δ_r of :data:`fluidem.coupling.contacts.RESOLVED_FILM`).  This is the
measurement behind the contact model of free bodies in a fluid (:mod:`fluidem.coupling.contacts`):
where the resolved force is right a quasi-static correction adds nothing, where it is low the
deficit adds what is missing, where it is high (P2+bubble on coarse meshes, MINI: locking)
nothing can be subtracted.

Writes ``benchmarks/results/narrow_gap.{md,json}``.  Run (about 3 minutes)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_narrow_gap.py
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.narrow_gap import resolved_film_length, wall_approach_force  # noqa: E402
from fluidem.coupling.contacts import RESOLVED_FILM  # noqa: E402
from fluidem.dem.lubrication import SQUEEZE_FILM, Lubrication  # noqa: E402

A = 0.1
GAPS = (1.0, 0.5, 0.25, 0.1, 0.05, 0.02)  # δ / h
RUNS = (("th", 0.04), ("th", 0.02), ("th", 0.01), ("p2b", 0.04), ("p2b", 0.02), ("p2b", 0.01),
        ("p3", 0.02), ("mini", 0.02))


def corrected(element: str, h: float, delta: float, force: float, radius: float, deficit: bool) -> float:
    """Resolved force plus a correction (μ = 1, cut-off h, regularised at 0.01 h): the whole law
    (the default) or, with ``deficit``, only the part the element misses (:data:`RESOLVED_FILM`)."""
    dr = RESOLVED_FILM[element] * h if deficit else None
    if dr == 0.0:
        return force
    lub = Lubrication(viscosity=1.0, range=h, min_gap=0.01 * h, resolved_gap=dr)
    return force + float(lub.coefficient(np.array([delta]), np.array([radius]))[0])


def run() -> list:
    rows = []
    for element, h in RUNS:
        for q in GAPS:
            t0 = time.perf_counter()
            r = wall_approach_force(element, h, q * h, a=A)
            f, ex = r["force"], r["exact"]
            rows.append({"element": element, "h": h, "a_over_h": A / h, "delta_over_h": q, "dofs": r["dofs"],
                         "resolved_over_exact": f / ex,
                         "lubrication_law_over_exact": SQUEEZE_FILM * (r["radius"] / (q * h)) ** 1.5 / ex,
                         "delta_r_over_h": resolved_film_length(f, q * h, r["radius"]) / h,
                         "full_law_over_exact": corrected(element, h, q * h, f, r["radius"], False) / ex,
                         "deficit_over_exact": corrected(element, h, q * h, f, r["radius"], True) / ex,
                         "seconds": time.perf_counter() - t0})
            print(rows[-1], flush=True)
    return rows


def report(rows: list, machine: str) -> None:
    lines = ["# Narrow gaps: resolved force on a disk approaching a wall against the exact solution", "",
             f"Machine: {machine}; one BLAS thread.  A 96-gon of radius a = 0.1 (equal-area radius 0.09996), "
             "a vertex facing the floor at the gap δ, moving towards it without turning, Stokes, box "
             "[−2, 2] × [0, 2]; the moving mesh of the free-body runs, size h at the disk.  Exact: "
             "4π/(α − tanh α), cosh α = 1 + δ/a (bipolar coordinates).  δ_r: the resolved-film length (the "
             "resolved force is the exact one at the gap √(δ² + δ_r²); 0 where it is at least the exact one).  "
             "Full law: plus the default lubrication correction (the law less its value at h).  Deficit: plus "
             "only the part the element misses, with δ_r / h "
             f"({', '.join(f'{k} {v:g}' for k, v in RESOLVED_FILM.items())}).", "",
             "| element | h | a/h | DOFs | δ/h | resolved / exact | δ_r / h | + full law / exact | + deficit / exact "
             "| lubrication law / exact |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['element']} | {r['h']} | {r['a_over_h']:.1f} | {r['dofs']} | {r['delta_over_h']} | "
                     f"{r['resolved_over_exact']:.3f} | {r['delta_r_over_h']:.3f} | {r['full_law_over_exact']:.3f} | "
                     f"{r['deficit_over_exact']:.3f} | {r['lubrication_law_over_exact']:.3f} |")
    (RESULTS / "narrow_gap.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    rows = run()
    machine = machine_description()
    write_json("narrow_gap", machine, rows)
    report(rows, machine)
