"""ALE flow on the moving mesh around prescribed bodies whose outlines move.

Each step the bodies move to their poses at t + dt and the mesh follows
(:meth:`fluidem.mesh.MovingMesh.update`).  While the connectivity is unchanged the flow
problem is moved, not rebuilt (:meth:`fluidem.fluid.problem.FlowProblem.update_geometry`:
same DOF numbering, patterns, condensed structure, Dirichlet lists; new basis values and
data), the rigid-mode operator's torque rows are refilled, and the lagged LU of the last
matrices preconditions GMRES (``fluid.solver = "direct"``: a fresh LU every step, for
bit-for-bit restarts).  At a re-triangulation everything is rebuilt, the LU is recomputed,
and u^n, u^{n−1} are interpolated onto the new nodes from the old connectivity at the
positions of t + dt, which covers the new domain exactly: the new nodes inherit the
trajectories of the old mesh motion (:meth:`fluidem.mesh.MovingMesh.node_history`) and the
step stays an ordinary ALE BDF2 step (no value extrapolated from the mesh at time t).

Scheme: BDF2 in the non-conservative ALE form with the mass matrix at t^{n+1} and the mesh
velocity w^{n+1} = (3x^{n+1} − 4x^n + x^{n−1}) / (2Δt) of the node trajectories (Formaggia &
Nobile 2004, CMAME 193, 4097–4116; Donea & Huerta 2003, Ch. 7): second order in Δt
(``benchmarks/results/ale_convergence.md``), a uniform flow is kept to round-off under any
mesh motion (the discrete GCL of this form).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..cost import CostSplit
from ..fluid.solvers.lagged import MOVING_MESH_STEPPING
from ..fluid.solvers.ordering import OrderingChoice
from ..geometry import barycentric, transform
from .bodies import LinearPath
from ..mesh.moving_images import periodic_copies
from ..mesh.params import REPAIR_SWEEPS
from ..mesh.periodic import bends_seams
from ..mesh.seam import period_of
from .boundary import periodic_axes_of, velocity_bcs, viscous_form_of
from .loads import FlowLoads

__all__ = ["LAGGED_REFACTOR_ITERATIONS", "MovingMeshFlow", "Outline", "p1_at_dofs", "transfer_change"]

#: GMRES iterations of a solve above which the lagged LU is recomputed on the moving mesh.
LAGGED_REFACTOR_ITERATIONS = MOVING_MESH_STEPPING["max_iterations_before_refactor"]


def p1_at_dofs(space, w_nodes: np.ndarray) -> np.ndarray:
    """Velocity coefficients (n_u,) of the piecewise linear field with vertex values ``w_nodes`` (n_vertices, 2).

    The mesh velocity is linear on each element (the mesh moves affinely), so every element
    pair represents it exactly: nodal DOFs take its point values, bubble DOFs zero.
    """
    ub, mesh = space.ub, space.mesh
    p, t = mesh.p, mesh.t
    ed = ub.element_dofs  # (Nbfun, n_elements)
    loc = ub.doflocs[:, ed]  # (2, Nbfun, n_elements)
    a, b, c = (p[:, t[k]][:, None, :] for k in range(3))
    l0, l1, l2 = np.moveaxis(barycentric(loc, a, b, c, axis=0), -1, 0)  # each (Nbfun, n_elements)
    comp = np.zeros(ub.N, dtype=int)
    comp[ub.split_indices()[1]] = 1
    cd = comp[ed]
    wv = w_nodes.T  # (2, n_vertices)
    val = np.where(cd == 0, l0 * wv[0, t[0]] + l1 * wv[0, t[1]] + l2 * wv[0, t[2]],
                   l0 * wv[1, t[0]] + l1 * wv[1, t[1]] + l2 * wv[1, t[2]])
    out = np.zeros(ub.N)
    out[ed.ravel()] = np.nan_to_num(val.ravel(), nan=0.0)  # NaN locations: bubble DOFs
    return out


def transfer_change(basis_old, u_old: np.ndarray, basis_new, u_new: np.ndarray) -> float:
    """Relative L2 change ``||u_new − u_old|| / ||u_old||`` a field transfer made (interpolation noise).

    Both functions are evaluated at the quadrature points of ``basis_new`` (the old one by
    point location in ``basis_old``'s mesh); the paper's Fig. 5 shows this noise per
    re-triangulation.  0 for a zero field.
    """
    from ..mesh import transfer

    x = np.asarray(basis_new.global_coordinates())  # (2, n_elements, n_qp)
    where = transfer.locate_clustered(basis_old.mesh, x)  # an element's points share their candidate cells
    old = transfer.values_at(basis_old, u_old, x.reshape(2, -1), where).reshape(2, *x.shape[1:])
    new = np.asarray(basis_new.interpolate(u_new))
    dx = basis_new.dx
    den = float(np.sqrt((dx * (old ** 2).sum(axis=0)).sum()))
    num = float(np.sqrt((dx * ((new - old) ** 2).sum(axis=0)).sum()))
    return num / den if den > 0 else 0.0


class Outline:
    """A body outline for :class:`fluidem.mesh.MovingMesh`: ``vertices`` (k, 2) in body coordinates and ``name``."""

    def __init__(self, vertices, name):
        self.vertices = np.asarray(vertices, float)
        self.name = name


class MovingMeshFlow(FlowLoads):
    """The flow around prescribed bodies whose outlines move: ALE on :class:`fluidem.mesh.MovingMesh`.

    One BDF2 step per time step with the mesh velocity w in the convection, (u − w)·∇u, w
    the BDF2 derivative of the node trajectories (module docstring; BDF1 on the first step).
    While the connectivity is unchanged the velocity coefficients stay attached to the nodes
    (no interpolation) and the problem is moved in place.  At a re-triangulation u^n and
    u^{n−1} are interpolated onto the new nodes from the old mesh moved to t + dt
    (:func:`fluidem.mesh.transfer.interpolate`), the new nodes continue the old mesh's
    trajectories and the step is an ordinary ALE step (``MeshEvent.history == "ale"``); only
    when the old mesh is not valid at t + dt (``reason == "inverted"``) is it Eulerian
    (w = 0, fields from the old mesh at time t, ``history == "eulerian"``).  The relative L2
    change of u^n by the transfer (interpolation noise) and the relative force change of that
    step go into the event (``transfer_change``, ``force_change``) and the event log.  A
    projection of the transferred fields onto discretely divergence-free ones was measured
    and left out: it made the force jumps larger (6.2 % against 1.4 % mean on the plate of
    ``tests/test_ale.py``).  Stokes is quasi-steady: one solve per step on the current mesh,
    no mesh velocity.  Outlines are polygons (straight edges).

    Parameters
    ----------
    bodies : list of fluidem.scene.BodySpec
        The bodies (names, initial poses, velocities and motions: fixed, prescribed).
    outlines : list of (k, 2) float
        Every body's outline in body coordinates, length.
    domain : fluidem.scene.DomainSpec
        The box and its sides.
    fluid : fluidem.scene.FluidSpec
    mesh : fluidem.scene.MeshSpec
        Mesh size, grading, strategy and re-triangulation period.
    dt : float
        The time step.
    sim : fluidem.simulation.Simulation
        Its ``counters`` are charged (``triangulations``, ``fluid_solvers``, ``transfers``): any
        object with a ``counters`` dict.

    Attributes
    ----------
    body_specs : list of fluidem.scene.BodySpec
        ``bodies``; ``fluid``, ``domain`` and ``dt`` are kept as given too (rebuilds read them).
    mm : MovingMesh
    mesh : skfem.MeshTri
    space : FlowSpace
    problem : FlowProblem
    rigid : RigidModes
        Rigid-mode operator of the outlines about the current centres (loads, prolongation).
    last_event : MeshEvent
    last_cost : CostSplit
        Seconds of the last step: ``mesh`` (mesh update and mesh velocity), ``rebuild``
        (problem moved or rebuilt, fields transferred), ``assembly``, ``solve``.
    """

    def __init__(self, bodies, outlines, *, domain, fluid, mesh, dt: float, sim):
        from ..fluid.navier_stokes import BDF2Stepper
        from ..mesh import MovingMesh

        fl, ms = fluid, mesh
        self.fluid, self.dt, self.domain, self.body_specs = fluid, dt, domain, list(bodies)
        t0 = time.perf_counter()
        mesh_outlines = [Outline(v, b.name) for b, v in zip(bodies, outlines)]
        self.path = [LinearPath(b.position, b.angle, b.velocity if b.motion != "fixed" else (0, 0),
                                b.omega if b.motion != "fixed" else 0.0) for b in bodies]
        grading = None
        if ms.grading is not None:
            g = ms.grading
            region = g["region"] if g["region"] != "bodies" else \
                [transform(v, b.position, b.angle) for b, v in zip(bodies, outlines)]
            grading = {"region": region, "growth": g["growth"], "h_max": g["h_max"]}
        self.mm = MovingMesh(domain.box, mesh_outlines, self._poses(0.0), ms.h, grading=grading,
                             strategy=ms.strategy, retriangulate_every=ms.retriangulate_every,
                             repair_sweeps=REPAIR_SWEEPS if ms.repair else 0, periodic=periodic_axes_of(domain))
        sim.counters["triangulations"] += 1
        self.sim = sim
        self.mesh_time = time.perf_counter() - t0
        self.curved = False
        self.rho = fl.density
        self.stokes = fl.model == "stokes"
        self.names = [b.name for b in bodies]
        self.t = 0.0
        self.last_event = None
        self.last_cost = CostSplit()
        self.mesh_seconds = 0.0
        self.ordering = OrderingChoice()  # SuperLU's ordering by measured fill, kept across re-triangulations
        self._build(0.0)
        if self.stokes:
            self.stepper = None
            self.x = self.problem.initial_vector(0.0)
        else:
            # "auto": the LU of an earlier step preconditions GMRES while it converges fast,
            # recomputed after every re-triangulation; "direct": a fresh LU each step.  The
            # matrix changes more per step than on a fixed mesh (geometry and mesh velocity):
            # 9-15 iterations after a few steps, where one LU costs 40-60 GMRES iterations
            # (Taylor-Hood, 20k-80k DOFs), so refactorise only above LAGGED_REFACTOR_ITERATIONS
            solver = self._make_solver()
            self.stepper = BDF2Stepper(self.problem, dt, convection=fl.convection, solver=solver,
                                       mesh_velocity=np.zeros(self.space.n_u))
            if fl.ale_form == "conservative":
                self.stepper.use_conservative_form(self._outline_dofs())
            self.x = self.stepper.state.x
        self.events = []
        sim.counters["fluid_solvers"] += 1

    def _poses(self, t):
        return np.array([[*p(t)[0], p(t)[1]] for p in self.path]).reshape(-1, 3)

    def _make_solver(self):
        """The linear solver of ``fluid.solver`` for the current problem: for ``"auto"`` and ``"lagged"`` the
        lagged LU with :data:`~fluidem.fluid.solvers.lagged.MOVING_MESH_STEPPING` (the block-Krylov
        path of ``"auto"`` keeps its own tolerance)."""
        from ..fluid.solvers import AutoSolver, make_solver

        fl = self.fluid
        if fl.solver == "lagged":
            return make_solver("lagged", problem=self.problem, **MOVING_MESH_STEPPING)
        s = make_solver(fl.solver, problem=self.problem, dt=self.dt)
        if isinstance(s, AutoSolver):
            s.lagged_options.update(MOVING_MESH_STEPPING)
        return s

    def _release_factors(self):
        """At a re-triangulation, before the new problem is built: drop the LU of the old mesh (it
        is refactorised for the new DOFs anyway).  Held through the build it raised the peak of a
        run: 1 000 settling polygons (1.57M DOFs) peaked at 16.3 GB at a re-triangulation against
        9.6 GB in an ordinary step."""
        from ..fluid.solvers import release_factors

        release_factors(getattr(self.stepper, "solver", None))

    def _retarget_solver(self):
        """After a re-triangulation: the solver's problem data (velocity DOFs, pressure and velocity
        masses of the block preconditioner) for the new problem; an LU is refactorised anyway."""
        from ..fluid.solvers import AutoSolver, BlockKrylovSolver

        s = self.stepper.solver
        if isinstance(s, AutoSolver):
            fresh = self._make_solver()
            s.n_u, s.iterative_options = fresh.n_u, fresh.iterative_options
            if s.chosen == "iterative":
                s.solver = None  # rebuilt for the new sizes at the next factorize
        elif isinstance(s, BlockKrylovSolver):
            self.stepper.solver = self._make_solver()

    def _build(self, t):
        """A new space, problem and rigid-mode operator on the current mesh (after a re-triangulation)."""
        from ..fluid.forces import RigidModes
        from ..fluid.problem import FlowProblem
        from ..fluid.space import FlowSpace

        fl = self.fluid
        self.mesh = self.mm.skfem_mesh()
        self._triangles = np.array(self.mm.triangles, copy=True)  # the connectivity this problem was built on
        self.space = FlowSpace(self.mesh, fl.element)
        self.centers = self._poses(t)[:, :2]
        self.problem = FlowProblem(self.space, fl.viscosity, velocity_bcs(self.domain, self.body_specs, self.centers),
                                   rho=fl.density, body_force=fl.body_force, moving=True, periodic=self.mm.periodic,
                                   viscous=viscous_form_of(self.body_specs),
                                   pin_pockets=not any(b.motion == "free" for b in self.body_specs))
        self.problem.ordering = self.ordering
        self.problem.lu_backend = getattr(fl, "lu_backend", "auto")
        self.rigid = RigidModes(self.space, self.names, self.centers, period=period_of(self.mm.box, self.mm.periodic))

    def _outline_dofs(self) -> np.ndarray:
        """Velocity DOFs on the body outlines (both components), (k,) int."""
        return np.unique(self.rigid.matrix.indices)

    def _constant_fields(self, space) -> np.ndarray:
        """Coefficients (2, n_u) of the constant fields e_x and e_y on ``space`` (exact in every pair)."""
        n = space.mesh.p.shape[1]
        return np.stack([p1_at_dofs(space, np.tile(e, (n, 1))) for e in ((1.0, 0.0), (0.0, 1.0))])

    def _transfer_mass_history(self, old_space, old_history, new_fields):
        """Conservative form after a re-triangulation: M u of the transferred fields on the new
        DOFs, shifted by a uniform velocity per component so that the momentum ∫ u dA of each
        level equals the old one (the transfer conserves it only to interpolation error)."""
        M = self.problem.M
        return self._with_momentum_of(old_space, old_history, [M @ u for u in new_fields])

    def _with_momentum_of(self, old_space, old_history, levels):
        """``levels`` (M u of each time level on the current DOFs) shifted by a uniform velocity per
        component so that each level's momentum ∫ u dA equals that of ``old_history`` (on
        ``old_space``)."""
        e_new = self._constant_fields(self.space)
        e_old = e_new if old_space is self.space else self._constant_fields(old_space)
        Me = self.problem.M @ e_new.T  # (n_u, 2)
        area = np.einsum("cn,nc->c", e_new, Me)
        return [m + Me @ ((e_old @ m_old - e_new @ m) / area) for m_old, m in zip(old_history, levels)]

    def _refit(self, t) -> bool:
        """Move space, problem and rigid modes to the current node positions; False if the triangles changed."""
        tri = self.mm.triangles
        if tri.shape != self._triangles.shape or not np.array_equal(tri, self._triangles) or \
                self.mm.points.shape[0] != self.mesh.p.shape[1]:
            return False
        mesh = dataclasses.replace(self.mesh, doflocs=np.ascontiguousarray(self.mm.points.T, dtype=float))
        self.mesh = mesh
        self.centers = self._poses(t)[:, :2]
        self.problem.update_geometry(mesh, velocity_bcs(self.domain, self.body_specs, self.centers))
        self.space = self.problem.space
        self.rigid.update(self.space, self.centers)
        return True

    @property
    def dofs(self):
        return self.space.n_dofs

    def step(self, dt):
        """One step to t + dt: move the bodies and the mesh, move or rebuild the problem, solve."""
        from ..fluid.navier_stokes import solve_stokes

        cost = CostSplit()
        t_new = self.t + dt
        ev, rebuilt, old_space = self._move_mesh(self._poses(t_new), t_new, cost)
        self.problem.check_pockets(t_new)  # an enclosed pocket whose area the bodies change: stop, say why
        if self.stokes:
            t0 = time.perf_counter()
            solve0 = self.problem.timings.solve
            self.t = t_new
            self.x = solve_stokes(self.problem, t_new).x
            solve = self.problem.timings.solve - solve0
            cost.add("assembly", time.perf_counter() - t0 - solve)
            cost.add("solve", solve)
            self._finish(cost)
            return
        st = self.stepper
        self._hand_over(ev, rebuilt, old_space, dt, cost)
        t0 = time.perf_counter()
        st.step()
        wall = time.perf_counter() - t0
        cost.add("assembly", wall - st.last_cost.solve)
        cost.add("solve", st.last_cost.solve)
        self.t = st.t
        self.x = st.state.x
        self._finish(cost)

    def _move_mesh(self, poses, t_new, cost):
        """Move the mesh to ``poses`` (n_bodies, 3) and the problem with it (rebuilt at a
        re-triangulation); returns (MeshEvent, rebuilt, the space before)."""
        t0 = time.perf_counter()
        ev = self.mm.update(poses)
        self.last_event = ev
        cost.add("mesh", time.perf_counter() - t0)
        if ev.retriangulated:
            self.sim.counters["triangulations"] += 1
            self._release_factors()
        t0 = time.perf_counter()
        old_space = self.space
        rebuilt = ev.retriangulated or not self._refit(t_new)
        if rebuilt:
            self._build(t_new)
            if self.stepper is not None:
                self._retarget_solver()
        cost.add("rebuild", time.perf_counter() - t0)
        return ev, rebuilt, old_space

    def _hand_over(self, ev, rebuilt, old_space, dt, cost):
        """Give the stepper u^n, u^{n−1} on the current DOFs (transferred at a re-triangulation)
        and the mesh velocity of this step."""
        st = self.stepper
        t0 = time.perf_counter()
        history = outline = None
        if ev.retriangulated:
            u_n, u_p = self._transfer(ev, old_space, st.state.u, st.previous_velocity)
            if st.conservative:
                history = self._transfer_mass_history(old_space, st.mass_history, [u for u in (u_n, u_p)
                                                                                   if u is not None])
                outline = self._outline_dofs()
            cost.add("rebuild", time.perf_counter() - t0)
            t0 = time.perf_counter()
        else:
            u_n, u_p = st.state.u, st.previous_velocity
            if st.conservative and rebuilt:  # a new problem on the same DOFs: the history stands
                history, outline = st.mass_history, self._outline_dofs()
            if len(ev.repaired_nodes):  # the repair moved nodes: their fields move with them
                u_n, u_p, history = self._transfer_repaired(ev, u_n, u_p)
                cost.add("rebuild", time.perf_counter() - t0)
                t0 = time.perf_counter()
        # BDF2 derivative of the node trajectories at t + dt (second order; BDF1 on the first step)
        w_nodes = self.mm.node_velocity(dt, order=2)
        t1 = time.perf_counter()
        w = p1_at_dofs(self.space, w_nodes)
        cost.add("mesh", t1 - t0)
        cost.add("rebuild", time.perf_counter() - t1)
        st.take_over(self.problem, u_n, u_p, mesh_velocity=w, renumbered=rebuilt, mass_history=history,
                     no_flux_dofs=outline)

    def _transfer_repaired(self, ev, u_n, u_p):
        """u^n, u^{n−1} (and the conservative form's M u history) after the repair moved a few
        nodes (``ev.repaired_nodes``, :mod:`fluidem.mesh.repair`): the old functions on the mesh
        before the repair, evaluated at the moved DOFs (:func:`fluidem.mesh.transfer.move_with_nodes`;
        the nodes' trajectories were pulled back alike, so the jump is not mesh velocity).  The
        history changes by M (u_new − u_old), shifted back to each level's momentum ∫ u dA
        (:meth:`_with_momentum_of`)."""
        from ..mesh.transfer import move_with_nodes

        st = self.stepper
        fields = u_n if u_p is None else np.column_stack([u_n, u_p])
        ub = self.space.ub
        new = move_with_nodes(ub.elem, ub.element_dofs, self.mm.triangles, ev.repaired_from, self.mm.points,
                              ev.repaired_nodes, fields)
        new_n, new_p = (new, None) if u_p is None else (new[:, 0].copy(), new[:, 1].copy())
        history = None
        if st.conservative and st.mass_history is not None:
            M = self.problem.M
            levels = [m if a is None else m + M @ (b - a)  # no u^{n−1} (BDF1 next): its history stands
                      for m, a, b in zip(st.mass_history, (u_n, u_p), (new_n, new_p))]
            history = self._with_momentum_of(self.space, st.mass_history, levels)
        self.sim.counters["repair_transfers"] = self.sim.counters.get("repair_transfers", 0) + 1
        return new_n, new_p, history

    def _transfer(self, ev, old_space, u_n, u_p):
        """u^n, u^{n−1} on the new DOFs after a re-triangulation (``ev.history``, :meth:`MovingMesh.node_history`).

        ``"ale"``: the old coefficients belong to the old nodes, which moved to
        ``ev.old_points`` (t + dt); the old finite element functions on that moved old mesh,
        evaluated at the new DOFs, are u^n, u^{n−1} at the points of the new DOFs'
        trajectories (the old mesh motion is affine per element), so the step is an
        ordinary ALE step and no value is extrapolated.  ``"eulerian"`` (old mesh invalid at
        t + dt, or not moved): interpolation from the old mesh at time t, nodes at rest.
        The relative L2 change the transfer makes to u^n goes to ``ev.transfer_change``.
        """
        from skfem import Basis, ElementVector, MeshTri

        from ..mesh import transfer

        src = ev.old_points if ev.history == "ale" else (ev.prev_points if ev.prev_points is not None
                                                          else ev.old_points)
        old = MeshTri(np.asarray(src, float).T.copy(), np.asarray(ev.old_triangles).T.copy())
        ob = Basis(old, ElementVector(old_space.pair.velocity()))
        fields = u_n if u_p is None else np.column_stack([u_n, u_p])
        if bends_seams(self.mm):
            # the old mesh reached across the bent seams: its copies a period away hold the new
            # DOFs by a seam (element by element the same local DOFs)
            pts, tri = periodic_copies(self.mm, np.asarray(src, float), np.asarray(ev.old_triangles))
            tiled = MeshTri(pts.T.copy(), tri.T.copy())
            tb = Basis(tiled, ElementVector(old_space.pair.velocity()))
            m = old.t.shape[1]
            tf = np.zeros((tb.N,) + fields.shape[1:])
            for k in range(tiled.t.shape[1] // m):  # a few copies
                tf[tb.element_dofs[:, k * m:(k + 1) * m]] = fields[ob.element_dofs]
            u_new = transfer.interpolate(tb, tf, self.space.ub)
        else:
            u_new = transfer.interpolate(ob, fields, self.space.ub)  # one point search for both
        new_n, new_p = (u_new, None) if u_p is None else (u_new[:, 0].copy(), u_new[:, 1].copy())
        ev.transfer_change = transfer_change(ob, u_n, self.space.ub, new_n)
        self.sim.counters["transfers"] = self.sim.counters.get("transfers", 0) + 1
        return new_n, new_p

    def loads(self):
        """Forces (n_bodies, 2) and torques (n_bodies,) of the fluid on the bodies (see :class:`FlowLoads`).

        After a re-triangulation step the relative change of the forces against the previous
        step goes to ``last_event.force_change``.
        """
        out = super().loads()
        now = self.__dict__.get("_forces_now")
        prev = self.__dict__.get("_forces_prev")
        if now is not None and now[0] != self.t:
            prev = self._forces_prev = now
        self._forces_now = (self.t, np.array(out[0], copy=True))
        ev = self.last_event
        if ev is not None and ev.retriangulated and prev is not None and prev[0] < self.t:
            ref = max(float(np.linalg.norm(prev[1])), 1e-300)
            ev.force_change = float(np.linalg.norm(out[0] - prev[1]) / ref)
        return out

    def _finish(self, cost):
        self.last_cost = cost
        self.mesh_seconds = cost.mesh

    def get_state(self):
        s = {"t": self.t, "x": self.x.copy(), "mm": self.mm, "ordering": self.ordering.state()}
        if self.stepper is not None:
            s["stepper"] = self.stepper.get_state()
        return s

    def set_state(self, s):
        self.mm = s["mm"]
        self.t = s["t"]
        self.ordering.restore(s.get("ordering"))
        self._build(self.t)
        self.x = s["x"].copy()
        if self.stepper is not None:
            outline = self._outline_dofs() if self.stepper.conservative else None
            self.stepper.take_over(self.problem, self.x[: self.space.n_u], renumbered=True, no_flux_dofs=outline)
            self.stepper.set_state(s["stepper"])
