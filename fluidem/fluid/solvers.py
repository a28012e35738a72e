r"""Linear solvers for the saddle-point systems of incompressible flow.

Every fluid step ends in one linear system

.. math::

    K \begin{bmatrix} u \\ p \end{bmatrix}
    = \begin{bmatrix} A & B^T \\ B & -C \end{bmatrix}
      \begin{bmatrix} u \\ p \end{bmatrix}
    = \begin{bmatrix} f \\ g \end{bmatrix},

assembled after Dirichlet condensation, velocity DOFs first (``n_u`` of them),
then pressure DOFs (``n_p``).  ``A`` is the velocity block (viscous term, plus
``(alpha/dt) M_u`` for unsteady flow, plus convection for Oseen/Newton systems,
so possibly non-symmetric), ``B`` the (negative) discrete divergence and ``C``
an optional pressure stabilisation (usually zero).

Solvers here share one shape, borrowed from pyamg: an object is configured in
its constructor, ``factorize(K)`` does the setup (LU, AMG hierarchies) and
returns the object, ``solve(b)`` returns ``x`` and records a :class:`SolveInfo`
in ``last_info``, ``as_preconditioner()`` gives a
:class:`scipy.sparse.linalg.LinearOperator`.

* :class:`DirectSolver` -- sparse LU (SuperLU through scipy; PARDISO through
  the optional ``pypardiso`` package).
* :class:`BlockKrylovSolver` -- GMRES with a block upper-triangular
  preconditioner, or MINRES with a block-diagonal one (symmetric Stokes).
  The velocity block is approximated by two V-cycles of pyamg smoothed
  aggregation (``velocity_cycles``), the Schur complement
  :math:`S = B A^{-1} B^T + C` by

  - ``"mass"``: :math:`S^{-1} \approx \nu M_p^{-1}` (steady Stokes; [ESW14]_,
    Stokes solver chapter; [SW94]_),
  - ``"cahouet-chabard"``: :math:`S^{-1} \approx \nu M_p^{-1} +
    (\alpha/\Delta t) L_p^{-1}` with :math:`L_p = B D_u^{-1} B^T` and
    :math:`D_u` the diagonal of the velocity mass matrix ([CC88]_; [ESW14]_,
    unsteady flow in the Navier--Stokes solver chapter); :math:`L_p^{-1}`
    is one AMG V-cycle,
  - ``"lsc"``: least-squares commutator :math:`S^{-1} \approx L_p^{-1}
    (B D_u^{-1} A D_u^{-1} B^T) L_p^{-1}` for convection-dominated Oseen
    systems ([ESW14]_, Navier--Stokes solver chapter; [EHSST06]_).

* :class:`LaggedLUSolver` -- keeps the LU of an earlier matrix and solves the
  current one by GMRES preconditioned with it; refactorises when the
  iteration count exceeds a threshold.  The LU of a Jacobian a few time
  steps old preconditions the current one in a handful of iterations.
* :func:`make_solver` -- solvers by name (``"auto"``, ``"direct"``,
  ``"iterative"``, ``"lagged"``); ``"auto"`` chooses by size and time step
  through :func:`choose_method`, whose thresholds come from the measurements
  in ``benchmarks/bench_solvers.py``.

No solver returns an unconverged field: the true relative residual
``||b - K x||_2 / ||b||_2`` is checked after every solve and
:class:`SolverError` is raised, with a summary of the residual history, when
it misses the tolerance, when a Krylov method stagnates or when the LU is
singular.

Singular systems.  With velocity Dirichlet conditions on the whole boundary
the pressure is determined only up to a constant and ``K`` is singular.  The
caller removes the null space by *pinning* one pressure DOF: treat it like a
Dirichlet DOF (condense it out with value 0) before handing ``K`` over, and
shift the pressure afterwards if a zero mean is wanted.  With an outflow
(natural) boundary nothing needs to be done.  Both the direct and the
iterative path assume a non-singular ``K``.

References
----------
.. [ESW14] Elman, H. C., Silvester, D. J., Wathen, A. J. (2014). *Finite
   Elements and Fast Iterative Solvers*, 2nd ed., Oxford University Press.
   Chapters on the solution of discrete Stokes problems (block-diagonal
   preconditioning, MINRES, pressure-mass Schur approximation) and of
   discrete Navier--Stokes problems (GMRES with block-triangular
   preconditioners, PCD and least-squares commutator, unsteady flow).
.. [CC88] Cahouet, J., Chabard, J.-P. (1988). Some fast 3D finite element
   solvers for the generalized Stokes problem. *Int. J. Numer. Meth. Fluids*
   8, 869--895.
.. [EHSST06] Elman, H., Howle, V. E., Shadid, J., Shuttleworth, R.,
   Tuminaro, R. (2006). Block preconditioners based on approximate
   commutators. *SIAM J. Sci. Comput.* 27, 1651--1668.
.. [SW94] Silvester, D., Wathen, A. (1994). Fast iterative solution of
   stabilised Stokes systems. Part II: using general block preconditioners.
   *SIAM J. Numer. Anal.* 31, 1352--1367.
.. [W87] Wathen, A. J. (1987). Realistic eigenvalue bounds for the Galerkin
   mass matrix. *IMA J. Numer. Anal.* 7, 449--457.
.. [S93] Saad, Y. (1993). A flexible inner-outer preconditioned GMRES
   algorithm. *SIAM J. Sci. Comput.* 14, 461--469.
.. [VMB96] Vanek, P., Mandel, J., Brezina, M. (1996). Algebraic multigrid by
   smoothed aggregation for second and fourth order elliptic problems.
   *Computing* 56, 179--196.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = [
    "SolveInfo",
    "SolverError",
    "DirectSolver",
    "BlockKrylovSolver",
    "LaggedLUSolver",
    "AutoSolver",
    "SOLVERS",
    "make_solver",
    "choose_method",
    "default_direct_backend",
    "DIRECT_MAX_DOFS",
    "DIRECT_MAX_DOFS_UNSTEADY",
    "DIRECT_MAX_DOFS_CONVECTIVE",
]

# --------------------------------------------------------------------------
# Crossover of the automatic choice.  Measured with benchmarks/bench_solvers.py
# (P2-bubble/P1-discontinuous pair on a unit square, one thread, wall clock on a
# shared machine; the table is in that file's docstring).
# --------------------------------------------------------------------------
#: Steady Stokes: LU below this many DOFs, block-preconditioned GMRES above; by
#: direct backend.  SuperLU: GMRES was 2x faster at 10k DOFs and 5-10x at 50k-200k.
#: PARDISO: LU was faster at every size measured (2.8x at 500k DOFs, 1.5 GB peak),
#: because the AMG iteration counts grow with refinement; the limit is memory
#: (extrapolated ~7 GB at 2M DOFs).
DIRECT_MAX_DOFS = {"superlu": 20_000, "pardiso": 2_000_000}
#: Unsteady systems with the Cahouet--Chabard preconditioner, whose iteration count
#: stayed at 40-50 from 10k to 500k DOFs.  SuperLU: equal at 10k, GMRES 2x faster at
#: 50k.  PARDISO: LU faster up to 200k, GMRES faster at 500k.
DIRECT_MAX_DOFS_UNSTEADY = {"superlu": 20_000, "pardiso": 400_000}
#: Steady convective systems (Oseen, Newton): the Schur approximations need iteration
#: counts that grow with refinement and Reynolds number (Newton at 200k DOFs: no
#: convergence in 1000 iterations), so LU up to its memory limit (SuperLU needed
#: 5x the memory of PARDISO at 50k DOFs).
DIRECT_MAX_DOFS_CONVECTIVE = {"superlu": 300_000, "pardiso": 2_000_000}


# ==========================================================================
# Results and errors
# ==========================================================================
@dataclass
class SolveInfo:
    """What one solve did.

    Attributes
    ----------
    method : str
        Short description, e.g. ``"superlu"`` or
        ``"gmres+tri(amg, cahouet-chabard)"``.
    n : int
        Size of the system, ``n_u + n_p``.
    iterations : int
        Krylov iterations (preconditioner applications); 0 for a direct solve.
    residuals : (k,) float ndarray
        History of relative residual norms ``||b - K x_i|| / ||b||``
        (Krylov estimates inside a cycle, true residuals at cycle ends).
    relative_residual : float
        True final relative residual ``||b - K x||_2 / ||b||_2``.
    setup_s : float
        Seconds spent in the last ``factorize`` (LU, AMG setup), wall clock.
    solve_s : float
        Seconds spent in this ``solve``, wall clock.
    reused_setup : bool
        Whether ``factorize`` reused an earlier LU or AMG hierarchy.
    factorizations : int
        LU factorisations done so far by this solver object.
    note : str
        Free text (refactorisation, fallbacks).
    """

    method: str
    n: int
    iterations: int = 0
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    relative_residual: float = math.nan
    setup_s: float = 0.0
    solve_s: float = 0.0
    reused_setup: bool = False
    factorizations: int = 0
    note: str = ""

    def __str__(self) -> str:
        s = (
            f"SolveInfo({self.method}, n={self.n}, iterations={self.iterations}, "
            f"relative_residual={self.relative_residual:.2e}, setup={self.setup_s:.3g} s, "
            f"solve={self.solve_s:.3g} s"
        )
        if self.reused_setup:
            s += ", reused setup"
        if self.factorizations:
            s += f", factorizations={self.factorizations}"
        if self.note:
            s += f", {self.note}"
        return s + ")"


class SolverError(RuntimeError):
    """A linear solve failed: singular matrix, no convergence or stagnation.

    Attributes
    ----------
    info : SolveInfo or None
        State of the failed solve (residual history included).
    """

    def __init__(self, message: str, info: SolveInfo | None = None):
        if info is not None and info.residuals.size:
            message = f"{message}\n  {_history_summary(info.residuals)}"
        super().__init__(message)
        self.info = info


def _history_summary(res: np.ndarray) -> str:
    res = np.asarray(res)
    if res.size <= 8:
        shown = ", ".join(f"{r:.2e}" for r in res)
    else:
        head = ", ".join(f"{r:.2e}" for r in res[:3])
        tail = ", ".join(f"{r:.2e}" for r in res[-4:])
        shown = f"{head}, ..., {tail}"
    return f"relative residual history ({res.size} entries): {shown}"


# ==========================================================================
# Helpers
# ==========================================================================
def _as_csr(K, name: str = "K") -> sp.csr_matrix:
    if not sp.issparse(K):
        raise TypeError(f"{name} must be a scipy sparse matrix, got {type(K).__name__}")
    K = sp.csr_matrix(K)
    if K.shape[0] != K.shape[1]:
        raise ValueError(f"{name} must be square, got shape {K.shape}")
    if not K.has_sorted_indices:
        K.sort_indices()
    return K


def _same_structure(a: sp.csr_matrix | None, b: sp.csr_matrix) -> bool:
    return (
        a is not None
        and a.shape == b.shape
        and a.nnz == b.nnz
        and np.array_equal(a.indptr, b.indptr)
        and np.array_equal(a.indices, b.indices)
    )


def _same_values(a: sp.csr_matrix | None, b: sp.csr_matrix) -> bool:
    return _same_structure(a, b) and np.array_equal(a.data, b.data)


def _is_symmetric(A: sp.spmatrix, tol: float = 1e-12) -> bool:
    d = abs(A - A.T)
    scale = abs(A).max() if A.nnz else 1.0
    return (d.max() if d.nnz else 0.0) <= tol * scale


def _relres(K, x, b) -> float:
    nb = np.linalg.norm(b)
    r = np.linalg.norm(b - K @ x)
    return float(r / nb) if nb > 0 else float(r)


def _split(K: sp.csr_matrix, n_u: int):
    n = K.shape[0]
    if not 0 < n_u < n:
        raise ValueError(f"n_u={n_u} must lie strictly between 0 and K.shape[0]={n}")
    A = K[:n_u, :n_u].tocsr()
    Bt = K[:n_u, n_u:].tocsr()
    B = K[n_u:, :n_u].tocsr()
    C = K[n_u:, n_u:].tocsr()
    return A, Bt, B, C


class _Counter:
    """Wrap a LinearOperator-like object and count applications."""

    def __init__(self, op):
        self.op = op
        self.count = 0

    def __call__(self, v):
        self.count += 1
        return self.op @ v


# ==========================================================================
# Direct solver
# ==========================================================================
def _pardiso_available() -> bool:
    try:
        import pypardiso  # noqa: F401
    except Exception:  # ImportError, or mkl_rt missing
        return False
    return True


def default_direct_backend() -> str:
    """The default direct backend: ``"superlu"``.

    PARDISO (optional ``pypardiso``) factorises faster at large sizes but is opt-in: with its
    default pivot perturbation it returned relative residuals of 3e-3 (33k DOFs) and 2e-2
    (85k DOFs) on P2-bubble/P1-discontinuous DFG systems, and each ``pypardiso`` solve call
    costs ~30 ms of overhead, which dominates Krylov iterations preconditioned by an LU.
    """
    return "superlu"


class DirectSolver:
    """Sparse LU factorisation of the whole saddle-point matrix.

    Parameters
    ----------
    backend : {"auto", "superlu", "pardiso"}
        ``"superlu"`` is :func:`scipy.sparse.linalg.splu`.  ``"pardiso"`` uses
        Intel MKL PARDISO through the optional ``pypardiso`` package (raises
        ``ImportError`` if it is missing); it was 4x faster than SuperLU at
        50k DOFs and 5-14x at 200k on one thread (see the benchmarks).
        ``"auto"``: :func:`default_direct_backend` (SuperLU; PARDISO is opt-in,
        see there why).  PARDISO runs on ``MKL_NUM_THREADS`` threads.
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
                 check_rtol: float = 1e-8, symmetric_mode: bool = False):
        if backend not in ("auto", "superlu", "pardiso"):
            raise ValueError(f"unknown direct backend {backend!r}; "
                             "use 'auto', 'superlu' or 'pardiso'")
        if backend == "auto":
            backend = default_direct_backend()
        if permc_spec == "MMD_AT_PLUS_A" and not symmetric_mode:
            raise ValueError("permc_spec='MMD_AT_PLUS_A' with pivoting does not finish on "
                             "saddle-point systems of practical size; use 'COLAMD' or "
                             "symmetric_mode=True")
        if backend == "pardiso" and not _pardiso_available():
            raise ImportError("backend='pardiso' needs the optional package pypardiso")
        self.backend = backend
        self.max_refinements = 3
        self.symmetric_mode = bool(symmetric_mode)
        self.permc_spec = "MMD_AT_PLUS_A" if self.symmetric_mode else permc_spec
        self.check_rtol = check_rtol
        self.K: sp.csr_matrix | None = None
        self.factorizations = 0
        self.last_info: SolveInfo | None = None
        self._lu = None
        self._setup_s = 0.0
        self._reused = False

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
        if self.backend == "superlu":
            try:
                if self.symmetric_mode:
                    self._lu = spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=1e-3,
                                         options={"SymmetricMode": True})
                else:
                    self._lu = spla.splu(K.tocsc(), permc_spec=self.permc_spec)
            except RuntimeError as err:  # "Factor is exactly singular"
                raise SolverError(
                    f"LU of the {K.shape[0]}x{K.shape[0]} system failed ({err}); with velocity "
                    "Dirichlet conditions on the whole boundary pin one pressure DOF") from err
        else:
            import pypardiso

            self._free()
            ps = pypardiso.PyPardisoSolver()  # mtype 11: real non-symmetric
            ps.set_statistical_info_off()
            try:
                ps.factorize(K)
            except pypardiso.pardiso_wrapper.PyPardisoError as err:
                raise SolverError(
                    f"PARDISO factorisation of the {K.shape[0]}x{K.shape[0]} system failed "
                    f"({err}); with velocity Dirichlet conditions on the whole boundary pin one "
                    "pressure DOF") from err
            self._lu = ps
        self.K = K
        self.factorizations += 1
        self._setup_s = time.perf_counter() - t0
        self._reused = False
        return self

    def _free(self):
        """Release PARDISO's memory for the previous factorisation."""
        if self.backend == "pardiso" and self._lu is not None:
            self._lu.free_memory()
            self._lu = None

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
        if self.backend == "superlu":
            return self._lu.solve(b)
        return self._lu.solve(self.K, b)

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
            of iterative refinement (near-singular ``K``).
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
        while not res[-1] <= self.check_rtol and len(res) <= self.max_refinements:
            x_new = x + self._apply(b - self.K @ x)
            r_new = _relres(self.K, x_new, b)
            if not r_new < 0.5 * res[-1]:
                break
            x = x_new
            res.append(r_new)
            note = f"{len(res) - 1} refinement step(s)"
        info = SolveInfo(
            method=self.backend, n=self.n, iterations=0, residuals=np.array(res),
            relative_residual=res[-1], setup_s=self._setup_s,
            solve_s=time.perf_counter() - t0, reused_setup=self._reused,
            factorizations=self.factorizations, note=note)
        self.last_info = info
        if not res[-1] <= self.check_rtol:
            raise SolverError(
                f"direct solve residual {res[-1]:.2e} exceeds {self.check_rtol:.1e}: the matrix "
                "is (near) singular; with velocity Dirichlet conditions on the whole boundary "
                "pin one pressure DOF", info)
        return x

    def as_preconditioner(self) -> spla.LinearOperator:
        """The stored LU as an operator ``v -> K_lu^{-1} v``, shape (n, n)."""
        if self._lu is None:
            raise RuntimeError("call factorize(K) first")
        n = self.n
        return spla.LinearOperator((n, n), matvec=self._apply, dtype=float)


