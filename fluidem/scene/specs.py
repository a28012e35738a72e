"""The scene description: spec dataclasses for the domain, fluid, bodies, contacts, mesh,
time and output, and :class:`Scene` that holds them, validates them and hands out its plan.

Units: none built in; every value is in the one consistent system the user picks (see
:mod:`fluidem.scene`).  Every user-typed name goes through :mod:`fluidem.names` and is
stored canonically; every bad value raises :class:`fluidem.errors.SceneError` (a
``ValueError``) in the one format of :mod:`fluidem.validate`.
"""

from __future__ import annotations

import copy
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import geometry as geo
from .. import names
from ..errors import InputError, SceneError
from ..validate import boolean, check_keys, fail, integer, nonnegative, number, pair, positive
from . import files

if TYPE_CHECKING:  # pragma: no cover
    from ..plan import Plan

__all__ = ["Scene", "FluidSpec", "DomainSpec", "SideSpec", "BodySpec", "ContactSpec", "MeshSpec", "TimeSpec",
           "OutputSpec", "default_h", "MAX_SEGMENTS", "MAX_COORDINATE"]

#: most outline vertices of a disk or ellipse (``segments``): a disk of radius r in a mesh of size h
#: needs about 2πr/h, so 100000 is a mesh of more than 1e9 triangles, far beyond one machine
MAX_SEGMENTS = 100_000
#: largest |coordinate| of the box, and 1 / the shortest side (lengths to the fourth power stay in double range)
MAX_COORDINATE = 1e50


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

    KEYS = ("density", "viscosity", "model", "body_force", "element", "convection", "solver", "coupling", "ale_form",
            "zero_net_flux")

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
        if self.ale_form == "conservative" and self.convection != "semi-implicit":
            raise SceneError(f"{where}.ale_form = 'conservative' with {where}.convection = {self.convection!r}: "
                             "the conservative form needs convection = 'semi-implicit'")


@dataclass
class SideSpec:
    """One side of the box.

    Parameters
    ----------
    type : {"wall", "inflow", "outflow", "periodic", "moving-wall"}
        ``names.meaning("side type", type)`` says what each is.  ``"periodic"`` sides come in
        pairs (``left`` with ``right``, ``bottom`` with ``top``): the mesh has matching nodes
        on both and the fluid DOFs there are identified (:mod:`fluidem.mesh.periodic`,
        :mod:`fluidem.fluid.periodic`); ``fluid.body_force`` (a mean pressure gradient G is
        ``body_force = −G / density``) or moving walls drive the flow.  Bodies must be narrower
        than the period and must not overlap a periodic side (on a moving mesh: stay at least
        ``mesh.h`` away from it).
    velocity : (2,) float
        Wall velocity of a ``"moving-wall"`` side, length/time (zero on every other type).
    profile : dict or None
        Inflow profile of this side; ``None``: the domain's ``inflow_profile``.
    """

    type: str = "wall"
    velocity: tuple = (0.0, 0.0)
    profile: dict | None = None

    KEYS = ("type", "velocity", "profile")


