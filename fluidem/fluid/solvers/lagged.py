"""GMRES preconditioned by the LU of an earlier matrix: :class:`LaggedLUSolver`.

Over a run of time steps the saddle-point matrices change a little from step to step (the
convecting velocity, the mesh nodes).  The LU of a matrix a few steps old preconditions the
current one in a handful of GMRES iterations (2-3 for Stokes and unsteady systems, 7 for
Oseen/Newton ones, independent of size: ``benchmarks/bench_solvers.py``), 5-20x cheaper than
a fresh LU; the solver refactorises when the iteration count exceeds a threshold.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._sparse import _as_csr, _same_values
from .direct import DirectSolver
from .krylov import run_fgmres
from .results import SolveInfo, SolverError, _notify_solve

__all__ = ["LaggedLUSolver", "FIXED_MESH_STEPPING", "MOVING_MESH_STEPPING", "PARDISO_REFACTOR_ITERATIONS"]

#: Lagged-LU settings for runs of time steps on a fixed mesh (semi-implicit convection): solve each
#: step's correction to a relative residual of 1e-6 (its right-hand side is the residual of the
#: extrapolated guess, already small).  Measured on DFG 2D-2 (P3/P2, 11.1k DOFs, BDF3 at dt = 0.005,
#: 1 200 steps, CPU seconds on one thread): 54.5 s (64 LUs, 7.1 iterations a step) against 65.1 s with
#: the general rtol 1e-10 (182 LUs, 7.4 iterations); refactorising above 5 / 20 / 3 iterations instead
#: of 10: 54.4 / 74.0 / 70.7 s.  St and c_D,max agree with the 1e-10 run to 1e-8.
FIXED_MESH_STEPPING = {"rtol": 1e-6}

#: Lagged-LU settings for runs of time steps on the moving mesh (prescribed and free bodies): the
#: same correction form (the right-hand side is the residual at the extrapolated guess, the
#: contact-load changes of the coupled step) to a relative residual of 1e-6, refactorising only
#: above 25 iterations (one LU costs 40-60 back-substitutions; an LU is recomputed at every
#: re-triangulation anyway).  Measured on the DKT (P2+bubble, 35k-38k DOFs, 300 steps to t = 1.5,
#: `benchmarks/bench_dkt.py` set-up): 127 s against 173 s with rtol 1e-10 (run side by side), 29 LUs
#: either way, centres agree to 1.6e-5 cm (8e-5 d).
MOVING_MESH_STEPPING = {"rtol": 1e-6, "max_iterations_before_refactor": 25}

#: GMRES iterations with the lagged LU, beyond the two back-substitutions of a fresh LU's solve, that
#: cost what a PARDISO numerical factorisation on the same analysis costs
#: (:meth:`~.pardiso.PardisoLU.refactor`): the price of "buy" in the rent-or-buy rule of
#: :attr:`LaggedLUSolver.refactor_after`.  Measured in 40-step runs of the coupled free-body systems
#: (one MKL thread, the two runs side by side): the numerical factorisations took 11.6-15.9 times
#: the median GMRES iteration at 54k DOFs (``column-collapse-fluid``, 0.22-0.31 s against 0.019 s)
#: and 10.2-14.4 times at 152k (100 settling polygons, 0.64-0.91 s against 0.063 s), with weighted
#: matching.  Without it (the default since) the ratio of a numerical factorisation to a lagged
#: iteration measured 7.0, 7.7 and 9.0 at 149k, 447k and 1.49M DOFs (0.16, 0.56 and 2.33 s against
#: 0.023, 0.073 and 0.26 s, ``benchmarks/results/pardiso_matching.md``): not re-measured over whole
#: runs, the count is kept.  A count, not a clock: the rule decides alike on a busy and an idle
#: machine, so a run repeats to the last bit.
PARDISO_REFACTOR_ITERATIONS = 12


# ==========================================================================
class LaggedLUSolver:
    """GMRES preconditioned by the LU of an earlier matrix; refactorise on demand.

    ``factorize(K)`` stores ``K`` but computes a new LU only when there is
    none yet, when the shape changed (re-triangulation), when the last solve
    needed more than ``max_iterations_before_refactor`` iterations, when the
    iterations since the last LU cost a factorisation (:attr:`refactor_after`),
    or when ``force=True``.  ``solve`` then runs GMRES on the current ``K`` with the
    old LU as right preconditioner.  If GMRES fails within ``maxiter``, the
    current ``K`` is factorised and solved directly, so the result always
    meets ``rtol``.

    Parameters
    ----------
    max_iterations_before_refactor : int
        A solve needing more GMRES iterations than this triggers an LU of
        the next matrix passed to ``factorize``.
    rtol : float
        Required true relative residual of every solve.
    maxiter : int
        GMRES iterations before falling back to a fresh LU.
    direct : DirectSolver, optional
        Configured direct solver to use for the factorisations.
    refactor_after : int, optional
        GMRES iterations beyond two a solve (summed since the last LU) after which the next
        matrix is factorised too (:attr:`refactor_after`); default
        :data:`PARDISO_REFACTOR_ITERATIONS` for PARDISO, none for SuperLU.

    Attributes
    ----------
    factorizations : int
        LU factorisations so far.
    solves, total_iterations : int
        Solves and GMRES iterations so far.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> K0 = sp.diags([-1.0, 4.0, -1.0], [-1, 0, 1], shape=(50, 50)).tocsr()
    >>> s = LaggedLUSolver(max_iterations_before_refactor=5).factorize(K0)
    >>> x = s.solve(np.ones(50))
    >>> x = s.factorize(1.01 * K0).solve(np.ones(50))
    >>> s.factorizations, s.last_info.iterations <= 5
    (1, True)
    """

    def __init__(self, max_iterations_before_refactor: int = 10, rtol: float = 1e-10,
                 maxiter: int = 50, direct: DirectSolver | None = None, refactor_after: int | None = None):
        self.max_iterations_before_refactor = int(max_iterations_before_refactor)
        self.rtol = float(rtol)
        self.maxiter = int(maxiter)
        self.direct = direct if direct is not None else DirectSolver()
        self._refactor_after = None if refactor_after is None else int(refactor_after)
        self.K: sp.csr_matrix | None = None
        self.factorizations = 0
        self.solves = 0
        self.total_iterations = 0
        self.last_info: SolveInfo | None = None
        self._refactor_next = False
        self._fresh = False
        self._setup_s = 0.0
        #: GMRES iterations since the last factorisation, beyond two a solve (what a fresh LU's
        #: solve costs: its back-substitution and one refinement step)
        self._lag_iterations = 0

    def _factorize_current(self):
        t0 = time.perf_counter()
        self.direct.factorize(self.K)
        self.factorizations += 1
        self._fresh = True
        self._refactor_next = False
        self._setup_s = time.perf_counter() - t0
        self._lag_iterations = 0

    @property
    def refactor_after(self) -> int | None:
        """GMRES iterations beyond two a solve, summed since the last LU, after which the next
        matrix passed to :meth:`factorize` is factorised too: once the lag has cost what a new LU
        costs (the rent-or-buy rule, never more than twice the best choice made in hindsight:
        Karlin et al., *Competitive snoopy caching*, Algorithmica 3, 1988).  PARDISO factorises
        numerically on the analysis of the same pattern (:meth:`~.pardiso.PardisoLU.refactor`) at
        the cost of :data:`PARDISO_REFACTOR_ITERATIONS` iterations; a SuperLU factorisation costs
        hundreds, and ``max_iterations_before_refactor`` alone decides (``None``).  The rule counts
        iterations, not seconds, so the LU in use, and every number of a run, do not depend on
        the machine's load."""
        if self._refactor_after is not None:
            return self._refactor_after
        return PARDISO_REFACTOR_ITERATIONS if self.direct.backend == "pardiso" else None

    def factorize(self, K, force: bool = False) -> "LaggedLUSolver":
        """Make ``K`` the current matrix; compute an LU only when needed.

        Parameters
        ----------
        K : (n, n) sparse matrix
        force : bool
            Factorise ``K`` now.

        Returns
        -------
        self : LaggedLUSolver
        """
        K = _as_csr(K)
        old_lu = self.direct.K
        self.K = K
        # only the shape matters: the old LU preconditions any matrix of that size
        # (sparsity patterns may differ by entries that cancelled in assembly)
        if force or old_lu is None or self._refactor_next or old_lu.shape != K.shape:
            self._factorize_current()
        else:
            self._fresh = _same_values(old_lu, K)
            self._setup_s = 0.0
        return self

    def release(self) -> None:
        """Drop the LU and the matrices (:meth:`DirectSolver.release`); the next :meth:`factorize`
        factorises."""
        self.direct.release()
        self.K = None

    def solve(self, b: np.ndarray, rtol: float | None = None) -> np.ndarray:
        """Solve ``K x = b`` for the current ``K``.

        Parameters
        ----------
        b : (n,) float ndarray
        rtol : float, optional
            Relative residual of this solve instead of :attr:`rtol` (e.g. looser for a small
            correction whose absolute accuracy is what matters); a fresh LU solves directly.

        Returns
        -------
        x : (n,) float ndarray
        """
        if self.K is None:
            raise RuntimeError("call factorize(K) before solve(b)")
        b = np.asarray(b, dtype=float)
        t0 = time.perf_counter()
        self.solves += 1
        note = ""
        krylov = not self._fresh  # a fresh LU solves directly, and reports that solve itself
        if self._fresh:
            x = self.direct.solve(b)
            it, hist = 0, self.direct.last_info.residuals
        else:
            x, it, hist, reason = run_fgmres(self.K, b, self.direct.as_preconditioner(), None,
                                          self.rtol if rtol is None else float(rtol), self.maxiter,
                                          self.maxiter, 0.999)
            self.total_iterations += it
            if reason:
                note = f"GMRES with the lagged LU failed ({reason}); refactorized"
                self._factorize_current()
                x = self.direct.solve(b)
                hist = np.concatenate([hist, self.direct.last_info.residuals])
            elif it > self.max_iterations_before_refactor:
                self._refactor_next = True
                note = "refactorization due at the next factorize"
            elif self.refactor_after is not None and it > 2:
                self._lag_iterations += it - 2
                if self._lag_iterations > self.refactor_after:
                    self._refactor_next = True
                    note = "refactorization due at the next factorize (the lag cost a factorisation)"
        info = SolveInfo(method="gmres+lagged-lu" if it else self.direct.backend,
                         n=self.K.shape[0], iterations=it, residuals=np.asarray(hist),
                         relative_residual=float(hist[-1]), setup_s=self._setup_s,
                         solve_s=time.perf_counter() - t0, reused_setup=not self._fresh,
                         factorizations=self.factorizations, note=note)
        self.last_info = info
        if krylov:
            _notify_solve(info)
        if not info.relative_residual <= max(self.rtol if rtol is None else rtol, self.direct.check_rtol):
            raise SolverError(f"lagged-LU solve ended at residual {info.relative_residual:.2e}",
                              info)
        return x

    def as_preconditioner(self) -> spla.LinearOperator:
        """The stored (possibly lagged) LU as a LinearOperator, shape (n, n)."""
        return self.direct.as_preconditioner()