# ==========================================================================
# Krylov driver
# ==========================================================================
def _krylov_start(K, b, M, x0):
    """Common start of the Krylov drivers: size, ‖b‖, initial iterate, counted preconditioner
    (as a LinearOperator) and the residual history with the initial relative residual."""
    n = K.shape[0]
    nb = np.linalg.norm(b) or 1.0
    x = np.zeros(n) if x0 is None else np.array(x0, dtype=float)
    Mc = _Counter(M)
    Mop = spla.LinearOperator((n, n), matvec=Mc, dtype=float)
    return n, nb, x, Mc, Mop, [np.linalg.norm(b - K @ x) / nb]


def _fgmres(K, b, M, x0, rtol, maxiter, restart, stagnation):
    """Restarted right-preconditioned flexible GMRES (Saad 1993).

    Runs pyamg's FGMRES one restart cycle at a time so that the true
    residual is checked after each cycle and a cycle that does not reduce it
    by at least the factor ``stagnation`` ends the solve.

    Returns ``(x, iterations, residual history, reason)`` where ``reason`` is
    ``""`` on convergence.
    """
    from pyamg.krylov import fgmres

    n, nb, x, Mc, Mop, history = _krylov_start(K, b, M, x0)
    if history[-1] <= rtol:
        return x, 0, np.array(history), ""
    restart = max(1, min(restart, n - 1))
    reason = f"no convergence within maxiter={maxiter} iterations"
    while Mc.count < maxiter:
        inner = min(restart, maxiter - Mc.count)
        start, count = history[-1], Mc.count
        res: list[float] = []
        x, _ = fgmres(K, b, x0=x, tol=rtol, restart=inner, maxiter=1, M=Mop, residuals=res)
        if Mc.count == count:  # FGMRES saw a converged start that our test did not
            reason = "stagnation: FGMRES made no iteration"
            history.append(np.linalg.norm(b - K @ x) / nb)
            break
        # tol in pyamg is relative to ||b||; res holds absolute norms
        r_true = np.linalg.norm(b - K @ x) / nb
        history.extend(np.asarray(res[1:-1]) / nb)
        history.append(r_true)
        if not np.isfinite(r_true):
            reason = "residual is not finite (NaN/inf from the preconditioner?)"
            break
        if r_true <= rtol:
            return x, Mc.count, np.array(history), ""
        if r_true > stagnation * start:
            reason = (f"stagnation: a restart cycle of {inner} iterations reduced the residual "
                      f"only from {start:.2e} to {r_true:.2e}")
            break
    return x, Mc.count, np.array(history), reason


