"""The scene file reference: every table and key with type, default, unit and allowed values.

:func:`markdown` writes it (``fluidem reference`` prints it; ``docs/scenes.md`` is its
output, checked in).  It is generated from what the scene reader accepts, so that it cannot
drift: the keys and defaults come from the spec dataclasses of the scene's tables (their
``KEYS``, ``PROFILE_KEYS``, ``GRADING_KEYS`` and field defaults) and from
:data:`fluidem.scene.files.TABLE_COLUMNS`, the allowed names and their meanings from
:data:`fluidem.names.REGISTRY`, the units of the output from :data:`fluidem.io.HISTORY_UNITS`.
Only what a key means and its unit are written here (:data:`KEY_DOCS`); a key the reader
accepts without an entry there makes :func:`markdown` raise, so a new key cannot be left out.

:data:`WORKED_EXAMPLE` is a complete scene written from the reference alone (a rotating
cylinder in a channel at Re = 40).

Examples
--------
>>> from fluidem.scene.reference import markdown, accepted_keys
>>> text = markdown()
>>> text.splitlines()[0]
'# Scene file reference'
>>> "fluid.viscosity" in accepted_keys() and "`viscosity`" in text
True
"""

from __future__ import annotations

import dataclasses

from .. import names
from ..errors import FluidemError
from . import files, specs
from .bodies import BodySpec
from .domain import DomainSpec, SideSpec
from .physics import ContactSpec, FluidSpec
from .settings import MeshSpec, OutputSpec, TimeSpec

__all__ = ["markdown", "accepted_keys", "KEY_DOCS", "WORKED_EXAMPLE", "TABLES"]

#: table name -> (heading, spec class or None, keys): in the order the reference shows them
TABLES = {
    "": ("Top level (before any table)", None, specs._TOP_KEYS),
    "fluid": ("[fluid]", FluidSpec, FluidSpec.KEYS),
    "domain": ("[domain]", DomainSpec, DomainSpec.KEYS),
    "domain.<side>": ("A side as a table: `left = { type = ..., velocity = ..., profile = ... }`", SideSpec,
                      SideSpec.KEYS),
    "domain.inflow_profile": ("An inflow profile: `inflow_profile = { ... }` or a side's `profile = { ... }`", None,
                              DomainSpec.PROFILE_KEYS),
    "bodies": ("[[bodies]] (one table per body)", BodySpec, BodySpec.KEYS),
    "bodies_table": ("[bodies_table] (many bodies: one CSV row per body)", None, files.TABLE_KEYS),
    "bodies_table.csv": ("Columns of the CSV body table", None, files.TABLE_COLUMNS),
    "contact": ("[contact]", ContactSpec, ContactSpec.KEYS),
    "mesh": ("[mesh]", MeshSpec, MeshSpec.KEYS),
    "mesh.grading": ("Mesh grading: `grading = { region = ..., growth = ..., h_max = ... }`", None,
                     MeshSpec.GRADING_KEYS),
    "time": ("[time]", TimeSpec, TimeSpec.KEYS),
    "output": ("[output]", OutputSpec, OutputSpec.KEYS),
}

#: names a key takes from :mod:`fluidem.names` (key -> registry kind)
NAME_KINDS = {
    ".units": "units", "fluid.model": "fluid model", "fluid.element": "element", "fluid.convection": "convection",
    "fluid.solver": "solver", "fluid.coupling": "coupling", "fluid.lu_backend": "LU backend",
    "fluid.ale_form": "ALE form", "time.scheme": "time scheme", "domain.bottom": "side type",
    "domain.right": "side type", "domain.top": "side type", "domain.left": "side type",
    "domain.<side>.type": "side type", "domain.inflow_profile.type": "profile", "bodies.shape": "shape",
    "bodies.motion": "motion", "bodies_table.shape": "shape", "bodies_table.motion": "motion",
    "bodies_table.csv.shape": "shape", "bodies_table.csv.motion": "motion", "mesh.strategy": "strategy",
}

