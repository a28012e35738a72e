"""Wrong element curvature (paper Sec. 3.1): gaps of 1, 2 and 3 element layers, per element pair.

Set-ups :mod:`fluidem.cases.curvature` (Stokes, μ = 1, disks of radius a = 1 meshed at h = a/8 away
from the gap, n element layers across the narrowest section): two disks sliding past each other at
±1 (the profile across the gap is linear at leading order) and a disk turning at unit rate above a
wall (the profile is the full parabola: the non-linear gap profile).  For each gap δ/a, element
pair and n: the error of the main load (the drag on a sliding disk, the torque on the turning one)
and of the second one (the torque on a sliding disk, the sideways force on the turning one) against
a reference, the spurious force normal to the gap (zero by symmetry and reversibility), the
largest error of u_x across the gap at x = 0 and x = √(aδ), and the 1-norm condition estimate of
the LU (:func:`fluidem.diagnostics.lu_condition`).  Reference: P3/P2 on the n = 3 mesh refined 2x
everywhere and 4x in the gap (about 12 layers); its own error is bounded by the same problem with
the gap refined 2x only and with Taylor–Hood on the reference mesh (both in the table).  A plane
Couette check (plates at ±1, periodic) confirms that every pair holds a linear profile exactly.

Writes ``benchmarks/results/stability_curvature.{md,json}``.  Run (about 7 minutes; ``--report``
writes the tables again from the stored JSON)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_stability_curvature.py
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, markdown_table, run_or_report  # noqa: E402

from fluidem.cases.curvature import couette_case, gap_case, lubrication_profile  # noqa: E402

GAPS = (0.1, 0.02, 0.005)  # δ / a
ELEMENTS = ("mini", "th", "p2b", "p3")
LAYERS = (1, 2, 3)
REFERENCE = {"element": "p3", "n": 3, "refine": 2.0, "gap_refine": 2.0}
#: The main and the second load of each set-up, and the scale of the normal force.
LOADS = {"sliding": ("fx", "torque"), "rotating": ("torque", "fx")}


def _scale(geometry: str, ref: dict) -> float:
    """Load scale of the normal force: the drag (sliding), torque / a (rotating, a = 1)."""
    return abs(ref["fx"]) if geometry == "sliding" else abs(ref["torque"])


def _compare(geometry: str, r: dict, ref: dict) -> dict:
    main, second = LOADS[geometry]
    prof = max(float(np.abs(np.asarray(p) - np.asarray(q)).max()) for p, q in zip(r["profiles"], ref["profiles"]))
    speed = 1.0  # surface speed: ±1 (sliding), ω a = 1 (rotating)
    return {"main_error": r[main] / ref[main] - 1.0, "second_error": r[second] / ref[second] - 1.0,
            "normal_force": r["fy"] / _scale(geometry, ref), "profile_error": prof / speed}


def run() -> list:
    rows = []
    for element in ELEMENTS:
        for n in (1, 3):
            c = couette_case(element, n)
            rows.append({"kind": "couette", "element": element, "n": n, "force_error": c["fx"] / c["exact"] - 1.0,
                         "profile_error": c["profile_error"], "condition": c["condition"]})
            print(rows[-1], flush=True)
    for geometry in LOADS:
        for delta in GAPS:
            t0 = time.perf_counter()
            ref = gap_case(geometry, REFERENCE["element"], REFERENCE["n"], delta, refine=REFERENCE["refine"],
                           gap_refine=REFERENCE["gap_refine"])
            eta = np.linspace(0.0, 1.0, len(ref["profiles"][0]))
            lub = float(np.abs(np.asarray(ref["profiles"][0]) - lubrication_profile(geometry, eta)).max())
            rows.append({"kind": "reference", "geometry": geometry, "delta_over_a": delta, **REFERENCE,
                         "fx": ref["fx"], "fy": ref["fy"], "torque": ref["torque"], "dofs": ref["dofs"],
                         "layers": ref["layers"], "condition": ref["condition"], "lubrication_profile_error": lub,
                         "seconds": time.perf_counter() - t0})
            print(rows[-1], flush=True)
            for label, element, gr in (("gap refined 2x only", "p3", 1.0), ("Taylor-Hood on it", "th", 2.0)):
                c = gap_case(geometry, element, 3, delta, refine=2.0, gap_refine=gr)
                rows.append({"kind": "reference_check", "geometry": geometry, "delta_over_a": delta, "check": label,
                             "element": element, "dofs": c["dofs"], **_compare(geometry, c, ref)})
                print(rows[-1], flush=True)
            for element in ELEMENTS:
                for n in LAYERS:
                    r = gap_case(geometry, element, n, delta)
                    rows.append({"kind": "gap", "geometry": geometry, "delta_over_a": delta, "element": element,
                                 "n": n, "layers": r["layers"], "dofs": r["dofs"], "cells": r["cells"],
                                 "h_min": r["h_min"], **_compare(geometry, r, ref), "fx": r["fx"], "fy": r["fy"],
                                 "torque": r["torque"], "condition": r["condition"], "seconds": r["seconds"]})
                    print(rows[-1], flush=True)
    return rows


def _pct(v: float) -> str:
    return f"{100 * v:+.3g} %"


def report(rows: list, machine: str) -> None:
    names = {"mini": "MINI", "th": "Taylor–Hood", "p2b": "P2+bubble", "p3": "P3/P2"}
    what = {"sliding": ("drag F_x", "torque", "F_y / |F_x|"), "rotating": ("torque", "sideways F_x", "F_y a / |T|")}
    lines = ["# Wrong element curvature: gaps of 1–3 element layers per element pair", "",
             f"Machine: {machine}; one BLAS thread.  Stokes, μ = 1, disks of radius a = 1 (polygons, a vertex at the "
             "gap), h = a/8 at the disks away from the gap, n element layers across the narrowest section "
             "(measured: the fewest mesh edges from one surface to the other).  *sliding*: two disks passing each "
             "other at ±1, box [−6, 6]²; *rotating*: a disk turning at ω = 1 at the gap δ above the floor of "
             "[−6, 6] × [0, 6].  Reference: P3/P2 on the n = 3 mesh refined 2x, 4x in the gap.  Errors are signed "
             "(+: a larger load than the reference, i.e. too stiff).  Normal force: zero by symmetry; given over the "
             "main load.  Profile: largest |u_x − u_x,ref| across the gap at x = 0 and x = √(aδ), over the surface "
             "speed (on one layer the section x = 0 is a mesh edge between the two facing vertices, so the "
             "profile there is the trace of one element's velocity on it).  κ₁: the condition estimate of the LU "
             "(`fluidem.diagnostics`).", "",
             "## Force error per element pair and layers across the gap", ""]
    gaps = [r for r in rows if r["kind"] == "gap"]
    for geometry in LOADS:
        main, second, normal = what[geometry]
        lines += [f"### {geometry}: {main}", "", "| δ/a | element | n = 1 | n = 2 | n = 3 |", "|---|---|---|---|---|"]
        for delta in GAPS:
            for e in ELEMENTS:
                cells = [_pct(r["main_error"]) for n in LAYERS for r in gaps
                         if r["geometry"] == geometry and r["delta_over_a"] == delta and r["element"] == e
                         and r["n"] == n]
                lines.append(f"| {delta} | {names[e]} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Every run", "", "| set-up | δ/a | element | n | layers | DOFs | main load | second load "
              "| normal force | profile | κ₁ |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in gaps:
        lines.append(f"| {r['geometry']} | {r['delta_over_a']} | {names[r['element']]} | {r['n']} | {r['layers']} | "
                     f"{r['dofs']} | {_pct(r['main_error'])} | {_pct(r['second_error'])} | "
                     f"{r['normal_force']:+.2e} | {r['profile_error']:.2e} | {r['condition']:.2e} |")
    lines += ["", "Main load: the drag F_x (sliding) or the torque (rotating); second: the torque (sliding) or the "
              "sideways force F_x (rotating).", "", "## References and their checks", "",
              ]
    lines += markdown_table(
        ["set-up", "δ/a", "F_x", "F_y", "torque", "DOFs", "layers", "κ₁", "profile at x = 0 − lubrication"],
        [[r["geometry"], str(r["delta_over_a"]), f"{r['fx']:.6g}", f"{r['fy']:+.1e}", f"{r['torque']:.6g}",
          str(r["dofs"]), str(r["layers"]), f"{r['condition']:.2e}", f"{r['lubrication_profile_error']:.3f}"]
         for r in rows if r["kind"] == "reference"])
    lines += [""] + markdown_table(
        ["set-up", "δ/a", "check", "DOFs", "main load", "second load", "normal force", "profile"],
        [[r["geometry"], str(r["delta_over_a"]), r["check"], str(r["dofs"]), f"{r['main_error']:+.1e}",
          f"{r['second_error']:+.1e}", f"{r['normal_force']:+.1e}", f"{r['profile_error']:.1e}"]
         for r in rows if r["kind"] == "reference_check"])
    lines += ["", "## Plane Couette flow (sanity check: every pair is exact)", "",
              "Plates at ±1, gap 0.1, periodic, n rows of right triangles across.", "",
              "| element | n | force error | profile error | κ₁ |", "|---|---|---|---|---|"]
    for r in rows:
        if r["kind"] == "couette":
            lines.append(f"| {names[r['element']]} | {r['n']} | {r['force_error']:+.1e} | {r['profile_error']:.1e} | "
                         f"{r['condition']:.2e} |")
    (RESULTS / "stability_curvature.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    run_or_report("stability_curvature", run, report)