def _minres(K, b, M, x0, rtol, maxiter, window, stagnation):
    """Preconditioned MINRES (scipy) stopped on the true residual.

    MINRES minimises the residual in the ``M`` norm, which for saddle-point
    systems can differ from the 2-norm by orders of magnitude, so the
    stopping test is done on the true 2-norm residual, computed in the
    callback (one extra product with ``K`` per iteration).  If scipy stops
    on its own test first, MINRES is restarted from the current iterate (at
    most three times).
    """
    n, nb, x, Mc, Mop, history = _krylov_start(K, b, M, x0)

    class _Stop(Exception):
        pass

    last = {"x": x}

    def cb(xk):
        last["x"] = xk.copy()
        history.append(np.linalg.norm(b - K @ xk) / nb)
        if history[-1] <= rtol:
            raise _Stop("")
        if not np.isfinite(history[-1]):
            raise _Stop("residual is not finite")
        if len(history) > window and history[-1] > stagnation * history[-1 - window]:
            raise _Stop(f"stagnation: {window} iterations reduced the residual only from "
                        f"{history[-1 - window]:.2e} to {history[-1]:.2e}")

    if history[-1] <= rtol:
        return x, 0, np.array(history), ""
    reason = f"no convergence within maxiter={maxiter} iterations"
    for _ in range(4):
        remaining = maxiter - Mc.count
        if remaining <= 0:
            break
        try:
            # ask for a little more than rtol: the built-in test is on the M-norm
            x, _ = spla.minres(K, b, x0=x, rtol=1e-3 * rtol, maxiter=remaining, M=Mop,
                               callback=cb)
        except _Stop as stop:
            x = last["x"]
            reason = str(stop)
            if not reason:
                return x, Mc.count, np.array(history), ""
            break
        r_true = np.linalg.norm(b - K @ x) / nb
        history.append(r_true)
        if r_true <= rtol:
            return x, Mc.count, np.array(history), ""
    return x, Mc.count, np.array(history), reason


