"""Block-preconditioned GMRES for the coupled fluid–body system, the body velocities in the velocity block.

The coupled matrix of :class:`fluidem.coupling.rigid_system.RigidBodySystem` acts on
z = [u_F, p_F, V] (free velocity DOFs, free pressure DOFs, 3 velocities per free body).  Its
body rows are rows of the momentum equation — the fluid's momentum tested with a rigid mode,
plus the body's own mass — and its body columns are velocities (the rigid-mode prolongation).
Reordered as [u_F, V | p_F] it is again a saddle-point matrix

    [[A_FF, A_FV, B_Fᵀ],
     [A_VF, A_VV + M_b a0/(ρΔt), B_Vᵀ],
     [B_F,  B_V,  0   ]]

whose velocity block contains the bodies (Πᵀ A Π plus their mass: the added mass is inside
A_VV) and whose divergence rows see the rigid motions through B Π.  The fluid's block
preconditioner (:class:`fluidem.fluid.solvers.block.BlockKrylovSolver`: AMG on the velocity
block, a Cahouet–Chabard Schur approximation) is applied to it unchanged, with the
pressure-Laplacian L_p = B D⁻¹ Bᵀ built from the diagonal of the extended velocity block
(which carries the mass terms a0/Δt, so no separate mass matrix is needed).  The body rows are
few, so a body adds a few denser rows to the AMG hierarchy and no unknown kind of its own.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from ..fluid.solvers.block import BlockKrylovSolver

__all__ = ["BodyBlockKrylovSolver"]


class BodyBlockKrylovSolver:
    """GMRES with the fluid's block preconditioner on the coupled fluid–body matrix (module docstring).

    Parameters
    ----------
    flow : object
        Read at every change of size: ``flow.problem`` (its free DOFs ``problem.free``, the
        velocity count ``problem.space.n_u``, the pressure basis for the pressure mass matrix,
        ``problem.nu``) and ``flow.system`` (:class:`RigidBodySystem`, ``n_bodies``).
    dt : float
        Time step, time (for the Cahouet–Chabard Schur approximation).
    **options
        Keywords of :class:`~fluidem.fluid.solvers.block.BlockKrylovSolver` (``rtol``,
        ``maxiter``, ``restart``, ``velocity_cycles``, ``reuse``; default ``reuse="always"``,
        the hierarchies kept between re-triangulations as on the moving mesh).

    Attributes
    ----------
    inner : BlockKrylovSolver
        The solver of the reordered matrix.
    last_info : SolveInfo or None
        The inner solver's record of the last solve (iterations, residuals, seconds).
    """

    def __init__(self, flow, dt: float, **options):
        self.flow = flow
        self.dt = float(dt)
        self.options = {"reuse": "always", "rtol": 1e-10, **options}
        self.inner: BlockKrylovSolver | None = None
        self._perm = None
        self.K = None

    def _setup(self, n: int) -> None:
        """Ordering and inner solver for a coupled system of size ``n`` (after a re-triangulation)."""
        from ..fluid.solvers.factory import flow_solver_options

        pr, sysm = self.flow.problem, self.flow.system
        fo = flow_solver_options(pr)
        n_u, n_b = fo["n_u"], 3 * sysm.n_bodies
        n_p = n - n_u - n_b
        if n_p != fo["pressure_mass"].shape[0]:
            raise ValueError(f"BodyBlockKrylovSolver: a coupled system of size {n} does not match the problem "
                             f"({n_u} velocity, {fo['pressure_mass'].shape[0]} pressure, {n_b} body unknowns)")
        # [u_F, p_F, V] -> [u_F, V, p_F]
        self._perm = np.concatenate([np.arange(n_u), n_u + n_p + np.arange(n_b), n_u + np.arange(n_p)])
        self.inner = BlockKrylovSolver(n_u + n_b, schur="cahouet-chabard", pressure_mass=fo["pressure_mass"],
                                       nu=fo["nu"], dt=self.dt, alpha=1.5, velocity_mass=None, **self.options)

    def factorize(self, K, force: bool = False) -> "BodyBlockKrylovSolver":
        """Set up the preconditioner for the coupled matrix ``K`` (nz, nz); ``force`` rebuilds the AMG."""
        K = K.tocsr()
        if force or self._perm is None or len(self._perm) != K.shape[0]:  # force: a new problem (re-triangulation)
            self._setup(K.shape[0])
            force = True
        p = self._perm
        self.K = K
        self.inner.factorize(K[p][:, p], rebuild=force)
        return self

    def release(self) -> None:
        """Drop the preconditioner (AMG hierarchy, matrix copies) and the matrix before a re-triangulation
        builds the new problem; the next :meth:`factorize` sets up afresh (as it would with ``force``)."""
        self.inner = None
        self._perm = None
        self.K = None

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``K z = b`` to the relative residual ``rtol``; (nz,) -> (nz,)."""
        p = self._perm
        out = np.empty_like(np.asarray(b, float))
        out[p] = self.inner.solve(np.asarray(b, float)[p])
        return out

    def as_preconditioner(self) -> spla.LinearOperator:
        """One application of the block preconditioner in the coupled ordering, (nz, nz)."""
        p, P = self._perm, self.inner.as_preconditioner()

        def apply(r):
            out = np.empty(len(p))
            out[p] = P.matvec(np.ravel(r)[p])
            return out

        return spla.LinearOperator((len(p), len(p)), matvec=apply, dtype=float)

    @property
    def last_info(self):
        return None if self.inner is None else self.inner.last_info