@dataclass
class DomainSpec:
    """The box ``(xmin, xmax, ymin, ymax)`` (length) and what each side is.

    Sides are named and ordered as ``names.choices("side")``: bottom (y = ymin), right
    (x = xmax), top (y = ymax), left (x = xmin).

    ``inflow_profile`` is ``{type = "parabolic" | "uniform", umax = U, ramp = T}``: the
    inflow speed normal to an inflow side (parabolic: ``4 U s (L − s) / L²`` along the
    side, ``U`` in length/time), raised smoothly from 0 over ``ramp`` time units (``0``: at once).
    """

    box: tuple = (0.0, 1.0, 0.0, 1.0)
    bottom: SideSpec = field(default_factory=SideSpec)
    right: SideSpec = field(default_factory=SideSpec)
    top: SideSpec = field(default_factory=SideSpec)
    left: SideSpec = field(default_factory=SideSpec)
    inflow_profile: dict | None = None

    KEYS = ("box",) + names.choices("side") + ("inflow_profile",)
    #: keys of an inflow profile table (``inflow_profile`` or a side's ``profile``)
    PROFILE_KEYS = ("type", "umax", "ramp")

    def side(self, name) -> SideSpec:
        """The :class:`SideSpec` of side ``name`` (a name of ``names.choices("side")``)."""
        return getattr(self, names.lookup("side", name, "side", SceneError))

    def profile_of(self, name) -> dict:
        """The inflow profile of side ``name``: its own, else the domain's ``inflow_profile``."""
        s = self.side(name)
        return s.profile if s.profile is not None else self.inflow_profile

    def validate(self, where="domain"):
        """Check the box, every side and the profiles; ``SceneError`` names the first bad value."""
        b = self.box
        if (not isinstance(b, (list, tuple, np.ndarray)) or len(b) != 4
                or not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                           and math.isfinite(float(v)) for v in b)
                or not (b[1] > b[0] and b[3] > b[2])):
            raise fail(f"{where}.box", b, "[xmin, xmax, ymin, ymax], finite, with xmax > xmin and ymax > ymin",
                       SceneError)
        if max(abs(float(v)) for v in b) > MAX_COORDINATE or min(b[1] - b[0], b[3] - b[2]) < 1.0 / MAX_COORDINATE:
            raise fail(f"{where}.box", list(b), f"coordinates of magnitude at most {MAX_COORDINATE:g} and sides at "
                       f"least {1.0 / MAX_COORDINATE:g} long (squares and fourth powers of lengths must stay finite "
                       "and nonzero in double precision; pick a unit that fits)", SceneError)
        self.box = tuple(float(v) for v in b)
        for s in names.choices("side"):
            side = getattr(self, s)
            if isinstance(side, str):
                side = SideSpec(side)
            elif isinstance(side, dict):
                check_keys(side, SideSpec.KEYS, f"{where}.{s}", error=SceneError)
                side = SideSpec(**side)
            if not isinstance(side, SideSpec):
                raise fail(f"{where}.{s}", side, "a side type string or a table {type = ..., velocity = ...}",
                           SceneError)
            side.type = names.lookup("side type", side.type,
                                     f"{where}.{s}" if isinstance(getattr(self, s), str) else f"{where}.{s}.type",
                                     SceneError)
            side.velocity = pair(f"{where}.{s}.velocity", side.velocity, error=SceneError)
            if side.type != "moving-wall" and any(side.velocity):
                raise fail(f"{where}.{s}.velocity", list(side.velocity),
                           f"no velocity on a {side.type!r} side (only a 'moving-wall' moves)", SceneError)
            if side.profile is not None:
                side.profile = self._check_profile(f"{where}.{s}.profile", side.profile)
            setattr(self, s, side)
        if self.inflow_profile is not None:
            self.inflow_profile = self._check_profile(f"{where}.inflow_profile", self.inflow_profile)
        for s in names.choices("side"):
            if getattr(self, s).type == "inflow" and self.profile_of(s) is None:
                raise SceneError(f"{where}.{s} = 'inflow' has no profile: add {where}.inflow_profile = "
                                 f"{{ type = 'parabolic', umax = ... }} (allowed types: "
                                 f"{', '.join(names.choices('profile'))})")
        for a, b_ in (("left", "right"), ("bottom", "top")):
            pa, pb = getattr(self, a).type == "periodic", getattr(self, b_).type == "periodic"
            if pa != pb:
                one, other = (a, b_) if pa else (b_, a)
                raise SceneError(f"{where}.{one} = 'periodic' but {where}.{other} = {getattr(self, other).type!r}: "
                                 f"periodic sides come in pairs; allowed: both {a} and {b_} 'periodic' or neither")

    @staticmethod
    def _check_profile(key, prof):
        if not isinstance(prof, dict):
            raise fail(key, prof, "a table { type = 'parabolic' | 'uniform', umax = ..., ramp = ... }", SceneError)
        check_keys(prof, DomainSpec.PROFILE_KEYS, key, error=SceneError)
        out = {"type": names.lookup("profile", prof.get("type", "parabolic"), f"{key}.type", SceneError)}
        if "umax" not in prof:
            raise SceneError(f"{key} has no umax: the inflow speed is required (a finite number, length/time)")
        out["umax"] = number(f"{key}.umax", prof["umax"], error=SceneError)
        out["ramp"] = nonnegative(f"{key}.ramp", prof.get("ramp", 0.0), error=SceneError)
        return out


@dataclass
class BodySpec:
    """One rigid body.

    Parameters
    ----------
    shape : {"disk", "polygon", "rectangle", "ellipse"}
        ``disk``: ``radius``, ``segments``; ``polygon``: ``vertices`` (n, 2) in body
        coordinates (shifted so that their area centroid is the origin), counter-clockwise,
        convex; ``rectangle``: ``width``, ``height``; ``ellipse``: semi-axes ``a``, ``b``,
        ``segments``.  Every size is a length.
    position : (2,) float
        Centre of mass, length.
    angle : float
        Orientation, rad.
    density : float
        Areal density, mass/length² (as the fluid's ``density``).
    motion : {"free", "fixed", "prescribed"}
        ``prescribed`` bodies move with constant ``velocity`` (2,) and ``omega`` (rad/time).
    velocity, omega
        Initial (free) or prescribed (prescribed) velocity (2,), length/time, and angular
        velocity, rad/time.
    name : str
        Boundary name of its outline on the mesh; default ``body<i>``.
    """

    shape: str = "disk"
    radius: float | None = None
    segments: int | None = None
    vertices: list | None = None
    width: float | None = None
    height: float | None = None
    a: float | None = None
    b: float | None = None
    position: tuple = (0.0, 0.0)
    angle: float = 0.0
    density: float = 1.0
    motion: str = "free"
    velocity: tuple = (0.0, 0.0)
    omega: float = 0.0
    name: str | None = None

    KEYS = ("shape", "radius", "segments", "vertices", "width", "height", "a", "b", "position", "angle",
            "density", "motion", "velocity", "omega", "name")
    SHAPE_KEYS = {"disk": ("radius",), "polygon": ("vertices",), "rectangle": ("width", "height"),
                  "ellipse": ("a", "b")}

    def validate(self, where):
        """Check and convert every value (``where``: ``"bodies[i]"``); ``SceneError`` names the first bad one."""
        self.shape = names.lookup("shape", self.shape, f"{where}.shape", SceneError)
        for k in self.SHAPE_KEYS[self.shape]:
            if getattr(self, k) is None:
                raise SceneError(f"{where}: shape = {self.shape!r} needs {k} "
                                 f"(a {self.shape} takes {', '.join(self.SHAPE_KEYS[self.shape])})")
        for k in ("radius", "width", "height", "a", "b"):
            if getattr(self, k) is not None:
                if k not in self.SHAPE_KEYS[self.shape]:
                    raise fail(f"{where}.{k}", getattr(self, k),
                               f"no {k} for shape {self.shape!r} (it takes {', '.join(self.SHAPE_KEYS[self.shape])})",
                               SceneError)
                setattr(self, k, positive(f"{where}.{k}", getattr(self, k), error=SceneError))
        if self.segments is not None:
            self.segments = integer(f"{where}.segments", self.segments, lo=3, hi=MAX_SEGMENTS, error=SceneError)
        if self.shape == "polygon":
            try:
                v = geo.validate_polygon(self.vertices, f"{where}.vertices", require_convex=True)
            except ValueError as exc:
                raise SceneError(f"{where}.vertices = {self.vertices!r}: {exc}; expected a counter-clockwise "
                                 f"convex polygon [[x0, y0], [x1, y1], ...] with at least 3 vertices") from None
            self.vertices = v - geo.polygon_centroid(v)
        self.position = pair(f"{where}.position", self.position, error=SceneError)
        self.angle = number(f"{where}.angle", self.angle, error=SceneError)
        self.density = positive(f"{where}.density", self.density, error=SceneError)
        self.motion = names.lookup("motion", self.motion, f"{where}.motion", SceneError)
        self.velocity = pair(f"{where}.velocity", self.velocity, error=SceneError)
        self.omega = number(f"{where}.omega", self.omega, error=SceneError)
        if self.motion == "fixed" and (any(self.velocity) or self.omega):
            raise fail(f"{where}.velocity/omega", (list(self.velocity), self.omega),
                       "zero for a fixed body (use motion = 'prescribed' to move it)", SceneError)

    def local_vertices(self, segments_default: int = 32) -> np.ndarray:
        """Outline in body coordinates, (n, 2), centroid at the origin."""
        n = self.segments or segments_default
        if self.shape == "disk":
            return geo.regular_polygon(self.radius, n)
        if self.shape == "rectangle":
            return geo.rectangle(self.width, self.height)
        if self.shape == "ellipse":
            return geo.ellipse_polygon(self.a, self.b, n)
        return np.asarray(self.vertices, dtype=float)

    def world_vertices(self, segments_default: int = 32, position=None, angle=None) -> np.ndarray:
        return geo.transform(self.local_vertices(segments_default), self.position if position is None else position,
                             self.angle if angle is None else angle)

    @property
    def bounding_radius(self) -> float:
        if self.shape == "disk":
            return self.radius
        if self.shape == "rectangle":
            return 0.5 * math.hypot(self.width, self.height)
        if self.shape == "ellipse":
            return max(self.a, self.b)
        return float(np.sqrt((np.asarray(self.vertices) ** 2).sum(axis=1)).max())

    @property
    def moves(self) -> bool:
        """Whether the body can move at all (free, or prescribed with a non-zero velocity)."""
        return self.motion == "free" or (self.motion == "prescribed" and (any(self.velocity) or self.omega != 0))

    @property
    def outline_moves(self) -> bool:
        """Whether the region it covers changes: a disk spinning about its centre does not."""
        if self.motion == "fixed":
            return False
        if self.motion == "prescribed":
            return any(self.velocity) or (self.omega != 0 and self.shape != "disk")
        return True


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