# ==========================================================================
# Block preconditioned Krylov solver
# ==========================================================================
_SCHUR = ("auto", "mass", "cahouet-chabard", "lsc")


class BlockKrylovSolver:
    r"""Krylov solver with a block preconditioner for ``K = [[A, B^T], [B, -C]]``.

    GMRES (default) uses the block upper-triangular preconditioner
    ``P = [[A~, B^T], [0, -S~]]``, MINRES (symmetric ``A`` only) the
    block-diagonal ``P = diag(A~, S~)``.  ``A~^{-1}`` is ``velocity_cycles``
    cycles of pyamg smoothed aggregation (Vanek, Mandel & Brezina 1996) on
    ``A``; the Schur complement approximation ``S~`` is chosen by ``schur``
    (Elman, Silvester & Wathen 2014; Cahouet & Chabard 1988).

    Parameters
    ----------
    n_u : int
        Number of velocity DOFs; ``K[:n_u, :n_u]`` is the velocity block.
    schur : {"auto", "mass", "cahouet-chabard", "lsc"}
        ``"mass"``: ``S~^{-1} = nu M_p^{-1}`` (steady Stokes, mildly
        convective Oseen).  ``"cahouet-chabard"``: ``S~^{-1} = nu M_p^{-1} +
        (alpha/dt) L_p^{-1}``, ``L_p = B D_u^{-1} B^T`` (unsteady, any
        ``dt``; needs ``dt``).  ``"lsc"``: least-squares commutator
        (convection-dominated Oseen).  ``"auto"``: ``"cahouet-chabard"`` if
        ``dt`` is given, else ``"mass"``.
    pressure_mass : (n_p, n_p) sparse matrix, optional
        Pressure mass matrix ``M_p`` (after the same condensation as ``K``).
        Required for ``"mass"`` and ``"cahouet-chabard"``.  It is inverted by
        a sparse LU (block diagonal for discontinuous pressure, so exact and
        cheap) or by its diagonal, see ``mass_solve``.
    nu : float
        Kinematic viscosity (the coefficient of the viscous term in ``A``),
        m^2/s or non-dimensional.
    dt : float, optional
        Time step, s.  ``A`` is taken to contain ``(alpha/dt) M_u``.
    alpha : float
        Coefficient of the mass term: 1 for backward Euler, 3/2 for BDF2;
        multiply by the density if ``A`` is not divided by it.
    velocity_mass : (n_u, n_u) sparse matrix, optional
        Velocity mass matrix ``M_u``; its diagonal is ``D_u`` in ``L_p`` (for
        ``"cahouet-chabard"`` and ``"lsc"``).  Without it ``D_u = diag(A)``
        is used and, for ``"cahouet-chabard"``, the factor ``alpha/dt`` is
        dropped (``diag(A)`` already carries it).
    krylov : {"gmres", "minres"}
        Outer Krylov method.  MINRES needs a symmetric ``K``.
    rtol : float
        Required true relative residual ``||b - K x||_2 / ||b||_2``.
    maxiter : int
        Maximum number of Krylov iterations (preconditioner applications).
    restart : int
        GMRES restart length.
    stagnation : float
        A GMRES restart cycle (MINRES: a window of ``restart`` iterations)
        must reduce the residual below ``stagnation`` times its value at the
        start, otherwise :class:`SolverError` is raised.
    reuse : {"values", "always", "never"}
        When ``factorize`` is called again: ``"values"`` keeps the AMG
        hierarchies if the blocks they were built on are unchanged (same
        pattern and values); ``"always"`` keeps them while the block shapes
        are unchanged, e.g. over time steps on a moving mesh between
        re-triangulations (a lagged preconditioner: the Krylov method still
        enforces ``rtol``, only the iteration count may grow); ``"never"``
        rebuilds them.  ``factorize(K, rebuild=True)`` forces a rebuild.
        Shapes are compared rather than sparsity patterns because assembly
        may drop entries that cancel to zero.
    mass_solve : {"exact", "diag"}
        How ``M_p^{-1}`` is applied: sparse LU, or the inverse diagonal
        (spectrally equivalent for P1, Wathen 1987).
    velocity_cycles : int
        AMG cycles per application of ``A~^{-1}``.
    cycle : {"V", "W", "F"}
        AMG cycle type.
    near_nullspace : (n_u, k) ndarray, optional
        Near-null-space vectors for smoothed aggregation on ``A`` (pyamg's
        ``B``); default the constant vector.
    amg_options : dict, optional
        Extra keyword arguments for :func:`pyamg.smoothed_aggregation_solver`.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> n_u, n_p = 40, 10
    >>> A = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n_u, n_u))
    >>> B = sp.random(n_p, n_u, density=0.3, random_state=0) + sp.eye(n_p, n_u)
    >>> K = sp.bmat([[A, B.T], [B, None]]).tocsr()
    >>> s = BlockKrylovSolver(n_u, schur="lsc", rtol=1e-10).factorize(K)
    >>> b = np.ones(n_u + n_p)
    >>> x = s.solve(b)
    >>> bool(np.linalg.norm(b - K @ x) <= 1e-10 * np.linalg.norm(b))
    True
    """

    def __init__(self, n_u: int, schur: str = "auto", pressure_mass=None, nu: float = 1.0,
                 dt: float | None = None, alpha: float = 1.0, velocity_mass=None,
                 krylov: str = "gmres", rtol: float = 1e-10, maxiter: int = 1000,
                 restart: int = 100, stagnation: float = 0.999, reuse: str = "values",
                 mass_solve: str = "exact", velocity_cycles: int = 2, cycle: str = "V",
                 near_nullspace=None, amg_options=None):
        if schur not in _SCHUR:
            raise ValueError(f"unknown schur={schur!r}; choose from {_SCHUR}")
        if schur == "auto":
            schur = "cahouet-chabard" if dt is not None else "mass"
        if schur == "cahouet-chabard" and dt is None:
            raise ValueError("schur='cahouet-chabard' needs the time step dt")
        if schur in ("mass", "cahouet-chabard") and pressure_mass is None:
            raise ValueError(f"schur={schur!r} needs pressure_mass (the pressure mass matrix)")
        if krylov not in ("gmres", "minres"):
            raise ValueError(f"unknown krylov={krylov!r}; use 'gmres' or 'minres'")
        if reuse not in ("values", "always", "never"):
            raise ValueError(f"unknown reuse={reuse!r}; use 'values', 'always' or 'never'")
        if mass_solve not in ("exact", "diag"):
            raise ValueError(f"unknown mass_solve={mass_solve!r}; use 'exact' or 'diag'")
        if nu <= 0:
            raise ValueError(f"nu must be positive, got {nu}")
        if dt is not None and dt <= 0:
            raise ValueError(f"dt must be positive, got {dt}")
        self.n_u = int(n_u)
        self.schur = schur
        self.nu = float(nu)
        self.dt = dt
        self.alpha = float(alpha)
        self.krylov = krylov
        self.rtol = float(rtol)
        self.maxiter = int(maxiter)
        self.restart = int(restart)
        self.stagnation = float(stagnation)
        self.reuse = reuse
        self.mass_solve = mass_solve
        self.near_nullspace = near_nullspace
        self.velocity_cycles = int(velocity_cycles)
        self.cycle = cycle
        self.amg_options = dict(amg_options or {})
        self.pressure_mass = None if pressure_mass is None else sp.csr_matrix(pressure_mass)
        self.velocity_mass = None if velocity_mass is None else sp.csr_matrix(velocity_mass)
        self.K: sp.csr_matrix | None = None
        self.last_info: SolveInfo | None = None
        self._A = None
        self._B = None
        self._ml_A = None
        self._ml_L = None
        self._Mp_inv = None
        self._P = None
        self._setup_s = 0.0
        self._reused = False
        self._Du_inv = None
        self._dkey = None

    # ---------------------------------------------------------------- setup
    def _amg(self, M, B=None, symmetric=True):
        import pyamg

        opts = dict(max_coarse=500)
        if not symmetric:
            opts.update(symmetry="nonsymmetric",
                        presmoother=("gauss_seidel", {"sweep": "forward"}),
                        postsmoother=("gauss_seidel", {"sweep": "backward"}))
        opts.update(self.amg_options)
        return pyamg.smoothed_aggregation_solver(M, B=B, **opts)

    def _keep(self, old, new) -> bool:
        if self.reuse == "never":
            return False
        if self.reuse == "always":
            return old is not None and old.shape == new.shape
        return _same_values(old, new)

    def _mass_inverse(self, n_p: int):
        Mp = self.pressure_mass
        if Mp.shape != (n_p, n_p):
            raise ValueError(f"pressure_mass has shape {Mp.shape}, expected ({n_p}, {n_p})")
        if self.mass_solve == "diag":
            d = 1.0 / Mp.diagonal()
            return lambda v: d * v
        lu = spla.splu(Mp.tocsc())
        return lu.solve

    def factorize(self, K, rebuild: bool = False) -> "BlockKrylovSolver":
        """Set up the block preconditioner for ``K``.

        Parameters
        ----------
        K : (n_u + n_p, n_u + n_p) sparse matrix
            Saddle-point matrix, velocity DOFs first.
        rebuild : bool
            Rebuild the AMG hierarchies even if ``reuse`` would keep them.

        Returns
        -------
        self : BlockKrylovSolver
        """
        K = _as_csr(K)
        t0 = time.perf_counter()
        A, Bt, B, C = _split(K, self.n_u)
        if self.krylov == "minres" and not _is_symmetric(K):
            raise ValueError("krylov='minres' needs a symmetric K; use krylov='gmres'")
        reused = []
        if self._ml_A is not None and not rebuild and self._keep(self._A, A):
            reused.append("A")
        else:
            self._ml_A = self._amg(A, self.near_nullspace, symmetric=_is_symmetric(A))
            self._A = A
        if self._Mp_inv is None and self.schur in ("mass", "cahouet-chabard"):
            self._Mp_inv = self._mass_inverse(K.shape[0] - self.n_u)
        if self.schur in ("cahouet-chabard", "lsc"):
            src = self.velocity_mass if self.velocity_mass is not None else A
            if src.shape != A.shape:
                raise ValueError(f"velocity_mass has shape {src.shape}, expected {A.shape}")
            dkey = sp.csr_matrix(src.diagonal()[None, :]) if self.velocity_mass is None else None
            keep_L = (self._ml_L is not None and not rebuild and self._keep(self._B, B)
                      and (self.velocity_mass is not None or self._keep(self._dkey, dkey)))
            if keep_L:
                reused.append("L_p")
            else:
                self._Du_inv = 1.0 / src.diagonal()
                Lp = (B @ sp.diags(self._Du_inv) @ B.T).tocsr()  # SPD (semi-definite)
                self._ml_L = self._amg(Lp, symmetric=True)
                self._B = B
                self._dkey = dkey
        self.K = K
        self._blocks = (A, Bt, B, C)
        self._P = self._build_preconditioner()
        self._setup_s = time.perf_counter() - t0
        self._reused = bool(reused)
        return self

    def _velocity_inverse(self):
        """The map ``r_u -> A~^{-1} r_u``: ``velocity_cycles`` AMG cycles from zero."""
        ml, k, cycle = self._ml_A, self.velocity_cycles, self.cycle
        if k == 1:
            return ml.aspreconditioner(cycle=cycle)
        n_u = self.n_u

        def apply(r):
            return ml.solve(np.ravel(r), x0=np.zeros(n_u), tol=1e-300, maxiter=k,
                            cycle=cycle, accel=None)

        return spla.LinearOperator((n_u, n_u), matvec=apply, dtype=float)

    def _schur_inverse(self):
        """The map ``r_p -> S~^{-1} r_p``."""
        A, _, B, _ = self._blocks
        nu = self.nu
        if self.schur == "mass":
            Mp_inv = self._Mp_inv
            return lambda r: nu * Mp_inv(r)
        Lsolve = self._ml_L.aspreconditioner(cycle="V")
        if self.schur == "cahouet-chabard":
            Mp_inv = self._Mp_inv
            c = self.alpha / self.dt if self.velocity_mass is not None else 1.0
            return lambda r: nu * Mp_inv(r) + c * (Lsolve @ r)
        # least-squares commutator (Elman et al. 2006), Q = D_u
        Dinv = self._Du_inv

        Btr = B.T.tocsr()

        def lsc(r):
            y = Lsolve @ r
            y = B @ (Dinv * (A @ (Dinv * (Btr @ y))))
            return Lsolve @ y

        return lsc

    def _build_preconditioner(self) -> spla.LinearOperator:
        n_u = self.n_u
        n = self.K.shape[0]
        _, Bt, _, _ = self._blocks
        Ainv = self._velocity_inverse()
        Sinv = self._schur_inverse()
        if self.krylov == "minres":
            def apply(r):
                r = np.ravel(r)
                return np.concatenate([Ainv @ r[:n_u], Sinv(r[n_u:])])
        else:
            def apply(r):
                # [[A, Bt], [0, -S]]^{-1} [f; g]: p = -S^{-1} g, u = A^{-1}(f - Bt p)
                r = np.ravel(r)
                p = -Sinv(r[n_u:])
                u = Ainv @ (r[:n_u] - Bt @ p)
                return np.concatenate([u, p])
        return spla.LinearOperator((n, n), matvec=apply, dtype=float)

    # ---------------------------------------------------------------- solve
    @property
    def method(self) -> str:
        kind = "diag" if self.krylov == "minres" else "tri"
        return f"{self.krylov}+{kind}(amg, {self.schur})"

    def solve(self, b: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Solve ``K x = b`` to the relative residual ``rtol``.

        Parameters
        ----------
        b : (n_u + n_p,) float ndarray
        x0 : (n_u + n_p,) float ndarray, optional
            Initial guess (e.g. the previous time step).

        Returns
        -------
        x : (n_u + n_p,) float ndarray

        Raises
        ------
        SolverError
            If the residual does not reach ``rtol`` within ``maxiter``
            iterations or stagnates; ``err.info`` holds the history.
        """
        if self._P is None:
            raise RuntimeError("call factorize(K) before solve(b)")
        b = np.asarray(b, dtype=float)
        if b.shape != (self.K.shape[0],):
            raise ValueError(f"b must have shape ({self.K.shape[0]},), got {b.shape}")
        t0 = time.perf_counter()
        if self.krylov == "gmres":
            x, it, hist, reason = _fgmres(self.K, b, self._P, x0, self.rtol, self.maxiter,
                                          self.restart, self.stagnation)
        else:
            x, it, hist, reason = _minres(self.K, b, self._P, x0, self.rtol, self.maxiter,
                                          self.restart, self.stagnation)
        info = SolveInfo(method=self.method, n=self.K.shape[0], iterations=it, residuals=hist,
                         relative_residual=float(hist[-1]), setup_s=self._setup_s,
                         solve_s=time.perf_counter() - t0, reused_setup=self._reused)
        self.last_info = info
        if reason:
            raise SolverError(f"{self.method} did not reach rtol={self.rtol:.1e}: {reason}", info)
        return x

    def as_preconditioner(self) -> spla.LinearOperator:
        """The block preconditioner ``P^{-1}`` as a LinearOperator, shape (n, n)."""
        if self._P is None:
            raise RuntimeError("call factorize(K) first")
        return self._P


# ==========================================================================
# Lagged LU
# ==========================================================================
class LaggedLUSolver:
    """GMRES preconditioned by the LU of an earlier matrix; refactorise on demand.

    ``factorize(K)`` stores ``K`` but computes a new LU only when there is
    none yet, when the shape changed (re-triangulation), when the last solve
    needed more than ``max_iterations_before_refactor`` iterations, or when
    ``force=True``.  ``solve`` then runs GMRES on the current ``K`` with the
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
                 maxiter: int = 50, direct: DirectSolver | None = None):
        self.max_iterations_before_refactor = int(max_iterations_before_refactor)
        self.rtol = float(rtol)
        self.maxiter = int(maxiter)
        self.direct = direct if direct is not None else DirectSolver()
        self.K: sp.csr_matrix | None = None
        self.factorizations = 0
        self.solves = 0
        self.total_iterations = 0
        self.last_info: SolveInfo | None = None
        self._refactor_next = False
        self._fresh = False
        self._setup_s = 0.0

    def _factorize_current(self):
        t0 = time.perf_counter()
        self.direct.factorize(self.K)
        self.factorizations += 1
        self._fresh = True
        self._refactor_next = False
        self._setup_s = time.perf_counter() - t0

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

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``K x = b`` for the current ``K``.

        Parameters
        ----------
        b : (n,) float ndarray

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
        if self._fresh:
            x = self.direct.solve(b)
            it, hist = 0, self.direct.last_info.residuals
        else:
            x, it, hist, reason = _fgmres(self.K, b, self.direct.as_preconditioner(), None,
                                          self.rtol, self.maxiter, self.maxiter, 0.999)
            self.total_iterations += it
            if reason:
                note = f"GMRES with the lagged LU failed ({reason}); refactorized"
                self._factorize_current()
                x = self.direct.solve(b)
                hist = np.concatenate([hist, self.direct.last_info.residuals])
            elif it > self.max_iterations_before_refactor:
                self._refactor_next = True
                note = "refactorization due at the next factorize"
        info = SolveInfo(method="gmres+lagged-lu" if it else self.direct.backend,
                         n=self.K.shape[0], iterations=it, residuals=np.asarray(hist),
                         relative_residual=float(hist[-1]), setup_s=self._setup_s,
                         solve_s=time.perf_counter() - t0, reused_setup=not self._fresh,
                         factorizations=self.factorizations, note=note)
        self.last_info = info
        if not info.relative_residual <= max(self.rtol, self.direct.check_rtol):
            raise SolverError(f"lagged-LU solve ended at residual {info.relative_residual:.2e}",
                              info)
        return x

    def as_preconditioner(self) -> spla.LinearOperator:
        """The stored (possibly lagged) LU as a LinearOperator, shape (n, n)."""
        return self.direct.as_preconditioner()


