"""What PARDISO's back-substitution costs through ``pypardiso``'s call and through fluidem's own.

``pypardiso``'s call into MKL converts the matrix's ``indptr`` and ``indices`` to 1-based 32-bit
arrays at every phase, also at each solve; :class:`fluidem.fluid.solvers.pardiso.PardisoLU` makes
them once an analysis.  A lagged LU's GMRES, the contact passes of a coupled step and the correction
solve each take a back-substitution, so the conversion is paid many times a step.

Systems: the coupled fluid–body matrices of the settling suspension of ``bench_dense.py`` after its
first step (``bench_solver_scale.make_system``: N = 100 → 149k DOFs, 300 → ~450k), factorised once
by :class:`PardisoLU`; then ``ROUNDS`` back-substitutions of one random right-hand side through each
call on the same factors, the two alternating (a load that changes meanwhile hits both); medians.
The solutions are compared bit for bit.  One BLAS and one MKL thread.

Run (a few minutes)::

    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/bench_pardiso_call.py [--bodies 100,300]

writes ``benchmarks/results/pardiso_call.{md,json}``.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import rows_by_bodies, write_results  # noqa: E402

ROUNDS = 31


def measure(n: int) -> dict:
    """Factorise the coupled matrix of ``n`` settling bodies and time both calls' back-substitutions."""
    import scipy.sparse as sp

    import bench_solver_scale
    from fluidem.fluid.solvers.pardiso import PardisoLU

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "K.npz")
        made = bench_solver_scale.make_system(n, path)
        K = sp.load_npz(path).tocsr()
    t0 = time.perf_counter()
    lu = PardisoLU(K)
    factor_s = time.perf_counter() - t0
    b = np.random.default_rng(n).standard_normal(K.shape[0])
    ps = lu._ps
    own, theirs = [], []
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        x_own = lu.solve(b)
        own.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        ps.set_phase(33)
        x_theirs = np.asarray(ps._call_pardiso(lu.K, np.asfortranarray(b).copy(order="F"))).reshape(b.shape)
        theirs.append(time.perf_counter() - t0)
    same = bool(np.array_equal(x_own, x_theirs))
    lu.free()
    return {"bodies": n, "dofs": made["dofs"], "nnz": made["nnz"], "fill": lu.fill, "factor_s": factor_s,
            "solve_own_s": float(np.median(own)), "solve_pypardiso_s": float(np.median(theirs)),
            "ratio": float(np.median(own) / np.median(theirs)), "bit_identical": same}


def main() -> None:
    rows = rows_by_bodies(__doc__, measure)
    cells = [[str(r["bodies"]), f"{r['dofs']:,}", f"{r['nnz'] / 1e6:.1f}M", f"{r['fill'] / 1e6:.0f}M",
              f"{r['solve_pypardiso_s']:.3f}", f"{r['solve_own_s']:.3f}", f"{r['ratio']:.2f}",
              "yes" if r["bit_identical"] else "**no**"] for r in rows]
    write_results("pardiso_call", rows, "PARDISO's back-substitution: pypardiso's call and fluidem's",
                  f"Medians of {ROUNDS} back-substitutions a call, alternating, on the same factors; "
                  "one BLAS and one MKL thread.",
                  ["bodies", "DOFs", "entries of K", "entries of L+U", "pypardiso's call, s", "fluidem's call, s",
                   "ratio", "same solution bit for bit"], cells)


if __name__ == "__main__":
    sys.exit(main())
