"""What PARDISO's weighted matching costs on the coupled systems of settling suspensions, and what it buys.

PARDISO (``fluidem.fluid.solvers.pardiso.PardisoLU``) factorises the coupled fluid–body matrix, whose
pressure block is zero.  With scaling and weighted matching (MC64, ``iparm(11) = iparm(13) = 1``, the
setting of earlier versions) large entries are permuted onto the diagonal, so few pivots are perturbed
and the factors alone solve to ~1e-7; without it (the default now) the zero pressure pivots are
perturbed to ε ‖K‖ and the factors are those of a slightly regularised matrix, to be refined or wrapped in
FGMRES, which every solver of fluidem does.  The matched matrix loses the symmetric pattern that nested
dissection orders well: its factors hold twice the entries.

Systems: the settling suspension of ``bench_dense.py`` (N bodies, h ≈ a/3) run 6 steps (``bench_krylov.py``);
the coupled matrix of step 1 is factorised, and its factors precondition the system of the last step (a
lagged LU's situation between refactorisations), right-hand side random.  For each setting: the analysis and
factorisation (phase 12), the numerical refactorisation on that analysis (phase 22) of the later matrix, one
back-substitution, the entries of L + U, perturbed pivots, PARDISO's peak memory, the residual the factors
leave alone, and FGMRES preconditioned by the step-1 factors (restart and limit 50, tolerance 1e-6: the
lagged LU's) on the later system: iterations and seconds.  The two settings alternate ``ROUNDS`` times;
medians.  One BLAS and one MKL thread.

Run (100 and 300 bodies: a few minutes; 1 000: ~15 minutes and ~10 GB)::

    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/bench_pardiso_matching.py [--bodies 100,300]

writes ``benchmarks/results/pardiso_matching.{md,json}``.
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import rows_by_bodies, write_results  # noqa: E402

ROUNDS = 3
RTOL, MAXITER = 1e-6, 50


def one_setting(K1, K, b, matching: bool) -> dict:
    """One round of measurements of PARDISO with or without matching (module docstring)."""
    from fluidem.fluid.solvers.krylov import run_fgmres
    from fluidem.fluid.solvers.pardiso import PardisoLU

    t0 = time.perf_counter()
    lu = PardisoLU(K1, matching=matching)
    factor_s = time.perf_counter() - t0
    alone = float(np.linalg.norm(b - K1 @ lu.solve(b)) / np.linalg.norm(b))

    class Preconditioner:
        def __matmul__(self, v):
            return lu.solve(v)

    t0 = time.perf_counter()
    x, iterations, _, reason = run_fgmres(K, b, Preconditioner(), None, RTOL, MAXITER, MAXITER, 0.999)
    lagged_s = time.perf_counter() - t0
    lagged_residual = float(np.linalg.norm(b - K @ x) / np.linalg.norm(b))
    t0 = time.perf_counter()
    for _ in range(3):
        lu.solve(b)
    back_s = (time.perf_counter() - t0) / 3
    row = {"factor_s": factor_s, "back_substitution_s": back_s, "fill": lu.fill, "perturbed": lu.perturbed,
           "peak_mib": lu.peak_bytes / 2**20, "alone_residual": alone, "lagged_iterations": iterations,
           "lagged_s": lagged_s, "lagged_residual": lagged_residual, "reason": reason}
    t0 = time.perf_counter()
    assert lu.refactor(K)
    row["refactor_s"] = time.perf_counter() - t0
    lu.free()
    return row


def measure(n: int) -> dict:
    """Both settings on the lagged system of ``n`` bodies, alternating; medians of the times."""
    from bench_krylov import lagged_pair

    K1, K = lagged_pair(n)
    b = np.random.default_rng(n).standard_normal(K.shape[0])
    runs = {True: [], False: []}
    for _ in range(ROUNDS):
        for matching in (True, False):
            runs[matching].append(one_setting(K1, K, b, matching))
    out = {"bodies": n, "dofs": int(K.shape[0])}
    for matching, rs in runs.items():
        key = "matching" if matching else "none"
        for field in rs[0]:
            values = [r[field] for r in rs]
            out[f"{key}_{field}"] = (float(np.median(values)) if field.endswith("_s") else values[-1])
    return out


def main() -> None:
    rows = rows_by_bodies(__doc__, measure)
    cells = []
    for r in rows:
        for key, label in (("matching", "with matching"), ("none", "without (default)")):
            cells.append([str(r["bodies"]), f"{r['dofs']:,}", label, f"{r[f'{key}_factor_s']:.2f}",
                          f"{r[f'{key}_refactor_s']:.2f}", f"{r[f'{key}_back_substitution_s']:.3f}",
                          f"{r[f'{key}_fill'] / 1e6:.1f}M", f"{r[f'{key}_peak_mib']:,.0f}",
                          f"{r[f'{key}_perturbed']:,}", f"{r[f'{key}_alone_residual']:.1e}",
                          f"{r[f'{key}_lagged_iterations']}", f"{r[f'{key}_lagged_s']:.2f}",
                          f"{r[f'{key}_lagged_residual']:.1e}"])
    notes = ["", "Without against with matching (time ratio): " + "; ".join(
        f"{r['bodies']} bodies: analysis and factorisation {r['none_factor_s'] / r['matching_factor_s']:.2f}, "
        f"numerical refactorisation {r['none_refactor_s'] / r['matching_refactor_s']:.2f}, back-substitution "
        f"{r['none_back_substitution_s'] / r['matching_back_substitution_s']:.2f}, lagged solve "
        f"{r['none_lagged_s'] / r['matching_lagged_s']:.2f}" for r in rows) + "."]
    write_results(
        "pardiso_matching", rows, "PARDISO with and without weighted matching on the coupled systems",
        f"`benchmarks/bench_pardiso_matching.py` (its docstring has the set-up): the factors of step 1, the "
        f"system of a later step; medians of {ROUNDS} rounds, the two settings alternating; one BLAS and one "
        f"MKL thread.",
        ["bodies", "DOFs", "PARDISO", "analysis + factorisation s", "numerical refactorisation s",
         "back-substitution s", "entries of L + U", "peak MiB", "perturbed pivots", "factors alone: residual",
         "lagged FGMRES iterations", "lagged solve s", "its residual"], cells, notes)


if __name__ == "__main__":
    main()