# ==========================================================================
# Automatic choice and registry
# ==========================================================================
def choose_method(n_dofs: int, convective: bool = False, dt: float | None = None,
                  backend: str | None = None) -> tuple[str, str]:
    """Choose ``"direct"`` or ``"iterative"`` from the measured crossover.

    Parameters
    ----------
    n_dofs : int
        System size ``n_u + n_p``.
    convective : bool
        Whether the velocity block is non-symmetric (Oseen, Newton).
    dt : float, optional
        Time step, s; ``None`` for steady problems.
    backend : {"superlu", "pardiso"}, optional
        Direct backend the choice is for; default :func:`default_direct_backend`.

    Returns
    -------
    method : str
        ``"direct"`` or ``"iterative"``.
    reason : str
        One line saying why.

    Notes
    -----
    Steady Stokes systems switch to the iterative path at
    ``DIRECT_MAX_DOFS[backend]``, unsteady ones (Cahouet--Chabard
    preconditioner) at ``DIRECT_MAX_DOFS_UNSTEADY[backend]``, steady
    convective ones at ``DIRECT_MAX_DOFS_CONVECTIVE[backend]``.  All are
    module-level dicts and can be changed at run time.  Timings behind them:
    ``benchmarks/bench_solvers.py``.

    Examples
    --------
    >>> choose_method(5_000)[0]
    'direct'
    >>> choose_method(10**8)[0]
    'iterative'
    """
    backend = backend or default_direct_backend()
    if dt is not None:
        limit, kind = DIRECT_MAX_DOFS_UNSTEADY[backend], "unsteady"
    elif convective:
        limit, kind = DIRECT_MAX_DOFS_CONVECTIVE[backend], "steady convective"
    else:
        limit, kind = DIRECT_MAX_DOFS[backend], "Stokes"
    where = f"(measured {backend} LU / AMG-GMRES crossover)"
    if n_dofs < limit:
        return "direct", f"{kind}: {n_dofs} DOFs < {limit} {where}"
    return "iterative", f"{kind}: {n_dofs} DOFs >= {limit} {where}"