# (type, unit, meaning[, default when the dataclass has none or the key is not a field])
_BODY = {
    "shape": ("name", "—", "outline shape; each shape takes its own size keys"),
    "radius": ("number > 0", "length", "radius of a `disk` (required for a disk)"),
    "segments": ("integer 3 to 100000", "—", "outline vertices of a `disk` or `ellipse` (in a fluid a disk is meshed "
                 "as a curved circle and this sets its outline nodes)", "32 dry; about 2πr/h (even, ≥ 16) in a fluid"),
    "vertices": ("[[x0, y0], [x1, y1], ...]", "length", "`polygon` vertices in body coordinates, counter-clockwise, "
                 "convex, ≥ 3; shifted so that their area centroid is the origin"),
    "width": ("number > 0", "length", "width of a `rectangle` (along the body x axis)"),
    "height": ("number > 0", "length", "height of a `rectangle`"),
    "a": ("number > 0", "length", "semi-axis of an `ellipse` along the body x axis"),
    "b": ("number > 0", "length", "semi-axis of an `ellipse` along the body y axis"),
    "position": ("[x, y]", "length", "centre of mass (area centroid) at the start"),
    "angle": ("number", "rad", "orientation at the start (counter-clockwise)"),
    "density": ("number > 0", "mass/length²", "areal density, per unit depth like the fluid's"),
    "motion": ("name", "—", "how the body moves"),
    "velocity": ("[vx, vy]", "length/time", "initial velocity (`free`) or the constant velocity (`prescribed`); "
                 "zero for `fixed`"),
    "omega": ("number", "rad/time", "initial (`free`) or constant (`prescribed`) angular velocity, "
              "counter-clockwise; zero for `fixed`"),
    "name": ("string", "—", "boundary name of its outline on the mesh; unique, not a side name", "body<i>"),
}

