"""Scenes: what to simulate, read from TOML or built in Python, and the plan of effects it needs.

A scene describes a domain, an optional fluid, rigid polygonal bodies, their contacts, the
mesh, the time span and the output.  :func:`Scene.from_toml` reads a file, validates every
key and value (a wrong one raises ``ValueError`` naming the key, the value and what is
allowed) and :meth:`Scene.plan` decides which effects the scene needs and why::

    gravity = [0.0, -980.0]          # top level, before any table (length/time²)
    [fluid]                          # absent: a dry (pure DEM) scene
    density = 1.0                    # mass/length² (2D)
    viscosity = 0.01                 # kinematic, length²/time
    model = "navier-stokes"          # or "stokes" (quasi-steady, no inertia)
    body_force = [0.0, 0.0]          # per unit mass, length/time²
    [domain]
    box = [0.0, 2.0, 0.0, 8.0]       # xmin, xmax, ymin, ymax
    left = "wall"                    # wall | inflow | outflow | periodic | moving-wall
    top = { type = "moving-wall", velocity = [1.0, 0.0] }
    inflow_profile = { type = "parabolic", umax = 1.5 }
    [[bodies]]
    shape = "disk"                   # disk | polygon | rectangle | ellipse
    radius = 0.1
    position = [1.0, 7.2]
    motion = "free"                  # free | fixed | prescribed (velocity, omega)
    [bodies_table]                   # many bodies: one CSV row per body
    file = "particles.csv"
    [contact]
    E = 1e5
    mu = 0.2
    gamma = 0.05
    [mesh]
    h = 0.02
    grading = { region = [0.0, 2.0, 5.0, 8.0], growth = 1.2 }
    strategy = "drag"                # drag | regenerate | fixed
    retriangulate_every = 30
    [time]
    dt = 1e-3
    t_end = 5.0
    [output]
    dir = "out"
    every = 10

Units are the user's (SI or CGS); they only have to be consistent.

Choices made here (see the CHANGELOG):

* A polygon body's ``vertices`` are in body coordinates; they are shifted so that their
  centroid is the origin, and ``position`` places that centroid (as in :mod:`fluidem.dem`).
* A disk in a fluid scene is meshed as a *curved* circle (isoparametric outline; the
  polygon error ~4/N² disappears) unless ``[mesh] curved = false``; its ``segments`` then
  only set the number of outline nodes (default: about 2πr/h, even, at least 16).
* Gravity acting on a fluid with only fixed or prescribed bodies adds a hydrostatic
  pressure and nothing else; it is left out of the fluid solve and the plan says so.
* Prescribed bodies whose outlines move need the moving mesh (ALE); a spinning disk does not.
* A Stokes scene is quasi-steady: every step solves the Stokes problem for the geometry and
  body velocities of that instant.  A Stokes scene whose prescribed bodies translate is
  legal without a moving mesh when it has a single time step (``t_end = dt``): the force at
  one instant needs only the geometry at that instant (the wall-correction example).
* Contacts are off when no two bodies (one of them movable), or a movable body and a wall,
  can meet before ``t_end`` at the speeds the scene allows: prescribed speed plus |ω| r for
  prescribed bodies, |v₀| t + |g| t²/2 for free bodies in a dry scene (until the first
  contact only gravity acts), zero for fixed bodies.
"""

from __future__ import annotations

import copy
import csv
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import geometry as geo

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["Scene", "FluidSpec", "DomainSpec", "SideSpec", "BodySpec", "ContactSpec", "MeshSpec", "TimeSpec",
           "OutputSpec", "Plan", "Effect", "SIDE_TYPES", "SHAPES", "MOTIONS", "FLUID_MODELS", "MESH_STRATEGIES"]

SIDE_TYPES = ("wall", "inflow", "outflow", "periodic", "moving-wall")
SIDES = ("left", "right", "bottom", "top")
SHAPES = ("disk", "polygon", "rectangle", "ellipse")
MOTIONS = ("free", "fixed", "prescribed")
FLUID_MODELS = ("navier-stokes", "stokes")
MESH_STRATEGIES = ("drag", "regenerate", "fixed")
PROFILE_TYPES = ("parabolic", "uniform")
CONVECTION = ("semi-implicit", "newton", "explicit")
SOLVERS = ("auto", "direct", "lagged-lu")


# ---------------------------------------------------------------------------------------
# small validation helpers: every error names the key, the value and what is allowed
# ---------------------------------------------------------------------------------------
def _err(key, value, allowed):
    return ValueError(f"{key} = {value!r}: expected {allowed}")


def _number(key, value, allowed="a finite number", lo=None, lo_open=False, hi=None):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise _err(key, value, allowed)
    v = float(value)
    if not math.isfinite(v):
        raise _err(key, value, allowed)
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise _err(key, value, allowed)
    if hi is not None and v > hi:
        raise _err(key, value, allowed)
    return v


def _positive(key, value):
    return _number(key, value, "a positive finite number", lo=0.0, lo_open=True)


def _nonneg(key, value):
    return _number(key, value, "a finite number >= 0", lo=0.0)


def _int(key, value, lo=1):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise _err(key, value, f"an integer >= {lo}")
    return int(value)


def _vec2(key, value):
    if (not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2
            or not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                       and math.isfinite(float(v)) for v in value)):
        raise _err(key, value, "a pair of finite numbers [x, y]")
    return (float(value[0]), float(value[1]))