class AutoSolver:
    """Direct or block-iterative solver chosen at ``factorize`` by :func:`choose_method`.

    Parameters
    ----------
    n_u : int, optional
        Velocity DOFs; needed if the iterative path may be chosen.
    direct_options, iterative_options : dict, optional
        Keyword arguments for :class:`DirectSolver` and
        :class:`BlockKrylovSolver` (``pressure_mass``, ``nu``, ``dt`` ...).
    fallback : bool
        If the iterative path raises :class:`SolverError`, factorise ``K``
        and solve directly (noted in ``last_info.note``) instead of raising.

    Attributes
    ----------
    chosen : str
        ``"direct"`` or ``"iterative"`` after ``factorize``.
    reason : str
        Why.
    solver : DirectSolver or BlockKrylovSolver
        The solver in use.
    """

    def __init__(self, n_u: int | None = None, direct_options: dict | None = None,
                 iterative_options: dict | None = None, fallback: bool = True):
        self.n_u = n_u
        self.fallback = fallback
        self.K: sp.csr_matrix | None = None
        self.direct_options = dict(direct_options or {})
        self.iterative_options = dict(iterative_options or {})
        self.chosen: str | None = None
        self.reason = ""
        self.solver = None

    def factorize(self, K) -> "AutoSolver":
        """Choose a method for ``K`` (shape (n, n)) and set it up; returns self."""
        K = _as_csr(K)
        opts = self.iterative_options
        convective = True
        if self.n_u is not None:
            convective = not _is_symmetric(K[: self.n_u, : self.n_u])
        backend = self.direct_options.get("backend", "auto")
        backend = default_direct_backend() if backend == "auto" else backend
        method, reason = choose_method(K.shape[0], convective=convective, dt=opts.get("dt"),
                                       backend=backend)
        if method == "iterative" and (self.n_u is None or (
                opts.get("pressure_mass") is None and opts.get("schur") != "lsc")):
            method, reason = "direct", reason + "; but no n_u/pressure_mass given, so direct"
        if method != self.chosen or self.solver is None:
            self.solver = (DirectSolver(**self.direct_options) if method == "direct"
                           else BlockKrylovSolver(self.n_u, **opts))
            self.chosen = method
        self.reason = reason
        self.K = K
        if method == "direct":
            self.solver.refactorize_if_changed(K)
        else:
            self.solver.factorize(K)
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve with the chosen solver; ``b`` shape (n,), returns ``x`` shape (n,)."""
        try:
            return self.solver.solve(b)
        except SolverError as err:
            if not (self.fallback and self.chosen == "iterative"):
                raise
            first_line = str(err).splitlines()[0]
            self.solver = DirectSolver(**self.direct_options).factorize(self.K)
            self.chosen = "direct"
            self.reason += f"; iterative path failed ({first_line}), fell back to LU"
            x = self.solver.solve(b)
            self.solver.last_info.note = f"fallback after: {first_line}"
            return x

    @property
    def last_info(self) -> SolveInfo | None:
        """:class:`SolveInfo` of the last solve."""
        return None if self.solver is None else self.solver.last_info

    def as_preconditioner(self) -> spla.LinearOperator:
        """The chosen solver's preconditioner, shape (n, n)."""
        return self.solver.as_preconditioner()