#: what each key means and its unit: "table.key" -> (type, unit, meaning[, default text])
KEY_DOCS = {
    ".name": ("string", "—", "scene name (plan, run record)", "the file name without .toml"),
    ".description": ("string", "—", "one line shown by `fluidem examples`", '`""`'),
    ".units": ("name", "—", "the unit system the numbers are in, for the labels of figures only (`x [m]` "
               "instead of `x [length]`); nothing is converted", "not named: labels give dimensions"),
    ".gravity": ("[gx, gy]", "length/time²", "acceleration of gravity (e.g. `[0, -9.81]` in SI, `[0, -981]` in "
                 "CGS); on the fluid with fixed or prescribed bodies only it adds a hydrostatic pressure and is "
                 "left out", "`[0.0, 0.0]`"),
    ".fluid": ("table", "—", "the fluid; absent: a dry scene (DEM only, no mesh)", "absent"),
    ".domain": ("table", "—", "the box and its sides (required)", "required"),
    ".bodies": ("array of tables", "—", "`[[bodies]]`, one table per body", "no bodies"),
    ".bodies_table": ("table", "—", "bodies from a CSV file, one row per body (added after `[[bodies]]`)",
                      "absent"),
    ".contact": ("table", "—", "contact law; absent: contacts off", "absent (contacts off)"),
    ".mesh": ("table", "—", "fluid mesh", "defaults"),
    ".time": ("table", "—", "time step and end time (absent: the defaults, and the plan says so)", "defaults"),
    ".output": ("table", "—", "what a run writes", "defaults"),
    "fluid.density": ("number > 0", "mass/length²", "density ρ per unit depth (a 3D density times the unit depth); "
                      "forces and pressures written are ρ times the kinematic ones"),
    "fluid.viscosity": ("number > 0", "length²/time", "**kinematic** viscosity ν = μ/ρ (the dynamic viscosity is "
                        "`density * viscosity`); Re = U L / ν"),
    "fluid.model": ("name", "—", "equations solved"),
    "fluid.body_force": ("[fx, fy]", "length/time²", "body force per unit mass (a mean pressure gradient G in a "
                         "periodic channel is `-G / density`)"),
    "fluid.element": ("name", "—", "velocity/pressure element pair"),
    "fluid.convection": ("name", "—", "convection term of the unsteady solver (free bodies with coupling "
                         "`implicit`: `semi-implicit` only)"),
    "fluid.solver": ("name", "—", "linear solver"),
    "fluid.coupling": ("name", "—", "how free bodies and the fluid are coupled"),
    "fluid.ale_form": ("name", "—", "moving meshes: the ALE form (conservative keeps the momentum exactly)"),
    "fluid.zero_net_flux": ("true or false", "—", "periodic sedimentation (Stokes, free bodies, gravity through "
                            "periodic sides): the mean pressure gradient G that keeps the volume flux through the "
                            "periodic sides zero is solved for and acts on the fluid and on every body (−G per unit "
                            "volume of each); in a doubly periodic cell G·L_x L_y = Σ (ρ_s − ρ_f) A g.  Carrying "
                            "the weight by a `body_force` on the fluid alone makes the bodies settle 1/(1 − φ) too "
                            "fast (φ the area fraction of bodies).  Not with a `body_force` along a periodic axis"),
    "fluid.lu_backend": ("name", "—", "the sparse LU of the direct and lagged solvers: `auto` is PARDISO (the "
                         "optional pypardiso) for systems of 20 000 DOFs and more when it is installed, SuperLU "
                         "otherwise; `pardiso` without pypardiso is refused"),
    "domain.box": ("[xmin, xmax, ymin, ymax]", "length", "the rectangular domain; coordinates of magnitude at most "
                   "1e50, sides at least 1e-50 long"),
    "domain.bottom": ("name or table", "—", "side y = ymin: a side type, or a table (below)"),
    "domain.right": ("name or table", "—", "side x = xmax: a side type, or a table (below)"),
    "domain.top": ("name or table", "—", "side y = ymax: a side type, or a table (below)"),
    "domain.left": ("name or table", "—", "side x = xmin: a side type, or a table (below)"),
    "domain.inflow_profile": ("table", "—", "inflow profile of every `inflow` side without its own (below); "
                              "required when a side is `inflow`", "absent"),
    "domain.<side>.type": ("name", "—", "side type", '`"wall"`'),
    "domain.<side>.velocity": ("[vx, vy]", "length/time", "wall velocity of a `moving-wall` (zero on every other "
                               "type)"),
    "domain.<side>.profile": ("table", "—", "inflow profile of this side (below)", "the domain's inflow_profile"),
    "domain.inflow_profile.type": ("name", "—", "shape of the inflow speed across the side", '`"parabolic"`'),
    "domain.inflow_profile.umax": ("number", "length/time", "peak inflow speed (normal to the side, into the box); "
                                   "the mean of a parabolic profile is 2/3 umax", "required"),
    "domain.inflow_profile.ramp": ("number ≥ 0", "time", "the inflow rises smoothly from 0 over this time (0: at "
                                   "once)", "`0.0`"),
    **{f"bodies.{k}": v for k, v in _BODY.items()},
    "bodies_table.file": ("string", "—", "path of the CSV file, relative to the scene file", "required"),
    **{f"bodies_table.{k}": (v[0], v[1], "default for every row: " + v[2], "—")
       for k, v in _BODY.items() if k in files.TABLE_KEYS},
    **{f"bodies_table.csv.{k}": (v[0] if k != "vertices" else '"x0 y0; x1 y1; ..."', v[1], v[2], "—")
       for k, v in _BODY.items() if k in files.TABLE_COLUMNS},
    "bodies_table.csv.x": ("number", "length", "centre x (required in every row)", "required"),
    "bodies_table.csv.y": ("number", "length", "centre y (required in every row)", "required"),
    "bodies_table.csv.vx": ("number", "length/time", "velocity x (as `velocity`)", "`0.0`"),
    "bodies_table.csv.vy": ("number", "length/time", "velocity y (as `velocity`)", "`0.0`"),
    "contact.E": ("number > 0", "force/length", "2D stiffness of the overlap law F = E A / l (overlap area A, "
                  "characteristic length l; forces per unit depth)"),
    "contact.mu": ("number ≥ 0", "—", "Coulomb friction coefficient"),
    "contact.gamma": ("number ≥ 0", "—", "normal damping coefficient"),
    "contact.enabled": ("true or false", "—", "`false` switches contacts off whatever the geometry"),
    "contact.repulsion_range": ("number > 0, below half the box's shorter side", "length",
                                "fluid scenes: cut-off distance ρ of the short-range repulsion between outlines "
                                "(and from walls), Glowinski et al. 2001; default 0.01 `mesh.h`: a backstop well "
                                "below the gaps whose film the mesh resolves"),
    "contact.repulsion_force": ("number ≥ 0", "force (per unit depth)", "fluid scenes: force scale c of the "
                                "repulsion, (c/ε)((ρ − g)/ρ)² at gap g; default the largest buoyant weight "
                                "of a free body; 0 switches it off"),
    "contact.repulsion_epsilon": ("number > 0", "—", "fluid scenes: stiffness ε of the repulsion (default "
                                  "1e-4 · mesh.h/ρ: the stiffness at contact of ε = 1e-4 at ρ = h); a body "
                                  "pressed by c rests at the gap ρ(1 − √ε)"),
    "contact.lubrication": ("true or false", "—", "fluid scenes with inertia: the 2D squeeze-film force "
                            "3√2π μ V (a*/g)^(3/2), less its value at the cut-off, in the contact sub-steps (a* the "
                            "reduced radius of the equal-area disks; the coupled step cannot follow the film in time)"),
    "contact.lubrication_range": ("number > 0, below half the box's shorter side", "length",
                                  "cut-off g_c of the lubrication correction; default `mesh.h`"),
    "contact.lubrication_resolved_gap": ("number ≥ 0", "length", "resolved-film length δ_r of the mesh: add only the "
                                         "part 3√2π μ a*^(3/2) (g^(−3/2) − (g² + δ_r²)^(−3/4)) the mesh misses "
                                         "quasi-statically (measured: Taylor–Hood 0.025 h, P3/P2 0.015 h, "
                                         "P2+bubble and MINI 0; 0 switches the correction off); default: the whole "
                                         "law"),
    "mesh.h": ("number > 0", "length", "target edge length of the fluid mesh",
               "min(L/20, d/4): L the box's shorter side, d the smallest body's bounding diameter"),
    "mesh.grading": ("table", "—", "finer mesh in a region, growing away from it (below)", "absent (uniform h)"),
    "mesh.strategy": ("name", "—", "moving mesh: how it follows the bodies"),
    "mesh.retriangulate_every": ("integer ≥ 1", "steps", "moving mesh `drag`: re-triangulate at least this often"),
    "mesh.repair": ("true or false", "—", "moving mesh `drag`: before re-triangulating for element quality, move the "
                    "nodes around the few degraded elements (fields transferred there); fewer re-triangulations in "
                    "dense settling suspensions", "`false`"),
    "mesh.curved": ("true or false", "—", "mesh disks as curved circles (isoparametric outline)"),
    "mesh.grading.region": ('"bodies" or [xmin, xmax, ymin, ymax]', "length", "where the size is h", '`"bodies"`'),
    "mesh.grading.growth": ("number ≥ 1", "—", "size ratio of neighbouring cells away from the region", "`1.2`"),
    "mesh.grading.h_max": ("number ≥ h", "length", "largest cell size", "8 h"),
    "time.dt": ("number > 0", "time", "time step"),
    "time.t_end": ("number ≥ dt", "time", "end time: a whole number of steps (the run takes t_end/dt steps)"),
    "time.scheme": ("name", "—", "BDF formula of the fluid: 'auto' is BDF3 on a fixed mesh (third order; DFG 2D-2: "
                    "St and c_D,max 8x closer to the reference than BDF2 at the same dt), BDF2 when the mesh moves"),
    "output.dir": ("string", "—", "output directory (`fluidem run --out` overrides it)"),
    "output.every": ("integer ≥ 1", "steps", "fields and body outlines every this many steps (and the last)"),
    "output.history_every": ("integer ≥ 1", "steps", "history.csv rows every this many steps (and the last)"),
    "output.checkpoint_every": ("integer ≥ 0", "steps", "checkpoints every this many steps (0: only at the end)",
                                "about ten a run, the newest three kept"),
    "output.fields": ("true or false", "—", "`false` writes no fluid fields"),
    "output.full_order": ("true or false", "—", "also write the fields at full resolution (`fields_full.pvd`: "
                          "quadratic triangles for P2/P1, a refined linear mesh for P3, P2+bubble and MINI); "
                          "`false`: vertex values only"),
    "output.xdmf": ("true or false", "—", "at the end of the run also write the field series as one XDMF time "
                    "series (`fields_full.xdmf` + `.h5`, for ParaView and meshio); needs a mesh built once and "
                    "h5py (`pip install \"fluidem[xdmf]\"`)"),
    "output.checkpoint_seconds": ("number ≥ 0", "s (wall clock)", "a checkpoint at least this often (0: off)"),
    "output.rheology_window": ("[t0, t1]", "time", "a Couette cell (walls across a periodic box, one moving): the "
                               "times over which run.json's `rheology` averages the effective viscosity; "
                               "0 ≤ t0 < t1 ≤ t_end", "the second half of the run"),
}

