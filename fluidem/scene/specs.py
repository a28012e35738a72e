"""The scene as a whole: :class:`Scene`, which holds the spec dataclasses of its tables,
validates them together, reads and writes them, and hands out its plan.

The tables live beside it: :mod:`fluidem.scene.domain` (:class:`DomainSpec`,
:class:`SideSpec`), :mod:`fluidem.scene.bodies` (:class:`BodySpec`),
:mod:`fluidem.scene.physics` (:class:`FluidSpec`, :class:`ContactSpec`) and
:mod:`fluidem.scene.settings` (:class:`MeshSpec`, :class:`TimeSpec`, :class:`OutputSpec`);
this module re-exports them.

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

from .. import names
from ..errors import InputError, SceneError
from ..validate import check_keys, fail, pair
from . import files
from .bodies import MAX_SEGMENTS, BodySpec
from .domain import MAX_COORDINATE, DomainSpec, SideSpec
from .physics import ContactSpec, FluidSpec
from .settings import MeshSpec, OutputSpec, TimeSpec

if TYPE_CHECKING:  # pragma: no cover
    from ..plan import Plan

__all__ = ["Scene", "FluidSpec", "DomainSpec", "SideSpec", "BodySpec", "ContactSpec", "MeshSpec", "TimeSpec",
           "OutputSpec", "default_h", "MAX_SEGMENTS", "MAX_COORDINATE"]


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
        """Bodies inside the box (or across its periodic sides where the run can take them) and not
        overlapping each other, through the periodic sides too (shapely, vectorised)."""
        if not self.bodies:
            return
        polys = self.world_outlines()
        lo = np.array([p.min(axis=0) for p in polys])
        hi = np.array([p.max(axis=0) for p in polys])
        # the moving mesh meshes a body across a periodic side as its images on both sides, and the
        # DEM of a dry scene takes every pair at its nearest image; a fixed mesh cannot
        moving_mesh = self.fluid is not None and any(b.outline_moves for b in self.bodies)
        can_cross = self.fluid is None or moving_mesh
        self._check_periodic_extents(lo, hi, can_cross)
        self._check_inside_box(lo, hi, can_cross)
        self._check_overlaps(polys, lo, hi)

    def _periodic_sides(self):
        """(axis, (low side, high side), (low, high)) of each periodic pair of the box."""
        x0, x1, y0, y1 = self.domain.box
        return [(c, sides, bounds) for c, sides, bounds in ((0, ("left", "right"), (x0, x1)),
                                                            (1, ("bottom", "top"), (y0, y1)))
                if self.domain.side(sides[0]).type == "periodic"]

    def _check_periodic_extents(self, lo, hi, can_cross):
        """Every body narrower than the period; across a periodic side only where the run can take it."""
        for c, (s0, s1), (b0, b1) in self._periodic_sides():
            width = hi[:, c] - lo[:, c]
            wide = np.flatnonzero(width >= b1 - b0)
            if len(wide):
                i = int(wide[0])
                raise SceneError(f"bodies[{i}] has width {width[i]:.4g} in {'xy'[c]} across the periodic sides "
                                 f"{s0}/{s1}: allowed: narrower than the period {b1 - b0:.4g}")
            cross = np.flatnonzero((lo[:, c] <= b0) | (hi[:, c] >= b1))
            if len(cross) and not can_cross:
                i = int(cross[0])
                side = s0 if lo[i, c] <= b0 else s1
                raise SceneError(f"bodies[{i}].position = {list(self.bodies[i].position)}: the body (extent "
                                 f"{'xy'[c]} {lo[i, c]:.4g}..{hi[i, c]:.4g}) overlaps the periodic side {side!r} "
                                 f"at {'xy'[c]} = {b0 if side == s0 else b1:g}; allowed: every vertex strictly "
                                 "inside the box (a body across a periodic side needs the moving mesh: a fluid "
                                 "scene with a free or moving body; or a dry scene)")

    def _check_inside_box(self, lo, hi, can_cross):
        """Every vertex inside the box, except across periodic sides where the run can take it."""
        x0, x1, y0, y1 = self.domain.box
        # a body whose outline moves in a fluid is meshed by the moving mesh, which merges a body
        # touching a wall with the wall: touching is fine there, overlapping is not
        touch = np.array([self.fluid is not None and b.outline_moves for b in self.bodies])
        tol = 1e-12 * max(x1 - x0, y1 - y0)
        below = np.where(touch, -tol, 0.0)
        px = can_cross and self.domain.side("left").type == "periodic"
        py = can_cross and self.domain.side("bottom").type == "periodic"
        out = np.flatnonzero((~px & ((lo[:, 0] - x0 <= below) | (x1 - hi[:, 0] <= below)))
                             | (~py & ((lo[:, 1] - y0 <= below) | (y1 - hi[:, 1] <= below))))
        if len(out):
            i = int(out[0])
            allowed = ("every vertex inside the box or on a wall (a moving body may touch a wall)" if touch[i]
                       else "every vertex strictly inside the box")
            raise SceneError(f"bodies[{i}].position = {list(self.bodies[i].position)}: the body (extent "
                             f"x {lo[i, 0]:.4g}..{hi[i, 0]:.4g}, y {lo[i, 1]:.4g}..{hi[i, 1]:.4g}) is not inside "
                             f"domain.box = {list(self.domain.box)}; allowed: {allowed}")

    def _check_overlaps(self, polys, lo, hi):
        """No two bodies overlap (a fluid scene: touch), also through a periodic side: a body across
        a side is tested with its images shifted by one period back into the box."""
        import shapely

        def polygons(rings):
            at = np.repeat(np.arange(len(rings)), [len(r) for r in rings])
            return shapely.polygons(shapely.linearrings(np.vstack(rings), indices=at))

        n = len(polys)
        back = np.zeros((n, 2))  # per body: the shift by one period back into the box, per periodic axis
        for c, _, (b0, b1) in self._periodic_sides():
            back[:, c] = np.where(lo[:, c] <= b0, b1 - b0, 0.0) - np.where(hi[:, c] >= b1, b1 - b0, 0.0)
        rings, owner = list(polys), list(range(n))
        for use in ((1, 0), (0, 1), (1, 1)):  # the images along x, along y, and at a corner
            d = back * use
            for k in np.flatnonzero(np.all((d != 0.0) | (np.array(use) == 0), axis=1) & d.any(axis=1)):
                rings.append(polys[k] + d[k])
                owner.append(int(k))
        geoms, owner = polygons(rings), np.array(owner)
        pairs = shapely.STRtree(geoms).query(geoms, predicate="intersects")
        pairs = pairs[:, (pairs[0] < pairs[1]) & (owner[pairs[0]] != owner[pairs[1]])]
        if not pairs.shape[1]:
            return
        i, j = pairs
        area = shapely.area(shapely.intersection(geoms[i], geoms[j]))
        ref = np.minimum(shapely.area(geoms[i]), shapely.area(geoms[j]))
        bad = np.flatnonzero(area > 1e-9 * ref)
        first = int(bad[0]) if len(bad) else 0
        a, b = sorted((int(owner[i[first]]), int(owner[j[first]])))
        where = f"bodies[{a}] (position {list(self.bodies[a].position)}) and bodies[{b}] (position " \
                f"{list(self.bodies[b].position)})"
        if len(bad):
            across = " (through a periodic side)" if max(i[first], j[first]) >= n else ""
            raise SceneError(f"{where} overlap at start{across} by {area[first]:.3g} (length²); allowed: bodies "
                             "that do not overlap" + (" or touch" if self.fluid is None else ""))
        if self.fluid is not None:  # touching outlines leave no fluid between them: no mesh can be built
            raise SceneError(f"{where} touch at start; in a fluid scene bodies need fluid between them: move them "
                             f"apart (a gap of at least mesh.h = {self.mesh.h:g}) or make them one polygon body")

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