#: Solvers by the names used in scene files and on the command line.
SOLVERS = {
    "auto": AutoSolver,
    "direct": DirectSolver,
    "iterative": BlockKrylovSolver,
    "lagged": LaggedLUSolver,
}

_DIRECT_KEYS = ("backend", "permc_spec", "check_rtol", "symmetric_mode")


def make_solver(method: str = "auto", **options):
    """Build a solver by name.

    Parameters
    ----------
    method : {"auto", "direct", "iterative", "lagged"}
        ``"auto"`` chooses direct or iterative at ``factorize`` by system
        size and time step (:func:`choose_method`).
    **options
        ``"direct"``: keywords of :class:`DirectSolver`.
        ``"iterative"``: keywords of :class:`BlockKrylovSolver` (``n_u`` is
        required).  ``"lagged"``: keywords of :class:`LaggedLUSolver`.
        ``"auto"``: ``n_u``, ``fallback``, the :class:`DirectSolver`
        keywords and the :class:`BlockKrylovSolver` keywords, sorted to the
        two.

    Returns
    -------
    solver
        An object with ``factorize(K)``, ``solve(b)``,
        ``as_preconditioner()`` and ``last_info``.

    Examples
    --------
    >>> make_solver("direct")  # doctest: +ELLIPSIS
    <...DirectSolver object at ...>
    >>> make_solver("cholesky")
    Traceback (most recent call last):
    ...
    ValueError: unknown solver 'cholesky'; choose from auto, direct, iterative, lagged
    """
    if method not in SOLVERS:
        raise ValueError(f"unknown solver {method!r}; choose from {', '.join(SOLVERS)}")
    if method == "auto":
        n_u = options.pop("n_u", None)
        fallback = options.pop("fallback", True)
        direct = {k: options.pop(k) for k in _DIRECT_KEYS if k in options}
        return AutoSolver(n_u=n_u, direct_options=direct, iterative_options=options,
                          fallback=fallback)
    if method == "iterative":
        if "n_u" not in options:
            raise ValueError("make_solver('iterative') needs n_u (number of velocity DOFs)")
        return BlockKrylovSolver(options.pop("n_u"), **options)
    return SOLVERS[method](**options)