#: a complete scene written from this reference alone: a rotating cylinder in a channel at Re = 40
WORKED_EXAMPLE = '''\
name = "rotating-cylinder"
description = "A cylinder spinning in a channel, Re = 40 on the mean inflow speed and the diameter"
# D = 0.1, mean inflow speed U = 2/3 umax = 0.4, Re = U D / nu = 0.4 * 0.1 / 1e-3 = 40.
# Surface speed omega D/2 = 8 * 0.05 = 0.4 = U (rotation rate 1).

[fluid]
density = 1.0              # mass/length^2 (per unit depth)
viscosity = 1e-3           # KINEMATIC, length^2/time: nu = U D / Re
element = "p2b"

[domain]
box = [0.0, 2.2, 0.0, 0.41]   # length
left = "inflow"
right = "outflow"
bottom = "wall"
top = "wall"
inflow_profile = { type = "parabolic", umax = 0.6, ramp = 1.0 }   # length/time, time

[[bodies]]
name = "cylinder"
shape = "disk"
radius = 0.05              # length
position = [0.2, 0.2]      # length
motion = "prescribed"      # spins in place: the mesh stays fixed
omega = 8.0                # rad/time, counter-clockwise

[mesh]
h = 0.0125                 # length, at the cylinder
grading = { region = "bodies", growth = 1.15, h_max = 0.04 }

[time]
dt = 0.01                  # time
t_end = 8.0

[output]
dir = "out-rotating-cylinder"
every = 50
'''


