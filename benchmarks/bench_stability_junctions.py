"""Cross-flow at junctions (paper Sec. 3.2, Fig. 4): the flux split at a junction between four
bodies with and without a junction node, against a fine body-fitted reference.

Set-up :mod:`fluidem.cases.junction_split`: four fixed bodies fill a box except for two channels of
width 0.1 crossing at 90° (Fig. 4a) or 45° (Fig. 4b), Stokes inflow at the left, three do-nothing
outlets.  For each angle, element pair and mesh size h (from 1.5 to 0.4 channel widths), the share of
the inflow leaving through each outlet on the moving mesh with the junction variants ``off``
(``junctions=False``), ``library`` (``junctions=True``, the mesh's own quality-screened Voronoi point),
``voronoi`` (the same point without the angle screen) and ``centre`` (one node at the crossing of the
junction quadrilateral's diagonals), its largest error against P2-bubble on a body-fitted Triangle mesh of
the same fluid at h = gap/16, the 1-norm condition estimate of the Stokes LU
(:func:`fluidem.diagnostics.lu_condition`) and the DOFs.

Writes ``benchmarks/results/stability_junctions.{md,json,png}``.  Run (about a minute, 2.5 GB)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_stability_junctions.py
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, markdown_table, write_json  # noqa: E402

from fluidem.cases.junction_split import (VARIANTS, flux_split, junction_case,  # noqa: E402
                                          junction_geometry, reference_mesh)

GAP = 0.1
ANGLES = (90.0, 45.0)
ELEMENTS = ("p2b", "th")
SIZES = (0.15, 0.12, 0.1, 0.08, 0.05, 0.04)  # h; one element across the gap down to h = 0.08 (gap_purge 1.1 h)
H_REFERENCE = (GAP / 8, GAP / 16)  # the last is the reference, the first bounds its error


def run() -> tuple[list, list]:
    rows, refs = [], []
    for angle in ANGLES:
        geo = junction_geometry(angle, GAP)
        # the reference split is the exact one's: P2-bubble at gap/16; its change from gap/8 and the
        # P2/P1 split at gap/8 bound its error
        fine = {(element, hr): flux_split(reference_mesh(geo, hr), geo, element)
                for element, hr in (("p2b", H_REFERENCE[0]), ("p2b", H_REFERENCE[1]), ("th", H_REFERENCE[0]))}
        ref = fine["p2b", H_REFERENCE[1]]
        for (element, hr), r in fine.items():
            refs.append({"angle": angle, "element": element, "h": hr, "split": r["split"].tolist(), "dofs": r["dofs"],
                         "condition": r["condition"], "difference": float(np.abs(r["split"] - ref["split"]).max())})
            print(refs[-1], flush=True)
        for element in ELEMENTS:
            for h in SIZES:
                for variant in VARIANTS:
                    t0 = time.perf_counter()
                    r = junction_case(angle, h, variant, element, reference=ref, gap=GAP)
                    rows.append({"angle": angle, "element": element, "h": h, "h_over_gap": h / GAP, "variant": variant,
                                 "junction_nodes": r["n_points"], "split": r["split"].tolist(), "error": r["error"],
                                 "condition": r["condition"], "dofs": r["dofs"], "mass_defect": r["mass_defect"],
                                 "seconds": time.perf_counter() - t0})
                    print(rows[-1], flush=True)
    return rows, refs


def report(rows: list, refs: list, machine: str) -> None:
    lines = ["# Cross-flow at junctions: the flux split at a junction between four bodies", "",
             f"Machine: {machine}; one BLAS thread.  Four fixed bodies fill a box except for two channels of "
             f"width {GAP} crossing at the angle given (90°: paper Fig. 4a; 45°: Fig. 4b, the bottom branch turns "
             "the flow by 135°); Stokes, ν = 1, Poiseuille inflow at the left, do-nothing outlets right, top, "
             "bottom.  Split: the share of the inflow leaving through each outlet (right / top / bottom).  "
             "Error: the largest difference of a share from the reference, P2-bubble on a body-fitted Triangle "
             "mesh of the same fluid at h = gap/16 (the reference table gives the difference from it of the "
             "fine solutions at gap/8: P2-bubble, and P2/P1, for both elements' rows).  Variants: `off` "
             "junctions=False; `library` junctions=True (the mesh's quality-screened Voronoi point); `voronoi` "
             "that point without the angle screen; `centre` one node at the crossing of the diagonals of the "
             "junction quadrilateral (two junction triangles split into four).  Nodes: junction nodes added.  "
             "κ₁: 1-norm condition estimate of the Stokes LU.", "",
             "## Reference", ""]

    def split(r):
        return " / ".join(f"{v:.4f}" for v in r["split"])

    lines += markdown_table(
        ["angle", "element", "h", "split (right / top / bottom)", "difference from the reference", "DOFs", "κ₁"],
        [[f"{r['angle']:g}°", r["element"], f"{r['h']:g}", split(r), f"{r['difference']:.1e}", str(r["dofs"]),
          f"{r['condition']:.2e}"] for r in refs])
    lines += ["", "## Coarse meshes", ""] + markdown_table(
        ["angle", "element", "h", "h/gap", "junction", "nodes", "split (right / top / bottom)", "error", "κ₁", "DOFs"],
        [[f"{r['angle']:g}°", r["element"], str(r["h"]), f"{r['h_over_gap']:.1f}", r["variant"],
          str(r["junction_nodes"]), split(r), f"{r['error']:.4f}", f"{r['condition']:.2e}", str(r["dofs"])]
         for r in rows])
    (RESULTS / "stability_junctions.md").write_text("\n".join(lines) + "\n")


def figure(rows: list) -> None:
    """Split error against h per variant (P2-bubble, both angles) and the 90° junction at h = gap."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fluidem.cases.junction_split import junction_mesh

    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    marks = {"off": ("k", "o"), "library": ("0.6", "x"), "voronoi": ("tab:red", "s"), "centre": ("tab:blue", "^")}
    for ax, angle in zip(axes[:2], ANGLES):
        for v in VARIANTS:
            rr = [r for r in rows if r["angle"] == angle and r["element"] == "p2b" and r["variant"] == v]
            c, m = marks[v]
            ax.semilogy([r["h_over_gap"] for r in rr], [max(r["error"], 1e-5) for r in rr], marker=m, color=c,
                        label=v, ls="-" if v != "library" else ":")
        rr = [r for r in rows if r["angle"] == angle and r["element"] == "th" and r["variant"] == "off"]
        ax.semilogy([r["h_over_gap"] for r in rr], [max(r["error"], 1e-5) for r in rr], color="tab:green", ls="--",
                    marker=".", label="off, P2/P1")
        ax.set_xlabel("h / gap")
        ax.set_ylabel("largest error of a share of the inflow")
        ax.set_title(f"P2-bubble/P1dc, channels at {angle:g}°")
        ax.invert_xaxis()
        ax.legend(fontsize=8)
    geo = junction_geometry(90.0, GAP)
    ax = axes[2]
    for v, c, lw in (("centre", "tab:blue", 1.6), ("off", "k", 0.8)):
        m, _ = junction_mesh(geo, GAP, v)
        ax.triplot(m.p[0], m.p[1], m.t.T, color=c, lw=lw)
    for b, pose in zip(geo["bodies"], geo["poses"]):
        ax.fill(*(b + pose[:2]).T, color="0.8")
    xj, yj = geo["junction"]
    ax.set_xlim(xj - 0.25, xj + 0.25)
    ax.set_ylim(yj - 0.25, yj + 0.25)
    ax.set_aspect("equal")
    ax.set_title("90°, h = gap: mesh off (black), centre node (blue)")
    fig.tight_layout()
    fig.savefig(RESULTS / "stability_junctions.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    rows, refs = run()
    machine = machine_description()
    write_json("stability_junctions", machine, [dict(r, variant="reference") for r in refs] + rows)
    report(rows, refs, machine)
    figure(rows)
