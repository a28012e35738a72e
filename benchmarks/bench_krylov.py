"""What a lagged LU's GMRES solve costs through fluidem's FGMRES cycle and through pyamg's ``fgmres``.

A lagged LU (:class:`fluidem.fluid.solvers.LaggedLUSolver`) solves each step's coupled system by
FGMRES preconditioned with the factors of an earlier step: a few back-substitutions a solve, with
restart length and iteration limit 50.  pyamg's ``fgmres`` (used up to this version) allocates
its Householder vectors as a zeroed ``(restart, n)`` array and the preconditioned vectors as a
zeroed ``(n, restart)`` array written by columns, so every solve touches all ``50 · n`` doubles
of the second (640 MB at 1.6 million unknowns) whatever the iterations;
:func:`fluidem.fluid.solvers.krylov.fgmres_cycle` keeps both as rows that are written only as the
iterations are made.

Systems: the settling suspension of ``bench_dense.py`` (N bodies, h ≈ a/3) run 6 steps; the
coupled matrix of step 1 is factorised by PARDISO and preconditions the system of step 6 (the
lag of a run between refactorisations), right-hand side random.  Both drivers solve it to the
lagged LU's tolerance (1e-6) with restart 50 and at most 50 iterations, alternating, ``ROUNDS``
times; medians.  The iteration counts and the solutions are compared.  One BLAS and one MKL thread.

Run (a few minutes at 100 and 300 bodies; 1 000 needs ~10 GB and ~10 min)::

    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/bench_krylov.py [--bodies 100,300]

writes ``benchmarks/results/krylov.{md,json}``.
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import rows_by_bodies, write_results  # noqa: E402

ROUNDS = 7
STEPS = 6
RTOL, MAXITER = 1e-6, 50


def pyamg_run_fgmres(K, b, M, rtol, maxiter):
    """The driver of earlier versions: pyamg's ``fgmres``, one restart cycle at a time."""
    import scipy.sparse.linalg as spla
    from pyamg.krylov import fgmres

    from fluidem.fluid.solvers._sparse import _Counter

    n = K.shape[0]
    nb = np.linalg.norm(b)
    Mc = _Counter(M)
    Mop = spla.LinearOperator((n, n), matvec=Mc, dtype=float)
    x = np.zeros(n)
    while Mc.count < maxiter:
        x, _ = fgmres(K, b, x0=x, tol=rtol, restart=min(maxiter, maxiter - Mc.count), maxiter=1, M=Mop)
        if np.linalg.norm(b - K @ x) / nb <= rtol:
            break
    return x, Mc.count


def lagged_pair(n: int):
    """The coupled matrices of steps 1 and ``STEPS`` of ``n`` settling bodies."""
    import warnings

    import bench_dense
    from fluidem.fluid.solvers import LaggedLUSolver
    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    warnings.simplefilter("ignore")
    seen = []
    original = LaggedLUSolver.factorize

    def record(self, K, *args, **kwargs):
        seen.append(K.tocsr().copy())
        if len(seen) > 2:
            seen.pop(1)  # keep the first and the latest
        return original(self, K, *args, **kwargs)

    LaggedLUSolver.factorize = record
    try:
        Simulation(Scene.from_dict(bench_dense.scene_dict(n, STEPS))).run(out_dir=None, n_steps=STEPS)
    finally:
        LaggedLUSolver.factorize = original
    return seen[0], seen[-1]


def measure(n: int) -> dict:
    """Time both drivers on the lagged system of ``n`` bodies."""
    from fluidem.fluid.solvers.krylov import run_fgmres
    from fluidem.fluid.solvers.pardiso import PardisoLU

    K1, K = lagged_pair(n)
    lu = PardisoLU(K1)

    class Preconditioner:
        def __matmul__(self, v):
            return lu.solve(v)

    P = Preconditioner()
    b = np.random.default_rng(n).standard_normal(K.shape[0])
    own, theirs = [], []
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        x_own, it_own, _, reason = run_fgmres(K, b, P, None, RTOL, MAXITER, MAXITER, 0.999)
        own.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        x_theirs, it_theirs = pyamg_run_fgmres(K, b, P, RTOL, MAXITER)
        theirs.append(time.perf_counter() - t0)
    nb = np.linalg.norm(b)
    res_own, res_theirs = (float(np.linalg.norm(b - K @ x) / nb) for x in (x_own, x_theirs))
    t0 = time.perf_counter()
    for _ in range(3):
        lu.solve(b)
    back_s = (time.perf_counter() - t0) / 3
    lu.free()
    return {"bodies": n, "dofs": int(K.shape[0]), "iterations_own": it_own, "iterations_pyamg": it_theirs,
            "residual_own": res_own, "residual_pyamg": res_theirs, "reason": reason,
            "difference": float(np.linalg.norm(x_own - x_theirs) / np.linalg.norm(x_theirs)),
            "solve_own_s": float(np.median(own)), "solve_pyamg_s": float(np.median(theirs)),
            "back_substitution_s": back_s, "ratio": float(np.median(own) / np.median(theirs))}


def main() -> None:
    rows = rows_by_bodies(__doc__, measure)
    cells = [[str(r["bodies"]), f"{r['dofs']:,}", f"{r['iterations_pyamg']} / {r['iterations_own']}",
              f"{r['residual_pyamg']:.2e} / {r['residual_own']:.2e}", f"{r['difference']:.1e}",
              f"{r['back_substitution_s']:.3f}", f"{r['solve_pyamg_s']:.3f}", f"{r['solve_own_s']:.3f}",
              f"{r['ratio']:.2f}"] for r in rows]
    write_results(
        "krylov", rows, "A lagged LU's GMRES solve: fluidem's FGMRES cycle against pyamg's fgmres",
        f"`benchmarks/bench_krylov.py` (its docstring has the set-up): the LU of step 1 preconditions the "
        f"system of step {STEPS}, restart and iteration limit {MAXITER}, tolerance {RTOL:g}; medians of "
        f"{ROUNDS} solves each, the two alternating; one BLAS and one MKL thread.",
        ["bodies", "DOFs", "iterations pyamg / fluidem", "relative residual pyamg / fluidem",
         "solutions apart (relative)", "one back-substitution s", "solve pyamg s", "solve fluidem s",
         "ratio fluidem / pyamg"], cells)


if __name__ == "__main__":
    main()