def accepted_keys() -> list:
    """Every key the scene reader accepts, as ``"table.key"`` (``".key"`` at the top level), in reference order.

    Nested tables are ``"domain.<side>.type"``, ``"domain.inflow_profile.umax"``,
    ``"mesh.grading.growth"``; the CSV columns of a body table are ``"bodies_table.csv.x"``.
    """
    return [f"{table}.{k}" for table, (_, _, keys) in TABLES.items() for k in keys]


def _default(table: str, key: str, spec) -> str:
    doc = KEY_DOCS[f"{table}.{key}"]
    if len(doc) > 3:
        return doc[3]
    f = {f.name: f for f in dataclasses.fields(spec)}[key]
    value = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    if isinstance(value, SideSpec):
        value = value.type
    return "—" if value is None else f"`{files.toml_value(value)}`"


def _allowed(path: str) -> str:
    kind = NAME_KINDS.get(path)
    if kind is None:
        return ""
    return ", ".join(f"`{n}`" for n in names.choices(kind))


def _names_section(kinds) -> list:
    lines = []
    for kind in kinds:
        k = names.REGISTRY[kind]
        lines.append(f"*{k.title}*:")
        lines.append("")
        for n, what in k.entries.items():
            alias = [a for a, c in k.aliases.items() if c == n]
            lines.append(f"- `{n}`: {what}" + (f" (alias: {', '.join(f'`{a}`' for a in alias)})" if alias else ""))
        lines.append("")
    return lines


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(table: str, seen: set) -> list:
    heading, spec, keys = TABLES[table]
    missing = [k for k in keys if f"{table}.{k}" not in KEY_DOCS]
    if missing:
        raise FluidemError(f"the scene reference has no entry for {table}.{missing[0]}: add it to "
                           "fluidem.scene.reference.KEY_DOCS")
    lines = [f"### {heading}", "", "| key | type | default | unit | allowed | meaning |",
             "|---|---|---|---|---|---|"]
    kinds = []
    for k in keys:
        path = f"{table}.{k}"
        typ, unit, meaning = KEY_DOCS[path][:3]
        default = _default(table, k, spec) if spec is not None or len(KEY_DOCS[path]) > 3 else "—"
        lines.append("| " + " | ".join(_cell(c) for c in (f"`{k}`", typ, default, unit, _allowed(path), meaning))
                     + " |")
        kind = NAME_KINDS.get(path)
        if kind is not None and kind not in kinds and kind not in seen:
            kinds.append(kind)
            seen.add(kind)
    lines.append("")
    if kinds:
        lines += _names_section(kinds)
    return lines