@dataclass
class MeshSpec:
    """Fluid mesh: target edge length ``h`` (length) and optional grading.

    ``h`` not given: from the scene's scale, ``min(L / 20, d / 4)`` with ``L`` the box's
    shorter side and ``d`` the smallest body's bounding diameter (:func:`default_h`; 0.05 for
    a 2 × 1 box with a disk of radius 0.1); the plan names it.

    ``grading = {region = [xmin, xmax, ymin, ymax] | "bodies", growth = g, h_max = H}``: size
    ``h`` in the region, growing by ``g`` per cell away from it up to ``H`` (default 8h).
    ``strategy`` (``"drag"``, ``"regenerate"`` or ``"fixed"``, see ``names.meaning("strategy",
    ...)``) and ``retriangulate_every`` (steps) apply to a moving mesh; ``curved`` meshes disks
    as circles.
    """

    h: float | None = None
    grading: dict | None = None
    strategy: str = "drag"
    retriangulate_every: int = 30
    curved: bool = True

    KEYS = ("h", "grading", "strategy", "retriangulate_every", "curved")
    #: keys of the ``grading`` table
    GRADING_KEYS = ("region", "growth", "h_max")

    def validate(self, where="mesh"):
        self.h = positive(f"{where}.h", self.h, error=SceneError)
        if self.grading is not None:
            g = self.grading
            check_keys(g, self.GRADING_KEYS, f"{where}.grading", error=SceneError)
            region = g.get("region", "bodies")
            if region != "bodies":
                if (not isinstance(region, (list, tuple)) or len(region) != 4
                        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in region)
                        or not (region[1] > region[0] and region[3] > region[2])):
                    raise fail(f"{where}.grading.region", region,
                               "'bodies' or [xmin, xmax, ymin, ymax] with xmax > xmin and ymax > ymin", SceneError)
                region = tuple(float(v) for v in region)
            growth = number(f"{where}.grading.growth", g.get("growth", 1.2), "a number >= 1", lo=1.0, error=SceneError)
            h_max = number(f"{where}.grading.h_max", g.get("h_max", 8.0 * self.h), f"a number >= h = {self.h}",
                            lo=self.h, error=SceneError)
            self.grading = {"region": region, "growth": growth, "h_max": h_max}
        self.strategy = names.lookup("strategy", self.strategy, f"{where}.strategy", SceneError)
        self.retriangulate_every = integer(f"{where}.retriangulate_every", self.retriangulate_every, error=SceneError)
        self.curved = boolean(f"{where}.curved", self.curved, error=SceneError)


