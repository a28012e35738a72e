"""Benchmarks of the saddle-point solvers in :mod:`fluidem.fluid.solvers`.

Direct LU vs block-preconditioned GMRES vs lagged LU, for Stokes, Oseen and
unsteady (backward-Euler-type, mass-dominated) systems with the default
element pair "p2b" (P2+bubble velocity, P1-discontinuous pressure) on the
unit square, at about 10k, 50k and 200k DOFs; the systems are the manufactured ones of
:mod:`fluidem.cases.manufactured`.

Run (one BLAS thread, results are wall-clock and therefore noisy on a shared
machine)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_solvers.py \
        --benchmark-only --benchmark-columns=median,min,rounds -p no:cacheprovider

Each benchmark stores ``n_dofs``, ``iterations`` and ``us_per_dof`` in
``extra_info``.  A benchmark round is ``factorize`` + ``solve`` (setup
included), except for "lagged", where the LU of a nearby matrix (viscosity
+5 %, convecting field +25 %, time step +5 %) is built once outside the timing
and each round is ``factorize`` (no new LU) + ``solve`` by GMRES preconditioned
with it: the per-step cost between refactorisations.  "direct" is SuperLU,
"pardiso" the optional PARDISO backend (skipped without pypardiso); "lagged"
uses the default backend.

Results (2026-11-24, 2-core shared VM, one BLAS/MKL thread, rtol 1e-8, medians
of 3 rounds, 1 round at 200k; first number from a run at load ~4, the one in
brackets from a rerun at load ~7, so read ratios, not digits; "lagged" is the
per-step cost without the LU; us = microseconds per DOF of the first run)::

    problem   DOFs    | SuperLU              | PARDISO            | GMRES+block (its)        | lagged LU
    stokes      10272 | 0.23 s [0.43]   22us | 0.26 s [0.59] 25us | 0.11 s [0.18] 11us 41it  | 0.04 s 2it
    stokes      50350 | 4.03 s [7.25]   80us | 0.93 s [2.08] 19us | 0.75 s [1.68] 15us 61it  | 0.21 s 2it
    stokes     198030 | 69.1 s [102]   349us | 5.00 s [7.86] 25us | 7.02 s [14.9] 35us 123it | 0.64 s 2it
    oseen       10272 | 0.18 s [0.29]   17us | 0.28 s [0.42] 27us | 0.24 s [0.56] 24us 87it  | 0.11 s 7it
    oseen       50350 | 3.70 s [5.80]   73us | 1.00 s [2.21] 20us | 2.27 s [3.25] 45us 121it | 0.56 s 7it
    oseen      198030 | 84.1 s [120]   425us | 6.32 s [10.3] 32us | 17.1 s [17.5] 86us 194it | 2.58 s 7it
    newton      10272 | 0.15 s [0.32]   15us | 0.27 s [0.55] 26us | 2.30 s [2.21] 224us 385it| 0.12 s 7it
    newton      50350 | 2.59 s [5.39]   51us | 1.04 s [2.20] 21us | 19.4 s [31.3] 386us 898it| 0.68 s 7it
    newton     198030 | 34.2 s [62.5]  172us | 7.53 s [7.53] 38us | no convergence in 1000 it | 3.22 s 7it
    unsteady    10272 | 0.32 s [0.38]   32us | 0.34 s [0.44] 33us | 0.36 s [0.29] 35us 49it  | 0.05 s 3it
    unsteady    50350 | 3.25 s [6.80]   65us | 0.81 s [1.70] 16us | 1.46 s [1.14] 29us 42it  | 0.21 s 3it
    unsteady   198030 | 42.9 s [84.7]  217us | 5.36 s [9.04] 27us | 6.93 s [6.46] 35us 50it  | 1.39 s 3it

    LU memory (Stokes): SuperLU 46 / 425 / 2585 MB, PARDISO 12 / 82 / 388 MB.
    One-off at 501k DOFs (Stokes / unsteady): PARDISO 20.8 s / 35.9 s (1.5 GB
    peak), GMRES+block 59.0 s (239 it) / 27.3 s (51 it).

Reading: PARDISO is 4x faster than SuperLU at 50k and 7-14x at 200k with 5-7x
less memory.  The block preconditioner's iteration count grows with refinement
for Stokes/Oseen (one smoothed-aggregation cycle pair on P2+bubble is not
h-independent) and explodes for Newton Jacobians, but stays at 40-50 for the
mass-dominated unsteady system with the Cahouet--Chabard Schur approximation.
The LU of a nearby matrix solves Stokes/unsteady systems in 2-3 and
Oseen/Newton systems in 7 GMRES iterations, independent of size.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")  # PARDISO (optional) on one thread too

import pytest  # noqa: E402

from fluidem.cases.manufactured import saddle_point_problem  # noqa: E402
from fluidem.fluid.solvers import (  # noqa: E402
    BlockKrylovSolver,
    DirectSolver,
    LaggedLUSolver,
)


# ---------------------------------------------------------------- cases
# grid sizes giving about 10k, 50k and 200k DOFs for "p2b" (n = 18 m^2)
SIZES = {"10k": 24, "50k": 53, "200k": 105}
KINDS = {
    "stokes": dict(),
    "oseen": dict(peclet=20.0),
    "newton": dict(peclet=20.0, newton=True),
    # mass-dominated velocity block: nu dt / h^2 = 0.06 at 10k DOFs, 1.1 at 200k
    "unsteady": dict(nu=1e-3, dt=1e-2, peclet=0.2),
}
_cache: dict = {}


def _problem(kind, size):
    key = (kind, size)
    if key not in _cache:
        _cache.clear()
        _cache[key] = saddle_point_problem(SIZES[size], **KINDS[kind])
    return _cache[key]


def _iterative(kind, P):
    kw = KINDS[kind]
    return BlockKrylovSolver(P.n_u, pressure_mass=P.Mp, nu=kw.get("nu", 1.0),
                             dt=kw.get("dt"), velocity_mass=P.Mu, rtol=1e-8)


def _record(benchmark, P, solver):
    info = solver.last_info
    n = P.K.shape[0]
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(
        n_dofs=n, iterations=info.iterations, relative_residual=info.relative_residual,
        setup_s=info.setup_s, us_per_dof=median / n * 1e6)
    lu = getattr(getattr(solver, "direct", solver), "_lu", None)
    if hasattr(lu, "L"):  # SuperLU fill: memory of the factors
        benchmark.extra_info["lu_mb"] = (lu.L.nnz + lu.U.nnz) * 12 / 1e6
    elif hasattr(lu, "get_iparm"):  # PARDISO: permanent memory of the factors, kB
        benchmark.extra_info["lu_mb"] = lu.get_iparm(17) / 1e3


def _pardiso():
    try:
        import pypardiso  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("method", ["direct", "pardiso", "iterative", "lagged"])
def test_solver(benchmark, method, kind, size):
    if method == "pardiso" and not _pardiso():
        pytest.skip("pypardiso is not installed")
    P = _problem(kind, size)
    K, b = P.K, P.b
    if method in ("direct", "pardiso"):
        backend = "superlu" if method == "direct" else "pardiso"

        def run():
            s = DirectSolver(backend=backend).factorize(K)
            s.solve(b)
            return s
    elif method == "iterative":
        def run():
            s = _iterative(kind, P)
            s.factorize(K)
            s.solve(b)
            return s
    else:
        # LU of a nearby matrix, as a few time steps ago: viscosity, convecting field
        # and time step changed by 5 %, 25 % and 5 %
        old = dict(KINDS[kind])
        old["nu"] = 1.05 * old.get("nu", 1.0)
        old["peclet"] = 1.25 * old.get("peclet", 0.0)
        if "dt" in old:
            old["dt"] *= 1.05
        K_old = saddle_point_problem(SIZES[size], **old).K
        lagged = LaggedLUSolver(max_iterations_before_refactor=10**6, rtol=1e-8)
        lagged.factorize(K_old)

        def run():
            lagged.factorize(K)
            lagged.solve(b)
            return lagged
    rounds = 1 if size == "200k" else 3
    s = benchmark.pedantic(run, rounds=rounds, iterations=1, warmup_rounds=0)
    _record(benchmark, P, s)