def _choice(key, value, allowed):
    if value not in allowed:
        raise _err(key, value, "one of " + ", ".join(repr(a) for a in allowed))
    return value


def _bool(key, value):
    if not isinstance(value, bool):
        raise _err(key, value, "true or false")
    return value


def _check_keys(table: dict, allowed, where: str):
    if not isinstance(table, dict):
        raise _err(where, table, "a table")
    unknown = [k for k in table if k not in allowed]
    if unknown:
        k = unknown[0]
        raise ValueError(f"unknown key {where + '.' if where else ''}{k} = {table[k]!r}; "
                         f"allowed keys{' in [' + where + ']' if where else ' at the top level'}: "
                         + ", ".join(allowed))


# ---------------------------------------------------------------------------------------
# the scene description
# ---------------------------------------------------------------------------------------
@dataclass
class FluidSpec:
    """The fluid: ``density`` (mass/length²), kinematic ``viscosity`` (length²/time), ``model``.

    ``model`` is ``"navier-stokes"`` (unsteady, BDF2) or ``"stokes"`` (quasi-steady, no
    inertia).  ``body_force`` (2,) is per unit mass (length/time²).  ``element`` is an
    element-pair name of :mod:`fluidem.fluid.elements`; ``convection`` the linearisation of
    the unsteady solver; ``solver`` ``"auto"`` (= ``"lagged-lu"``: one LU reused as a GMRES
    preconditioner across steps, refactorised when iterations grow), ``"direct"`` (a fresh LU
    every step: restarts reproduce bit for bit; with the lagged LU only to the GMRES tolerance).
    """

    density: float = 1.0
    viscosity: float = 0.01
    model: str = "navier-stokes"
    body_force: tuple = (0.0, 0.0)
    element: str = "p2b"
    convection: str = "semi-implicit"
    solver: str = "auto"

    KEYS = ("density", "viscosity", "model", "body_force", "element", "convection", "solver")

    def validate(self, where="fluid"):
        from .fluid.elements import ELEMENT_PAIRS

        self.density = _positive(f"{where}.density", self.density)
        self.viscosity = _positive(f"{where}.viscosity", self.viscosity)
        _choice(f"{where}.model", self.model, FLUID_MODELS)
        self.body_force = _vec2(f"{where}.body_force", self.body_force)
        _choice(f"{where}.element", self.element, tuple(ELEMENT_PAIRS))
        _choice(f"{where}.convection", self.convection, CONVECTION)
        _choice(f"{where}.solver", self.solver, SOLVERS)


@dataclass
class SideSpec:
    """One side of the box: ``type`` in :data:`SIDE_TYPES`; ``velocity`` (2,) for a moving wall."""

    type: str = "wall"
    velocity: tuple = (0.0, 0.0)
    profile: dict | None = None

    KEYS = ("type", "velocity", "profile")


@dataclass
class DomainSpec:
    """The box ``(xmin, xmax, ymin, ymax)`` and what each side is.

    ``inflow_profile`` is ``{type = "parabolic" | "uniform", umax = U, ramp = T}``: the
    inflow speed normal to an inflow side (parabolic: ``4 U s (L − s) / L²`` along the
    side), raised smoothly from 0 over ``ramp`` time units (``0``: at once).
    """

    box: tuple = (0.0, 1.0, 0.0, 1.0)
    left: SideSpec = field(default_factory=SideSpec)
    right: SideSpec = field(default_factory=SideSpec)
    bottom: SideSpec = field(default_factory=SideSpec)
    top: SideSpec = field(default_factory=SideSpec)
    inflow_profile: dict | None = None

    KEYS = ("box",) + SIDES + ("inflow_profile",)

    def side(self, name) -> SideSpec:
        return getattr(self, name)

    def profile_of(self, name) -> dict:
        s = self.side(name)
        return s.profile if s.profile is not None else self.inflow_profile

    def validate(self, where="domain"):
        b = self.box
        if (not isinstance(b, (list, tuple, np.ndarray)) or len(b) != 4
                or not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                           and math.isfinite(float(v)) for v in b)
                or not (b[1] > b[0] and b[3] > b[2])):
            raise _err(f"{where}.box", b, "[xmin, xmax, ymin, ymax], finite, with xmax > xmin and ymax > ymin")
        self.box = tuple(float(v) for v in b)
        for s in SIDES:
            side = getattr(self, s)
            if isinstance(side, str):
                side = SideSpec(side)
            elif isinstance(side, dict):
                _check_keys(side, SideSpec.KEYS, f"{where}.{s}")
                side = SideSpec(**side)
            if not isinstance(side, SideSpec):
                raise _err(f"{where}.{s}", side, "a side type string or a table {type = ..., velocity = ...}")
            _choice(f"{where}.{s}" if isinstance(getattr(self, s), str) else f"{where}.{s}.type", side.type,
                    SIDE_TYPES)
            side.velocity = _vec2(f"{where}.{s}.velocity", side.velocity)
            if side.type != "moving-wall" and any(side.velocity):
                raise _err(f"{where}.{s}.velocity", list(side.velocity),
                           f"no velocity on a {side.type!r} side (only a 'moving-wall' moves)")
            if side.profile is not None:
                side.profile = self._check_profile(f"{where}.{s}.profile", side.profile)
            setattr(self, s, side)
        if self.inflow_profile is not None:
            self.inflow_profile = self._check_profile(f"{where}.inflow_profile", self.inflow_profile)
        for s in SIDES:
            if getattr(self, s).type == "inflow" and self.profile_of(s) is None:
                raise ValueError(f"{where}.{s} = 'inflow' has no profile: add {where}.inflow_profile = "
                                 f"{{ type = 'parabolic', umax = ... }} (allowed types: {', '.join(PROFILE_TYPES)})")
        for a, b_ in (("left", "right"), ("bottom", "top")):
            pa, pb = getattr(self, a).type == "periodic", getattr(self, b_).type == "periodic"
            if pa != pb:
                one, other = (a, b_) if pa else (b_, a)
                raise ValueError(f"{where}.{one} = 'periodic' but {where}.{other} = {getattr(self, other).type!r}: "
                                 f"periodic sides come in pairs; allowed: both {a} and {b_} 'periodic' or neither")

    @staticmethod
    def _check_profile(key, prof):
        if not isinstance(prof, dict):
            raise _err(key, prof, "a table { type = 'parabolic' | 'uniform', umax = ..., ramp = ... }")
        _check_keys(prof, ("type", "umax", "ramp"), key)
        out = {"type": _choice(f"{key}.type", prof.get("type", "parabolic"), PROFILE_TYPES)}
        if "umax" not in prof:
            raise ValueError(f"{key} has no umax: the inflow speed is required (a finite number)")
        out["umax"] = _number(f"{key}.umax", prof["umax"])
        out["ramp"] = _nonneg(f"{key}.ramp", prof.get("ramp", 0.0))
        return out


