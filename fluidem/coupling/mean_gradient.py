"""Zero net volume flux through periodic sides: the mean pressure gradient as a Lagrange multiplier.

Periodic sedimentation (Batchelor 1972, J. Fluid Mech. 52, 245; Hasimoto 1959, J. Fluid Mech. 5,
317; Sangani & Acrivos 1982, Int. J. Multiphase Flow 8, 193): in a periodic cell the pressure is
p = G·x + p' with p' periodic, and the cell is the frame of zero volume flux,

    Q_d = ∫_Ω_f u_d dA + Σ_k A_k U_k,d = 0        (d along every periodic axis)

(for a divergence-free periodic field Q_d / L_d is the flux through every section across d, a
periodic side included).  The mean gradient G acts on everything in the cell: on the fluid as
the body force −G per unit volume (``fluid.body_force`` = −G/ρ) and on each body as −G A_k, the
force of the pressure G·x on the volume the body occupies.  It is the multiplier of the flux
constraint, so the Stokes mobility problem with it is the bordered system

    [K  −C] [δ]   [r]
    [Cᵀ  0] [g] = [b]

on the coupled unknowns z = z₀ − δ (fluid DOFs and body velocities,
:class:`~fluidem.coupling.rigid_system.RigidBodySystem`), with C_d = Tᵀ (M e_d) + A_k on the rows
U_k,d (the flux is C_dᵀ z plus the walls' part; its adjoint is the load of a unit force per unit
volume on fluid and bodies), g = −f_G the kinematic mean gradient (G = ρ g) and b the flux of z₀.

In a doubly periodic cell holding only free bodies the constant velocity fields e_x, e_y
(fluid and bodies translating together) are in K's null space, and the equations have a solution
only when the cell's net force is zero: eᵀ(r + C g) = 0 gives

    G |Ω| = Σ_k (ρ_s − ρ_f)_k A_k g_grav          (|Ω| = L_x L_y, fluid and bodies)

—the mean gradient carries the buoyant weight of the whole suspension (the "backflow"
pressure gradient of Batchelor 1972) — and the flux condition fixes the null-space component.  A
gradient applied to the fluid alone would have to be Σ W / |Ω_f| to balance the weight, and the
hydrodynamic drag on each body is then the whole weight W instead of (1 − φ) W: the bodies
settle 1/(1 − φ) too fast (φ = Σ A_k / |Ω|).

The same doubly periodic cell without the key still has the null space: its forces must balance
(a ``fluid.body_force`` carrying the weight on the fluid alone) and the velocities are given in
the frame of zero volume flux.

:class:`ZeroFluxSolver` wraps the solver of the mobility problem so that every
``factorize`` / ``solve`` pair (one per Newton iteration of the repulsion too) solves the
bordered system by the Schur complement: m back-substitutions per factorisation (m the number
of constrained axes) and one per solve, no dense row in the LU.  With a null space the matrix is
first made regular by pinning one nodal velocity DOF per component (row and column replaced by
the identity).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError

__all__ = ["ZeroFluxSolver", "flux_conditions", "flux_solver", "FLUX_BALANCE_TOLERANCE"]

#: relative net force (of the total weight) above which a doubly periodic cell without
#: ``fluid.zero_net_flux`` is refused: its Stokes flow has no solution
FLUX_BALANCE_TOLERANCE = 1e-8


class ZeroFluxSolver:
    """The solver of the Stokes mobility problem with zero net volume flux through periodic sides.

    Parameters
    ----------
    inner : solver
        Has ``factorize(K)`` and ``solve(b)`` (:class:`~fluidem.fluid.solvers.DirectSolver`,
        :class:`~fluidem.fluid.solvers.LaggedLUSolver`).
    flux : (nz, a) float
        Columns C_d: the volume flux along each constrained axis d is ``C_dᵀ z`` plus the part
        of the Dirichlet data.
    multiplier : bool
        The mean pressure gradient along the same axes is an unknown (``fluid.zero_net_flux``);
        otherwise it is not, and only the null space (if any) is fixed by the flux.
    null : (nz, k) float or None
        Null vectors of the matrix (the constant fields, fluid and bodies translating together;
        k = a = 2 in a doubly periodic cell of free bodies) or None.
    force_scale : float
        Scale of the loads (kinematic), for the balance check without a multiplier.

    Attributes
    ----------
    target : (a,) float
        b: set before each solve to the flux of the z₀ that the solve corrects (z = z₀ − δ).
    last_multiplier : (a,) float
        g of the last solve (kinematic mean gradient G/ρ along the axes), zeros without a multiplier.

    Examples
    --------
    K = diag(1, 2, 3) with the "flux" δ₁ + δ₂ + δ₃ held at zero: δ = K⁻¹(r + g C), g = −6/11.

    >>> import numpy as np, scipy.sparse as sp
    >>> from fluidem.fluid.solvers import DirectSolver
    >>> s = ZeroFluxSolver(DirectSolver(), np.ones((3, 1)), multiplier=True)
    >>> d = s.factorize(sp.diags([1.0, 2.0, 3.0]).tocsr()).solve(np.array([1.0, 0.0, 0.0]))
    >>> np.round(11 * d, 12).tolist(), round(11 * float(s.last_multiplier[0]), 12)
    ([5.0, -3.0, -2.0], -6.0)
    """

    def __init__(self, inner, flux: np.ndarray, multiplier: bool, null: np.ndarray | None = None,
                 force_scale: float = 1.0):
        self.inner = inner
        self.C = np.asarray(flux, float)
        self.multiplier = bool(multiplier)
        self.E = None if null is None else np.asarray(null, float)
        self.force_scale = float(force_scale)
        self.target = np.zeros(self.C.shape[1])
        self.last_multiplier = np.zeros(self.C.shape[1])
        self.pins = np.zeros(0, np.int64)
        if self.E is not None:
            if self.E.shape[1] != self.C.shape[1]:
                raise ValueError("ZeroFluxSolver: one flux condition per null vector")
            # one pinned DOF per null vector: its entry 1 there, the others' 0 (a nodal DOF of a component)
            pins = []
            for j in range(self.E.shape[1]):
                others = np.delete(self.E, j, axis=1)
                ok = (np.abs(self.E[:, j] - 1.0) < 1e-12) & (np.abs(others) < 1e-12).all(axis=1)
                if not ok.any():
                    raise ValueError("ZeroFluxSolver: no DOF to pin for a null vector")
                pins.append(int(np.argmax(ok)))  # the first: a fluid DOF (they come before the bodies')
            self.pins = np.array(pins, np.int64)
        self._Y = None

    def _pinned(self, K):
        """K with the pinned rows and columns replaced by the identity (regular; symmetric if K is)."""
        n = K.shape[0]
        keep = np.ones(n)
        keep[self.pins] = 0.0
        D = sp.diags(keep)
        return (D @ K @ D + sp.diags(1.0 - keep)).tocsr()

    def _solve_pinned(self, r):
        r = np.array(r, float, copy=True)
        r[self.pins] = 0.0
        return self.inner.solve(r)

    def factorize(self, K):
        """Factorise K (pinned if it has a null space) and solve for the flux columns."""
        self.inner.factorize(self._pinned(K) if len(self.pins) else K)
        self._Y = np.column_stack([self._solve_pinned(c) for c in self.C.T]) if self.multiplier else None
        return self

    def solve(self, r: np.ndarray) -> np.ndarray:
        """δ of the bordered system: K δ = r + C g (the multiplier's load), Cᵀ δ = ``target``."""
        C, E, b = self.C, self.E, self.target
        d = self._solve_pinned(r)
        g = np.zeros(C.shape[1])
        if E is not None:
            if self.multiplier:  # the net force of the cell vanishes: Eᵀ (r + C g) = 0
                g = np.linalg.solve(E.T @ C, -(E.T @ r))
                d = d + self._Y @ g
            else:
                net = np.abs(E.T @ r).max()
                if net > FLUX_BALANCE_TOLERANCE * self.force_scale:
                    raise SolverError(
                        f"a doubly periodic Stokes cell of free bodies has a net force of {net:.4g} (kinematic, "
                        f"{net / self.force_scale:.3g} of the loads) and so no steady flow; expected a "
                        "fluid.body_force that carries the bodies' buoyant weight, or fluid.zero_net_flux = true "
                        "(the mean pressure gradient on fluid and bodies)")
            d = d + E @ np.linalg.solve(C.T @ E, b - C.T @ d)
        elif self.multiplier:
            g = np.linalg.solve(C.T @ self._Y, b - C.T @ d)
            d = d + self._Y @ g
        self.last_multiplier = g
        return d


def flux_conditions(domain, bodies, fluid) -> tuple[tuple[int, ...], bool, bool]:
    """Which flux conditions a Stokes flow of free bodies needs: (axes, multiplier, null space).

    ``domain``, ``bodies`` and ``fluid`` are the :class:`~fluidem.scene.DomainSpec`, the list of
    :class:`~fluidem.scene.BodySpec` and the :class:`~fluidem.scene.FluidSpec` of the flow.
    ``axes``: the periodic axes (0: x, 1: y) whose volume flux is held at zero; ``multiplier``:
    the mean pressure gradient along them is solved for (``fluid.zero_net_flux``); ``null``:
    the cell is doubly periodic and holds free bodies only, so fluid and bodies translating
    together is a null mode of the mobility problem (fixed by the flux, with or without the key).
    """
    axes = tuple(a for a, (s0, _) in enumerate((("left", "right"), ("bottom", "top")))
                 if domain.side(s0).type == "periodic")
    null = len(axes) == 2 and all(b.motion == "free" for b in bodies)
    multiplier = bool(fluid.zero_net_flux)
    if not (null or multiplier):
        return (), False, False
    return axes, multiplier, null


def flux_solver(flow, inner, x: np.ndarray, z0: np.ndarray, axes, multiplier: bool, null: bool) -> ZeroFluxSolver:
    """The :class:`ZeroFluxSolver` of a :class:`~fluidem.coupling.free_flow.FreeBodyFlow`'s mobility
    problem on its current mesh: flux columns C_d = Tᵀ (M e_d) + A_k, null vectors (the constant
    fields e_d with every free body translating along d), and the flux of z₀ (with the data ``x``)
    as the target, so that z = z₀ − δ carries none."""
    sysm, pr, n_u = flow.system, flow.problem, flow.space.n_u
    e = flow._constant_fields(flow.space)  # (2, n_u)
    Me = pr.M @ e.T  # (n_u, 2): ∫ φ_i e_d, the load of a unit force per unit mass along d
    nf = len(flow.free)
    C, E = [], []
    for d in axes:
        v = np.zeros(pr.space.n_dofs)
        v[:n_u] = Me[:, d]
        c = sysm.restrict(v)
        c[sysm.n_fluid + 3 * np.arange(nf) + d] += flow.area
        C.append(c)
        if null:
            xe = np.zeros(pr.space.n_dofs)
            xe[:n_u] = e[d]
            V = np.zeros((nf, 3))
            V[:, d] = 1.0
            E.append(sysm.gather(xe, V))
    C = np.column_stack(C)
    scale = float(np.abs(flow._weight[:, :2]).sum()) / flow.rho
    scale += float(np.abs(pr.body_force).sum() * Me.sum())
    s = ZeroFluxSolver(inner, C, multiplier, np.column_stack(E) if null else None, max(scale, 1e-300))
    u = sysm.prolong(z0, x)[:n_u]
    V0 = sysm.split(z0)[1]
    s.target = np.array([Me[:, d] @ u + flow.area @ V0[:, d] for d in axes])
    return s
