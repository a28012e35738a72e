"""The incompressible flow problem on one mesh: operators, boundary data, residuals.

:class:`FlowProblem` holds the constant operators of the (Navier–)Stokes equations in
kinematic form on a :class:`~fluidem.fluid.space.FlowSpace` — viscous ν A, mass M,
divergence B (forms in :mod:`fluidem.fluid.forms`) — the Dirichlet DOFs of the velocity
conditions, and the condensed free-DOF saddle-point structure
(:class:`~fluidem.fluid.assembly.CondensedSystem`).  :meth:`FlowProblem.update_geometry`
moves it to a mesh with the same connectivity and moved nodes (ALE): DOF numbering,
sparsity patterns, scatter maps, condensed structure and Dirichlet lists stay; the basis
values and the data arrays are refreshed.  :class:`FlowState` is one solution ``x = [u, p]``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from skfem import asm

from ..cost import CostSplit
from . import forms
from .assembly import CondensedSystem, DivergencePattern, VectorAssembler, affine_reference
from .solvers import DirectSolver
from .space import FlowSpace, RigidMotion, VelocityBC

#: SuperLU's pivoting threshold for P2-bubble/P1-discontinuous systems (:meth:`FlowProblem.direct_solver`).
P2B_PIVOT_THRESHOLD = 0.01

__all__ = ["FlowProblem", "FlowState"]


@dataclass
class FlowState:
    """A velocity/pressure solution: ``x = [u, p]`` with ``u`` (n_u,) and ``p`` (n_p,)."""

    x: np.ndarray
    n_u: int
    t: float = 0.0
    residual_history: list = field(default_factory=list)

    @property
    def u(self) -> np.ndarray:
        return self.x[: self.n_u]

    @property
    def p(self) -> np.ndarray:
        return self.x[self.n_u:]


class FlowProblem:
    """An incompressible flow problem on a fixed mesh.

    Parameters
    ----------
    space : FlowSpace
        Mesh and element pair.
    nu : float
        Kinematic viscosity, length²/time, > 0.
    bcs : sequence of VelocityBC
        Velocity conditions; boundaries not named get the do-nothing condition.
    rho : float
        Density, mass/length³ (2D: mass/length²); forces are ρ times the kinematic ones.
    body_force : (2,) float
        Body force per unit mass, length/time².
    moving : bool
        The mesh will move (ALE): assemble the constant forms by the same pattern refill as
        :meth:`update_geometry` (straight meshes only), so that a problem built on a mesh
        and one moved onto it agree bit for bit (restarts of moving-mesh runs).  Default:
        scikit-fem assembly.
    periodic : sequence of {"x", "y"}
        Periodic axes (``"x"``: sides ``left``/``right``, ``"y"``: ``bottom``/``top``; the mesh
        has matching nodes there, :mod:`fluidem.mesh.periodic`): their velocity DOFs (and
        continuous pressure DOFs) are identified (:mod:`fluidem.fluid.periodic`); periodic
        sides take no velocity condition and are no do-nothing boundary.  A body force (or
        the equivalent mean pressure gradient, ``body_force = −∇p̄ / ρ``) drives a periodic
        channel.
    viscous : {"laplacian", "stress"}
        Form of the viscous term (:mod:`fluidem.fluid.forms`): ``"laplacian"`` ν ∇u : ∇v
        (natural condition: do-nothing, ν ∂u/∂n − p n = 0; exact loads on fixed and
        translating bodies) or ``"stress"`` 2ν ε(u) : ε(v) (natural condition: traction-free;
        exact torques on rotating bodies too).
    pin_pockets : bool
        Give every closed fluid region its own pressure reference: one pinned pressure DOF per
        region whose boundary has no natural part, its pressure shifted to zero mean over the
        region afterwards (:mod:`fluidem.fluid.pockets`; fluid enclosed by touching bodies).
        False: one pin for the whole mesh when it has no natural boundary (a coupled system whose
        body velocities are unknowns, held by the pockets' pressures).  With one fluid region both
        are the same.

    Attributes
    ----------
    components : FluidComponents
        The fluid regions of the mesh, which are closed and which are enclosed pockets
        (:func:`fluidem.fluid.pockets.fluid_components`, once per triangulation).
    free : (n_free,) int
        The unknowns of the condensed system: free DOFs of ``[u, p]`` (with periodic sides
        only the representatives of identified DOFs).
    rep : (n_u + n_p,) int or None
        Representative of every DOF (periodic sides; ``None`` without).
    """

    def __init__(self, space: FlowSpace, nu: float, bcs: Sequence[VelocityBC] = (), rho: float = 1.0,
                 body_force=(0.0, 0.0), moving: bool = False, periodic=(), viscous: str = "laplacian",
                 pin_pockets: bool = True):
        if viscous not in ("laplacian", "stress"):
            raise ValueError(f"viscous must be 'laplacian' or 'stress', got {viscous!r}")
        self.viscous = viscous
        if not (np.isfinite(nu) and nu > 0):
            raise ValueError(f"viscosity nu must be a positive number, got {nu!r}")
        if not (np.isfinite(rho) and rho > 0):
            raise ValueError(f"density rho must be a positive number, got {rho!r}")
        self.space = space
        self.nu = float(nu)
        self.rho = float(rho)
        self.bcs = list(bcs)
        self.body_force = np.asarray(body_force, dtype=float)
        from ..mesh.periodic import SIDE_PAIRS, periodic_axes

        self.periodic = periodic_axes(periodic)
        periodic_sides = {s for a in self.periodic for s in SIDE_PAIRS[a]}
        for name in sorted(periodic_sides):
            space._check_boundary(name)
        named = set()
        for bc in self.bcs:
            for name in bc.names:
                space._check_boundary(name)
                if name in periodic_sides:
                    raise ValueError(f"boundary {name!r} is periodic: it takes no velocity condition")
                named.add(name)
            for c in bc.components:
                if c not in (0, 1):
                    raise ValueError(f"velocity components must be 0 or 1, got {bc.components!r}")
        self.natural_boundaries = [b for b in space.boundary_names if b not in named and b not in periodic_sides]
        self._dirichlet_dofs = self._collect_dirichlet_dofs()
        n = space.n_dofs
        # With no natural boundary the pressure is fixed only up to a constant: pin one DOF
        # (the pressure is shifted to zero mean afterwards).
        self.pressure_pinned = not self.natural_boundaries
        self.rep = None
        pin = space.n_u
        alone = None
        if self.periodic:
            from .periodic import periodic_pairs, representatives

            self.rep = representatives(n, periodic_pairs(space, self.periodic), self._dirichlet_dofs)
            # pin a pressure DOF identified with no other (off the periodic sides)
            alone = np.bincount(self.rep, minlength=n)[self.rep] == 1
            pin = space.n_u + int(np.argmax(alone[space.n_u:]))
        # fluid regions no fluid connects (pockets enclosed by touching bodies): one pin per closed one
        # (fluidem.fluid.pockets); with a single region the rule above is the same
        from .pockets import fluid_components

        self.pin_pockets = bool(pin_pockets)
        self.components = fluid_components(space, self._dirichlet_dofs, self.natural_boundaries, self.rep)
        self._pocket_pins = self.pin_pockets and self.components.n_components > 1
        fixed = self._dirichlet_dofs
        if self._pocket_pins:
            pins = space.n_u + self.components.pins(pin - space.n_u, None if alone is None else alone[space.n_u:])
            self.pressure_pinned = bool(len(pins))
            fixed = np.concatenate([fixed, pins])
        elif self.pressure_pinned:
            fixed = np.concatenate([fixed, [pin]])
        self.fixed = np.unique(fixed)
        mask = np.ones(n, dtype=bool)
        mask[self.fixed] = False
        if self.rep is not None:
            mask &= self.rep == np.arange(n)
        self.free = np.flatnonzero(mask)
        self._fold = None
        if self.rep is not None:
            pos = np.full(n, -1, dtype=np.int64)
            pos[self.free] = np.arange(len(self.free))
            fold = pos[self.rep]
            fold[self.fixed] = -1
            self._fold = fold
            self._fold_src = np.flatnonzero(fold >= 0)
            self._fold_dst = fold[self._fold_src]
        self.timings = CostSplit()  # seconds in assembly and solve, accumulated
        t0 = time.perf_counter()
        ub, pb = space.ub, space.pb
        self.assembler = VectorAssembler(ub)
        self._divergence = None  # B's scatter map, built for a moving mesh
        if moving:
            self._refill_forms()
        else:
            form = forms.viscous_stress if viscous == "stress" else forms.viscous
            self.A_data = self.assembler.pattern_data(self.nu * asm(form, ub))
            self.M_data = self.assembler.pattern_data(asm(forms.mass, ub))
            self.A = self.assembler.matrix(self.A_data)
            self.M = self.assembler.matrix(self.M_data)
            self.B = asm(forms.divergence, ub, pb).tocsr()
            self._f = self._body_force_vector()
        self._system = None  # the condensed structure, built when first asked for (:attr:`system`)
        self._bv_index = None
        self._index_boundary_values()
        self.timings.add("assembly", time.perf_counter() - t0)

    # -- moving mesh ---------------------------------------------------------------------
    def update_geometry(self, mesh, bcs: Sequence[VelocityBC] | None = None) -> None:
        """Move the problem to ``mesh``: the same connectivity with moved nodes (ALE).

        Keeps the DOF numbering, the sparsity patterns and scatter maps, the condensed
        free-DOF structure and the Dirichlet DOF lists; recomputes the basis values (the
        geometry map, :meth:`FlowSpace.moved`) and refills the data of ν A, M, B and the
        body-force vector.  Measured at 30k DOFs (Taylor–Hood, one thread): 20 ms, against
        90 ms for a new space and problem (``moving=True``) and 160 ms with scikit-fem assembly.

        Parameters
        ----------
        mesh : skfem.MeshTri
            Same triangles (``mesh.t``) as the current mesh, nodes moved.
        bcs : sequence of VelocityBC, optional
            New velocity conditions on the same boundaries and components (e.g. rigid
            motions about moved centres); the current ones by default.

        Raises
        ------
        ValueError
            If the connectivity differs (a re-triangulation needs a new FlowProblem) or
            ``bcs`` name other boundaries or components.
        """
        t0 = time.perf_counter()
        if bcs is not None:
            bcs = list(bcs)
            if [(b.names, tuple(b.components)) for b in bcs] != [(b.names, tuple(b.components)) for b in self.bcs]:
                raise ValueError("update_geometry: bcs must name the same boundaries and components as before")
            self.bcs = bcs
        self.space = self.space.moved(mesh)
        self.assembler.update_geometry(self.space.ub)
        self._refill_forms()
        if self._system is not None and not self._system.update_divergence(self.B):
            # B's structure changed (built by scikit-fem, which drops structural zeros): once
            self._system = self._condensed()
        self._index_boundary_values()
        self.timings.add("rebuild", time.perf_counter() - t0)

    @property
    def system(self):
        """The condensed saddle-point structure on the free DOFs (:class:`~.assembly.CondensedSystem`, or
        :class:`~.periodic.FoldedSystem` with periodic sides) whose data :meth:`condensed_matrix` refills;
        built at the first use.  A flow with free bodies solves the coupled system of
        :class:`fluidem.coupling.rigid_system.RigidBodySystem` instead and never asks for it: at 1 000
        settling polygons (1.57M DOFs) it took 2.6 s of every re-triangulation's set-up and held 962 MiB
        (the coupled system's structure and maps: 1 115 MiB)."""
        if self._system is None:
            self._system = self._condensed()
        return self._system

    def _condensed(self):
        """The condensed saddle-point structure (folded onto the periodic unknowns if any)."""
        if self._fold is None:
            return CondensedSystem(self.assembler, self.B, self.free)
        from .periodic import FoldedSystem

        return FoldedSystem(self.assembler, self.B, self._fold, len(self.free))

    # -- the condensed unknowns ----------------------------------------------------------
    def condensed_index(self) -> np.ndarray:
        """Row of every DOF of ``[u, p]`` in the condensed system (its representative's with
        periodic sides), −1 for fixed DOFs: ``(n_u + n_p,)`` int."""
        if self._fold is not None:
            return self._fold
        fold = np.full(self.space.n_dofs, -1, dtype=np.int64)
        fold[self.free] = np.arange(len(self.free))
        return fold

    def reduce(self, r: np.ndarray) -> np.ndarray:
        """A full residual ``(n_u + n_p,)`` on the condensed unknowns, ``(n_free,)``: ``Pᵀ r``
        restricted to the free DOFs (``r[free]`` without periodic sides)."""
        if self._fold is None:
            return r[self.free]
        return np.bincount(self._fold_dst, weights=r[self._fold_src], minlength=len(self.free))

    def expand(self, y: np.ndarray) -> np.ndarray:
        """A correction on the condensed unknowns ``(n_free,)`` on all DOFs: ``P y``, zero on fixed DOFs."""
        out = np.zeros(self.space.n_dofs)
        if self._fold is None:
            out[self.free] = y
        else:
            out[self._fold_src] = y[self._fold_dst]
        return out

    def make_periodic(self, x: np.ndarray) -> None:
        """Give every identified DOF of ``x`` its representative's value, in place (no-op without
        periodic sides)."""
        if self.rep is not None:
            keep = np.zeros(len(x), dtype=bool)
            keep[self.fixed] = True
            x[~keep] = x[self.rep[~keep]]

    def _refill_forms(self) -> None:
        """ν A, M, B and the body-force vector from the assembler's current basis values."""
        va, pb = self.assembler, self.space.pb
        self.A_data = self.nu * (va.stress_data() if self.viscous == "stress" else va.viscous_data())
        self.M_data = va.mass_data()
        self.A = va.matrix(self.A_data)
        self.M = va.matrix(self.M_data)
        if self._divergence is None:
            self._divergence = DivergencePattern(va, pb)
        self.B = self._divergence.matrix(pb)
        self._f = self._refilled_body_force()

    def _refilled_body_force(self) -> np.ndarray:
        """The body-force vector ∫ f · φ_i from the assembler's current basis values (n_u,)."""
        va = self.assembler
        if not np.any(self.body_force):
            return np.zeros(va.n)
        w = va.psi_dx.sum(axis=2)  # (nel, ns): ∫ ψ_s
        return sum(np.bincount(va.dofs_c[c].ravel(), weights=self.body_force[c] * w.ravel(), minlength=va.n)
                   for c in range(2))

    def set_body_force(self, body_force) -> None:
        """Change the body force per unit mass (2,), length/time², on the current mesh (e.g. a mean
        pressure gradient G found by a solve: ``body_force = −G/ρ``); the operators stay."""
        self.body_force = np.array(body_force, dtype=float).reshape(2)
        self._f = self._refilled_body_force() if self._divergence is not None else self._body_force_vector()

    # -- boundary data -------------------------------------------------------------------
    def _collect_dirichlet_dofs(self):
        parts = []
        for bc in self.bcs:
            for name in bc.names:
                for c in bc.components:
                    parts.append(self.space.velocity_dofs(name, c))
        return np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)

    def _index_boundary_values(self) -> None:
        """DOF -> condition index, built once per connectivity (later conditions win on shared DOFs).

        Conditions with a :class:`RigidMotion` of constant velocity go into one table
        (DOF, component, body) evaluated in one expression; the others (walls, inflow
        profiles, callables) keep one evaluation per condition.
        """
        if getattr(self, "_bv_index", None) is None:
            n_u = self.space.n_u
            winner = np.full(n_u, -1)
            per_bc = []
            for i, bc in enumerate(self.bcs):
                d = [self.space.velocity_dofs(name, c) for name in bc.names for c in bc.components]
                cmp = [np.full(len(self.space.velocity_dofs(name, c)), c) for name in bc.names for c in bc.components]
                d = np.concatenate(d) if d else np.zeros(0, np.int64)
                cmp = np.concatenate(cmp) if cmp else np.zeros(0, np.int64)
                winner[d] = i
                per_bc.append((d, cmp))
            rigid, other = [], []
            for i, (bc, (d, cmp)) in enumerate(zip(self.bcs, per_bc)):
                keep = winner[d] == i
                d, cmp = d[keep], cmp[keep]
                d, first = np.unique(d, return_index=True)  # a DOF on two names of one condition
                cmp = cmp[first]
                (rigid if _constant_rigid(bc.value) else other).append((i, d, cmp))
            body = np.concatenate([np.full(len(d), k) for k, (_, d, _) in enumerate(rigid)]) if rigid else \
                np.zeros(0, np.int64)
            self._bv_index = {
                "other": other, "rigid_bc": [i for i, _, _ in rigid],
                "rigid_dofs": np.concatenate([d for _, d, _ in rigid]) if rigid else np.zeros(0, np.int64),
                "rigid_comp": np.concatenate([c for _, _, c in rigid]) if rigid else np.zeros(0, np.int64),
                "rigid_body": body,
            }
        ix = self._bv_index
        ix["rigid_xy"] = self.space.dof_locations(ix["rigid_dofs"])
        ix["other_xy"] = [self.space.dof_locations(d) for _, d, _ in ix["other"]]

    def dirichlet_values(self, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(dofs, values) of all velocity conditions at time ``t`` (later ones win on corners).

        Rigid-body conditions are evaluated for all their DOFs in one vectorised expression,
        U_k + ω_k e_z × (x − X_k) through the DOF -> body index (built once per connectivity).
        """
        ix = self._bv_index
        x = np.zeros(self.space.n_u)
        for (i, d, cmp), xy in zip(ix["other"], ix["other_xy"]):
            x[d] = self.bcs[i].evaluate(xy, t)[cmp, np.arange(len(d))]
        if ix["rigid_bc"]:
            rm = [self.bcs[i].value for i in ix["rigid_bc"]]
            U = np.array([np.asarray(r.velocity, float) for r in rm]).reshape(-1, 2)
            om = np.array([float(r.omega) for r in rm])
            X = np.array([np.asarray(r.center, float) for r in rm]).reshape(-1, 2)
            k, xy = ix["rigid_body"], ix["rigid_xy"]
            x[ix["rigid_dofs"]] = np.where(ix["rigid_comp"] == 0, U[k, 0] - om[k] * (xy[1] - X[k, 1]),
                                           U[k, 1] + om[k] * (xy[0] - X[k, 0]))
        return self._dirichlet_dofs, x[self._dirichlet_dofs]

    def _body_force_vector(self):
        if not np.any(self.body_force):
            return np.zeros(self.space.n_u)
        f = self.body_force
        return asm(forms.body_force, self.space.ub, f=f[:, None, None] * np.ones((1,) + self.space.ub.dx.shape))

    # -- operators -----------------------------------------------------------------------
    def condensed_matrix(self, uu_data: np.ndarray) -> sp.csr_matrix:
        """Saddle-point matrix on the free DOFs for velocity-block data ``uu_data`` on the pattern."""
        return self.system.matrix(uu_data)

    def convection_data(self, b: np.ndarray) -> np.ndarray:
        """Pattern data of ((b · ∇) u) · v for convecting velocity coefficients ``b`` (n_u,)."""
        return self.assembler.convection(b)

    def newton_data(self, a: np.ndarray, b: np.ndarray | None = None) -> np.ndarray:
        """Pattern data of the convection Jacobian at ``a``: ((b·∇)δu + (δu·∇)a) · v, b = a by default."""
        return self.assembler.convection(a if b is None else b, a)

    def convection_matrix(self, b: np.ndarray) -> sp.csr_matrix:
        """Matrix of ((b · ∇) u) · v for the convecting velocity coefficients ``b`` (n_u,)."""
        return self.assembler.matrix(self.convection_data(b))

    def convection_vector(self, a: np.ndarray, b: np.ndarray | None = None,
                          b_values: np.ndarray | None = None) -> np.ndarray:
        """Vector ((b · ∇) a) · v (b = a when omitted; ``b_values``: b at the quadrature points,
        if already evaluated)."""
        return self.assembler.convection_vector(a, b, b_values)

    def steady_residual(self, x: np.ndarray, convection: bool = True) -> np.ndarray:
        """Residual of the (Navier–)Stokes equations at ``x`` on all DOFs, no conditions applied."""
        u, p = x[: self.space.n_u], x[self.space.n_u:]
        r = np.empty_like(x)
        r[: self.space.n_u] = self.A @ u + self.B.T @ p - self._f
        if convection:
            r[: self.space.n_u] += self.convection_vector(u)
        r[self.space.n_u:] = self.B @ u
        return r

    def normalise_pressure(self, x: np.ndarray) -> None:
        """Shift the pressure to zero mean when it is defined only up to a constant (and, with
        periodic sides, make the identified DOFs equal: :meth:`make_periodic`)."""
        self.make_periodic(x)
        if self._pocket_pins:
            self._normalise_closed_regions(x)
        elif self.pressure_pinned:
            one = np.ones(self.space.n_p)
            pm = self.space.pb
            area = pm.dx.sum()
            mean = (self._pressure_values(x[self.space.n_u:]) * pm.dx).sum() / area
            x[self.space.n_u:] -= mean * one

    def _pressure_values(self, p: np.ndarray) -> np.ndarray:
        """The pressure with coefficients ``p`` (n_p,) at the quadrature points, (n_elements, n_qp).

        ``pb.interpolate(p)`` without the gradients: on straight triangles from the reference
        values (the same in every element), the same sum in the same order, so the same numbers.
        """
        pm = self.space.pb
        ref = affine_reference(pm)
        if ref is None:
            return np.asarray(pm.interpolate(p))
        ed = pm.element_dofs
        out = 0.0 * (p[ed[0]][:, None] * ref[0][0])  # as scikit-fem's interpolate
        for i in range(pm.Nbfun):
            out += p[ed[i]][:, None] * ref[0][i]
        return out

    def _normalise_closed_regions(self, x: np.ndarray) -> None:
        """Shift the pressure of every closed region to zero mean over that region (open ones stay)."""
        fc = self.components
        pm = self.space.pb
        p = x[self.space.n_u:]
        area = pm.dx.sum(axis=1)
        integral = (self._pressure_values(p) * pm.dx).sum(axis=1)
        n = fc.n_components
        mean = np.bincount(fc.element_label, weights=integral, minlength=n) / \
            np.bincount(fc.element_label, weights=area, minlength=n)
        mean[~fc.closed] = 0.0
        x[self.space.n_u:] -= mean[fc.pressure_label]

    def check_pockets(self, t: float) -> None:
        """Raise :class:`~fluidem.fluid.pockets.PocketError` when the velocity conditions at ``t`` change the
        area of an enclosed pocket (:func:`~fluidem.fluid.pockets.pocket_area_rates`; above
        :data:`~fluidem.fluid.pockets.POCKET_RATE_TOL` of its boundary flux).  One sparse product; nothing
        to do without pockets or with ``pin_pockets = False`` (free bodies: their velocities are unknowns
        that the pocket's pressure holds)."""
        from .pockets import POCKET_RATE_TOL, PocketError, pocket_area_rates

        fc = self.components
        pk = fc.pockets
        if not self._pocket_pins or not len(pk):
            return
        rate, scale = pocket_area_rates(self, t, pk)
        bad = np.abs(rate) > POCKET_RATE_TOL * np.maximum(scale, 1e-300)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            c = int(pk[k])
            names = fc.boundaries[c]
            raise PocketError(
                f"the fluid pocket of area {fc.areas[c]:.4g} enclosed by {', '.join(map(repr, names))} would change "
                f"its area at dA/dt = {rate[k]:.4g} per unit time ({abs(rate[k]) / scale[k]:.2g} of its boundary "
                f"flux; allowed {POCKET_RATE_TOL:g}) at t = {t:.6g}: the prescribed motion of the bodies around it "
                "squeezes or stretches fluid that has no way out; move them so that the pocket keeps its area, "
                "or keep a gap wider than the mesh's contact gap (mesh min_gap) open to the rest of the fluid",
                c, float(fc.areas[c]), float(rate[k]), names)

    #: the run's :class:`~fluidem.fluid.solvers.ordering.OrderingChoice` (set by a flow that
    #: rebuilds its problems: the choice outlives a re-triangulation), or None
    ordering = None
    #: the LU backend of :meth:`direct_solver`: ``"auto"`` (PARDISO for large systems when
    #: ``pypardiso`` is installed, :func:`~fluidem.fluid.solvers.default_direct_backend`),
    #: ``"superlu"`` or ``"pardiso"`` (a flow sets the scene's ``fluid.lu_backend``)
    lu_backend = "auto"

    def direct_solver(self) -> DirectSolver:
        """The fastest reliable sparse LU for this element pair and size (:attr:`lu_backend`).

        PARDISO when :attr:`lu_backend` says so or, for ``"auto"``, from
        :data:`~fluidem.fluid.solvers.direct.PARDISO_MIN_DOFS` DOFs when it is installed.  With SuperLU:

        Continuous pressure (th, p3, mini): SuperLU with a symmetric minimum-degree ordering
        (2-3x faster than COLAMD, half the fill on DFG systems), or, with :attr:`ordering` set,
        that or COLAMD by the fill each gives (moving-mesh systems with bodies: up to 2x less
        fill and 4.7x faster with COLAMD; :mod:`fluidem.fluid.solvers.ordering`).
        Discontinuous pressure (p2b): COLAMD, as that ordering does not finish there, with
        threshold pivoting at 0.01 (half the fill and twice as fast as partial pivoting;
        :class:`DirectSolver`'s ``pivot_threshold``).
        """
        if self.space.pair.pressure_discontinuous:
            return DirectSolver(backend=self.lu_backend, pivot_threshold=P2B_PIVOT_THRESHOLD)
        return DirectSolver(backend=self.lu_backend, symmetric_mode=True, ordering=self.ordering)

    def initial_vector(self, t: float = 0.0) -> np.ndarray:
        x = np.zeros(self.space.n_dofs)
        d, v = self.dirichlet_values(t)
        x[d] = v
        self.make_periodic(x)
        return x


def _constant_rigid(value) -> bool:
    """A rigid motion with constant velocity and angular velocity (vectorised boundary values)."""
    return isinstance(value, RigidMotion) and not callable(value.velocity) and not callable(value.omega)