@dataclass
class BodySpec:
    """One rigid body.

    Parameters
    ----------
    shape : {"disk", "polygon", "rectangle", "ellipse"}
        ``disk``: ``radius``, ``segments``; ``polygon``: ``vertices`` (n, 2) in body
        coordinates (centroid shifted to the origin), counter-clockwise, convex;
        ``rectangle``: ``width``, ``height``; ``ellipse``: ``a``, ``b``, ``segments``.
    position : (2,) float
        Centre of mass, length.
    angle : float
        Orientation, rad.
    density : float
        Areal density, mass/length².
    motion : {"free", "fixed", "prescribed"}
        ``prescribed`` bodies move with constant ``velocity`` (2,) and ``omega`` (rad/time).
    velocity, omega
        Initial (free) or prescribed (prescribed) velocity and angular velocity.
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
        _choice(f"{where}.shape", self.shape, SHAPES)
        for k in self.SHAPE_KEYS[self.shape]:
            if getattr(self, k) is None:
                raise ValueError(f"{where}: shape = {self.shape!r} needs {k} "
                                 f"(a {self.shape} takes {', '.join(self.SHAPE_KEYS[self.shape])})")
        for k in ("radius", "width", "height", "a", "b"):
            if getattr(self, k) is not None:
                if k not in self.SHAPE_KEYS[self.shape]:
                    raise _err(f"{where}.{k}", getattr(self, k),
                               f"no {k} for shape {self.shape!r} (it takes {', '.join(self.SHAPE_KEYS[self.shape])})")
                setattr(self, k, _positive(f"{where}.{k}", getattr(self, k)))
        if self.segments is not None:
            self.segments = _int(f"{where}.segments", self.segments, lo=3)
        if self.shape == "polygon":
            try:
                v = geo.validate_polygon(self.vertices, f"{where}.vertices", require_convex=True)
            except ValueError as exc:
                raise ValueError(f"{where}.vertices = {self.vertices!r}: {exc}; expected a counter-clockwise "
                                 f"convex polygon [[x0, y0], [x1, y1], ...] with at least 3 vertices") from None
            self.vertices = v - geo.polygon_centroid(v)
        self.position = _vec2(f"{where}.position", self.position)
        self.angle = _number(f"{where}.angle", self.angle)
        self.density = _positive(f"{where}.density", self.density)
        _choice(f"{where}.motion", self.motion, MOTIONS)
        self.velocity = _vec2(f"{where}.velocity", self.velocity)
        self.omega = _number(f"{where}.omega", self.omega)
        if self.motion == "fixed" and (any(self.velocity) or self.omega):
            raise _err(f"{where}.velocity/omega", (list(self.velocity), self.omega),
                       "zero for a fixed body (use motion = 'prescribed' to move it)")

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
    """Contact law of :class:`fluidem.dem.ContactModel`: ``E`` (force/length), ``mu``, ``gamma``.

    ``enabled = false`` switches contacts off whatever the geometry.
    """

    E: float = 1e7
    mu: float = 0.23
    gamma: float = 0.025
    enabled: bool = True

    KEYS = ("E", "mu", "gamma", "enabled")

    def validate(self, where="contact"):
        self.E = _positive(f"{where}.E", self.E)
        self.mu = _nonneg(f"{where}.mu", self.mu)
        self.gamma = _nonneg(f"{where}.gamma", self.gamma)
        self.enabled = _bool(f"{where}.enabled", self.enabled)


@dataclass
class MeshSpec:
    """Fluid mesh: target edge length ``h`` (length) and optional grading.

    ``grading = {region = [xmin, xmax, ymin, ymax] | "bodies", growth = g, h_max = H}``: size
    ``h`` in the region, growing by ``g`` per cell away from it up to ``H`` (default 8h).
    ``strategy`` and ``retriangulate_every`` apply to a moving mesh; ``curved`` meshes disks
    as circles; ``element`` overrides ``[fluid] element``.
    """

    h: float = 0.05
    grading: dict | None = None
    strategy: str = "drag"
    retriangulate_every: int = 30
    curved: bool = True

    KEYS = ("h", "grading", "strategy", "retriangulate_every", "curved")

    def validate(self, where="mesh"):
        self.h = _positive(f"{where}.h", self.h)
        if self.grading is not None:
            g = self.grading
            _check_keys(g, ("region", "growth", "h_max"), f"{where}.grading")
            region = g.get("region", "bodies")
            if region != "bodies":
                if (not isinstance(region, (list, tuple)) or len(region) != 4
                        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in region)
                        or not (region[1] > region[0] and region[3] > region[2])):
                    raise _err(f"{where}.grading.region", region,
                               "'bodies' or [xmin, xmax, ymin, ymax] with xmax > xmin and ymax > ymin")
                region = tuple(float(v) for v in region)
            growth = _number(f"{where}.grading.growth", g.get("growth", 1.2), "a number >= 1", lo=1.0)
            h_max = _number(f"{where}.grading.h_max", g.get("h_max", 8.0 * self.h), f"a number >= h = {self.h}",
                            lo=self.h)
            self.grading = {"region": region, "growth": growth, "h_max": h_max}
        _choice(f"{where}.strategy", self.strategy, MESH_STRATEGIES)
        self.retriangulate_every = _int(f"{where}.retriangulate_every", self.retriangulate_every)
        self.curved = _bool(f"{where}.curved", self.curved)


@dataclass
class TimeSpec:
    """Time step ``dt`` and end time ``t_end`` (time units); the run takes round(t_end/dt) steps."""

    dt: float = 1e-3
    t_end: float = 1.0

    KEYS = ("dt", "t_end")

    def validate(self, where="time"):
        self.dt = _positive(f"{where}.dt", self.dt)
        self.t_end = _positive(f"{where}.t_end", self.t_end)
        if self.t_end < self.dt * (1 - 1e-9):
            raise _err(f"{where}.t_end", self.t_end, f"a number >= dt = {self.dt}")

    @property
    def n_steps(self) -> int:
        return max(1, int(round(self.t_end / self.dt)))


@dataclass
class OutputSpec:
    """Output: directory ``dir``; fields and body outlines every ``every`` steps; history every
    ``history_every`` steps; a checkpoint every ``checkpoint_every`` steps (0: only at the end);
    ``fields = false`` writes no fluid fields."""

    dir: str = "out"
    every: int = 10
    history_every: int = 1
    checkpoint_every: int = 0
    fields: bool = True

    KEYS = ("dir", "every", "history_every", "checkpoint_every", "fields")

    def validate(self, where="output"):
        if not isinstance(self.dir, str) or not self.dir:
            raise _err(f"{where}.dir", self.dir, "a non-empty path string")
        self.every = _int(f"{where}.every", self.every)
        self.history_every = _int(f"{where}.history_every", self.history_every)
        self.checkpoint_every = _int(f"{where}.checkpoint_every", self.checkpoint_every, lo=0)
        self.fields = _bool(f"{where}.fields", self.fields)


_TABLES = {"fluid": FluidSpec, "domain": DomainSpec, "contact": ContactSpec, "mesh": MeshSpec, "time": TimeSpec,
           "output": OutputSpec}
_TOP_KEYS = ("name", "description", "gravity", "fluid", "domain", "bodies", "bodies_table", "contact", "mesh", "time",
             "output")
_TABLE_COLUMNS = ("shape", "radius", "segments", "width", "height", "a", "b", "x", "y", "angle", "density", "motion",
                  "vx", "vy", "omega", "vertices", "name")


@dataclass
class Scene:
    """A complete scene: domain, optional fluid, bodies, contacts, mesh, time and output.

    Build it from a TOML file with :meth:`from_toml`, from a dict with :meth:`from_dict`, or
    directly from the spec dataclasses, then call :meth:`validate` (done by the loaders) and
    :meth:`plan`.

    Parameters
    ----------
    domain : DomainSpec
    bodies : list of BodySpec
    fluid : FluidSpec or None
        ``None`` for a dry scene (DEM only: no mesh, no fluid solver).
    gravity : (2,) float
        length/time².
    contact : ContactSpec or None
        ``None``: contacts off.
    mesh, time, output : MeshSpec, TimeSpec, OutputSpec
    name, description : str

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
    source: str | None = None

    # -- loading ------------------------------------------------------------------------
    @classmethod
    def from_toml(cls, path) -> "Scene":
        """Read and validate a scene file (relative ``bodies_table.file`` is relative to it)."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                data = tomllib.load(f)
        except FileNotFoundError:
            raise ValueError(f"scene file {str(path)!r} does not exist") from None
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"scene file {str(path)!r} is not valid TOML: {exc}") from None
        data.setdefault("name", path.stem)
        scene = cls.from_dict(data, base_dir=path.parent)
        scene.source = str(path)
        return scene

    @classmethod
    def from_dict(cls, data: dict, base_dir=".") -> "Scene":
        """Build and validate a scene from the nested dict of a TOML file."""
        _check_keys(data, _TOP_KEYS, "")
        kw = {}
        for key, spec in _TABLES.items():
            if key in data:
                tab = data[key]
                _check_keys(tab, spec.KEYS, key)
                kw[key] = spec(**tab)
        if "domain" not in kw:
            raise ValueError("the scene has no [domain] table; it needs at least box = [xmin, xmax, ymin, ymax]")
        if "gravity" in data:
            kw["gravity"] = data["gravity"]
        for k in ("name", "description"):
            if k in data:
                if not isinstance(data[k], str):
                    raise _err(k, data[k], "a string")
                kw[k] = data[k]
        bodies = []
        raw = data.get("bodies", [])
        if not isinstance(raw, list):
            raise _err("bodies", raw, "an array of tables [[bodies]]")
        for i, b in enumerate(raw):
            _check_keys(b, BodySpec.KEYS, f"bodies[{i}]")
            bodies.append(BodySpec(**b))
        if "bodies_table" in data:
            bodies.extend(_read_bodies_table(data["bodies_table"], base_dir, len(bodies)))
        kw["bodies"] = bodies
        scene = cls(**kw)
        scene.validate()
        return scene

    # -- validation ---------------------------------------------------------------------
    def validate(self) -> "Scene":
        """Check every value and the geometry; raises ``ValueError`` naming key, value and what is allowed."""
        self.gravity = _vec2("gravity", self.gravity)
        if self.fluid is not None:
            self.fluid.validate()
        self.domain.validate()
        for spec, key in ((self.contact, "contact"), (self.mesh, "mesh"), (self.time, "time"),
                          (self.output, "output")):
            if spec is not None:
                spec.validate(key)
        names = set()
        for i, b in enumerate(self.bodies):
            if not isinstance(b, BodySpec):
                raise _err(f"bodies[{i}]", b, "a BodySpec")
            b.validate(f"bodies[{i}]")
            b.name = b.name or f"body{i}"
            if not isinstance(b.name, str) or b.name in names or b.name in SIDES:
                raise _err(f"bodies[{i}].name", b.name, f"a unique string other than {', '.join(SIDES)}")
            names.add(b.name)
        self._check_geometry()
        return self

    def _check_geometry(self):
        """Bodies inside the box and not overlapping each other (shapely, vectorised)."""
        import shapely

        if not self.bodies:
            return
        x0, x1, y0, y1 = self.domain.box
        polys = self.world_outlines()
        lo = np.array([p.min(axis=0) for p in polys])
        hi = np.array([p.max(axis=0) for p in polys])
        out = np.flatnonzero((lo[:, 0] <= x0) | (hi[:, 0] >= x1) | (lo[:, 1] <= y0) | (hi[:, 1] >= y1))
        if len(out):
            i = int(out[0])
            raise ValueError(f"bodies[{i}].position = {list(self.bodies[i].position)}: the body (extent "
                             f"x {lo[i, 0]:.4g}..{hi[i, 0]:.4g}, y {lo[i, 1]:.4g}..{hi[i, 1]:.4g}) is not inside "
                             f"domain.box = {list(self.domain.box)}; allowed: every vertex strictly inside the box")
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
                raise ValueError(f"bodies[{a}] (position {list(self.bodies[a].position)}) and bodies[{b}] (position "
                                 f"{list(self.bodies[b].position)}) overlap at start by {area[bad[0]]:.3g} "
                                 f"(length²); allowed: bodies that do not overlap (touching is fine)")

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
        return max(16, 2 * int(math.ceil(math.pi * r / self.mesh.h)))

    # -- TOML out ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain nested dict (the inverse of :meth:`from_dict`, tables and bodies inline)."""
        d = {"name": self.name, "description": self.description, "gravity": list(self.gravity),
             "domain": _plain(asdict(self.domain)), "mesh": _plain(asdict(self.mesh)),
             "time": _plain(asdict(self.time)), "output": _plain(asdict(self.output)),
             "bodies": [{k: v for k, v in _plain(asdict(b)).items() if v is not None} for b in self.bodies]}
        if self.fluid is not None:
            d["fluid"] = _plain(asdict(self.fluid))
        if self.contact is not None:
            d["contact"] = _plain(asdict(self.contact))
        return d

    def copy(self) -> "Scene":
        return copy.deepcopy(self)

    # -- the plan -------------------------------------------------------------------------
    def plan(self) -> "Plan":
        """The effects this scene needs and why, see :class:`Plan`."""
        return _make_plan(self)


