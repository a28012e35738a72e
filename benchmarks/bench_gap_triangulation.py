"""How much the resolved force in a narrow gap depends on the triangulation of the gap.

In a settling pile a re-triangulation can change the hydrodynamic forces of close pairs by several
times an ordinary step's change, also of pairs far from the element that fired: every gap gets a new
triangulation.  Measured here on the disk approaching a wall of :mod:`fluidem.cases.narrow_gap`
(a 96-gon of radius a = 0.1, a vertex facing the floor, Stokes, P2+bubble/P1dc, the moving mesh of the
free-body runs, size h at the disk), the force against the exact one (bipolar coordinates), at
a/h = 2.5 (about the dense suspensions' a/h ≈ 2.1–3.3 at h = 0.012) and a/h = 5:

* *fresh*: a new :class:`fluidem.mesh.MovingMesh` at each gap δ/h = 0.5, 0.25, 0.1, the disk shifted
  along x by 0, 0.13, 0.29, 0.41 and 0.77 h (five triangulations of the same gap): min, median, max;
* *approach*: one moving mesh whose disk is moved towards the wall from δ = h to 0.05 h in steps of
  0.025 h (:meth:`~fluidem.mesh.MovingMesh.update`, re-triangulating as its triggers say: here at
  every step) against a fresh mesh at each gap: the ranges in three bands of δ/h.

Run (about ten minutes)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_gap_triangulation.py

writes ``benchmarks/results/gap_triangulation.{md,json}``.
"""

from __future__ import annotations

import os
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import write_results  # noqa: E402

A, SEGMENTS, ELEMENT = 0.1, 96, "p2b"
A_OVER_H = (2.5, 5.0)
SHIFTS = (0.0, 0.13, 0.29, 0.41, 0.77)
GAPS = (0.5, 0.25, 0.1)
BANDS = ((0.5, 1.01), (0.2, 0.5), (0.0, 0.2))


def force_over_exact(mm, centre, delta: float) -> float:
    """F⊥ on the disk of ``mm`` at ``centre`` moving down at unit speed, over the exact force at gap ``delta``."""
    from fluidem.cases.narrow_gap import approach_load, bipolar_force
    from fluidem.dem.lubrication import equal_area_radius
    from fluidem.geometry import polygon_area, regular_polygon

    r = float(equal_area_radius(polygon_area(regular_polygon(A, SEGMENTS))))
    return approach_load(mm, ELEMENT, centre)[0] / float(bipolar_force(delta, r))


def _mesh(h: float, delta: float, x: float = 0.0):
    from fluidem.cases.narrow_gap import wall_approach_mesh

    return wall_approach_mesh(h, delta, A, SEGMENTS, x)


def measure(a_over_h: float) -> dict:
    """Fresh triangulations of three gaps and the approach of one moving mesh, at ``a_over_h``."""
    h = A / a_over_h
    fresh = {}
    for frac in GAPS:
        values = []
        for s in SHIFTS:
            mm, centre = _mesh(h, frac * h, s * h)
            values.append(force_over_exact(mm, centre, frac * h))
        fresh[frac] = values
        print(a_over_h, frac, np.round(values, 3).tolist(), flush=True)
    approach = []
    mm, _ = _mesh(h, h)
    for frac in np.round(np.arange(1.0, 0.049, -0.025), 4):
        delta = float(frac) * h
        new, centre = _mesh(h, delta)
        event = mm.update(np.array([[centre[0], centre[1], 0.0]]))
        moved = force_over_exact(mm, centre, delta)
        approach.append({"delta_over_h": float(frac), "moved": moved, "fresh": force_over_exact(new, centre, delta),
                         "retriangulated": bool(getattr(event, "retriangulated", False))})
    return {"a_over_h": a_over_h, "h": h, "fresh": {str(k): v for k, v in fresh.items()}, "approach": approach}


def main() -> None:
    warnings.simplefilter("ignore")
    rows = [measure(q) for q in A_OVER_H]
    cells = []
    for r in rows:
        for frac in GAPS:
            v = r["fresh"][str(frac)]
            cells.append([f"{r['a_over_h']:g}", "fresh, 5 shifts", f"{frac:g}", f"{min(v):.3f}", f"{np.median(v):.3f}",
                          f"{max(v):.3f}"])
        d = np.array([[p["delta_over_h"], p["moved"], p["fresh"]] for p in r["approach"]])
        n_retri = sum(p["retriangulated"] for p in r["approach"])
        for lo, hi in BANDS:
            m = (d[:, 0] >= lo) & (d[:, 0] < hi)
            cells.append([f"{r['a_over_h']:g}", f"approach ({n_retri} of {len(d)} updates re-triangulated)",
                          f"[{lo:g}, {min(hi, 1.0):g}]", f"{d[m, 1].min():.3f}", f"{np.median(d[m, 1]):.3f}",
                          f"{d[m, 1].max():.3f} (fresh at the same gaps {d[m, 2].min():.3f}–{d[m, 2].max():.3f})"])
    write_results("gap_triangulation", rows, "The force in a narrow gap against the triangulation of the gap",
                  "A 96-gon of radius 0.1 approaching a wall at unit speed, Stokes, P2+bubble/P1dc, the moving mesh of "
                  "the free-body runs; force over the exact (bipolar) force; `benchmarks/bench_gap_triangulation.py`.",
                  ["a/h", "meshes", "δ/h", "force / exact: min", "median", "max"], cells)


if __name__ == "__main__":
    main()