@dataclass
class TimeSpec:
    """Time step ``dt`` and end time ``t_end`` (time units); the run takes round(t_end/dt) steps.
    ``scheme``: the BDF formula of the fluid (``names.meaning("time scheme", ...)``); ``"auto"``
    is BDF3 on a fixed mesh (DFG 2D-2: 8x smaller errors than BDF2 at the same dt) and BDF2 when
    the mesh moves."""

    dt: float = 1e-3
    t_end: float = 1.0
    scheme: str = "auto"

    KEYS = ("dt", "t_end", "scheme")

    def validate(self, where="time"):
        self.scheme = names.lookup("time scheme", self.scheme, f"{where}.scheme", SceneError)
        self.dt = positive(f"{where}.dt", self.dt, error=SceneError)
        self.t_end = positive(f"{where}.t_end", self.t_end, error=SceneError)
        if self.t_end < self.dt * (1 - 1e-9):
            raise fail(f"{where}.t_end", self.t_end, f"a number >= dt = {self.dt}", SceneError)
        n = self.t_end / self.dt
        if abs(n - round(n)) > 1e-6 * max(1.0, n):  # the last step lands on t_end: t_end = n dt
            lo, hi = math.floor(n) * self.dt, math.ceil(n) * self.dt
            raise fail(f"{where}.t_end", self.t_end, f"a whole number of steps dt = {self.dt:g} (e.g. {lo:.10g} or "
                       f"{hi:.10g}), so that the last step lands on t_end", SceneError)

    @property
    def n_steps(self) -> int:
        return max(1, int(round(self.t_end / self.dt)))

    def bdf_scheme(self, moving_mesh: bool) -> str:
        """The BDF formula the fluid uses: ``scheme`` with ``"auto"`` resolved.

        ``"auto"`` is ``"bdf3"`` on a fixed mesh (DFG 2D-2, P3/P2, Δt = 0.005: St and c_D,max
        within 6e-4 against 4e-3 with BDF2 at the same cost) and ``"bdf2"`` on a moving mesh,
        whose transfer and coupling keep two time levels.

        >>> t = TimeSpec()
        >>> t.bdf_scheme(moving_mesh=False), t.bdf_scheme(moving_mesh=True)
        ('bdf3', 'bdf2')
        """
        if self.scheme == "auto":
            return "bdf2" if moving_mesh else "bdf3"
        return self.scheme


@dataclass
class OutputSpec:
    """Output: directory ``dir``; fields and body outlines every ``every`` steps; history every
    ``history_every`` steps; ``fields = false`` writes no fluid fields; ``full_order = false``
    writes the fields at the mesh vertices only (no ``fields_full`` series); ``xdmf = true``
    also collects the field series into one XDMF time series at the end (a mesh built once;
    needs h5py).

    Checkpoints: every ``checkpoint_every`` steps (0: only at the end; not given: about ten a
    run, the newest three kept) and in any case every ``checkpoint_seconds`` of wall-clock
    time (default 600; 0: off), and at the end.

    ``rheology_window = [t0, t1]``: the times over which a Couette cell's effective viscosity
    is averaged (:mod:`fluidem.rheology`; default: the second half of the run), within
    ``[0, time.t_end]``."""

    dir: str = "out"
    every: int = 10
    history_every: int = 1
    checkpoint_every: int | None = None
    fields: bool = True
    checkpoint_seconds: float = 600.0
    full_order: bool = True
    xdmf: bool = False
    rheology_window: tuple | None = None

    KEYS = ("dir", "every", "history_every", "checkpoint_every", "fields", "checkpoint_seconds", "full_order",
            "xdmf", "rheology_window")

    def validate(self, where="output"):
        if not isinstance(self.dir, str) or not self.dir:
            raise fail(f"{where}.dir", self.dir, "a non-empty path string", SceneError)
        self.every = integer(f"{where}.every", self.every, error=SceneError)
        self.history_every = integer(f"{where}.history_every", self.history_every, error=SceneError)
        if self.checkpoint_every is not None:
            self.checkpoint_every = integer(f"{where}.checkpoint_every", self.checkpoint_every, lo=0,
                                            error=SceneError)
        self.checkpoint_seconds = nonnegative(f"{where}.checkpoint_seconds", self.checkpoint_seconds, error=SceneError)
        self.fields = boolean(f"{where}.fields", self.fields, error=SceneError)
        self.full_order = boolean(f"{where}.full_order", self.full_order, error=SceneError)
        self.xdmf = boolean(f"{where}.xdmf", self.xdmf, error=SceneError)
        if self.rheology_window is not None:
            try:
                self.rheology_window = pair(f"{where}.rheology_window", self.rheology_window, error=SceneError)
            except SceneError:
                raise fail(f"{where}.rheology_window", self.rheology_window, "[t0, t1], two finite times within the "
                           "run", SceneError) from None


_TABLES = {"fluid": FluidSpec, "domain": DomainSpec, "contact": ContactSpec, "mesh": MeshSpec, "time": TimeSpec,
           "output": OutputSpec}
_TOP_KEYS = ("name", "description", "units", "gravity", "fluid", "domain", "bodies", "bodies_table", "contact", "mesh",
             "time", "output")
#: where keys that belong elsewhere go (the hint an unknown key's error gives instead of the nearest key)
_BODY_HINTS = {"file": "a CSV body table is [bodies_table] file = ..., not a key of a body",
               "x": "the centre is position = [x, y]", "y": "the centre is position = [x, y]",
               "vx": "the velocity is velocity = [vx, vy]", "vy": "the velocity is velocity = [vx, vy]"}
_TOP_HINTS = {"file": "a CSV body table is [bodies_table] file = ...", "h": "the mesh size is [mesh] h",
              "dt": "the time step is [time] dt", "t_end": "the end time is [time] t_end",
              "viscosity": "the viscosity is [fluid] viscosity", "density": "a density is [fluid] density or a "
              "body's density", "box": "the box is [domain] box"}