def _plain(obj):
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return obj


def _read_bodies_table(tab, base_dir, offset):
    """Rows of a CSV body table -> BodySpec list.  Columns: see ``_TABLE_COLUMNS``; table keys give defaults."""
    if not isinstance(tab, dict):
        raise _err("bodies_table", tab, "a table { file = 'bodies.csv', ... defaults }")
    _check_keys(tab, ("file",) + tuple(k for k in _TABLE_COLUMNS if k not in ("x", "y", "vx", "vy")), "bodies_table")
    if "file" not in tab or not isinstance(tab["file"], str):
        raise _err("bodies_table.file", tab.get("file"), "the path of a CSV file (relative to the scene file)")
    path = Path(base_dir) / tab["file"]
    defaults = {k: v for k, v in tab.items() if k != "file"}
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise ValueError(f"bodies_table.file = {tab['file']!r}: file {str(path)!r} does not exist") from None
    if not rows:
        raise ValueError(f"bodies_table.file = {tab['file']!r} is empty; expected a header row")
    header = [h.strip() for h in rows[0]]
    for h in header:
        if h not in _TABLE_COLUMNS:
            raise ValueError(f"bodies_table.file {tab['file']!r}: unknown column {h!r}; allowed columns: "
                             + ", ".join(_TABLE_COLUMNS))
    for need in ("x", "y"):
        if need not in header:
            raise ValueError(f"bodies_table.file {tab['file']!r}: no column {need!r}; x and y are required")
    numeric = {"radius", "width", "height", "a", "b", "x", "y", "angle", "density", "vx", "vy", "omega"}
    out = []
    for r, row in enumerate(rows[1:], start=1):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise ValueError(f"bodies_table.file {tab['file']!r} row {r}: {len(row)} values for {len(header)} columns")
        rec = dict(defaults)
        for h, c in zip(header, row):
            c = c.strip()
            if c == "":
                continue
            where = f"bodies_table row {r} column {h}"
            try:
                if h in numeric:
                    rec[h] = float(c)
                elif h == "segments":
                    rec[h] = int(c)
                elif h == "vertices":  # "x0 y0; x1 y1; ..."
                    rec[h] = [[float(t) for t in p.split()] for p in c.split(";")]
                else:
                    rec[h] = c
            except ValueError:
                raise _err(where, c, "a number" if h != "vertices" else "'x0 y0; x1 y1; ...'") from None
        rec["position"] = (rec.pop("x"), rec.pop("y"))
        if "vx" in rec or "vy" in rec:
            rec["velocity"] = (rec.pop("vx", 0.0), rec.pop("vy", 0.0))
        out.append(BodySpec(**rec))
    return out


