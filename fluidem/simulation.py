"""Run a scene: build only the parts its plan needs, step, record.

:class:`Simulation` takes a :class:`fluidem.scene.Scene`, asks it for its
:class:`~fluidem.scene.Plan` and builds

* a dry scene: no mesh and no fluid solver; bodies move by the DEM when contacts are on,
  or in closed form (``x = x₀ + v₀ t + g t²/2``, ``θ = θ₀ + ω t``) when they are off, so a
  lone body does no contact search at all;
* a fluid scene with fixed (or outline-preserving) bodies: one mesh, built once; Stokes
  (``solve_stokes`` per step, one LU for the whole run since the matrix never changes) or
  Navier–Stokes (``BDF2Stepper``); loads on the bodies by the residual method;
* a Stokes scene with translating prescribed bodies and a single step (quasi-steady at
  one instant): the mesh of the initial geometry.

* a fluid scene whose prescribed bodies move their outlines: the moving mesh
  (:class:`fluidem.mesh.MovingMesh`), ALE Navier–Stokes or quasi-steady Stokes on it
  (:class:`_MovingMeshFlow`); without the moving-mesh layer such scenes are refused.

Free bodies in a fluid need the coupled solver (a later version) and are refused with a
``ValueError`` that says so.

Each step's wall time is split into ``bodies``, ``fluid``, ``loads`` and ``output``
(:class:`StepTimes`), reported to a progress callback.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .scene import Scene

__all__ = ["Simulation", "RunResult", "StepTimes", "run", "LinearPath"]


@dataclass
class StepTimes:
    """Wall seconds of one step per part: ``bodies``, ``mesh``, ``fluid``, ``loads``, ``output``."""

    bodies: float = 0.0
    mesh: float = 0.0
    fluid: float = 0.0
    loads: float = 0.0
    output: float = 0.0

    @property
    def total(self) -> float:
        return self.bodies + self.mesh + self.fluid + self.loads + self.output

    def __str__(self):
        parts = [(k, getattr(self, k)) for k in ("bodies", "mesh", "fluid", "loads", "output") if getattr(self, k)]
        return " + ".join(f"{k} {1e3 * v:.1f}" for k, v in parts) + " ms" if parts else "0 ms"


@dataclass
class RunResult:
    """Outcome of :meth:`Simulation.run`: steps taken, final time, output directory, timings."""

    steps: int
    t: float
    out_dir: str | None
    wall_s: float
    dofs: int = 0
    totals: StepTimes = field(default_factory=StepTimes)
    geometry: str = ""

    def __str__(self):
        s = f"{self.steps} steps to t = {self.t:.6g} in {self.wall_s:.2f} s"
        if self.dofs:
            s += f", {self.dofs} DOFs ({self.geometry} geometry)"
        if self.out_dir:
            s += f"; output in {self.out_dir}"
        return s


class LinearPath:
    """Prescribed rigid motion with constant velocity: ``path(t) -> (position (2,), angle)``."""

    def __init__(self, position, angle, velocity, omega):
        self.position = np.asarray(position, float)
        self.angle = float(angle)
        self.velocity = np.asarray(velocity, float)
        self.omega = float(omega)

    def __call__(self, t):
        return self.position + self.velocity * t, self.angle + self.omega * t


# ---------------------------------------------------------------------------------------
# bodies: closed form (no contacts) or DEM
# ---------------------------------------------------------------------------------------
class _Kinematic:
    """Bodies without contacts: free bodies fall under gravity, prescribed ones follow their path."""

    def __init__(self, scene: Scene):
        B = scene.bodies
        n = len(B)
        self.x0 = np.array([b.position for b in B], float).reshape(n, 2)
        self.a0 = np.array([b.angle for b in B], float)
        self.v0 = np.array([b.velocity for b in B], float).reshape(n, 2)
        self.w0 = np.array([b.omega for b in B], float)
        fixed = np.array([b.motion == "fixed" for b in B], bool)
        self.v0[fixed] = 0.0
        self.w0[fixed] = 0.0
        self.g = np.where(np.array([b.motion == "free" for b in B])[:, None], np.asarray(scene.gravity), 0.0)
        self.t = 0.0
        self.n = n

    def step(self, dt):
        self.t += dt

    @property
    def positions(self):
        t = self.t
        return self.x0 + self.v0 * t + 0.5 * self.g * t * t

    @property
    def angles(self):
        return self.a0 + self.w0 * self.t

    @property
    def velocities(self):
        return self.v0 + self.g * self.t

    @property
    def omegas(self):
        return self.w0.copy()

    def loads(self):
        return np.zeros((self.n, 2)), np.zeros(self.n), np.zeros(self.n, int)

    def get_state(self):
        return {"t": self.t}

    def set_state(self, s):
        self.t = s["t"]


class _DEMBodies:
    """Bodies moved by :class:`fluidem.dem.DEM` (sub-steps of at most ``dt_max`` inside a scene step)."""

    def __init__(self, scene: Scene):
        from .dem import DEM, Body, ContactModel

        bodies = []
        for b in scene.bodies:
            v = b.local_vertices(scene.default_segments(b))
            if b.motion == "prescribed":
                path = LinearPath(b.position, b.angle, b.velocity, b.omega)
                bodies.append(Body.polygon(v, density=b.density, motion="prescribed", path=path))
            else:
                bodies.append(Body.polygon(v, density=b.density, position=b.position, angle=b.angle,
                                           velocity=b.velocity, omega=b.omega, motion=b.motion))
        x0, x1, y0, y1 = scene.domain.box
        sides = {s: scene.domain.side(s).type for s in ("left", "right", "bottom", "top")}
        walls = (x0 if sides["left"] == "wall" else -np.inf, x1 if sides["right"] == "wall" else np.inf,
                 y0 if sides["bottom"] == "wall" else -np.inf, y1 if sides["top"] == "wall" else np.inf)
        c = scene.contact
        self.dem = DEM(bodies, walls=walls, gravity=scene.gravity, contact=ContactModel(E=c.E, mu=c.mu, gamma=c.gamma))
        self.n = len(bodies)
        self.substeps = 0

    def step(self, dt):
        self.substeps += self.dem.advance(dt)

    positions = property(lambda self: self.dem.positions.copy())
    angles = property(lambda self: self.dem.angles.copy())
    velocities = property(lambda self: self.dem.velocities.copy())
    omegas = property(lambda self: self.dem.omegas.copy())

    def loads(self):
        d = self.dem
        F = d.forces - d.mass[:, None] * d.gravity - d.external_force
        T = d.torques - d.external_torque
        C = d.contacts
        cnt = np.bincount(np.concatenate([C.i, C.j[C.j >= 0]]).astype(np.int64), minlength=self.n)
        return F, T, cnt

    def get_state(self):
        return {"dem": self.dem, "substeps": self.substeps}

    def set_state(self, s):
        self.dem = s["dem"]
        self.substeps = s["substeps"]


# ---------------------------------------------------------------------------------------
# fluid on a mesh built once
# ---------------------------------------------------------------------------------------
def _inflow_value(side: str, box, profile: dict):
    """Velocity ``(x, y, t) -> (2, n)`` of an inflow side, normal to it, pointing into the box."""
    x0, x1, y0, y1 = box
    kind, U, ramp = profile["type"], profile["umax"], profile["ramp"]
    normal = {"left": (1.0, 0.0), "right": (-1.0, 0.0), "bottom": (0.0, 1.0), "top": (0.0, -1.0)}[side]

    def value(x, y, t):
        s, L = ((y - y0), y1 - y0) if side in ("left", "right") else ((x - x0), x1 - x0)
        shape = 4.0 * s * (L - s) / L**2 if kind == "parabolic" else np.ones_like(s)
        f = 1.0 if ramp <= 0 or t >= ramp else 0.5 * (1.0 - math.cos(math.pi * t / ramp))
        speed = U * f * shape
        return np.array([normal[0] * speed, normal[1] * speed])

    return value


class _FlowLoads:
    """Hydrodynamic loads on every body from the residual of the last solve (shared by both flows)."""

    def residual(self):
        if self.stokes:
            return self.problem.steady_residual(self.x, convection=False)
        return self.stepper.last_residual()

    def loads(self):
        from .fluid.forces import body_loads

        r = self.residual()
        n = len(self.names)
        F, T = np.zeros((n, 2)), np.zeros(n)
        for k, (name, c) in enumerate(zip(self.names, self.centers)):  # one short dot product per body
            L = body_loads(self.space, r, name, rho=self.rho, center=c)
            F[k] = L.fx, L.fy
            T[k] = L.torque
        return F, T


class _FixedMeshFlow(_FlowLoads):
    """The flow around bodies whose outlines do not move: one mesh, one FlowProblem."""

    def __init__(self, scene: Scene, sim: "Simulation"):
        from .fluid.navier_stokes import BDF2Stepper, FlowProblem
        from .fluid.solvers import LaggedLUSolver
        from .fluid.space import FlowSpace
        from .mesh import triangulate as tri
        from .mesh.background import GradedSize, UniformSize

        fl, ms = scene.fluid, scene.mesh
        t0 = time.perf_counter()
        obstacles = []
        for b, outline in zip(scene.bodies, scene.world_outlines()):
            circle = (*b.position, b.radius) if (b.shape == "disk" and ms.curved) else None
            obstacles.append(tri.Obstacle(outline, b.name, circle=circle, refine_outline=b.shape != "disk"))
        if ms.grading is None:
            size = UniformSize(ms.h)
        else:
            g = ms.grading
            region = g["region"] if g["region"] != "bodies" else [o.vertices for o in obstacles]
            size = GradedSize(h_min=ms.h, growth=g["growth"], h_max=g["h_max"], region=region) if region else \
                UniformSize(ms.h)
        tmesh = tri.triangulate_box(scene.domain.box, obstacles, size)
        self.curved = bool(tmesh.circles)
        self.mesh = tri.to_skfem(tmesh, curved=self.curved)
        sim.counters["triangulations"] += 1
        self.mesh_time = time.perf_counter() - t0
        self.space = FlowSpace(self.mesh, fl.element)
        bcs = _velocity_bcs(scene, [b.position for b in scene.bodies])
        self.rho = fl.density
        self.problem = FlowProblem(self.space, fl.viscosity, bcs, rho=fl.density, body_force=fl.body_force)
        self.stokes = fl.model == "stokes"
        self.centers = [b.position for b in scene.bodies]
        self.names = [b.name for b in scene.bodies]
        if self.stokes:
            # the Stokes matrix of a fixed mesh never changes: one LU, reused while the values match
            self.solver = LaggedLUSolver(direct=self.problem.direct_solver())
            self.stepper = None
            self.x = self.problem.initial_vector(0.0)
        else:
            # "auto": an LU reused as a GMRES preconditioner across steps (2-7 iterations, 5-20x
            # cheaper per step than a fresh LU); "direct": a fresh LU every step, for runs
            # that must restart bit for bit
            if fl.solver == "direct":
                solver = self.problem.direct_solver()
            else:
                solver = LaggedLUSolver(direct=self.problem.direct_solver())
            self.stepper = BDF2Stepper(self.problem, scene.time.dt, convection=fl.convection, solver=solver)
            self.x = self.stepper.state.x
        self.t = 0.0
        sim.counters["fluid_solvers"] += 1

    @property
    def dofs(self):
        return self.space.n_dofs

    def step(self, dt):
        from .fluid.navier_stokes import solve_stokes

        if self.stokes:
            self.t += dt
            st = solve_stokes(self.problem, self.t, solver=self.solver)
            self.x = st.x
            self._res = None
        else:
            st = self.stepper.step()
            self.t = self.stepper.t
            self.x = st.x

    def get_state(self):
        if self.stokes:
            return {"t": self.t, "x": self.x.copy()}
        return self.stepper.get_state()

    def set_state(self, s):
        self.t = s["t"]
        self.x = s["x"].copy()
        if not self.stokes:
            self.stepper.set_state(s)


def _velocity_bcs(scene: Scene, centers):
    """Velocity conditions of the box sides and the bodies (rigid motion about ``centers`` (n, 2))."""
    from .fluid.space import RigidMotion, VelocityBC

    bcs = []
    for s in ("left", "right", "bottom", "top"):
        side = scene.domain.side(s)
        if side.type == "wall":
            bcs.append(VelocityBC(s, (0.0, 0.0)))
        elif side.type == "moving-wall":
            bcs.append(VelocityBC(s, side.velocity))
        elif side.type == "inflow":
            bcs.append(VelocityBC(s, _inflow_value(s, scene.domain.box, scene.domain.profile_of(s))))
    for b, c in zip(scene.bodies, centers):
        if b.motion == "fixed":
            bcs.append(VelocityBC(b.name, (0.0, 0.0)))
        else:
            bcs.append(VelocityBC(b.name, RigidMotion(b.velocity, b.omega, tuple(map(float, c)))))
    return bcs


def _p1_at_dofs(space, w_nodes: np.ndarray) -> np.ndarray:
    """Velocity coefficients (n_u,) of the piecewise linear field with vertex values ``w_nodes`` (n_vertices, 2).

    The mesh velocity is linear on each element (the mesh moves affinely), so every element
    pair represents it exactly: nodal DOFs take its point values, bubble DOFs zero.
    """
    ub, mesh = space.ub, space.mesh
    p, t = mesh.p, mesh.t
    ed = ub.element_dofs  # (Nbfun, n_elements)
    loc = ub.doflocs[:, ed]  # (2, Nbfun, n_elements)
    a, b, c = p[:, t[0]], p[:, t[1]], p[:, t[2]]
    d1, d2 = b - a, c - a
    det = d1[0] * d2[1] - d1[1] * d2[0]
    r = loc - a[:, None, :]
    l1 = (d2[1] * r[0] - d2[0] * r[1]) / det
    l2 = (-d1[1] * r[0] + d1[0] * r[1]) / det
    l0 = 1.0 - l1 - l2
    comp = np.zeros(ub.N, dtype=int)
    comp[ub.split_indices()[1]] = 1
    cd = comp[ed]
    wv = w_nodes.T  # (2, n_vertices)
    val = np.where(cd == 0, l0 * wv[0, t[0]] + l1 * wv[0, t[1]] + l2 * wv[0, t[2]],
                   l0 * wv[1, t[0]] + l1 * wv[1, t[1]] + l2 * wv[1, t[2]])
    out = np.zeros(ub.N)
    out[ed.ravel()] = np.nan_to_num(val.ravel(), nan=0.0)  # NaN locations: bubble DOFs
    return out


class _Outline:
    """A body outline for :class:`fluidem.mesh.MovingMesh`: ``vertices`` in body coordinates and ``name``."""

    def __init__(self, vertices, name):
        self.vertices = np.asarray(vertices, float)
        self.name = name


class _MovingMeshFlow(_FlowLoads):
    """The flow around prescribed bodies whose outlines move: ALE on :class:`fluidem.mesh.MovingMesh`.

    Each step the bodies move to their poses at t + dt, the mesh follows
    (``MovingMesh.update``), the flow problem is assembled on the new node positions and
    one BDF2 step is taken with the mesh velocity w in the convection, (u − w)·∇u.  While
    the connectivity is unchanged the velocity coefficients stay attached to the nodes
    (no interpolation); at a re-triangulation u^n and u^{n−1} are interpolated from the old
    mesh at time t onto the new nodes (:func:`fluidem.mesh.transfer.interpolate`), that step
    is Eulerian (w = 0), and the event is logged.  The history
    term uses the mass matrix of the new positions (not geometric-conservation exact; first
    order in the mesh motion per step).  Stokes is quasi-steady: one solve per step on the
    current mesh, no mesh velocity.  Outlines are polygons (straight edges).
    """

    def __init__(self, scene: Scene, sim: "Simulation"):
        from .fluid.navier_stokes import BDF2Stepper
        from .mesh import MovingMesh

        fl, ms = scene.fluid, scene.mesh
        self.scene = scene
        t0 = time.perf_counter()
        outlines = [_Outline(b.local_vertices(scene.default_segments(b)), b.name) for b in scene.bodies]
        self.path = [LinearPath(b.position, b.angle, b.velocity if b.motion != "fixed" else (0, 0),
                                b.omega if b.motion != "fixed" else 0.0) for b in scene.bodies]
        grading = None
        if ms.grading is not None:
            g = ms.grading
            region = g["region"] if g["region"] != "bodies" else scene.world_outlines()
            grading = {"region": region, "growth": g["growth"], "h_max": g["h_max"]}
        self.mm = MovingMesh(scene.domain.box, outlines, self._poses(0.0), ms.h, grading=grading,
                             strategy=ms.strategy, retriangulate_every=ms.retriangulate_every)
        sim.counters["triangulations"] += 1
        self.sim = sim
        self.mesh_time = time.perf_counter() - t0
        self.curved = False
        self.rho = fl.density
        self.stokes = fl.model == "stokes"
        self.names = [b.name for b in scene.bodies]
        self.t = 0.0
        self._build(0.0)
        if self.stokes:
            self.stepper = None
            self.x = self.problem.initial_vector(0.0)
        else:
            # the matrix changes every step on a moving mesh: a fresh LU each step
            self.stepper = BDF2Stepper(self.problem, scene.time.dt, convection=fl.convection,
                                       solver=self.problem.direct_solver(),
                                       mesh_velocity=np.zeros(self.space.n_u))
            self.x = self.stepper.state.x
        self.events = []
        sim.counters["fluid_solvers"] += 1

    def _poses(self, t):
        return np.array([[*p(t)[0], p(t)[1]] for p in self.path]).reshape(-1, 3)

    def _build(self, t):
        from .fluid.navier_stokes import FlowProblem
        from .fluid.space import FlowSpace

        fl = self.scene.fluid
        self.mesh = self.mm.skfem_mesh()
        self.space = FlowSpace(self.mesh, fl.element)
        self.centers = self._poses(t)[:, :2]
        self.problem = FlowProblem(self.space, fl.viscosity, _velocity_bcs(self.scene, self.centers), rho=fl.density,
                                   body_force=fl.body_force)

    @property
    def dofs(self):
        return self.space.n_dofs

    def step(self, dt):
        from .fluid.navier_stokes import FlowState, solve_stokes
        from .mesh import transfer

        t_new = self.t + dt
        t0 = time.perf_counter()
        ev = self.mm.update(self._poses(t_new))
        self.last_event = ev
        if ev.retriangulated:
            self.sim.counters["triangulations"] += 1
        self._build(t_new)
        self.mesh_seconds = time.perf_counter() - t0
        if self.stokes:
            self.t = t_new
            self.x = solve_stokes(self.problem, t_new).x
            return
        st = self.stepper
        n_u = self.space.n_u
        if ev.retriangulated:
            from skfem import Basis, ElementVector, MeshTri

            # the old connectivity at the old positions (time t): the interpolation to the new
            # nodes at t + dt is Eulerian, so this step has no mesh velocity
            src = ev.prev_points if ev.prev_points is not None else ev.old_points
            old = MeshTri(np.asarray(src, float).T.copy(), np.asarray(ev.old_triangles).T.copy())
            ob = Basis(old, ElementVector(self.space.pair.velocity()))
            u_n = transfer.interpolate(ob, st.state.u, self.space.ub)
            u_p = None if st._u_prev is None else transfer.interpolate(ob, st._u_prev, self.space.ub)
            self.sim.counters["transfers"] = self.sim.counters.get("transfers", 0) + 1
        else:
            u_n, u_p = st.state.u, st._u_prev
        x = np.zeros(self.space.n_dofs)
        x[:n_u] = u_n
        st.problem = self.problem
        st.state = FlowState(x, n_u, self.t)
        st._u_prev = u_p
        st.mesh_velocity = (np.zeros(n_u) if ev.retriangulated
                            else _p1_at_dofs(self.space, self.mm.node_velocity(dt)))
        st.step()
        self.t = st.t
        self.x = st.state.x

    def get_state(self):
        s = {"t": self.t, "x": self.x.copy(), "mm": self.mm}
        if self.stepper is not None:
            s["stepper"] = self.stepper.get_state()
        return s

    def set_state(self, s):
        self.mm = s["mm"]
        self.t = s["t"]
        self._build(self.t)
        self.x = s["x"].copy()
        if self.stepper is not None:
            self.stepper.problem = self.problem
            self.stepper.set_state(s["stepper"])


# ---------------------------------------------------------------------------------------
# the driver
# ---------------------------------------------------------------------------------------
class Simulation:
    """Run a :class:`~fluidem.scene.Scene`, building only what its plan needs.

    Parameters
    ----------
    scene : Scene or str or Path
        A scene or the path of a TOML scene file.

    Attributes
    ----------
    plan : Plan
    counters : dict
        Parts built and work done: ``triangulations``, ``fluid_solvers``, ``dem``,
        ``steps``, ``dem_substeps``.
    flow : object or None
        The fluid part (``None`` for a dry scene).

    Raises
    ------
    ValueError
        A scene this version cannot run (free bodies in a fluid, translating bodies in an
        unsteady fluid, periodic sides), with the reason.

    Examples
    --------
    >>> from fluidem import scene, simulation
    >>> s = scene.Scene.from_dict({"gravity": [0, -10], "domain": {"box": [0, 1, 0, 1]},
    ...     "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.8]}],
    ...     "time": {"dt": 0.01, "t_end": 0.1}})
    >>> sim = simulation.Simulation(s)
    >>> r = sim.run(out_dir=None)
    >>> round(float(sim.bodies.positions[0, 1]), 6)   # 0.8 - 10 * 0.1**2 / 2
    0.75
    """

    def __init__(self, scene):
        if not isinstance(scene, Scene):
            scene = Scene.from_toml(scene)
        self.scene = scene
        self.plan = scene.plan()
        if self.plan.unsupported:
            raise ValueError("this scene cannot run yet: " + "; ".join(self.plan.unsupported))
        self.counters = {"triangulations": 0, "fluid_solvers": 0, "dem": 0, "steps": 0, "dem_substeps": 0}
        self.step_index = 0
        self.t = 0.0
        self.flow = None
        self.events = [("built", f"plan: mesh {self.plan.mesh}, contacts {self.plan.on('contacts')}")]
        if self.plan.on("contacts") and scene.fluid is None:
            self.bodies = _DEMBodies(scene)
            self.counters["dem"] += 1
        else:
            self.bodies = _Kinematic(scene)
        if scene.fluid is not None:
            if self.plan.mesh == "moving":
                self.flow = _MovingMeshFlow(scene, self)
            else:
                self.flow = _FixedMeshFlow(scene, self)
            self.events.append(("mesh", ("moving, initial: " if self.plan.mesh == "moving" else "built once: ")
                                + f"{self.flow.mesh.t.shape[1]} triangles, "
                                        f"{self.flow.dofs} DOFs, {'curved' if self.flow.curved else 'polygonal'}"))

    # -- state ------------------------------------------------------------------------------
    def _state(self) -> dict:
        return {"bodies": self.bodies.get_state(), "flow": self.flow.get_state() if self.flow else None,
                "scene": self.scene.to_dict(), "counters": dict(self.counters)}

    def restore(self, checkpoint) -> None:
        """Continue from a checkpoint file or output directory (its newest checkpoint)."""
        from .io import load_checkpoint

        data = load_checkpoint(checkpoint)
        if data["scene"] != self.scene.to_dict():
            diff = [k for k in data["scene"] if data["scene"][k] != self.scene.to_dict().get(k)]
            allowed = {"time", "output"}
            if set(diff) - allowed:
                raise ValueError(f"checkpoint {str(checkpoint)!r} belongs to a different scene (tables differ: "
                                 f"{', '.join(sorted(set(diff) - allowed))}); allowed changes: time.t_end, output")
        self.bodies.set_state(data["bodies"])
        if self.flow is not None:
            self.flow.set_state(data["flow"])
        self.step_index = int(data["step"])
        self.t = float(data["t"])

    def _record(self, writer, fields: bool, last: bool = False):
        b = self.bodies
        F, T, cnt = b.loads()
        tl = time.perf_counter()
        if self.flow is not None and len(self.scene.bodies) and self.step_index > 0:
            F, T = self.flow.loads()  # at step 0 the flow is only its initial data: no loads
        t_loads = time.perf_counter() - tl
        self.last_loads = (F, T)
        if writer is None:
            return t_loads
        sc = self.scene
        if self.step_index % sc.output.history_every == 0 or last:
            writer.history(self.step_index, self.t, b.positions, b.angles, b.velocities, b.omegas, F, T, cnt)
        if fields:
            pos, ang = b.positions, b.angles
            outlines = [sb.world_vertices(sc.default_segments(sb), pos[k], ang[k]) for k, sb in enumerate(sc.bodies)]
            if outlines:
                writer.bodies(self.step_index, self.t, outlines, b.velocities, b.omegas)
            if self.flow is not None and sc.output.fields:
                from .io import fluid_point_data

                m = self.flow.mesh
                writer.fields(self.step_index, self.t, m.p[:, :m.nvertices].T, _ccw(m), fluid_point_data(self.flow.space, self.flow.x))
        return t_loads

    # -- running ---------------------------------------------------------------------------------
    def run(self, out_dir="scene", restart=None, progress=None, n_steps: int | None = None) -> RunResult:
        """Step to ``time.t_end`` (or ``n_steps`` steps in total), writing output to ``out_dir``.

        Parameters
        ----------
        out_dir : str, Path or None
            Output directory; ``"scene"`` takes ``[output] dir``; ``None`` writes nothing.
        restart : str, Path or True, optional
            Continue from a checkpoint file, or from the newest checkpoint in ``out_dir``
            (``True``); the history is cut back to the checkpoint and continued.
        progress : callable, optional
            ``progress(step, n_steps, t, StepTimes)`` after every step.
        n_steps : int, optional
            Stop after this many steps in total (the plan's ``round(t_end/dt)`` by default).
        """
        from .io import OutputWriter

        sc = self.scene
        if out_dir == "scene":
            out_dir = sc.output.dir
        if restart is not None and restart is not False:
            if restart is True:
                if out_dir is None:
                    raise ValueError("restart = True needs an output directory with checkpoints")
                restart = out_dir
            self.restore(restart)
        writer = None
        if out_dir is not None:
            writer = OutputWriter(out_dir, restart_step=self.step_index if restart else None)
            if not restart:
                _write_scene_toml(sc, Path(out_dir) / "scene.toml")
                for kind, msg in self.events:
                    writer.event(0, 0.0, kind, msg)
                if self.flow is not None:
                    from .mesh.quality import mesh_quality

                    writer.mesh_quality(0, 0.0, mesh_quality(self.flow.mesh.p[:, :self.flow.mesh.nvertices].T, _ccw(self.flow.mesh)))
            else:
                writer.event(self.step_index, self.t, "restart", f"from {restart}")
        N = self.plan.n_steps if n_steps is None else int(n_steps)
        dt = sc.time.dt
        ev, ck = sc.output.every, sc.output.checkpoint_every
        totals = StepTimes()
        wall0 = time.perf_counter()
        try:
            if self.step_index == 0 and writer is not None:
                self._record(writer, fields=True)
            while self.step_index < N:
                st = StepTimes()
                t0 = time.perf_counter()
                self.bodies.step(dt)
                st.bodies = time.perf_counter() - t0
                if self.flow is not None:
                    t0 = time.perf_counter()
                    self.flow.step(dt)
                    st.fluid = time.perf_counter() - t0
                    ev_mesh = getattr(self.flow, "last_event", None)
                    if ev_mesh is not None:
                        st.mesh = self.flow.mesh_seconds
                        st.fluid -= st.mesh
                        if writer is not None:
                            if ev_mesh.retriangulated:
                                writer.event(self.step_index + 1, self.t + dt, "retriangulation",
                                             f"reason={ev_mesh.reason} nodes={ev_mesh.n_nodes} "
                                             f"triangles={ev_mesh.n_triangles}; fields transferred by interpolation"
                                             if self.scene.fluid.model != "stokes" else f"reason={ev_mesh.reason}")
                            if len(ev_mesh.oscillating):
                                writer.event(self.step_index + 1, self.t + dt, "oscillation",
                                             f"{len(ev_mesh.oscillating)} oscillating nodes")
                self.step_index += 1
                self.counters["steps"] += 1
                self.t = self.step_index * dt
                t0 = time.perf_counter()
                last = self.step_index == N
                st.loads = self._record(writer, fields=(self.step_index % ev == 0 or last), last=last)
                if writer is not None and self.plan.mesh == "moving" and (self.step_index % ev == 0 or last):
                    writer.mesh_quality(self.step_index, self.t, self.flow.mm.quality())
                if writer is not None and ((ck and self.step_index % ck == 0) or last):
                    writer.checkpoint(self.step_index, self.t, self._state())
                st.output = time.perf_counter() - t0 - st.loads
                for k in ("bodies", "mesh", "fluid", "loads", "output"):
                    setattr(totals, k, getattr(totals, k) + getattr(st, k))
                if progress is not None:
                    progress(self.step_index, N, self.t, st)
        finally:
            if writer is not None:
                writer.event(self.step_index, self.t, "end", f"{self.counters['steps']} steps this run")
                writer.close()
        if isinstance(self.bodies, _DEMBodies):
            self.counters["dem_substeps"] = self.bodies.substeps
        return RunResult(self.step_index, self.t, None if out_dir is None else str(out_dir),
                         time.perf_counter() - wall0, self.flow.dofs if self.flow else 0, totals,
                         ("curved" if self.flow.curved else "polygonal") if self.flow else "")


def _ccw(mesh) -> np.ndarray:
    """Triangles (m, 3) of a scikit-fem mesh, counter-clockwise (scikit-fem sorts vertex indices)."""
    p, t = mesh.p, mesh.t.T.copy()
    a, b, c = p[:, t[:, 0]], p[:, t[:, 1]], p[:, t[:, 2]]
    neg = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) < 0
    t[neg] = t[neg][:, [0, 2, 1]]
    return t


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    return repr(float(v)) if isinstance(v, float) else str(v)


def _write_scene_toml(scene: Scene, path: Path):
    """The scene as run, as TOML (bodies inline; re-readable by Scene.from_toml)."""
    d = scene.to_dict()
    lines = [f"name = {_toml_value(d.pop('name'))}", f"description = {_toml_value(d.pop('description'))}",
             f"gravity = {_toml_value(d.pop('gravity'))}"]
    bodies = d.pop("bodies")
    for key, tab in d.items():
        lines.append(f"\n[{key}]")
        for k, v in tab.items():
            if isinstance(v, dict) and "type" in v and key == "domain":
                v = {kk: vv for kk, vv in v.items() if not (kk == "profile" and vv is None)}
            lines.append(f"{k} = {_toml_value(v)}")
    for b in bodies:
        lines.append("\n[[bodies]]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in b.items()]
    path.write_text("\n".join(lines) + "\n")


def run(scene, out_dir="scene", restart=None, progress=None) -> RunResult:
    """Build a :class:`Simulation` for ``scene`` (a Scene or a TOML path) and run it."""
    return Simulation(scene).run(out_dir=out_dir, restart=restart, progress=progress)
