"""Free bodies in a fluid on the moving mesh: the bodies move with the flow they stir.

Per step (t → t + Δt), for the bodies with ``motion = "free"``:

1. **Predict** their poses at t + Δt from the BDF2 pose update with extrapolated velocities,
   X* = (4Xⁿ − Xⁿ⁻¹ + 2Δt V*)/3, V* = 2Vⁿ − Vⁿ⁻¹ (first step: X* = Xⁿ + Δt Vⁿ);
   prescribed bodies follow their paths.
2. **Move the mesh** there (dragging, re-triangulation when due) and the flow problem with it
   (:class:`fluidem.coupling.moving_flow.MovingMeshFlow`: ALE history, BDF2 mesh velocity).
3. **Solve fluid and bodies together** (:class:`fluidem.coupling.free_bodies.FreeBodyStepper`,
   Navier–Stokes: BDF2 Newton–Euler rows with the added mass implicit) or, for Stokes, the
   mobility problem (force and torque balance, no inertia) in the same bordered system.
4. **Correct** the poses with the new velocities, Xⁿ⁺¹ = (4Xⁿ − Xⁿ⁻¹ + 2Δt Vⁿ⁺¹)/3 (BDF2, the
   fluid's scheme; BDF1 on the first step).  The mesh outline stays at X*, which differs from
   Xⁿ⁺¹ by O(Δt³) per step; the next step moves it from there.  Stokes: the poses advance
   by Adams–Bashforth 2 from the mobilities at the current geometry.

``fluid.coupling = "explicit"`` (staggered, for comparison): the new body velocities come from
the hydrodynamic loads of the last step, m (a0 Vⁿ⁺¹ + a1 Vⁿ + a2 Vⁿ⁻¹)/Δt = F_hydⁿ + F_ext, the
poses from them by the BDF2 update, and the fluid step then sees the bodies as prescribed.  The
fluid's added mass m_a then acts with a one-step lag: the scheme amplifies by about −m_a/m per
step and blows up once the added mass exceeds the body mass (a disk: m_a ≈ ρ_f A, so
ρ_s/ρ_f ≲ 1; Causin, Gerbeau & Nobile 2005).

External loads on a free body: its buoyant weight (ρ_s − ρ_f) A g (the fluid carries no
gravity: its hydrostatic pressure is subtracted).

Contacts (a ``contact`` spec given: bodies that may meet):
:class:`fluidem.coupling.contacts.FluidContacts` sub-steps the DEM contact law and the
short-range repulsion over the step with the fluid's force held, and its mean load enters the
coupled solve of step 3 by fixed-point iteration (a few back-substitutions, only in steps
where outlines are within reach), or the staggered body update.  Stokes free bodies have no
inertia to sub-step: there the short-range repulsion enters the mobility problem itself, at the
poses of the end of the step, linearised (linearly implicit Euler, Newton iterations, one solve
each: :meth:`FreeBodyFlow._solve_with_repulsion`), so a body rests where the repulsion carries
its buoyant weight at any stiffness; no lubrication correction, DEM contact law or friction.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from ..cost import CostSplit
from ..mesh.contact_outline import wall_depths
from ..mesh.nodes import world
from ..mesh.triangulate import SIDE_NAMES
from .contacts import FluidContacts
from .free_bodies import FreeBodyStepper, carried_contact_load
from .mean_gradient import flux_conditions, flux_solver
from .moving_flow import MovingMeshFlow
from .rigid_system import RigidBodySystem

__all__ = ["Approach", "FreeBodyFlow"]


class Approach(NamedTuple):
    """Two outlines the prediction of a step put into each other, or an outline past a wall
    (:meth:`FreeBodyFlow.predicted_into_each_other`)."""

    first: str
    """A body's name."""
    second: str
    """The other body's name, or the wall's side (``"bottom"``, ``"right"``, ``"top"``, ``"left"``) if ``wall``."""
    gap: float
    """Their distance at the start of the step, length."""
    wall: bool = False


def _wall_gaps(mm, image_poses) -> np.ndarray:
    """Distances ``(n_images, 4)`` of the outlines of ``mm`` (a MovingMesh) at ``image_poses`` from the box
    sides bottom, right, top, left (negative: past the side; :func:`fluidem.mesh.contact_outline.wall_depths`)."""
    return wall_depths(world(mm._vcat, mm._vbody, image_poses), mm._vbody, mm.n_bodies, mm.box)