# ---------------------------------------------------------------------------------------
# the plan
# ---------------------------------------------------------------------------------------
@dataclass
class Effect:
    """One effect of the plan: whether it is ``on``, a short ``value`` and the reason ``why``."""

    name: str
    on: bool
    why: str
    value: str = ""

    def __str__(self):
        state = "on " if self.on else "off"
        val = f" [{self.value}]" if self.value else ""
        return f"  {self.name:15s} {state}{val}  — {self.why}"


@dataclass
class Plan:
    """Which effects a scene needs and why; :class:`fluidem.Simulation` builds only those.

    Attributes
    ----------
    effects : list of Effect
        In order: fluid, inertia, moving-bodies, mesh, ale, contacts, gravity, buoyancy,
        rotation, remeshing, solver.
    mesh : {"none", "once", "moving"}
        No mesh (dry), a mesh built once, or a moving mesh.
    contact_pairs : int
        Pairs (body–body and body–wall) that can meet before ``t_end``.
    unsupported : list of str
        Reasons this version cannot run the scene (empty when it can).
    n_steps : int
    """

    scene_name: str
    effects: list
    mesh: str
    contact_pairs: int
    n_steps: int
    unsupported: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    def effect(self, name) -> Effect:
        for e in self.effects:
            if e.name == name:
                return e
        raise ValueError(f"unknown effect {name!r}; allowed: {', '.join(e.name for e in self.effects)}")

    def on(self, name) -> bool:
        return self.effect(name).on

    def __str__(self):
        lines = [f"plan for scene {self.scene_name!r}: {self.n_steps} steps"]
        lines += [str(e) for e in self.effects]
        lines += [f"  note: {n}" for n in self.notes]
        if self.unsupported:
            lines.append("  cannot run yet:")
            lines += [f"    - {u}" for u in self.unsupported]
        return "\n".join(lines)