@dataclass
class Scene:
    """A complete scene: domain, optional fluid, bodies, contacts, mesh, time and output.

    Build it from a TOML file with :meth:`from_toml`, from a dict with :meth:`from_dict`, or
    directly from the spec dataclasses, then call :meth:`validate` (done by the loaders) and
    :meth:`plan`; :meth:`to_toml` writes it back.  Every quantity is in the one consistent
    unit system the user picks (see :mod:`fluidem.scene`).

    Parameters
    ----------
    domain : DomainSpec
    bodies : list of BodySpec
    fluid : FluidSpec or None
        ``None`` for a dry scene (DEM only: no mesh, no fluid solver).
    gravity : (2,) float
        Acceleration of gravity, length/time² (e.g. ``[0, -9.81]`` in SI, ``[0, -981]`` in CGS).
    contact : ContactSpec or None
        ``None``: contacts off.
    mesh, time, output : MeshSpec, TimeSpec, OutputSpec
    name, description : str
    units : {None, "SI", "CGS"}
        The unit system the numbers are in, for labels only (figures write ``x [m]`` instead
        of ``x [length]``); nothing is converted.  ``None``: not named.

    Examples
    --------
    >>> from fluidem.scene import Scene
    >>> s = Scene.from_dict({"domain": {"box": [0, 1, 0, 1]},
    ...                      "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.5, 0.5]}],
    ...                      "time": {"dt": 0.01, "t_end": 0.1}})
    >>> s.plan().effect("fluid").on
    False
    """

    domain: DomainSpec = field(default_factory=DomainSpec)
    bodies: list = field(default_factory=list)
    fluid: FluidSpec | None = None
    gravity: tuple = (0.0, 0.0)
    contact: ContactSpec | None = None
    mesh: MeshSpec = field(default_factory=MeshSpec)
    time: TimeSpec = field(default_factory=TimeSpec)
    output: OutputSpec = field(default_factory=OutputSpec)
    name: str = "scene"
    description: str = ""
    units: str | None = None
    source: str | None = None
    #: tables or keys the scene did not give and that took their defaults ("time", "mesh.h"); the plan names them
    defaulted: list = field(default_factory=list, compare=False, repr=False)

    # -- loading ------------------------------------------------------------------------
    @classmethod
    def from_toml(cls, path) -> Scene:
        """Read and validate a scene file (relative ``bodies_table.file`` is relative to it)."""
        if not isinstance(path, (str, os.PathLike)) or not str(path):
            raise fail("Scene.from_toml(path)", path, "the path of a TOML file (str or Path)", InputError)
        path = Path(path)
        data = files.read_toml(path)
        data.setdefault("name", path.stem)
        scene = cls.from_dict(data, base_dir=path.parent)
        scene.source = str(path)
        return scene

    @classmethod
    def from_dict(cls, data: dict, base_dir=".") -> Scene:
        """Build and validate a scene from the nested dict of a TOML file."""
        if not isinstance(data, dict):
            raise fail("Scene.from_dict(data)", data, "a dict of the scene's tables, as a TOML file reads "
                       "({'domain': {'box': [0, 1, 0, 1]}, ...})", InputError)
        check_keys(data, _TOP_KEYS, "", error=SceneError, hints=_TOP_HINTS)
        kw = {}
        for key, spec in _TABLES.items():
            if key in data:
                tab = data[key]
                check_keys(tab, spec.KEYS, key, error=SceneError)
                kw[key] = spec(**tab)
        if "domain" not in kw:
            raise SceneError("the scene has no [domain] table; it needs at least box = [xmin, xmax, ymin, ymax]")
        if "gravity" in data:
            kw["gravity"] = data["gravity"]
        if "units" in data:
            kw["units"] = data["units"]
        for k in ("name", "description"):
            if k in data:
                if not isinstance(data[k], str):
                    raise fail(k, data[k], "a string", SceneError)
                kw[k] = data[k]
        bodies = []
        raw = data.get("bodies", [])
        if isinstance(raw, dict) and "file" in raw:  # [bodies] file = ...: the CSV table is [bodies_table]
            raise SceneError(f"bodies.file = {raw['file']!r}: a CSV body table is given as [bodies_table] with "
                             f"file = {raw['file']!r} (and defaults for every row); [[bodies]] (double brackets) "
                             "is one table per body")
        if not isinstance(raw, list):
            raise fail("bodies", raw, "an array of tables [[bodies]] (one per body; a CSV table of bodies is "
                       "[bodies_table] file = ...)", SceneError)
        for i, b in enumerate(raw):
            check_keys(b, BodySpec.KEYS, f"bodies[{i}]", error=SceneError, hints=_BODY_HINTS)
            bodies.append(BodySpec(**b))
        if "bodies_table" in data:
            bodies.extend(BodySpec(**rec) for rec in files.read_bodies_table(data["bodies_table"], base_dir))
        kw["bodies"] = bodies
        kw["defaulted"] = [k for k in ("time",) if k not in data]
        if "fluid" in data and "h" not in (data.get("mesh") or {}):
            kw["defaulted"].append("mesh.h")
        scene = cls(**kw)
        scene.validate()
        return scene

    # -- validation ---------------------------------------------------------------------
    def validate(self) -> Scene:
        """Check every value and the geometry; returns ``self``.

        Names are made canonical (aliases resolved), numbers converted to ``float``, pairs to
        tuples, and polygon vertices shifted so that their area centroid is the origin.

        Raises
        ------
        fluidem.errors.SceneError
            (a ``ValueError``) naming the first bad key, its value and what is allowed.
        """
        self._check_specs()
        self.gravity = pair("gravity", self.gravity, error=SceneError)
        if self.units is not None:
            self.units = names.lookup("units", self.units, "units", SceneError)
        if self.fluid is not None:
            self.fluid.validate()
        self.domain.validate()
        for spec, key in ((self.contact, "contact"), (self.time, "time"), (self.output, "output")):
            if spec is not None:
                spec.validate(key)
        sides = names.choices("side")
        taken = set()
        for i, b in enumerate(self.bodies):
            if not isinstance(b, BodySpec):
                raise fail(f"bodies[{i}]", b, "a BodySpec", SceneError)
            b.validate(f"bodies[{i}]")
            b.name = b.name or f"body{i}"
            if not isinstance(b.name, str) or b.name in taken or b.name in sides:
                raise fail(f"bodies[{i}].name", b.name, f"a unique string other than {', '.join(sides)}", SceneError)
            taken.add(b.name)
        if self.mesh.h is None:  # from the scene's scale (before anything uses h: outlines, grading)
            self.mesh.h = default_h(self)
            if "mesh.h" not in self.defaulted and self.fluid is not None:
                self.defaulted.append("mesh.h")
        self.mesh.validate("mesh")
        self._check_free_body_convection()
        self._check_rheology_window()
        self._check_zero_net_flux()
        self._check_cutoffs()
        self._check_geometry()
        return self

    #: each table of a scene built in Python: (attribute, spec class, may be None)
    _SPECS = (("domain", DomainSpec, False), ("fluid", FluidSpec, True), ("contact", ContactSpec, True),
              ("mesh", MeshSpec, False), ("time", TimeSpec, False), ("output", OutputSpec, False))

    def _check_specs(self):
        """Each table is its spec dataclass, ``bodies`` a list, ``name`` and ``description`` strings: a
        scene built in Python (``Scene(mesh=None)``) is refused here instead of failing in the plan or the run."""
        for key, spec, optional in self._SPECS:
            v = getattr(self, key)
            if not isinstance(v, spec) and not (optional and v is None):
                article = "an" if spec.__name__[0] in "AEIOU" else "a"
                raise fail(f"Scene({key}=...)", v, f"{article} {spec.__name__}" + (" or None" if optional else "")
                           + f" (Scene.from_dict takes the [{key}] table as a dict)", SceneError)
        if not isinstance(self.bodies, (list, tuple)):
            raise fail("Scene(bodies=...)", self.bodies, "a list of BodySpec (empty: no bodies)", SceneError)
        self.bodies = list(self.bodies)
        for key in ("name", "description"):
            if not isinstance(getattr(self, key), str):
                raise fail(f"Scene({key}=...)", getattr(self, key), "a string", SceneError)

    def _check_free_body_convection(self):
        """Free bodies in Navier–Stokes with ``coupling = "implicit"``: the coupled step
        (:class:`fluidem.coupling.free_bodies.FreeBodyStepper`) linearises the convection
        semi-implicitly, so ``"newton"`` and ``"explicit"`` cannot be honoured there."""
        fl = self.fluid
        if fl is None or fl.model != "navier-stokes" or fl.coupling != "implicit" or fl.convection == "semi-implicit":
            return
        free = [i for i, b in enumerate(self.bodies) if b.motion == "free"]
        if free:
            i = free[0]
            raise SceneError(f"fluid.convection = {fl.convection!r} with free bodies (bodies[{i}] "
                             f"{self.bodies[i].name!r}) and fluid.coupling = 'implicit': the coupled fluid-body step "
                             "takes convection 'semi-implicit' only; expected fluid.convection = 'semi-implicit', or "
                             "fluid.coupling = 'explicit' (the staggered step, which takes every convection)")

    def _check_rheology_window(self):
        """``output.rheology_window`` lies within the run: 0 ≤ t0 < t1 ≤ t_end."""
        w = self.output.rheology_window
        if w is not None and not (0.0 <= w[0] < w[1] <= self.time.t_end * (1 + 1e-12)):
            raise fail("output.rheology_window", list(w), f"[t0, t1] with 0 <= t0 < t1 <= time.t_end = "
                       f"{self.time.t_end:g} (times within the run)", SceneError)

    def _check_zero_net_flux(self):
        """``fluid.zero_net_flux = true``: Stokes, free bodies, gravity only through periodic pairs, and
        no body force along a periodic axis (the mean gradient there is the flux condition's
        multiplier: it would cancel it)."""
        fl = self.fluid
        if fl is None:
            return
        if not fl.zero_net_flux:
            return self._check_periodic_balance()
        key = "fluid.zero_net_flux = true"
        if fl.model != "stokes":
            raise SceneError(f"{key} with fluid.model = {fl.model!r}: allowed with fluid.model = 'stokes' only "
                             "(periodic sedimentation in quasi-steady Stokes flow)")
        if not any(b.motion == "free" for b in self.bodies):
            raise SceneError(f"{key} without free bodies: allowed with at least one body of motion = 'free' (the "
                             "mean pressure gradient carries their buoyant weight)")
        periodic = [self.domain.side(s0).type == "periodic" for s0 in ("left", "bottom")]
        pairs = ("left/right", "bottom/top")
        if not any(periodic):
            raise SceneError(f"{key} without periodic sides: allowed with the sides gravity points through "
                             "periodic (domain.bottom and domain.top = 'periodic' for gravity along y)")
        g = self.gravity
        if not any(g) or any(g[c] and not periodic[c] for c in range(2)):
            allowed = " and ".join("xy"[c] for c in range(2) if periodic[c])
            raise SceneError(f"{key} with gravity = {list(g)}: allowed: gravity non-zero and along the periodic "
                             f"axis {allowed} only (the sides it points through, "
                             f"{' and '.join(pairs[c] for c in range(2) if periodic[c])}, a periodic pair)")
        bf = fl.body_force
        along = [c for c in range(2) if periodic[c] and bf[c]]
        if along:
            raise SceneError(f"fluid.body_force = {list(bf)} with {key}: the mean pressure gradient along "
                             f"{'xy'[along[0]]} is solved for to keep the flux zero and would cancel a body force "
                             f"there; allowed: body_force component 0 along the periodic axes "
                             f"({', '.join('xy'[c] for c in range(2) if periodic[c])})")

    def _check_periodic_balance(self):
        """Stokes free bodies alone in a doubly periodic cell without ``fluid.zero_net_flux``: the
        cell's net force, Σ (ρ_s − ρ_f) A g + ρ f |Ω_f| (areas of the outline polygons), must vanish,
        or the Stokes flow has no solution (:mod:`fluidem.coupling.mean_gradient`)."""
        fl = self.fluid
        if fl.model != "stokes" or not self.bodies or any(b.motion != "free" for b in self.bodies) or \
                any(self.domain.side(s).type != "periodic" for s in ("left", "bottom")):
            return
        from ..geometry import polygon_area

        x0, x1, y0, y1 = self.domain.box
        area = np.array([polygon_area(p) for p in self.world_outlines()])
        rho = np.array([b.density for b in self.bodies])
        weight = ((rho - fl.density) * area).sum() * np.asarray(self.gravity)
        push = fl.density * np.asarray(fl.body_force) * ((x1 - x0) * (y1 - y0) - area.sum())
        net = weight + push
        scale = np.abs(weight).sum() + np.abs(push).sum()
        if np.abs(net).max() > 1e-8 * scale:
            raise SceneError(f"the doubly periodic cell of free bodies has a net force of [{net[0]:.4g}, {net[1]:.4g}] "
                             f"(buoyant weight [{weight[0]:.4g}, {weight[1]:.4g}] + fluid.body_force "
                             f"{list(fl.body_force)} on the fluid) and so no Stokes flow; expected "
                             "fluid.zero_net_flux = true (the mean pressure gradient on fluid and bodies), or a "
                             "body_force that balances the weight on the fluid alone (bodies then settle "
                             "1/(1 - φ) too fast)")

    def _check_cutoffs(self):
        """Contact cut-offs (``repulsion_range``, ``lubrication_range``) shorter than half the box's
        shorter side: beyond that every body is within reach of a wall wherever it is, and the
        short-range forces act everywhere."""
        if self.contact is None:
            return
        x0, x1, y0, y1 = self.domain.box
        half = 0.5 * min(x1 - x0, y1 - y0)
        for key in ("repulsion_range", "lubrication_range"):
            v = getattr(self.contact, key)
            if v is not None and v >= half:
                raise fail(f"contact.{key}", v, f"a positive number below {half:g}, half the shorter side of "
                           f"domain.box = {list(self.domain.box)} (a short-range cut-off, of the order of mesh.h = "
                           f"{self.mesh.h:g}; a longer one reaches a wall from anywhere in the box)", SceneError)

    def _check_geometry(self):
        """Bodies inside the box and not overlapping each other (shapely, vectorised)."""
        import shapely

        if not self.bodies:
            return
        x0, x1, y0, y1 = self.domain.box
        polys = self.world_outlines()
        lo = np.array([p.min(axis=0) for p in polys])
        hi = np.array([p.max(axis=0) for p in polys])
        # the moving mesh meshes a body across a periodic side as its images on both sides
        moving_mesh = self.fluid is not None and any(b.outline_moves for b in self.bodies)
        for c, (s0, s1), (b0, b1) in ((0, ("left", "right"), (x0, x1)), (1, ("bottom", "top"), (y0, y1))):
            if self.domain.side(s0).type != "periodic":
                continue
            width = hi[:, c] - lo[:, c]
            wide = np.flatnonzero(width >= b1 - b0)
            if len(wide):
                i = int(wide[0])
                raise SceneError(f"bodies[{i}] has width {width[i]:.4g} in {'xy'[c]} across the periodic sides "
                                 f"{s0}/{s1}: allowed: narrower than the period {b1 - b0:.4g}")
            cross = np.flatnonzero((lo[:, c] <= b0) | (hi[:, c] >= b1))
            if len(cross) and not moving_mesh:
                i = int(cross[0])
                side = s0 if lo[i, c] <= b0 else s1
                raise SceneError(f"bodies[{i}].position = {list(self.bodies[i].position)}: the body (extent "
                                 f"{'xy'[c]} {lo[i, c]:.4g}..{hi[i, c]:.4g}) overlaps the periodic side {side!r} "
                                 f"at {'xy'[c]} = {b0 if side == s0 else b1:g}; allowed: every vertex strictly "
                                 "inside the box (a body across a periodic side needs the moving mesh: a fluid "
                                 "scene with a free or moving body)")
        # a body whose outline moves in a fluid is meshed by the moving mesh, which merges a body
        # touching a wall with the wall: touching is fine there, overlapping is not
        touch = np.array([self.fluid is not None and b.outline_moves for b in self.bodies])
        tol = 1e-12 * max(x1 - x0, y1 - y0)
        below = np.where(touch, -tol, 0.0)
        px = moving_mesh and self.domain.side("left").type == "periodic"
        py = moving_mesh and self.domain.side("bottom").type == "periodic"
        out = np.flatnonzero((~px & ((lo[:, 0] - x0 <= below) | (x1 - hi[:, 0] <= below)))
                             | (~py & ((lo[:, 1] - y0 <= below) | (y1 - hi[:, 1] <= below))))
        if len(out):
            i = int(out[0])
            allowed = ("every vertex inside the box or on a wall (a moving body may touch a wall)" if touch[i]
                       else "every vertex strictly inside the box")
            raise SceneError(f"bodies[{i}].position = {list(self.bodies[i].position)}: the body (extent "
                             f"x {lo[i, 0]:.4g}..{hi[i, 0]:.4g}, y {lo[i, 1]:.4g}..{hi[i, 1]:.4g}) is not inside "
                             f"domain.box = {list(self.domain.box)}; allowed: {allowed}")
        idx = np.repeat(np.arange(len(polys)), [len(p) for p in polys])
        geoms = shapely.polygons(shapely.linearrings(np.vstack(polys), indices=idx))
        tree = shapely.STRtree(geoms)
        pairs = tree.query(geoms, predicate="intersects")
        i, j = pairs[:, pairs[0] < pairs[1]] if pairs.size else (np.zeros(0, int), np.zeros(0, int))
        if len(i):
            area = shapely.area(shapely.intersection(geoms[i], geoms[j]))
            ref = np.minimum(shapely.area(geoms[i]), shapely.area(geoms[j]))
            bad = np.flatnonzero(area > 1e-9 * ref)
            if len(bad):
                a, b = int(i[bad[0]]), int(j[bad[0]])
                raise SceneError(f"bodies[{a}] (position {list(self.bodies[a].position)}) and bodies[{b}] (position "
                                 f"{list(self.bodies[b].position)}) overlap at start by {area[bad[0]]:.3g} "
                                 f"(length²); allowed: bodies that do not overlap"
                                 + (" or touch" if self.fluid is None else ""))
            if self.fluid is not None:  # touching outlines leave no fluid between them: no mesh can be built
                a, b = int(i[0]), int(j[0])
                raise SceneError(f"bodies[{a}] (position {list(self.bodies[a].position)}) and bodies[{b}] (position "
                                 f"{list(self.bodies[b].position)}) touch at start; in a fluid scene bodies need "
                                 f"fluid between them: move them apart (a gap of at least mesh.h = {self.mesh.h:g}) "
                                 "or make them one polygon body")

    def world_outlines(self) -> list:
        """Initial outlines in world coordinates, list of (n_i, 2) arrays."""
        return [b.world_vertices(self.default_segments(b)) for b in self.bodies]

    def default_segments(self, body: BodySpec) -> int:
        """Outline vertex count of a disk or ellipse without ``segments``: 32 dry, ~2πr/h (even, ≥ 16) in a fluid."""
        if body.segments:
            return body.segments
        if self.fluid is None or body.shape not in ("disk", "ellipse"):
            return 32
        r = body.radius if body.shape == "disk" else max(body.a, body.b)
        half = math.pi * r / self.mesh.h  # inf for an absurdly small h: capped (the plan refuses such a mesh)
        return MAX_SEGMENTS if half >= MAX_SEGMENTS // 2 else max(16, 2 * int(math.ceil(half)))

    # -- TOML out ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain nested dict (the inverse of :meth:`from_dict`, tables and bodies inline)."""
        d = {"name": self.name, "description": self.description, "gravity": list(self.gravity),
             "domain": _plain(asdict(self.domain)), "mesh": _plain(asdict(self.mesh)),
             "time": _plain(asdict(self.time)), "output": _plain(asdict(self.output)),
             "bodies": [{k: v for k, v in _plain(asdict(b)).items() if v is not None} for b in self.bodies]}
        if self.units is not None:  # only when named: scenes without it keep their key (run.json)
            d["units"] = self.units
        if self.fluid is not None:
            d["fluid"] = _plain(asdict(self.fluid))
        if self.contact is not None:
            d["contact"] = _plain(asdict(self.contact))
        return d

    def to_toml(self, path) -> None:
        """Write the scene as a TOML scene file (:func:`fluidem.scene.files.write_scene_toml`)."""
        files.write_scene_toml(self, path)

    def copy(self) -> Scene:
        """A deep copy."""
        return copy.deepcopy(self)

    def default_mesh_size(self) -> float:
        """The mesh size ``mesh.h`` takes when not given (:func:`default_h`), length units."""
        return default_h(self)

    # -- the plan -------------------------------------------------------------------------
    def plan(self) -> Plan:
        """The effects this scene needs and why, see :class:`fluidem.plan.Plan`."""
        from ..plan import make_plan

        self._check_specs()  # a scene built in Python and never validated: a clean error, not an AttributeError
        return make_plan(self)


def default_h(scene) -> float:
    """The default mesh size of ``scene``: ``min(L / 20, d / 4)``, length.

    ``L``: the shorter side of the domain box; ``d``: the smallest bounding diameter of a body
    (no bodies: ``L / 20``).  So the mesh resolves the box and every body whatever the units.

    Examples
    --------
    >>> from fluidem.scene import Scene
    >>> Scene.from_dict({"domain": {"box": [0, 2, 0, 1]}, "fluid": {},
    ...                  "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.5, 0.5]}]}).mesh.h
    0.05
    >>> Scene.from_dict({"domain": {"box": [0, 1e-3, 0, 2e-4]}, "fluid": {}}).mesh.h
    1e-05
    """
    x0, x1, y0, y1 = (float(v) for v in scene.domain.box)
    h = min(x1 - x0, y1 - y0) / 20.0
    if scene.bodies:
        h = min(h, min(2.0 * b.bounding_radius for b in scene.bodies) / 4.0)
    return float(f"{h:.3g}")


def _plain(obj):
    """``asdict`` output as plain TOML-ready values: ``None`` dropped, tuples and arrays as lists."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return obj