def _polygon_inertia(v: np.ndarray) -> tuple[float, float]:
    """Area and polar second moment about the centroid of a counter-clockwise polygon (k, 2)."""
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cr = x * yn - xn * y
    area = 0.5 * cr.sum()
    cx = ((x + xn) * cr).sum() / (6 * area)
    cy = ((y + yn) * cr).sum() / (6 * area)
    j0 = ((x * x + x * xn + xn * xn + y * y + y * yn + yn * yn) * cr).sum() / 12.0
    return float(area), float(j0 - area * (cx * cx + cy * cy))


class FreeBodyFlow(MovingMeshFlow):
    """The flow around free (and prescribed) bodies on the moving mesh, bodies moved by it.

    Parameters
    ----------
    bodies, outlines, domain, fluid, mesh, dt, sim
        As :class:`~fluidem.coupling.moving_flow.MovingMeshFlow` (``bodies`` may be free).
    gravity : (2,) float
        Acceleration of gravity, length/time² (the free bodies' buoyant weight).
    contact : fluidem.scene.ContactSpec or None
        The contacts between the bodies (:class:`~fluidem.coupling.contacts.FluidContacts`);
        None: none.

    Attributes
    ----------
    free : (n_free,) int
        Indices of the free bodies among ``bodies``.
    poses : (n_bodies, 3) float
        x, y, angle of every body at the current time (length units, rad).
    body_velocities : (n_bodies, 3) float
        U_x, U_y, ω of every body at the current time.
    mass, inertia : (n_free,) float
        Per unit depth: mass/length and mass·length (ρ_s A, ρ_s J about the centroid).
    """

    def __init__(self, bodies, outlines, *, domain, fluid, mesh, dt: float, gravity, contact, sim):
        B = bodies
        self.free = np.array([k for k, b in enumerate(B) if b.motion == "free"], dtype=np.int64)
        self.poses = np.array([[*b.position, b.angle] for b in B], float).reshape(-1, 3)
        self.body_velocities = np.array([[*b.velocity, b.omega] if b.motion != "fixed" else [0.0, 0.0, 0.0]
                                         for b in B], float).reshape(-1, 3)
        self._poses_prev = None
        self._V_prev = None
        self._lagged_mobility = None  # Stokes: the LU kept between steps (_mobility_solver)
        self._mesh_poses = self.poses.copy()  # where the mesh has the outlines
        super().__init__(bodies, outlines, domain=domain, fluid=fluid, mesh=mesh, dt=dt, sim=sim)
        rho_f = fluid.density
        geo = [_polygon_inertia(np.asarray(outlines[k])) for k in self.free]
        self.area = np.array([a for a, _ in geo])
        dens = np.array([B[k].density for k in self.free])
        self.mass = dens * self.area
        self.inertia = dens * np.array([j for _, j in geo])
        g = np.asarray(gravity, float)
        self._weight = np.zeros((len(self.free), 3))
        self._weight[:, :2] = ((dens - rho_f) * self.area)[:, None] * g[None, :]
        self.system = RigidBodySystem(self.problem, self.rigid, self.free)
        self.explicit = fluid.coupling == "explicit" and not self.stokes
        self.contacts = None
        self._contact_step = False  # Stokes: the last mobility solve had the repulsion in it
        #: fluid regions of the mesh the last contact load was found on (:func:`carried_contact_load`)
        self._load_regions = None
        #: Stokes with contacts: Newton iterations of the repulsion per step (relative tolerance
        #: on the force, of the repulsion's force scale, and most iterations); the last count and
        #: the repulsion (n_free, 3) at the end poses of the last step
        self.contact_tolerance = 1e-3
        self.contact_iterations = 8
        self.last_contact_iterations = 0
        self.contact_load = np.zeros((len(self.free), 3))
        if contact is not None and len(self.free):
            self.contacts = FluidContacts(B, self.free, list(outlines), self.path, domain=domain, fluid=fluid,
                                          contact=contact, gravity=gravity, h=mesh.h)
        #: Stokes in a periodic cell: the zero-flux conditions (:mod:`fluidem.coupling.mean_gradient`)
        #: and the mean pressure gradient G (2,) of the last solve, force/length³ (dynamic; zero
        #: without ``fluid.zero_net_flux``): on the fluid −G, on each free body −G A_k
        self._flux = flux_conditions(domain, B, fluid) if self.stokes else ((), False, False)
        self.mean_gradient = np.zeros(2)
        if self.stokes:
            self.coupled = None
            self._solve_mobility(0.0)
        else:
            self.coupled = FreeBodyStepper(self.stepper, self.system, self.mass, self.inertia, rho_f,
                                           velocities=self.body_velocities[self.free], solver=self._coupled_solver())

    #: how ``fluid.solver = "auto"`` solved the coupled system: DOFs, LU backend, path and why (run.json)
    solver_choice = None

    def _lu_fits(self) -> bool:
        """Whether the LU of ``fluid.lu_backend`` for the current system fits in memory
        (:func:`fluidem.fluid.solvers.memory.lu_fits`); records the choice in :attr:`solver_choice`."""
        from ..fluid.solvers.direct import default_direct_backend
        from ..fluid.solvers.memory import lu_fits

        n = int(self.dofs)
        backend = getattr(self.fluid, "lu_backend", "auto")
        backend = default_direct_backend(n) if backend == "auto" else backend
        fits, why = lu_fits(n, backend)
        self.solver_choice = {"dofs": n, "lu_backend": backend, "path": "lagged LU" if fits else "block GMRES",
                              "note": why}
        return fits

    def _coupled_solver(self):
        """The coupled system's solver, by ``fluid.solver``: the fluid's LU (fresh or
        lagged) for ``"direct"`` and ``"lagged"``; block-preconditioned GMRES with the bodies in the
        velocity block (:class:`~fluidem.coupling.body_krylov.BodyBlockKrylovSolver`) for
        ``"iterative"`` (less memory); the lagged LU for ``"auto"`` at every size, also above the
        fluid's :data:`~fluidem.fluid.solvers.choose.LAGGED_MAX_DOFS`: it took 0.027 s per step
        against 0.27 s for the block GMRES at 12.7k DOFs, and 4.7 s at 353k DOFs (100 disks,
        ``benchmarks/results/free_flow.md``) where the fluid's block GMRES took 11.7 s."""
        from ..fluid.solvers import AutoSolver, DirectSolver, LaggedLUSolver
        from ..fluid.solvers.lagged import MOVING_MESH_STEPPING
        from .body_krylov import BodyBlockKrylovSolver

        s = self.stepper.solver
        if isinstance(s, (DirectSolver, LaggedLUSolver)):
            return s
        dt = self.dt
        if self.fluid.solver == "iterative":
            return BodyBlockKrylovSolver(self, dt)
        if isinstance(s, AutoSolver):  # "auto": the lagged LU while it fits in memory
            if not self._lu_fits():
                return BodyBlockKrylovSolver(self, dt)
            return AutoSolver(direct_options=s.direct_options, iterative_options={"dt": dt},
                              lagged_options=s.lagged_options)
        return LaggedLUSolver(direct=self.problem.direct_solver(), **MOVING_MESH_STEPPING)

    # -- poses --------------------------------------------------------------------------------
    def _poses(self, t):
        """Poses of all bodies for the mesh at time ``t``: the paths of prescribed ones, the
        current mesh poses (prediction) of the free ones."""
        P = super()._poses(t)
        if len(self.free):
            P[self.free] = self._mesh_poses[self.free]
        return P

    def _prescribed(self, t):
        """Poses and velocities (n_bodies, 3) of the non-free bodies at ``t`` from their paths."""
        P = MovingMeshFlow._poses(self, t)
        V = np.array([[*p.velocity, p.omega] for p in self.path], float).reshape(-1, 3)
        return P, V

    # -- stepping -----------------------------------------------------------------------------
    def _bdf_pose(self, X, V, dt):
        """Poses at t + dt from the velocities there: BDF2, (4Xⁿ − Xⁿ⁻¹ + 2Δt V)/3 (BDF1 on the first step)."""
        return X + dt * V if self._poses_prev is None else (4 * X - self._poses_prev + 2 * dt * V) / 3

    def _predicted_poses(self, dt):
        """Poses (n_bodies, 3) the mesh moves to for the step to t + dt (step 1 of the module
        docstring): the free bodies' predictions, the paths of the others."""
        f = self.free
        X, V = self.poses[f], self.body_velocities[f]
        if self.stokes:  # Adams–Bashforth 2 with the mobilities of the current geometry
            ab2 = self._V_prev is not None and not self._contact_step  # Euler where the repulsion acted
            X_new = X + dt * (1.5 * V - 0.5 * self._V_prev if ab2 else V)
        else:
            V_star = V if self._V_prev is None else 2.0 * V - self._V_prev
            X_new = self._bdf_pose(X, V_star, dt)
        P, _ = self._prescribed(self.t + dt)
        P[f] = X_new
        return P

    def predicted_into_each_other(self, predicted) -> Approach | None:
        """Two bodies, or a body and a wall, apart now (by more than the mesh's ``min_gap``, less
        than ``h``) whose outlines overlap (or cross the wall) at the ``predicted`` poses
        (n_bodies, 3): the :class:`Approach` with the narrowest gap at the current poses, or None.

        The step then does not resolve their approach: the mesh follows the bodies into each
        other, re-triangulates an inverted mesh (an Eulerian step) and can kick them through
        each other (``docs/free-bodies.md``, "Where a kiss can still fail").

        >>> from fluidem.cases.dkt import uhlmann_dkt_scene
        >>> from fluidem.simulation import Simulation
        >>> fl = Simulation(uhlmann_dkt_scene(h=0.05, t_end=1e-3)).flow   # disks d = 0.25 cm, 0.25 cm apart
        >>> fl.predicted_into_each_other(fl.poses) is None
        True
        >>> fl.poses[1] = fl.poses[0] + [0.0, 0.25 + 0.03, 0.0]   # the trailing disk 0.03 cm above the leading
        >>> ahead = fl.poses.copy(); ahead[1, 1] -= 0.04           # predicted 0.01 cm into it
        >>> a = fl.predicted_into_each_other(ahead)
        >>> a.first, a.second, round(a.gap, 3), a.wall
        ('leading', 'trailing', 0.03, False)
        >>> ahead[1, 1] += 0.02                                    # predicted 0.01 cm apart
        >>> fl.predicted_into_each_other(ahead) is None
        True
        >>> fl.poses[0, 1] = 0.125 + 0.03                          # the leading disk 0.03 cm above the floor
        >>> ahead = fl.poses.copy(); ahead[0, 1] -= 0.04
        >>> a = fl.predicted_into_each_other(ahead)
        >>> a.first, a.second, round(a.gap, 3), a.wall
        ('leading', 'bottom', 0.03, True)
        """
        import shapely

        from ..mesh.moving_images import image_poses

        mm = self.mm
        if not mm.n_bodies:
            return None
        # the current poses hold the prescribed bodies' path poses at t too (set by the last step)
        now, then = image_poses(self.poses, mm.images), image_poses(predicted, mm.images)
        poly = mm._polygons(now)
        found = []  # (gap, first, second, wall)
        a, b = shapely.STRtree(poly).query(poly, predicate="dwithin", distance=mm.h)
        keep = (a < b) & (mm.images.body[a] != mm.images.body[b])
        a, b = a[keep], b[keep]
        if len(a):
            gap = shapely.distance(poly[a], poly[b])
            apart = gap > mm.min_gap
            a, b, gap = a[apart], b[apart], gap[apart]
            ahead = mm._polygons(then)  # only when some pair is within reach
            hit = np.flatnonzero(shapely.intersects(ahead[a], ahead[b]))
            if len(hit):
                k = hit[np.argmin(gap[hit])]
                found.append((float(gap[k]), self.names[mm.images.body[a[k]]], self.names[mm.images.body[b[k]]],
                              False))
        gap_w, ahead_w = _wall_gaps(mm, now), _wall_gaps(mm, then)
        hit_w = (gap_w > mm.min_gap) & (gap_w < mm.h) & (ahead_w <= 0.0) & mm._wall_sides[None, :]
        if hit_w.any():
            i, side = np.unravel_index(np.argmin(np.where(hit_w, gap_w, np.inf)), gap_w.shape)
            found.append((float(gap_w[i, side]), self.names[mm.images.body[i]], SIDE_NAMES[side], True))
        if not found:
            return None
        g, first, second, wall = min(found)
        return Approach(first, second, g, wall)

    def step(self, dt):
        """One coupled step to t + dt (see the module docstring).

        Navier–Stokes: ``unresolved_approach`` is set to the pair the prediction put into each
        other (:meth:`predicted_into_each_other`; None if none) if the solve kept them apart
        (farther than the mesh's ``min_gap`` at the corrected poses: the mesh followed an overlap
        the bodies did not reach), and the step's cost counts ``approach_unresolved``.  Bodies
        that do come into contact in the step (a collision) are not reported.
        """
        if self.explicit:
            return self._staggered_step(dt)
        predicted = self._predicted_poses(dt)
        closing = None if self.stokes else self.predicted_into_each_other(predicted)
        self._step(dt, predicted)
        if closing is not None and self._gap_now(closing) <= self.mm.min_gap:
            closing = None
        self.unresolved_approach = closing
        if closing is not None:
            self.last_cost.count("approach_unresolved")

    def _gap_now(self, approach: Approach) -> float:
        """Distance (length) at the current poses between the two outlines, or the outline and the
        wall, of ``approach`` (nearest periodic images)."""
        import shapely

        from ..mesh.moving_images import image_poses

        mm = self.mm
        ia = np.flatnonzero(mm.images.body == self.names.index(approach.first))
        if approach.wall:
            gaps = _wall_gaps(mm, image_poses(self.poses, mm.images))
            return float(gaps[ia, SIDE_NAMES.index(approach.second)].min())
        poly = mm._polygons(image_poses(self.poses, mm.images))
        ib = np.flatnonzero(mm.images.body == self.names.index(approach.second))
        return float(shapely.distance(poly[ia][:, None], poly[ib][None, :]).min())

    #: Navier–Stokes: what the last step's prediction put into each other and the solve kept apart (:class:`Approach`)
    unresolved_approach = None

    def _step(self, dt, mesh_poses):
        """One coupled step to t + dt with the mesh at ``mesh_poses`` (n_bodies, 3) (module docstring)."""
        cost = CostSplit()
        t_new = self.t + dt
        f = self.free
        X, V = self.poses[f], self.body_velocities[f]
        _, Vp = self._prescribed(t_new)
        self._mesh_poses = np.array(mesh_poses, float, copy=True)
        ev, rebuilt, old_space = self._move_mesh(self._mesh_poses, t_new, cost)
        if rebuilt:
            with cost.timer("rebuild"):
                self.system = RigidBodySystem(self.problem, self.rigid, f)
        if self.stokes:
            self.t = t_new
            self._solve_mobility(t_new, cost, rebuilt)
            self._V_prev = V
            self.poses = self._mesh_poses.copy()
        else:
            self._hand_over(ev, rebuilt, old_space, dt, cost)  # charges "rebuild" and "mesh" itself
            t0 = time.perf_counter()
            self.coupled.system = self.system
            if rebuilt:
                self.coupled.refactorize = True
            load = None if self.contacts is None else self.contacts.load_function(self.t, dt, self.poses,
                                                                                   self.body_velocities)
            dem_s = 0.0 if self.contacts is None else self.contacts.seconds
            passes = self._dem_work()
            regions = self.problem.components.n_components
            guess = carried_contact_load(self.coupled.last_contact_load, self._load_regions, regions)
            self._load_regions = regions
            self.coupled.step(self._weight, contact=load, contact_guess=guess)
            dem_s = 0.0 if self.contacts is None else self.contacts.seconds - dem_s
            self._count_dem_work(passes, cost)
            tm = self.coupled.last_cost
            cost.add("assembly", tm.assembly)
            cost.add("solve", tm.solve)
            if load is not None:
                cost.add("dem", dem_s)
                cost.count("contact_solves", self.coupled.last_contact_iterations)
                if not self.coupled.last_contact_converged:
                    cost.count("contact_unsettled")
            cost.add("coupling", time.perf_counter() - t0 - tm.assembly - tm.solve - dem_s)
            V_new = self.coupled.V
            X_corr = self._bdf_pose(X, V_new, dt)
            self._poses_prev = X
            self._V_prev = V
            self.poses = self._mesh_poses.copy()
            self.poses[f] = X_corr
            self.body_velocities = Vp.copy()
            self.body_velocities[f] = V_new
            self.t = self.stepper.t
            self.x = self.stepper.state.x
        self._finish(cost)

    def _dem_work(self) -> tuple:
        """DEM sub-steps and passes taken so far by the contacts (zeros without them)."""
        c = self.contacts
        return (0, 0, 0, 0) if c is None else (c.substeps, c.dem_calls, c.redone, c.body_substeps)

    def _count_dem_work(self, before: tuple, cost: CostSplit) -> None:
        """Count the step's DEM sub-steps (``dem_substeps``: those of the group of bodies that took the most in
        each pass), the sub-steps summed over the bodies (``dem_body_substeps``,
        :meth:`FluidContacts.sub_step_groups`), sub-stepped passes (``dem_passes``) and the passes redone at the
        DEM's bound (``dem_passes_redone``, :meth:`FluidContacts.sub_steps`)."""
        sub, calls, redone, body_sub = self._dem_work()
        if calls > before[1]:
            cost.count("dem_substeps", sub - before[0])
            cost.count("dem_body_substeps", body_sub - before[3])
            cost.count("dem_passes", calls - before[1])
            if redone > before[2]:
                cost.count("dem_passes_redone", redone - before[2])

    def _staggered_step(self, dt):
        """``coupling = "explicit"``: bodies moved by the last step's fluid loads, then the fluid."""
        from ..fluid.space import RigidMotion, VelocityBC

        cost = CostSplit()
        t0 = time.perf_counter()
        f = self.free
        X, V = self.poses[f], self.body_velocities[f]
        F, T = self.loads() if self.stepper.n_steps else (np.zeros((len(self.body_specs), 2)),
                                                           np.zeros(len(self.body_specs)))
        load = np.column_stack([F[f], T[f]]) + self._weight
        m = np.column_stack([self.mass, self.mass, self.inertia])
        if self._V_prev is None:  # BDF1
            V_new = V + dt * load / m
        else:
            V_new = (2 * dt * load / m + 4 * V - self._V_prev) / 3
        if self.contacts is not None:  # the contacts' mean load over the step, added to the body update
            t1 = time.perf_counter()
            passes = self._dem_work()
            load = self.contacts.load_function(self.t, dt, self.poses, self.body_velocities)
            if load is not None:
                c = 1.0 if self._V_prev is None else 2.0 / 3.0  # the load's weight in the BDF1/BDF2 update
                V_new = V_new + c * dt * load(V_new, np.zeros_like(V_new)) / m
            cost.add("dem", time.perf_counter() - t1)
            self._count_dem_work(passes, cost)
        X_new = self._bdf_pose(X, V_new, dt)
        P, Vp = self._prescribed(self.t + dt)
        self._mesh_poses = P.copy()
        self._mesh_poses[f] = X_new
        cost.add("coupling", time.perf_counter() - t0)
        ev, rebuilt, old_space = self._move_mesh(self._mesh_poses, self.t + dt, cost)
        first = len(self.problem.bcs) - len(self.body_specs)  # body conditions follow the sides'
        for j, k in enumerate(f):
            self.problem.bcs[first + k] = VelocityBC(self.names[k], RigidMotion(tuple(V_new[j, :2]), float(V_new[j, 2]),
                                                                             tuple(X_new[j, :2]),
                                                                             self.rigid.period))
        self._hand_over(ev, rebuilt, old_space, dt, cost)
        t0 = time.perf_counter()
        st = self.stepper
        st.step()
        cost.add("assembly", time.perf_counter() - t0 - st.last_cost.solve)
        cost.add("solve", st.last_cost.solve)
        self._poses_prev, self._V_prev = X, V
        self.poses = self._mesh_poses.copy()
        self.body_velocities = Vp.copy()
        self.body_velocities[f] = V_new
        self.t, self.x = st.t, st.state.x
        self._finish(cost)

    def _release_factors(self):
        """The fluid's LU (:meth:`MovingMeshFlow._release_factors`), the coupled one, the Stokes
        mobility's, and the coupled index maps of the old mesh (rebuilt after the new problem)."""
        from ..fluid.solvers import release_factors

        super()._release_factors()
        release_factors(getattr(self.coupled, "solver", None), self._lagged_mobility)
        self._lagged_mobility = None
        if not self.explicit:
            self.system = None
            if self.coupled is not None:
                self.coupled.system = None

    def _mobility_solver(self, rebuilt):
        """Stokes: a fresh LU every step for ``solver = "direct"`` (bit-for-bit restarts), otherwise
        one lagged LU kept between steps (the matrix changes only with the geometry) and refactorised
        at re-triangulations or when GMRES needs many iterations."""
        from ..fluid.solvers import LaggedLUSolver
        from .moving_flow import LAGGED_REFACTOR_ITERATIONS

        if self.fluid.solver == "direct":
            return self.problem.direct_solver()
        if self.fluid.solver == "auto" and self._lagged_mobility is None and not self._lu_fits():
            from ..fluid.solvers import SolverError

            raise SolverError(self.solver_choice["note"] + "; Stokes free bodies have no iterative path: "
                              "coarsen the mesh (mesh.h) or free memory")
        s = self._lagged_mobility
        if s is None or rebuilt:
            s = self._lagged_mobility = LaggedLUSolver(direct=self.problem.direct_solver(),
                                                       max_iterations_before_refactor=LAGGED_REFACTOR_ITERATIONS)
        return s

    def _solve_mobility(self, t, cost=None, rebuilt=True):
        """Stokes: the velocities of the free bodies at which fluid forces balance the external loads."""
        t0 = time.perf_counter()
        pr, sysm = self.problem, self.system
        axes, multiplier, null = self._flux
        if multiplier:  # the residual without the mean gradient: the solve finds all of it
            pr.set_body_force(self.fluid.body_force)
        x = pr.initial_vector(t)
        z = sysm.gather(x, np.zeros((len(self.free), 3)))
        x = sysm.prolong(z, x)
        rz = sysm.restrict(pr.steady_residual(x, convection=False))
        rz[sysm.n_fluid:] -= self._weight.ravel() / self.rho
        K = sysm.matrix(pr.A_data, np.zeros(3 * len(self.free)))
        t1 = time.perf_counter()
        solver = self._mobility_solver(rebuilt)
        if axes:
            solver = flux_solver(self, solver, x, z, axes, multiplier, null)
        dt = self.dt
        c = self.contacts
        self._contact_step = c is not None and c.within_reach(
            self._mesh_poses, 2.0 * dt * float(np.abs(self.body_velocities[self.free, :2]).max()))
        if self._contact_step:
            z, dem_s = self._solve_with_repulsion(t, solver, K, z, rz, dt, cost)
            t1 += dem_s
        else:
            solver.factorize(K)
            z = z - solver.solve(rz)
        t2 = time.perf_counter()
        self.x = sysm.prolong(z, x)
        if multiplier:  # G = ρ g on the axes: the fluid's body force −G/ρ from now on (loads, output)
            self.mean_gradient = np.zeros(2)
            self.mean_gradient[list(axes)] = self.rho * solver.last_multiplier
            pr.set_body_force(np.asarray(self.fluid.body_force) - self.mean_gradient / self.rho)
        pr.normalise_pressure(self.x)
        P, Vp = self._prescribed(t)
        self.body_velocities = Vp.copy()
        self.body_velocities[self.free] = sysm.split(z)[1]
        if cost is not None:
            cost.add("assembly", t1 - t0)
            cost.add("solve", t2 - t1)

    def _solve_with_repulsion(self, t, solver, K, z0, rz, dt, cost):
        """Stokes with the short-range repulsion: the velocities V of the coming step [t, t + Δt]
        at which the fluid's force balances the buoyant weight and the repulsion at the end of
        the step, F_c(Xⁿ + Δt V): linearly implicit Euler in the poses, Newton on the
        linearisation F_c(X*) + K*(X − X*) (:meth:`FluidContacts.repulsion_linearised`), each
        iteration one solve with −Δt K*/ρ added to the body block.  Stable for any stiffness
        (K* is negative semi-definite, the mobility positive definite); a body resting on
        another or on a wall carries its buoyant weight on the repulsion and does not move.  The
        linearisation point moves to the solved end poses, by half steps once the mismatch stops
        halving (a settling pile of 12 frictionless disks otherwise cycles between two states as
        they slide: 8 iterations, the cap, per step; damped 4–7).
        Returns (z, seconds spent in the contact geometry)."""
        import scipy.sparse as sp

        c, sysm, f = self.contacts, self.system, self.free
        nf = len(f)
        X0 = self._prescribed(t + dt)[0]  # the other bodies where they will be at the end of the step
        X0[f] = self._mesh_poses[f]
        X_lin = X0.copy()
        scale = max(float(c.repulsion.force), 1e-300)
        body = np.arange(sysm.n_fluid, sysm.shape[0])
        geo_s = 0.0
        z = z0
        relax, last_miss = 1.0, np.inf
        self.last_contact_iterations = 0
        at_lin = None  # the repulsion and its stiffness at X_lin when already evaluated there
        for _ in range(self.contact_iterations):
            t0 = time.perf_counter()
            F_lin, K_lin = at_lin if at_lin is not None else c.repulsion_linearised(X_lin)
            geo_s += time.perf_counter() - t0
            # F_c(X0 + Δt V) ≈ F_lin + K_lin (X0 − X_lin) + Δt K_lin V
            F_at_0 = F_lin.ravel() + K_lin @ (X0[f] - X_lin[f]).ravel()
            Kb = K_lin.tocoo()
            Kc = K + sp.csr_matrix((-(dt / self.rho) * Kb.data, (body[Kb.row], body[Kb.col])), shape=K.shape)
            r = rz.copy()
            r[sysm.n_fluid:] -= F_at_0 / self.rho
            solver.factorize(Kc)
            z = z0 - solver.solve(r)
            self.last_contact_iterations += 1
            V = sysm.split(z)[1]
            X_end = X0.copy()
            X_end[f] = X0[f] + dt * V
            t0 = time.perf_counter()
            at_end = c.repulsion_linearised(X_end)
            F_end = at_end[0]
            geo_s += time.perf_counter() - t0
            predicted = F_at_0 + dt * (K_lin @ V.ravel())
            miss = float(np.abs(F_end.ravel() - predicted).max())
            if miss <= self.contact_tolerance * scale:
                break
            if miss > 0.5 * last_miss:  # not contracting: damp the step of the linearisation point
                relax *= 0.5
            last_miss = miss
            X_lin = X_lin + relax * (X_end - X_lin)
            at_lin = at_end if relax == 1.0 else None
        self.contact_load = F_end.reshape(nf, 3)
        if cost is not None:
            cost.add("dem", geo_s)
            cost.count("contact_solves", self.last_contact_iterations)
        return z, geo_s

    # -- checkpoints --------------------------------------------------------------------------
    def get_state(self):
        s = super().get_state()
        s["bodies"] = {"poses": self.poses.copy(), "velocities": self.body_velocities.copy(),
                       "mesh_poses": self._mesh_poses.copy(),
                       "poses_prev": None if self._poses_prev is None else self._poses_prev.copy(),
                       "V_prev": None if self._V_prev is None else self._V_prev.copy(),
                       "contact_step": self._contact_step}
        if self.contacts is not None:
            s["bodies"]["contacts"] = self.contacts.get_state()
        if self.coupled is not None:
            s["bodies"]["contact_load"] = self.coupled.last_contact_load.copy()
            s["bodies"]["contact_regions"] = self._load_regions
            s["bodies"]["coupled_V"] = self.coupled.V.copy()
            s["bodies"]["coupled_V_prev"] = None if self.coupled.V_prev is None else self.coupled.V_prev.copy()
        return s

    def set_state(self, s):
        b = s["bodies"]
        self.poses = np.array(b["poses"], float)
        self.body_velocities = np.array(b["velocities"], float)
        self._mesh_poses = np.array(b["mesh_poses"], float)
        self._poses_prev = None if b["poses_prev"] is None else np.array(b["poses_prev"], float)
        self._V_prev = None if b["V_prev"] is None else np.array(b["V_prev"], float)
        self._contact_step = bool(b.get("contact_step", False))
        super().set_state(s)
        self._lagged_mobility = None
        self.system = RigidBodySystem(self.problem, self.rigid, self.free)
        if self.contacts is not None and "contacts" in b:
            self.contacts.set_state(b["contacts"])
        if self.coupled is not None:
            self.coupled.fluid = self.stepper
            self.coupled.system = self.system
            self.coupled.V = np.array(b["coupled_V"], float)
            if "contact_load" in b:
                self.coupled.last_contact_load = np.array(b["contact_load"], float)
            regions = b.get("contact_regions")
            self._load_regions = None if regions is None else int(regions)
            self.coupled.V_prev = None if b["coupled_V_prev"] is None else np.array(b["coupled_V_prev"], float)
            self.coupled.refactorize = True

