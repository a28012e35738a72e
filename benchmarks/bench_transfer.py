"""What a re-triangulation's field transfer costs: the interpolation and the interpolation-noise figure.

At a re-triangulation the velocity is interpolated onto the new mesh (:func:`fluidem.mesh.transfer.interpolate`)
and the relative L2 change this makes is measured at the new mesh's quadrature points
(:func:`fluidem.coupling.moving_flow.transfer_change`, the "noise" of ``--verbose`` and ``events.log``).  At
1 000 settling polygons (1.57M DOFs) a re-triangulation step took 90–105 s, the transfer 18 s of it and the
noise figure 12 s of that.

Case: the flow's velocity space (P2+bubble vector, the quadrature of :class:`fluidem.fluid.space.FlowSpace`,
16 points an element) on a Friedrichs–Keller grid (old) and a Delaunay mesh (new) of the unit square at
mesh size ``h``; a smooth field on the old one; 3 calls each of :func:`transfer_change` and of
:func:`interpolate` (two fields at once, as at a re-triangulation) in each of 3 processes: the median over the
processes of each one's median;
one BLAS thread.  With ``--before PATH`` the same with the fluidem package found at ``PATH`` (an earlier
checkout), the processes of the two versions alternating.

Run (a few minutes)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_transfer.py [--before PATH]

writes ``benchmarks/results/transfer.{md,json}``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import write_results  # noqa: E402

SIZES = (0.01, 0.005)  # h: 45k and 180k new elements (the second about the 1 000-polygon mesh)
ROUNDS = 3  # processes per version and size, alternating


def case(h: float) -> dict:
    """Seconds of the noise figure and the interpolation at mesh size ``h`` (this process's fluidem)."""
    from skfem import Basis, ElementVector, MeshTri

    from fluidem.coupling.moving_flow import transfer_change
    from fluidem.fluid.space import FlowSpace
    from fluidem.mesh.background import friedrichs_keller_grid
    from fluidem.mesh.transfer import interpolate
    from fluidem.mesh.triangulate import to_skfem, triangulate_box

    p, t = friedrichs_keller_grid((0, 1, 0, 1), h)
    old = MeshTri(p.T.copy(), t.T.copy())
    new_space = FlowSpace(to_skfem(triangulate_box((0, 1, 0, 1), (), size=0.9 * h)))
    bn = new_space.ub
    bo = Basis(old, ElementVector(new_space.pair.velocity()), intorder=new_space.pair.quadrature_order)
    x = bo.doflocs
    u = np.nan_to_num(np.where(np.arange(bo.N) % 2 == 0, np.sin(3 * x[0]) * x[1], np.cos(2 * x[1])))
    fields = np.column_stack([u, 0.5 * u])
    noise, interp = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        moved = interpolate(bo, fields, bn)
        interp.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        change = transfer_change(bo, u, bn, moved[:, 0])
        noise.append(time.perf_counter() - t0)
    n_points = int(np.asarray(bn.global_coordinates()).reshape(2, -1).shape[1])
    return {"h": h, "elements": int(bn.mesh.t.shape[1]), "points": n_points, "noise_s": float(np.median(noise)),
            "interpolate_s": float(np.median(interp)), "noise": float(change)}


def main(argv: list) -> None:
    before = None
    if argv[:1] == ["--before"]:
        before = argv[1]
    rows = []
    for h in SIZES:
        runs = {}
        for _ in range(ROUNDS):  # the versions alternate: a load that changes meanwhile hits both
            for version, where in ([("before", before)] if before else []) + [("this version", None)]:
                env = dict(os.environ, OPENBLAS_NUM_THREADS="1", **({"PYTHONPATH": where} if where else {}))
                out = subprocess.run([sys.executable, os.path.abspath(__file__), "--case", str(h)],
                                     capture_output=True, text=True, check=True, env=env)
                runs.setdefault(version, []).append(json.loads(out.stdout.strip().splitlines()[-1]))
                print(version, runs[version][-1], flush=True)
        for version, found in runs.items():
            rows.append(dict(found[0], version=version, noise_s=float(np.median([r["noise_s"] for r in found])),
                             interpolate_s=float(np.median([r["interpolate_s"] for r in found]))))
    write(rows)


def write(rows: list) -> None:
    """``transfer.{md,json}`` from the rows of :func:`main` (``version`` "before" present: the ratios too)."""
    notes = []
    if any(r["version"] == "before" for r in rows):
        mine = {r["h"]: r for r in rows if r["version"] == "this version"}
        old = [r for r in rows if r["version"] == "before"]
        ratios = ", ".join(f"{r['noise_s'] / mine[r['h']]['noise_s']:.2f} at {r['points']:,} points" for r in old)
        agree = max(abs(r["noise"] / mine[r["h"]]["noise"] - 1) for r in old)
        control = ", ".join(f"{r['interpolate_s'] / mine[r['h']]['interpolate_s']:.2f}" for r in old)
        notes = ["", f"Ratio before / this version, noise figure: {ratios}; the noise figures agree to {agree:.1g} "
                 f"(relative). Ratio of the interpolation: {control} (where the two versions share its code, as "
                 "since the noise figure's change, this is how much the machine's load moved the timings)."]
    write_results("transfer", rows, "The field transfer of a re-triangulation: interpolation and noise figure",
                  "One BLAS thread. The flow's velocity space (P2+bubble) on a Friedrichs–Keller grid (old) and a "
                  "Delaunay mesh (new) of the unit square; median of 3 calls in each of 3 processes a version, the "
                  "processes of the two versions alternating.",
                  ["version", "h", "new elements", "quadrature points", "noise figure s", "interpolation s",
                   "noise"],
                  [[r["version"], f"{r['h']:g}", f"{r['elements']:,}", f"{r['points']:,}", f"{r['noise_s']:.2f}",
                    f"{r['interpolate_s']:.2f}", f"{r['noise']:.3g}"] for r in rows], notes)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--case"]:
        print(json.dumps(case(float(sys.argv[2]))))
    else:
        main(sys.argv[1:])
