"""Sparse LU of the whole saddle-point matrix: :class:`DirectSolver`.

SuperLU through :func:`scipy.sparse.linalg.splu` (COLAMD ordering, or a symmetric
minimum-degree ordering in SuperLU's symmetric mode for continuous-pressure pairs), or Intel
MKL PARDISO through the optional ``pypardiso`` package.  Every solve checks the true relative
residual and does up to three steps of iterative refinement (Wilkinson; Higham, *Accuracy
and Stability of Numerical Algorithms*, 2nd ed., 2002, Ch. 12) while it exceeds
``check_rtol``.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ... import validate
from ._sparse import _as_csr, _relres, _same_values
from .krylov import run_fgmres
from .pardiso import PardisoLU, pardiso_available
from .results import SolveInfo, SolverError, _notify_factorization, _notify_solve

__all__ = ["DirectSolver", "default_direct_backend", "COLAMD_PIVOT_THRESHOLD", "PARDISO_MIN_DOFS",
           "MAX_PERTURBED_ITERATIONS"]

#: FGMRES iterations, preconditioned by PARDISO's factors, that a solve may take when the factors hold
#: perturbed pivots and iterative refinement stalls above ``check_rtol`` (:meth:`DirectSolver.solve`)
MAX_PERTURBED_ITERATIONS = 50

#: SuperLU's diagonal pivot threshold with COLAMD when an :class:`~.ordering.OrderingChoice`
#: picks it (as ``pivot_threshold`` for P2-bubble: half the fill of partial pivoting)
COLAMD_PIVOT_THRESHOLD = 0.01


# ==========================================================================
def _pardiso_available() -> bool:
    return pardiso_available()


#: ``"auto"`` factorises systems of at least this many DOFs with PARDISO when ``pypardiso`` is
#: installed.  Second factorisations of coupled moving-mesh systems, one thread (MKL loaded):
#: 15 135 DOFs (10 settling polygons, P2+bubble) SuperLU/COLAMD 0.41 s, PARDISO 0.29 s;
#: 10 307 (20 disks, Taylor–Hood) 0.66 / 0.23 s; 149 285 (100 polygons) 18.5 / 4.3 s, with a
#: quarter of the fill (78.2M / 19.5M entries; ``benchmarks/results/solver_scale.md``).  Below
#: it the gain is a fraction of a second per LU and SuperLU keeps small runs as they were.
PARDISO_MIN_DOFS = 20_000


def default_direct_backend(n_dofs: int | None = None) -> str:
    """The direct backend ``"auto"`` means for a system of ``n_dofs`` (``None``: a large one).

    ``"pardiso"`` when the optional ``pypardiso`` is installed and ``n_dofs`` is at least
    :data:`PARDISO_MIN_DOFS`, else ``"superlu"``.  PARDISO factorised the coupled systems of
    settling suspensions 1.4x (15k DOFs) to 4.3x (149k) faster than SuperLU with a quarter of
    its fill (:mod:`.pardiso` has the settings that make its solves accurate).

    Examples
    --------
    >>> default_direct_backend(5_000)
    'superlu'
    """
    if n_dofs is not None and n_dofs < PARDISO_MIN_DOFS:
        return "superlu"
    return "pardiso" if pardiso_available() else "superlu"


class DirectSolver:
    """Sparse LU factorisation of the whole saddle-point matrix.

    Parameters
    ----------
    backend : {"auto", "superlu", "pardiso"}
        ``"superlu"`` is :func:`scipy.sparse.linalg.splu`.  ``"pardiso"`` uses
        Intel MKL PARDISO through the optional ``pypardiso`` package (raises
        ``ImportError`` if it is missing; settings in :mod:`.pardiso`); it was 4x
        faster than SuperLU at 50k DOFs and 5-14x at 200k on one thread (see the
        benchmarks).  ``"auto"``: :func:`default_direct_backend` of the size of
        each matrix factorised (PARDISO from :data:`PARDISO_MIN_DOFS` DOFs when
        installed); :attr:`backend` is then the one last used.  PARDISO runs on
        ``MKL_NUM_THREADS`` threads.
    permc_spec : str
        Column ordering for SuperLU, ``"COLAMD"`` by default.  ``"MMD_AT_PLUS_A"``
        is allowed only through ``symmetric_mode``.
    symmetric_mode : bool
        SuperLU with a symmetric minimum-degree ordering of Kᵀ + K, SuperLU's
        symmetric mode and a small diagonal pivot threshold (1e-3), for saddle-point
        matrices with a symmetric pattern and a *continuous* pressure (P2/P1, P3/P2,
        MINI): half the fill of COLAMD and 2-3x faster factorisations and solves
        (DFG systems of 12k-156k DOFs).  Do not use it with discontinuous pressure
        (P2-bubble/P1-discontinuous): the ordering did not finish in 2 minutes on a
        26k-DOF system.  Every solve is checked (and refined once) as usual.
    check_rtol : float
        The true relative residual of every solve is checked; up to three steps
        of iterative refinement are done while it exceeds this value, and
        :class:`SolverError` is raised if it still does.
    pivot_threshold : float
        SuperLU's threshold of partial pivoting (``diag_pivot_thresh``, in (0, 1]) with
        ``permc_spec``: a diagonal entry is kept as pivot while it is at least this fraction
        of the largest in its column.  1 (the default) is plain partial pivoting; smaller
        values keep more of COLAMD's ordering.  On P2-bubble/P1-discontinuous systems
        (zero pressure diagonal) 0.01 halved the fill and the factorisation time (DKT,
        35k DOFs: 19.7M → 10.1M entries, 0.90 → 0.42 s, solves 1.4x faster) at a relative
        residual of 2.5e-9 before refinement; 0 fails (zero pivots).
    ordering : fluidem.fluid.solvers.ordering.OrderingChoice, optional
        With ``symmetric_mode`` (continuous pressure) and SuperLU: the run's choice between the
        symmetric-mode ordering and COLAMD with threshold pivoting (0.01), by the fill each
        gave (:mod:`.ordering`; one object shared by the solvers of a run, so it outlives a
        re-triangulation).  Each factorisation reports its fill to it.

    Examples
    --------
    >>> import scipy.sparse as sp, numpy as np
    >>> K = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 0.0]]))
    >>> s = DirectSolver().factorize(K)
    >>> np.round(s.solve(np.array([3.0, 1.0])), 12)
    array([1., 1.])
    >>> s.last_info.iterations
    0
    """

    def __init__(self, backend: str = "auto", permc_spec: str = "COLAMD",
                 check_rtol: float = 1e-8, symmetric_mode: bool = False, pivot_threshold: float = 1.0,
                 ordering=None):
        backend = validate.choice("backend", backend, ("auto", "superlu", "pardiso"))
        self.auto = backend == "auto"
        if self.auto:
            backend = default_direct_backend()
        if permc_spec == "MMD_AT_PLUS_A" and not symmetric_mode:
            raise ValueError("permc_spec='MMD_AT_PLUS_A' with pivoting does not finish on "
                             "saddle-point systems of practical size; use 'COLAMD' or "
                             "symmetric_mode=True")
        if backend == "pardiso" and not self.auto and not _pardiso_available():
            raise ImportError("backend='pardiso' needs the optional package pypardiso: pip install 'fluidem[pardiso]'")
        self.backend = backend
        self.max_refinements = 3
        self.symmetric_mode = bool(symmetric_mode)
        self.permc_spec = "MMD_AT_PLUS_A" if self.symmetric_mode else permc_spec
        self.check_rtol = check_rtol
        self.pivot_threshold = validate.fraction("pivot_threshold", pivot_threshold, lo_open=True)
        self.K: sp.csr_matrix | None = None
        self.factorizations = 0
        self.last_info: SolveInfo | None = None
        self._lu = None
        #: the last factorisation was PARDISO's numerical one on the previous analysis (same pattern)
        self.numeric_only = False
        self._setup_s = 0.0
        self._reused = False
        self.ordering = ordering if (backend == "superlu" or self.auto) and self.symmetric_mode else None
        self._threshold_pivoting = self.pivot_threshold < 1.0

    @property
    def n(self) -> int:
        return 0 if self.K is None else self.K.shape[0]

    def factorize(self, K) -> "DirectSolver":
        """Factorise ``K``.

        Parameters
        ----------
        K : (n, n) sparse matrix
            Non-singular system matrix (see the module notes on pinning a
            pressure DOF).

        Returns
        -------
        self : DirectSolver
        """
        K = _as_csr(K)
        t0 = time.perf_counter()
        if self.auto:
            self.backend = default_direct_backend(K.shape[0])
        if self.backend == "superlu":
            self.numeric_only = False
            how = self.ordering.next() if self.ordering is not None else None
            try:
                if self.symmetric_mode and how != "colamd":
                    self._lu = spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=1e-3,
                                         options={"SymmetricMode": True})
                    self._threshold_pivoting = False
                elif how == "colamd":
                    self._lu = spla.splu(K.tocsc(), permc_spec="COLAMD", diag_pivot_thresh=COLAMD_PIVOT_THRESHOLD)
                    self._threshold_pivoting = True
                else:
                    self._lu = spla.splu(K.tocsc(), permc_spec=self.permc_spec,
                                         diag_pivot_thresh=self.pivot_threshold)
            except RuntimeError as err:  # "Factor is exactly singular"
                raise SolverError(
                    f"LU of the {K.shape[0]}x{K.shape[0]} system failed ({err}); with velocity "
                    "Dirichlet conditions on the whole boundary pin one pressure DOF") from err
            if how is not None:
                self.ordering.record(how, self._lu.L.nnz + self._lu.U.nnz, K.nnz)
        else:
            try:
                # the pattern of the last LU: its numerical factorisation alone (a fifth of the time)
                self.numeric_only = isinstance(self._lu, PardisoLU) and self._lu.refactor(K)
                if not self.numeric_only:
                    self._free()
                    self._lu = PardisoLU(K)
            except RuntimeError as err:
                raise SolverError(
                    f"PARDISO factorisation of the {K.shape[0]}x{K.shape[0]} system failed "
                    f"({err}); with velocity Dirichlet conditions on the whole boundary pin one "
                    "pressure DOF") from err
            self._threshold_pivoting = True  # perturbed pivots: one refinement step always
        self.K = K
        self.factorizations += 1
        self._setup_s = time.perf_counter() - t0
        self._reused = False
        _notify_factorization(self)
        return self

    def _free(self):
        """Release PARDISO's memory for the previous factorisation."""
        if isinstance(self._lu, PardisoLU):
            self._lu.free()
            self._lu = None

    @property
    def held_lu_bytes(self) -> float:
        """Memory of the PARDISO factorisation held now (PARDISO's own peak of it, bytes), which
        :meth:`factorize` releases before computing the next; 0 for none and for SuperLU, which keeps
        its old factors until the new ones are done."""
        return float(self._lu.peak_bytes) if isinstance(self._lu, PardisoLU) else 0.0

    def release(self) -> None:
        """Drop the factors and the matrix (before a system of other DOFs is built, e.g. at a
        re-triangulation: an LU of the old mesh preconditions nothing there, and holding it while
        the new system is built raised a run's peak memory).  The next :meth:`factorize` starts
        afresh."""
        self._free()
        self._lu = None
        self.K = None

    def refactorize_if_changed(self, K) -> bool:
        """Factorise ``K`` unless it equals the matrix factorised last.

        Parameters
        ----------
        K : (n, n) sparse matrix

        Returns
        -------
        refactorized : bool
            ``True`` if a new LU was computed.
        """
        K = _as_csr(K)
        if _same_values(self.K, K):
            self._reused = True
            return False
        self.factorize(K)
        return True

    def _apply(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(b)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``K x = b`` with the stored factorisation.

        Parameters
        ----------
        b : (n,) or (n, k) float ndarray

        Returns
        -------
        x : ndarray, same shape as ``b``

        Raises
        ------
        SolverError
            If the relative residual exceeds ``check_rtol`` after up to three steps
            of iterative refinement (near-singular ``K``) and, for PARDISO factors with
            perturbed pivots, after up to :data:`MAX_PERTURBED_ITERATIONS` FGMRES
            iterations preconditioned by them.
        """
        if self._lu is None:
            raise RuntimeError("call factorize(K) before solve(b)")
        b = np.asarray(b, dtype=float)
        if b.shape[0] != self.n:
            raise ValueError(f"b has {b.shape[0]} rows, the matrix has {self.n}")
        t0 = time.perf_counter()
        x = self._apply(b)
        res = [_relres(self.K, x, b)]
        note = ""
        # iterative refinement (Wilkinson; Higham 2002, ch. 12): up to three steps while the
        # residual keeps falling; LU with threshold pivoting of ill-conditioned saddle-point
        # systems (a pinned pressure of a closed box) may need more than one
        # with threshold pivoting (pivot_threshold < 1) one step always: the larger growth of the
        # factors leaves round-off 100x that of partial pivoting, which one step removes
        forced = 1 if self._threshold_pivoting else 0
        # factors with perturbed pivots (PARDISO's static pivoting: without weighted matching every
        # zero pressure pivot) are those of a matrix ~1e-8 ‖K‖ away: their solve leaves 1e-7-1e-2, each
        # step takes off about that factor, and the steps go on while the residual halves, to round-off
        # (100 ε) as a solve with exact factors ends (a 1 760-DOF Stokes system: 3.1e-7, 9.1e-12, 7.1e-16)
        perturbed = int(getattr(self._lu, "perturbed", 0))
        roundoff = 100 * np.finfo(float).eps
        while ((len(res) <= forced or not res[-1] <= self.check_rtol or (perturbed and not res[-1] <= roundoff))
               and len(res) <= self.max_refinements):
            x_new = x + self._apply(b - self.K @ x)
            r_new = _relres(self.K, x_new, b)
            if not r_new < 0.5 * res[-1] and len(res) > forced:
                break
            x = x_new
            res.append(r_new)
            note = f"{len(res) - 1} refinement step(s)"
        iterations = 0
        if not res[-1] <= self.check_rtol and perturbed:
            # PARDISO replaced small pivots by ε ‖K‖ (static pivoting, Schenk & Gärtner 2004), and
            # refinement stalled: FGMRES preconditioned by the same factors corrects the perturbation
            # (a flipped element pair of 100 settling polygons: refinement stopped at 5.4e-4, FGMRES
            # reached 2.8e-10 in 9 iterations, and the run went on, where SuperLU's partial pivoting
            # solved directly)
            # (a singular K, no pressure pinned, gets the cycle's least-squares step; the residual
            # below judges the solve)
            x_k, iterations, _, _ = run_fgmres(self.K, b, self.as_preconditioner(), x, self.check_rtol,
                                               MAX_PERTURBED_ITERATIONS, MAX_PERTURBED_ITERATIONS, 0.999)
            r_k = _relres(self.K, x_k, b)
            if r_k < res[-1]:
                x = x_k
                res.append(r_k)
            note = f"{perturbed} perturbed pivot(s): {iterations} FGMRES iterations around the factors"
        info = SolveInfo(
            method=self.backend, n=self.n, iterations=iterations, residuals=np.array(res),
            relative_residual=res[-1], setup_s=self._setup_s,
            solve_s=time.perf_counter() - t0, reused_setup=self._reused,
            factorizations=self.factorizations, note=note)
        self.last_info = info
        _notify_solve(info)
        if not res[-1] <= self.check_rtol:
            raise SolverError(
                f"direct solve residual {res[-1]:.2e} exceeds {self.check_rtol:.1e}: the matrix "
                "is (near) singular; with velocity Dirichlet conditions on the whole boundary "
                "pin one pressure DOF", info)
        return x

    def inverse_operator(self) -> spla.LinearOperator | None:
        """The stored LU as ``K⁻¹`` with its transpose: ``matvec`` solves ``K x = v``, ``rmatvec``
        solves ``Kᵀ x = v`` (``trans="T"`` of SuperLU and of :class:`~.pardiso.PardisoLU`), shape
        (n, n); what a 1-norm estimate of ``‖K⁻¹‖₁`` needs
        (:func:`fluidem.diagnostics.condition_estimate`).  No refinement: the factors as they are.
        """
        if self._lu is None:
            raise RuntimeError("call factorize(K) first")
        lu, n = self._lu, self.n
        return spla.LinearOperator((n, n), matvec=lu.solve, matmat=lu.solve,
                                   rmatvec=lambda v: lu.solve(v, trans="T"),
                                   rmatmat=lambda v: lu.solve(v, trans="T"), dtype=float)

    def as_preconditioner(self) -> spla.LinearOperator:
        """The stored LU as an operator ``v -> K_lu^{-1} v``, shape (n, n)."""
        if self._lu is None:
            raise RuntimeError("call factorize(K) first")
        n = self.n
        return spla.LinearOperator((n, n), matvec=self._apply, dtype=float)
