r"""Block-preconditioned Krylov solver for ``K = [[A, B^T], [B, -C]]``: :class:`BlockKrylovSolver`.

GMRES with the block upper-triangular preconditioner ``[[A~, B^T], [0, -S~]]``, or MINRES
with the block-diagonal ``diag(A~, S~)`` (symmetric Stokes).  The velocity block is
approximated by ``velocity_cycles`` cycles of pyamg smoothed aggregation ([VMB96]_), the Schur
complement :math:`S = B A^{-1} B^T + C` by one of

- ``"mass"`` (:func:`mass_schur_inverse`): :math:`S^{-1} \approx \nu M_p^{-1}`
  (steady Stokes; [ESW14]_, Stokes solver chapter; [SW94]_),
- ``"cahouet-chabard"`` (:func:`cahouet_chabard_schur_inverse`):
  :math:`S^{-1} \approx \nu M_p^{-1} + (\alpha/\Delta t) L_p^{-1}` with
  :math:`L_p = B D_u^{-1} B^T` and :math:`D_u` the diagonal of the velocity mass matrix
  ([CC88]_; [ESW14]_, unsteady flow in the Navier--Stokes solver chapter); :math:`L_p^{-1}`
  is one AMG V-cycle,
- ``"lsc"`` (:func:`lsc_schur_inverse`): least-squares commutator :math:`S^{-1} \approx
  L_p^{-1} (B D_u^{-1} A D_u^{-1} B^T) L_p^{-1}` for convection-dominated Oseen systems
  ([ESW14]_, Navier--Stokes solver chapter; [EHSST06]_).

The names are those of kind ``"schur"`` in :mod:`fluidem.names`.

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
.. [VMB96] Vanek, P., Mandel, J., Brezina, M. (1996). Algebraic multigrid by
   smoothed aggregation for second and fourth order elliptic problems.
   *Computing* 56, 179--196.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ... import names
from ._sparse import _as_csr, _is_symmetric, _same_values, _split
from .krylov import run_fgmres, run_minres
from .results import SolveInfo, SolverError, _notify_solve
from .seeded import seeded

__all__ = ["BlockKrylovSolver", "mass_schur_inverse", "cahouet_chabard_schur_inverse",
           "lsc_schur_inverse"]


# --------------------------------------------------------------------------
# Schur-complement approximations: each returns the map r_p -> S~^{-1} r_p
# --------------------------------------------------------------------------
def mass_schur_inverse(Mp_inv, nu: float):
    r"""Pressure-mass approximation :math:`\tilde S^{-1} r = \nu M_p^{-1} r` ([ESW14]_, [SW94]_).

    Parameters
    ----------
    Mp_inv : callable
        ``r -> M_p^{-1} r`` for (n_p,) arrays.
    nu : float
        Kinematic viscosity (coefficient of the viscous term in ``A``).

    Returns
    -------
    callable
        ``r -> S~^{-1} r``, (n_p,) -> (n_p,).

    Examples
    --------
    >>> import numpy as np
    >>> mass_schur_inverse(lambda r: r / 2.0, 0.1)(np.ones(3))
    array([0.05, 0.05, 0.05])
    """
    return lambda r: nu * Mp_inv(r)


def cahouet_chabard_schur_inverse(Mp_inv, Lp_inv, nu: float, c: float):
    r"""Cahouet--Chabard approximation :math:`\tilde S^{-1} r = \nu M_p^{-1} r + c\, L_p^{-1} r`
    ([CC88]_), with :math:`c = \alpha/\Delta t` and :math:`L_p = B D_u^{-1} B^T`.

    Parameters
    ----------
    Mp_inv : callable
        ``r -> M_p^{-1} r`` for (n_p,) arrays.
    Lp_inv : (n_p, n_p) operator
        Approximate inverse of the pressure Laplacian ``L_p`` (``Lp_inv @ r``).
    nu : float
        Kinematic viscosity.
    c : float
        Coefficient of ``L_p^{-1}``: ``alpha / dt`` when ``D_u`` is the velocity mass
        diagonal, 1 when ``D_u = diag(A)`` (which already carries ``alpha / dt``).

    Returns
    -------
    callable
        ``r -> S~^{-1} r``, (n_p,) -> (n_p,).
    """
    return lambda r: nu * Mp_inv(r) + c * (Lp_inv @ r)


def lsc_schur_inverse(A, B, Du_inv, Lp_inv):
    r"""Least-squares commutator :math:`\tilde S^{-1} = L_p^{-1} (B D_u^{-1} A D_u^{-1} B^T)
    L_p^{-1}` with :math:`L_p = B D_u^{-1} B^T` ([EHSST06]_; [ESW14]_).

    Parameters
    ----------
    A : (n_u, n_u) sparse matrix
        Velocity block.
    B : (n_p, n_u) sparse matrix
        Divergence block.
    Du_inv : (n_u,) float ndarray
        Inverse of the diagonal ``D_u`` (velocity mass or ``diag(A)``).
    Lp_inv : (n_p, n_p) operator
        Approximate inverse of ``L_p``.

    Returns
    -------
    callable
        ``r -> S~^{-1} r``, (n_p,) -> (n_p,).
    """
    Btr = B.T.tocsr()

    def lsc(r):
        y = Lp_inv @ r
        y = B @ (Du_inv * (A @ (Du_inv * (Btr @ y))))
        return Lp_inv @ y

    return lsc


# ==========================================================================
#: Schur names accepted by BlockKrylovSolver: those of kind "schur" in fluidem.names.
_SCHUR = names.choices("schur")


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
        A name of kind ``"schur"`` in :mod:`fluidem.names` (``"auto"``: Cahouet–Chabard
        when ``dt`` is given, the mass approximation otherwise).
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
        schur = names.lookup("schur", schur, where="schur")
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
        with seeded():  # the Jacobi weights' spectral-radius estimates start from numpy.random
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
        """The map ``r_p -> S~^{-1} r_p`` of the configured approximation."""
        A, _, B, _ = self._blocks
        if self.schur == "mass":
            return mass_schur_inverse(self._Mp_inv, self.nu)
        Lsolve = self._ml_L.aspreconditioner(cycle="V")
        if self.schur == "cahouet-chabard":
            c = self.alpha / self.dt if self.velocity_mass is not None else 1.0
            return cahouet_chabard_schur_inverse(self._Mp_inv, Lsolve, self.nu, c)
        return lsc_schur_inverse(A, B, self._Du_inv, Lsolve)

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
            x, it, hist, reason = run_fgmres(self.K, b, self._P, x0, self.rtol, self.maxiter,
                                          self.restart, self.stagnation)
        else:
            x, it, hist, reason = run_minres(self.K, b, self._P, x0, self.rtol, self.maxiter,
                                          self.restart, self.stagnation)
        info = SolveInfo(method=self.method, n=self.K.shape[0], iterations=it, residuals=hist,
                         relative_residual=float(hist[-1]), setup_s=self._setup_s,
                         solve_s=time.perf_counter() - t0, reused_setup=self._reused)
        self.last_info = info
        _notify_solve(info)
        if reason:
            raise SolverError(f"{self.method} did not reach rtol={self.rtol:.1e}: {reason}", info)
        return x

    def as_preconditioner(self) -> spla.LinearOperator:
        """The block preconditioner ``P^{-1}`` as a LinearOperator, shape (n, n)."""
        if self._P is None:
            raise RuntimeError("call factorize(K) first")
        return self._P