def moving_mesh_available() -> bool:
    """True when the moving-mesh layer (:class:`fluidem.mesh.MovingMesh`) can be imported."""
    try:
        from .mesh import MovingMesh  # noqa: F401
    except ImportError:
        return False
    return True


def _sweep(scene: Scene):
    """Motion of each body before any contact: (p0 (n, 2), v (n, 2), acc (n, 2), bounded (n,) bool).

    Until its first contact a body in a dry scene moves exactly as ``p0 + v t + acc t²/2``
    (``acc`` = gravity for free bodies, 0 otherwise); a free body in a fluid is unbounded.
    """
    B = scene.bodies
    n = len(B)
    p0 = np.array([b.position for b in B], float).reshape(n, 2)
    motion = np.array([b.motion for b in B])
    v = np.array([b.velocity for b in B], float).reshape(n, 2)
    v[motion == "fixed"] = 0.0
    acc = np.zeros((n, 2))
    acc[motion == "free"] = scene.gravity
    bounded = ~((motion == "free") & (scene.fluid is not None))
    return p0, v, acc, bounded


def _swept_boxes(p0, v, acc, T):
    """Axis-aligned boxes (lo, hi), each (n, 2), of the centre paths p0 + v t + acc t²/2 for t in [0, T]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(acc != 0, -v / np.where(acc != 0, acc, 1.0), 0.0)
    ts = [np.zeros_like(v), np.full_like(v, T), np.clip(tv, 0.0, T)]  # ends and the parabola's vertex
    pts = np.stack([p0 + v * t + 0.5 * acc * t * t for t in ts])
    return pts.min(axis=0), pts.max(axis=0)


def _min_distance_linear(dp, dv, T):
    """Smallest |dp + dv t| over t in [0, T], rows of (m, 2) arrays."""
    vv = (dv * dv).sum(axis=1)
    t = np.where(vv > 0, -(dp * dv).sum(axis=1) / np.where(vv > 0, vv, 1.0), 0.0)
    t = np.clip(t, 0.0, T)[:, None]
    return np.linalg.norm(dp + dv * t, axis=1)


def contact_candidates(scene: Scene) -> tuple[int, int]:
    """(body–body, body–wall) pairs that may touch before ``t_end``.

    Only free bodies feel contact forces, so every pair counted has a free body.  Walls: the
    swept box of a body's centre path, grown by its bounding radius, reaches a solid side.
    Bodies: their grown swept boxes overlap and, when
    both have the same acceleration (two free bodies under gravity, or two prescribed or
    fixed bodies), their relative motion is linear and its closest approach is exact.
    """
    n = len(scene.bodies)
    if n == 0:
        return 0, 0
    T = scene.time.t_end
    p0, v, acc, bounded = _sweep(scene)
    r = np.array([b.bounding_radius for b in scene.bodies])
    moving = np.array([b.motion == "free" for b in scene.bodies])
    lo, hi = _swept_boxes(p0, v, acc, T)
    lo, hi = lo - r[:, None], hi + r[:, None]
    lo[~bounded], hi[~bounded] = -np.inf, np.inf
    x0, x1, y0, y1 = scene.domain.box
    solid = {k: scene.domain.side(k).type in ("wall", "moving-wall") or (scene.fluid is None and
             scene.domain.side(k).type != "outflow") for k in SIDES}
    hit = {"left": lo[:, 0] <= x0, "right": hi[:, 0] >= x1, "bottom": lo[:, 1] <= y0, "top": hi[:, 1] >= y1}
    n_wall = int(sum((hit[k] & moving).sum() for k in SIDES if solid[k]))
    if not bounded.all():  # free bodies in a fluid: every pair with a free body
        nm = int(moving.sum())
        return int(nm * (nm - 1) // 2 + nm * (n - nm)), n_wall
    n_body = 0
    step = max(1, 1_000_000 // n)
    for a in range(0, n, step):  # brute force in row blocks of ~1e6 pairs
        sl = slice(a, min(a + step, n))
        ii = np.arange(a, min(a + step, n))[:, None]
        jj = np.arange(n)[None, :]
        ok = (jj > ii) & (moving[sl, None] | moving[None, :])
        ok &= (lo[sl, None, 0] <= hi[None, :, 0]) & (lo[None, :, 0] <= hi[sl, None, 0])
        ok &= (lo[sl, None, 1] <= hi[None, :, 1]) & (lo[None, :, 1] <= hi[sl, None, 1])
        i, j = np.nonzero(ok)
        i = i + a
        same = np.all(acc[i] == acc[j], axis=1)
        d = _min_distance_linear(p0[j] - p0[i], v[j] - v[i], T)
        n_body += int((~same | (d < r[i] + r[j])).sum())
    return n_body, n_wall


def prescribed_collisions(scene: Scene) -> list:
    """Descriptions of prescribed bodies that reach a side or another non-free body before ``t_end``."""
    B = scene.bodies
    idx = [k for k, b in enumerate(B) if b.motion == "prescribed" and any(b.velocity)]
    if not idx:
        return []
    T = scene.time.t_end
    p0, v, acc, _ = _sweep(scene)
    r = np.array([b.bounding_radius for b in B])
    lo, hi = _swept_boxes(p0, v, acc, T)
    lo, hi = lo - r[:, None], hi + r[:, None]
    x0, x1, y0, y1 = scene.domain.box
    out = []
    for k in idx:  # prescribed bodies: a handful
        if lo[k, 0] <= x0 or hi[k, 0] >= x1 or lo[k, 1] <= y0 or hi[k, 1] >= y1:
            out.append(f"{B[k].name} to a side of the box")
        others = [j for j, b in enumerate(B) if j != k and b.motion != "free"]
        if others:
            o = np.array(others)
            d = _min_distance_linear(p0[o] - p0[k], v[o] - v[k], T)
            out += [f"{B[k].name} onto {B[j].name}" for j in o[d < r[o] + r[k]] if j > k or B[j].motion == "fixed"]
    return out


def _make_plan(scene: Scene) -> Plan:
    fl = scene.fluid
    bodies = scene.bodies
    n = len(bodies)
    E = []
    unsupported, notes = [], []
    n_steps = scene.time.n_steps
    free = [b for b in bodies if b.motion == "free"]
    moving = [b for b in bodies if b.moves]
    outline_moving = [b for b in bodies if b.outline_moves]
    rotating = [b for b in bodies if (b.motion == "prescribed" and b.omega) or (b.motion == "free")]
    g_on = any(scene.gravity)
    periodic = [s for s in SIDES if scene.domain.side(s).type == "periodic"]

    # fluid
    if fl is None:
        E.append(Effect("fluid", False, "no [fluid] table: a dry scene (no mesh, no fluid solver)"))
        E.append(Effect("inertia", bool(moving), "rigid-body inertia only (DEM)" if moving else "nothing moves",
                        "bodies"))
    else:
        E.append(Effect("fluid", True, f"[fluid] model = {fl.model!r}", f"{fl.model}, element {fl.element}"))
        if fl.model == "stokes":
            E.append(Effect("inertia", False, "model = 'stokes': quasi-steady, no convection and no time derivative"))
        else:
            E.append(Effect("inertia", True, "model = 'navier-stokes': BDF2 in time, convection "
                            f"{fl.convection}", "BDF2"))
    # moving bodies
    if not moving:
        E.append(Effect("moving-bodies", False, "all bodies fixed (or none)" if n else "no bodies"))
    else:
        kinds = sorted({b.motion for b in moving})
        E.append(Effect("moving-bodies", True, f"{len(moving)} of {n} bodies move ({', '.join(kinds)})",
                        f"{len(moving)}"))
    # mesh
    quasi_static_once = fl is not None and fl.model == "stokes" and n_steps == 1
    if fl is None:
        mesh = "none"
        E.append(Effect("mesh", False, "dry scene: no fluid, no mesh"))
        E.append(Effect("ale", False, "no fluid"))
    elif not outline_moving:
        mesh = "once"
        why = "no body outline moves" + (" (spinning disks keep their outline)" if moving else "")
        E.append(Effect("mesh", True, why + ": the mesh is built once", "once"))
        E.append(Effect("ale", False, "the mesh never moves"))
    elif quasi_static_once:
        mesh = "once"
        E.append(Effect("mesh", True, "Stokes at one instant (a single step): the geometry at t = 0 is all a "
                        "quasi-steady solve needs; the mesh is built once", "once"))
        E.append(Effect("ale", False, "one quasi-steady step: the mesh never moves"))
    else:
        mesh = "moving"
        E.append(Effect("mesh", True, f"{len(outline_moving)} body outline(s) move: the mesh follows them",
                        f"moving, strategy {scene.mesh.strategy}"))
        E.append(Effect("ale", fl.model == "navier-stokes",
                        "mesh velocity enters convection (u − w)·∇u" if fl.model == "navier-stokes"
                        else "Stokes has no convection: the mesh velocity does not enter"))
    # contacts
    nb, nw = contact_candidates(scene)
    if scene.contact is None:
        E.append(Effect("contacts", False, "no [contact] table"))
        c_on = False
    elif not scene.contact.enabled:
        E.append(Effect("contacts", False, "contact.enabled = false"))
        c_on = False
    elif nb + nw == 0:
        why = ("no two bodies, or body and wall, can meet before t_end = "
               f"{scene.time.t_end:g} at the speeds the scene allows")
        E.append(Effect("contacts", False, why))
        c_on = False
    else:
        E.append(Effect("contacts", True, f"{nb} body pair(s) and {nw} body–wall pair(s) may meet before t_end",
                        f"E={scene.contact.E:g}, mu={scene.contact.mu:g}, gamma={scene.contact.gamma:g}"))
        c_on = True
    # gravity and buoyancy
    if not g_on:
        E.append(Effect("gravity", False, "gravity = [0, 0]"))
        E.append(Effect("buoyancy", False, "no gravity"))
    elif not free:
        E.append(Effect("gravity", False, "no free bodies: gravity moves nothing" +
                        (" (in the fluid it only adds a hydrostatic pressure)" if fl else "")))
        E.append(Effect("buoyancy", False, "no free bodies"))
    else:
        E.append(Effect("gravity", True, f"{len(free)} free bodies", f"{list(scene.gravity)}"))
        E.append(Effect("buoyancy", fl is not None, "free bodies in a fluid" if fl else "dry scene: no fluid"))
    # rotation
    E.append(Effect("rotation", bool(rotating),
                    f"{len(rotating)} bodies can rotate (free or prescribed omega)" if rotating
                    else "no body rotates"))
    # remeshing
    if mesh == "moving":
        st = scene.mesh.strategy
        E.append(Effect("remeshing", st != "fixed", f"strategy {st!r}, re-triangulate every "
                        f"{scene.mesh.retriangulate_every} steps or when quality drops", st))
    else:
        E.append(Effect("remeshing", False, "no moving mesh: never re-triangulated"))
    # solver
    if fl is None:
        if not moving:
            s = "nothing to integrate: bodies never move"
        elif c_on:
            s = "DEM, Gear predictor-corrector with contact sub-steps"
        else:
            s = "ballistic: closed-form rigid motion (no contacts, no search)"
        E.append(Effect("solver", bool(moving), s))
    elif fl.model == "stokes":
        E.append(Effect("solver", True, "one Stokes saddle-point solve per step (direct LU)", "stokes"))
    else:
        E.append(Effect("solver", True, f"BDF2, {fl.convection} convection, solver {fl.solver}", "bdf2"))

    hit = prescribed_collisions(scene)
    if hit:
        notes.append("prescribed motion brings " + "; ".join(hit[:3]) + (" ..." if len(hit) > 3 else "")
                     + " before t_end (prescribed bodies feel no contact forces)")
    # what this version cannot do (the plan still says what would be needed)
    if periodic:
        unsupported.append(f"periodic sides ({', '.join(periodic)}) are not supported yet by the "
                           + ("fluid solver" if fl else "DEM") + "; use 'wall' or 'outflow'")
    if fl is not None:
        if free:
            unsupported.append(f"free bodies in a fluid ({len(free)}: {', '.join(b.name for b in free[:5])}"
                               f"{', ...' if len(free) > 5 else ''}) need the coupled fluid-body solver, which "
                               "comes in a later version; use motion = 'fixed' or 'prescribed'")
        elif mesh == "moving":
            if not moving_mesh_available():
                unsupported.append("moving bodies in fluid need the moving-mesh layer (fluidem.mesh.MovingMesh), "
                                   "which is not available in this installation")
            else:
                notes.append("prescribed translating bodies use fluidem.mesh.MovingMesh (ALE)")
        if fl.model == "stokes" and n_steps == 1 and outline_moving:
            notes.append("quasi-steady Stokes at t = 0 only: forces are those of the initial geometry")
    else:
        bad = [s for s in SIDES if scene.domain.side(s).type in ("inflow", "moving-wall")]
        if bad:
            unsupported.append(f"domain sides {', '.join(bad)} are fluid conditions; a dry scene allows "
                               "'wall' and 'outflow' (open)")
    return Plan(scene.name, E, mesh, nb + nw, n_steps, unsupported, notes)