_UNITS = """\
## Units

fluidem has **no built-in unit system**: every number is in the one consistent system you
pick (SI: m, kg, s, N, Pa; CGS: cm, g, s, dyn; or dimensionless), and nothing is converted.
The columns below give each quantity's dimension in that system: *length*, *time*, *mass*,
*force* (= mass·length/time²), *rad*.

- The simulation is **two-dimensional and per unit depth**: a `density` (fluid or body) is
  **mass/length²** (a 3D density times the unit depth: water in SI is 1000 kg/m³ × 1 m =
  1000 kg/m²), masses and moments of inertia are per unit depth, and **forces and torques are per
  unit depth** (force/length and force·length/length in 3D terms).
- `viscosity` is the **kinematic** viscosity ν = μ/ρ, **length²/time** (water in SI:
  1.0e-6 m²/s, *not* 1.0e-3 Pa·s, which with density 1000 would be a fluid 1000× too
  viscous); the dynamic viscosity is `density * viscosity`.  A Reynolds number is
  Re = U L / ν.
- Velocities are length/time, angular velocities rad/time, accelerations (`gravity`,
  `body_force`) length/time², angles rad.
- The fluid is solved for the kinematic pressure p/ρ; the pressure and loads a run writes are
  dynamic (ρ times the kinematic ones).
"""

_CSV = """\
The CSV file has a header row naming its columns (any of those below, in any order; `x` and
`y` are required), then one row per body; an empty cell takes the `[bodies_table]` default
or the body default.  `x`, `y` are the body's `position`, `vx`, `vy` its `velocity`.  A
`vertices` cell holds a polygon's vertices as `"x0 y0; x1 y1; ..."` (pairs separated by
`;`, coordinates by spaces; quote the cell):

```text
shape,radius,width,height,x,y,angle,vertices
disk,0.005,,,0.10,0.05,0.0,
rectangle,,0.008,0.004,0.12,0.05,0.3,
polygon,,,,0.14,0.05,0.0,"0 0; 0.006 0; 0.003 0.005"
```

`fluidem fill OUT.csv --box XMIN XMAX YMIN YMAX --fraction PHI --radius R_MIN R_MAX --shapes ...`
writes such a table of random non-overlapping bodies (a suspension; `docs/suspensions.md`).
"""


def markdown() -> str:
    """The scene file reference as Markdown (the text of ``docs/scenes.md``).

    Raises
    ------
    fluidem.errors.FluidemError
        When a key the scene reader accepts has no entry in :data:`KEY_DOCS`.
    """
    from ..io import HISTORY_UNITS

    out = ["# Scene file reference", "",
           "<!-- generated by `fluidem reference` (fluidem.scene.reference.markdown); do not edit by hand -->", "",
           "A scene is a TOML file: a few top-level keys, then tables.  Every key is optional unless it says "
           "*required*; a key the reader does not know is an error naming the nearest known key.  Start from a "
           "built-in scene: `fluidem examples` lists them, `fluidem examples --show NAME` prints one, "
           "`fluidem new NAME DIR` copies it (with its CSV body table); `fluidem plan SCENE` checks a scene and "
           "says what it will compute, without running it.", "", _UNITS, "## Tables and keys", ""]
    seen: set = set()
    for table in TABLES:
        if table == "bodies_table.csv":
            out += [f"### {TABLES[table][0]}", "", _CSV]
            out += _table(table, seen)[2:]
            continue
        out += _table(table, seen)
    out += ["## What a run writes", "",
            "`history.csv` has one row per recorded step and body; its columns and their units (also in the "
            "run's `run.json`):", "", "| column | unit |", "|---|---|"]
    out += [f"| `{k}` | {v} |" for k, v in HISTORY_UNITS.items()]
    out += ["", "`fx`, `fy`, `torque` are the hydrodynamic load in a fluid scene (dynamic: ρ times the kinematic "
            "load) and the contact load in a dry scene.", "",
            "## Worked example: a rotating cylinder in a channel, Re = 40", "",
            "Written from the tables above alone.  The channel and cylinder are those of the DFG benchmark "
            "(diameter D = 0.1 in a channel 0.41 high); the parabolic inflow has peak `umax` = 0.6, so its mean "
            "is U = 2/3 · 0.6 = 0.4, and Re = U D / ν = 40 gives the kinematic viscosity ν = 1e-3.  The "
            "cylinder is `prescribed` with `omega` only: it spins in place, so the mesh is built once.  "
            "`fluidem plan rotating-cylinder.toml` checks it.", "", "```toml", WORKED_EXAMPLE.rstrip("\n"), "```",
            ""]
    return "\n".join(out)
