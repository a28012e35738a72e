"""The flow around bodies whose outlines do not move: one mesh, one FlowProblem for the run."""

from __future__ import annotations

from time import perf_counter

from ..cost import CostSplit
from .boundary import periodic_axes_of, velocity_bcs, viscous_form_of
from .loads import FlowLoads

__all__ = ["FixedMeshFlow"]


class FixedMeshFlow(FlowLoads):
    """Stokes or Navier–Stokes (BDF2) on a mesh built once.

    Parameters
    ----------
    bodies : list of fluidem.scene.BodySpec
        The bodies (names, shapes, poses, motions), each a hole in the mesh.
    outlines : list of (k, 2) float
        Every body's outline in body coordinates, length.
    domain : fluidem.scene.DomainSpec
        The box and its sides.
    fluid : fluidem.scene.FluidSpec
    mesh : fluidem.scene.MeshSpec
        Mesh size, grading and whether disks get curved edges.
    time : fluidem.scene.TimeSpec
        The step ``dt`` and the BDF scheme.
    sim : fluidem.simulation.Simulation
        Its ``counters`` are charged (``triangulations``, ``fluid_solvers``): any object with a
        ``counters`` dict.

    Attributes
    ----------
    periodic : tuple of {"x", "y"}
        Periodic axes of the box (matched mesh nodes, identified DOFs).
    mesh : skfem.MeshTri or MeshTri2
    space : FlowSpace
    problem : FlowProblem
    stepper : BDFStepper or None (Stokes)
    rigid : RigidModes
        Loads operator of the body outlines about their (fixed) centres.
    last_cost : CostSplit
        ``assembly`` and ``solve`` seconds of the last step.
    """

    def __init__(self, bodies, outlines, *, domain, fluid, mesh, time, sim):
        from .. import geometry as geo
        from ..fluid.forces import RigidModes
        from ..fluid.navier_stokes import BDFStepper, FlowProblem
        from ..fluid.solvers import make_solver
        from ..fluid.space import FlowSpace
        from ..mesh import triangulate as tri
        from ..mesh.background import GradedSize, UniformSize

        fl, ms, time_spec = fluid, mesh, time
        t0 = perf_counter()
        obstacles = []
        for b, v in zip(bodies, outlines):
            outline = geo.transform(v, b.position, b.angle)
            circle = (*b.position, b.radius) if (b.shape == "disk" and ms.curved) else None
            obstacles.append(tri.Obstacle(outline, b.name, circle=circle, refine_outline=b.shape != "disk"))
        if ms.grading is None:
            size = UniformSize(ms.h)
        else:
            g = ms.grading
            region = g["region"] if g["region"] != "bodies" else [o.vertices for o in obstacles]
            size = GradedSize(h_min=ms.h, growth=g["growth"], h_max=g["h_max"], region=region) if region else \
                UniformSize(ms.h)
        self.periodic = periodic_axes_of(domain)
        tmesh = tri.triangulate_box(domain.box, obstacles, size, periodic=self.periodic)
        self.curved = bool(tmesh.circles)
        self.mesh = tri.to_skfem(tmesh, curved=self.curved)
        sim.counters["triangulations"] += 1
        self.mesh_time = perf_counter() - t0
        self.space = FlowSpace(self.mesh, fl.element)
        bcs = velocity_bcs(domain, bodies, [b.position for b in bodies])
        self.rho = fl.density
        self.problem = FlowProblem(self.space, fl.viscosity, bcs, rho=fl.density, body_force=fl.body_force,
                                   periodic=self.periodic, viscous=viscous_form_of(bodies))
        self.problem.lu_backend = getattr(fl, "lu_backend", "auto")
        self.stokes = fl.model == "stokes"
        self.centers = [b.position for b in bodies]
        self.names = [b.name for b in bodies]
        self.rigid = RigidModes(self.space, self.names, self.centers)
        # solver names mean what the solver factory says (fluidem.fluid.solvers.make_solver):
        # "auto" on a run of time steps is an LU reused as a GMRES preconditioner across steps
        # (2-7 iterations, 5-20x cheaper per step than a fresh LU); "direct" a fresh LU every
        # step, for runs that must restart bit for bit
        if self.stokes:
            # the Stokes matrix of a fixed mesh never changes: a run of identical systems
            self.solver = make_solver(fl.solver, problem=self.problem, kind="unsteady")
            self.stepper = None
            self.x = self.problem.initial_vector(0.0)
        else:
            solver = make_solver(fl.solver, problem=self.problem, dt=time_spec.dt)
            order = 3 if time_spec.bdf_scheme(moving_mesh=False) == "bdf3" else 2
            self.stepper = BDFStepper(self.problem, time_spec.dt, convection=fl.convection, solver=solver,
                                      order=order)
            self.x = self.stepper.state.x
        self.t = 0.0
        self.last_cost = CostSplit()
        sim.counters["fluid_solvers"] += 1

    @property
    def dofs(self):
        return self.space.n_dofs

    def step(self, dt):
        """One step of length ``dt`` (``time.dt``); charges ``assembly`` and ``solve`` to ``last_cost``."""
        from ..fluid.navier_stokes import solve_stokes

        t0 = perf_counter()
        solve0 = self.problem.timings.solve
        if self.stokes:
            self.t += dt
            st = solve_stokes(self.problem, self.t, solver=self.solver)
            self.x = st.x
        else:
            st = self.stepper.step()
            self.t = self.stepper.t
            self.x = st.x
        wall = perf_counter() - t0
        solve = self.problem.timings.solve - solve0
        self.last_cost = CostSplit({"assembly": wall - solve, "solve": solve})

    def get_state(self):
        if self.stokes:
            return {"t": self.t, "x": self.x.copy()}
        return self.stepper.get_state()

    def set_state(self, s):
        self.t = s["t"]
        self.x = s["x"].copy()
        if not self.stokes:
            self.stepper.set_state(s)
