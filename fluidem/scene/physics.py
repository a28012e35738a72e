"""The physics of a scene: the fluid (:class:`FluidSpec`) and the contact law between bodies
(:class:`ContactSpec`).

Units: none built in; every value is in the one consistent system the user picks (see
:mod:`fluidem.scene`).  Every user-typed name goes through :mod:`fluidem.names` and is
stored canonically; every bad value raises :class:`fluidem.errors.SceneError` (a
``ValueError``) in the one format of :mod:`fluidem.validate`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .. import names
from ..errors import SceneError
from ..validate import boolean, nonnegative, pair, positive

__all__ = ["FluidSpec", "ContactSpec"]


@dataclass
class FluidSpec:
    """The fluid (2D, per unit depth; units: see :mod:`fluidem.scene`).

    Every name is looked up in :mod:`fluidem.names` and stored canonically (an alias such as
    ``solver = "lagged-lu"`` is stored as ``"lagged"``).

    Parameters
    ----------
    density : float
        ρ, mass/length² (a 3D density times the unit depth), > 0.  Forces on bodies are ρ
        times the kinematic ones.
    viscosity : float
        *Kinematic* viscosity ν = μ/ρ, length²/time, > 0 (the dynamic viscosity is
        ``density * viscosity``).
    model : {"navier-stokes", "stokes"}
        Unsteady incompressible Navier–Stokes (BDF2) or quasi-steady Stokes (no inertia).
    body_force : (2,) float
        Per unit mass, length/time².
    element : {"p2b", "th", "p3", "mini"}
        Velocity/pressure element pair (:mod:`fluidem.fluid.elements`).
    convection : {"semi-implicit", "newton", "explicit"}
        Treatment of the convection term by the unsteady solver.
    solver : {"auto", "direct", "iterative", "lagged"}
        Linear solver by name (alias ``"lagged-lu"`` = ``"lagged"``); what each name, and
        ``"auto"`` in particular, means is the solver factory's
        (:func:`fluidem.fluid.solvers.make_solver`), not the scene's.  ``"direct"``
        (a fresh LU every step) makes restarts reproduce bit for bit; an LU reused as a GMRES
        preconditioner reproduces them only to the GMRES tolerance.
    ale_form : {"non-conservative", "conservative"}
        Moving meshes: the ALE form of the time derivative and the convection
        (:class:`fluidem.fluid.navier_stokes.BDF2Stepper`).  ``"non-conservative"`` keeps a
        uniform flow to round-off on any mesh motion (its discrete GCL is exact);
        ``"conservative"`` keeps the momentum of fluid and free bodies to solver tolerance
        where the boundary carries none (a periodic box), with re-triangulations corrected to
        conserve it too, at 1.9× the velocity error of the default form on the moving
        Taylor–Green test; semi-implicit convection only.
    coupling : {"implicit", "explicit"}
        Free bodies: ``"implicit"`` solves fluid and bodies together every step
        (:mod:`fluidem.coupling.free_bodies`); ``"explicit"`` moves the bodies by the fluid
        forces of the last step and then solves the fluid (staggered), unstable when the
        fluid's added mass exceeds the body mass (density ratio ≲ 1 for a disk).
    zero_net_flux : bool
        Periodic sedimentation (Stokes, free bodies, gravity through a periodic pair): the mean
        pressure gradient G that keeps the volume flux through the periodic sides zero acts on
        the fluid (−G per unit volume) *and* on every body (−G A, the pressure's force on its
        volume) and is solved for with the flow (:mod:`fluidem.coupling.mean_gradient`); in a
        doubly periodic cell of free bodies G |Ω| = Σ (ρ_s − ρ_f) A g.  Carrying the weight by a
        ``body_force`` on the fluid alone makes the bodies settle 1/(1 − φ) too fast.
    lu_backend : {"auto", "superlu", "pardiso"}
        The sparse LU of the direct and lagged solvers: ``"auto"`` uses Intel MKL PARDISO
        (the optional ``pypardiso``) for systems of 20 000 DOFs and more when it is installed
        (4.3x faster factorisations than SuperLU with a quarter of the memory at 149k DOFs,
        ``benchmarks/results/solver_scale.md``), SuperLU otherwise.  ``"pardiso"`` without
        ``pypardiso`` is refused.
    """

    density: float = 1.0
    viscosity: float = 0.01
    model: str = "navier-stokes"
    body_force: tuple = (0.0, 0.0)
    element: str = "p2b"
    convection: str = "semi-implicit"
    solver: str = "auto"
    coupling: str = "implicit"
    ale_form: str = "non-conservative"
    zero_net_flux: bool = False
    lu_backend: str = "auto"

    KEYS = ("density", "viscosity", "model", "body_force", "element", "convection", "solver", "coupling", "ale_form",
            "zero_net_flux", "lu_backend")

    def validate(self, where="fluid"):
        """Check and convert every value (names made canonical); ``SceneError`` names the first bad one."""
        self.density = positive(f"{where}.density", self.density, error=SceneError)
        self.viscosity = positive(f"{where}.viscosity", self.viscosity, error=SceneError)
        self.model = names.lookup("fluid model", self.model, f"{where}.model", SceneError)
        self.body_force = pair(f"{where}.body_force", self.body_force, error=SceneError)
        self.element = names.lookup("element", self.element, f"{where}.element", SceneError)
        self.convection = names.lookup("convection", self.convection, f"{where}.convection", SceneError)
        self.solver = names.lookup("solver", self.solver, f"{where}.solver", SceneError)
        self.coupling = names.lookup("coupling", self.coupling, f"{where}.coupling", SceneError)
        self.ale_form = names.lookup("ALE form", self.ale_form, f"{where}.ale_form", SceneError)
        self.zero_net_flux = boolean(f"{where}.zero_net_flux", self.zero_net_flux, error=SceneError)
        self.lu_backend = names.lookup("LU backend", self.lu_backend, f"{where}.lu_backend", SceneError)
        if self.lu_backend == "pardiso":
            from ..fluid.solvers.pardiso import pardiso_available

            if not pardiso_available():
                raise SceneError(f"{where}.lu_backend = 'pardiso' needs the optional package pypardiso "
                                 "(pip install 'fluidem[pardiso]'); 'auto' uses it when it is installed")
        if self.ale_form == "conservative" and self.convection != "semi-implicit":
            raise SceneError(f"{where}.ale_form = 'conservative' with {where}.convection = {self.convection!r}: "
                             "the conservative form needs convection = 'semi-implicit'")



@dataclass
class ContactSpec:
    """Contact law of :class:`fluidem.dem.ContactModel`.

    Parameters
    ----------
    E : float
        2D stiffness of the overlap law ``F = E A / l`` (overlap area A, characteristic
        length l), force/length (forces per unit depth), > 0.
    mu : float
        Coulomb friction coefficient, ≥ 0.
    gamma : float
        Normal damping coefficient (dimensionless), ≥ 0.
    enabled : bool
        ``false`` switches contacts off whatever the geometry.
    repulsion_range : float or None
        Fluid scenes: cut-off distance ρ of the short-range repulsion between outlines
        (:mod:`fluidem.dem.repulsion`, Glowinski et al. 2001), length, > 0; ``None`` takes
        ``0.01 · mesh.h``: a backstop well below the gaps whose film the mesh resolves
        (``benchmarks/results/narrow_gap.md``).
    repulsion_force : float or None
        Fluid scenes: its force scale c, force (per unit depth), ≥ 0 (0: no repulsion);
        ``None`` takes the largest buoyant weight |ρ_s − ρ_f| A |g| of a free body.
    repulsion_epsilon : float or None
        Fluid scenes: its stiffness ε, > 0 (force c/ε at contact; a body pressed by c rests
        at the gap ρ(1 − √ε)); ``None`` takes ``1e-4 · mesh.h / ρ``, which keeps the stiffness at
        contact, 2c/(ερ), and so the DEM sub-step, those of ε = 1e-4 at ρ = h.
    lubrication : bool
        Fluid scenes with inertia: the lubrication correction between outlines (and from walls)
        closer than ``lubrication_range``, the 2D squeeze-film force sub-stepped with the gap
        (:mod:`fluidem.dem.lubrication`, :mod:`fluidem.coupling.contacts`).
    lubrication_range : float or None
        Its cut-off g_c, length, > 0; ``None`` takes ``mesh.h``.
    lubrication_resolved_gap : float or None
        The mesh's resolved-film length δ_r, length, ≥ 0 (0: no correction): add only the part of
        the film force the mesh misses quasi-statically (the element's measured value is
        :data:`fluidem.coupling.contacts.RESOLVED_FILM` times ``mesh.h``); ``None`` adds the
        whole law less its value at the cut-off.
    """

    E: float = 1e7
    mu: float = 0.23
    gamma: float = 0.025
    enabled: bool = True
    repulsion_range: float | None = None
    repulsion_force: float | None = None
    repulsion_epsilon: float | None = None
    lubrication: bool = True
    lubrication_range: float | None = None
    lubrication_resolved_gap: float | None = None

    KEYS = ("E", "mu", "gamma", "enabled", "repulsion_range", "repulsion_force", "repulsion_epsilon", "lubrication",
            "lubrication_range", "lubrication_resolved_gap")

    def validate(self, where="contact"):
        self.E = positive(f"{where}.E", self.E, error=SceneError)
        self.mu = nonnegative(f"{where}.mu", self.mu, error=SceneError)
        self.gamma = nonnegative(f"{where}.gamma", self.gamma, error=SceneError)
        self.enabled = boolean(f"{where}.enabled", self.enabled, error=SceneError)
        if self.repulsion_range is not None:
            self.repulsion_range = positive(f"{where}.repulsion_range", self.repulsion_range, error=SceneError)
        if self.repulsion_force is not None:
            self.repulsion_force = nonnegative(f"{where}.repulsion_force", self.repulsion_force, error=SceneError)
        if self.repulsion_epsilon is not None:
            self.repulsion_epsilon = positive(f"{where}.repulsion_epsilon", self.repulsion_epsilon, error=SceneError)
        self.lubrication = boolean(f"{where}.lubrication", self.lubrication, error=SceneError)
        if self.lubrication_range is not None:
            self.lubrication_range = positive(f"{where}.lubrication_range", self.lubrication_range, error=SceneError)
        if self.lubrication_resolved_gap is not None:
            self.lubrication_resolved_gap = nonnegative(f"{where}.lubrication_resolved_gap",
                                                        self.lubrication_resolved_gap, error=SceneError)

