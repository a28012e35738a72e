"""Scenes: what to simulate, read from TOML or built in Python.

A scene describes a domain, an optional fluid, rigid polygonal bodies, their contacts, the
mesh, the time span and the output.  :meth:`Scene.from_toml` reads a file, validates every
key and value (a wrong one raises :class:`fluidem.errors.SceneError`, a ``ValueError``,
naming the key, the value and what is allowed) and :meth:`Scene.plan` hands the scene to
:mod:`fluidem.plan`, which decides which effects it needs and why::

    gravity = [0.0, -980.0]          # top level, before any table (length/time²)
    [fluid]                          # absent: a dry (pure DEM) scene
    density = 1.0                    # mass/length² (2D: per unit depth)
    viscosity = 0.01                 # kinematic, length²/time
    model = "navier-stokes"          # or "stokes" (quasi-steady, no inertia)
    body_force = [0.0, 0.0]          # per unit mass, length/time²
    solver = "auto"                  # auto | direct | iterative | lagged (alias lagged-lu)
    [domain]
    box = [0.0, 2.0, 0.0, 8.0]       # xmin, xmax, ymin, ymax (length)
    left = "wall"                    # wall | inflow | outflow | periodic | moving-wall
    top = { type = "moving-wall", velocity = [1.0, 0.0] }
    inflow_profile = { type = "parabolic", umax = 1.5 }
    [[bodies]]
    shape = "disk"                   # disk | polygon | rectangle | ellipse
    radius = 0.1
    position = [1.0, 7.2]
    density = 1.01                   # mass/length²
    motion = "free"                  # free | fixed | prescribed (velocity, omega)
    [bodies_table]                   # many bodies: one CSV row per body
    file = "particles.csv"
    [contact]
    E = 1e5                          # force/length (F = E A / l)
    mu = 0.2
    gamma = 0.05
    [mesh]
    h = 0.02                         # length
    grading = { region = [0.0, 2.0, 5.0, 8.0], growth = 1.2 }
    strategy = "drag"                # drag | regenerate | fixed
    retriangulate_every = 30
    [time]
    dt = 1e-3                        # time
    t_end = 5.0
    [output]
    dir = "out"
    every = 10

Units
-----
fluidem has no built-in unit system: every quantity is in the one consistent system the
user picks — SI (m, kg, s, N, Pa) or CGS (cm, g, s, dyn), say — and nothing converts.  The
simulation is two-dimensional and every 2D quantity is per unit depth: ``density`` (fluid
and bodies) is mass/length² (a 3D density times the unit depth), forces are per unit depth,
and so are masses (density × area) and moments of inertia.  ``viscosity`` is *kinematic*,
ν = μ/ρ in length²/time (the dynamic viscosity is ``density * viscosity``); the fluid is
solved for the kinematic pressure p/ρ.  Velocities are length/time, angular velocities
rad/time, ``gravity`` and ``body_force`` length/time², ``E`` of the contact law force/length.
Docstrings name quantities in these terms (``length``, ``time``, ``mass``).

Names
-----
Every name typed in a scene (``solver``, ``convection``, ``element``, ``model``, side types,
``shape``, ``motion``, ``strategy``, inflow ``type``) is looked up in
:data:`fluidem.names.REGISTRY`, the table the command line and the Python factories use
too; old spellings are accepted as aliases and stored canonically.  Sides are named and
ordered as ``names.choices("side")``: bottom, right, top, left.

Choices made here (see the CHANGELOG):

* A polygon body's ``vertices`` are in body coordinates; they are shifted so that their
  area centroid is the origin, and ``position`` places that centroid (as in :mod:`fluidem.dem`).
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
* Contacts are off when no pair can meet before ``t_end`` (:mod:`fluidem.plan`).

Layout: :mod:`fluidem.scene.specs` (:class:`Scene`), the spec dataclasses of its tables in
:mod:`fluidem.scene.domain`, :mod:`fluidem.scene.bodies`, :mod:`fluidem.scene.physics` and
:mod:`fluidem.scene.settings`,
:mod:`fluidem.scene.files` (TOML and CSV in, TOML out), :mod:`fluidem.scene.reference` (the
reference of every table and key, ``docs/scenes.md``, printed by ``fluidem reference``) and
:mod:`fluidem.plan` (the plan).

Examples
--------
>>> from fluidem.scene import Scene
>>> s = Scene.from_dict({"domain": {"box": [0, 1, 0, 1]},
...                      "fluid": {"viscosity": 1e-3, "solver": "lagged-lu"},
...                      "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.5, 0.5],
...                                  "motion": "fixed"}]})
>>> s.fluid.solver
'lagged'
>>> Scene.from_dict({"domain": {"box": [0, 1, 0, 1], "left": "slippery"}})  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
fluidem.errors.SceneError: domain.left = 'slippery': expected one of 'wall', 'inflow', ..., 'moving-wall' (side type)
"""

from .. import names as _names
from ..plan import Effect, Plan, contact_candidates, make_plan, moving_mesh_available, prescribed_collisions
from . import files, specs
from .files import read_bodies_table, read_toml, scene_toml, tomllib, write_scene_toml
from .bodies import BodySpec
from .domain import DomainSpec, SideSpec
from .physics import ContactSpec, FluidSpec
from .settings import MeshSpec, OutputSpec, TimeSpec
from .specs import Scene

# The names a scene accepts, from the registry (kept for code that imported these tuples).
SIDE_TYPES = _names.choices("side type")
SIDES = _names.choices("side")
SHAPES = _names.choices("shape")
MOTIONS = _names.choices("motion")
FLUID_MODELS = _names.choices("fluid model")
MESH_STRATEGIES = _names.choices("strategy")
PROFILE_TYPES = _names.choices("profile")
CONVECTION = _names.choices("convection")
SOLVERS = _names.choices("solver")

__all__ = ["Scene", "FluidSpec", "DomainSpec", "SideSpec", "BodySpec", "ContactSpec", "MeshSpec", "TimeSpec",
           "OutputSpec", "Plan", "Effect", "make_plan", "moving_mesh_available", "contact_candidates",
           "prescribed_collisions", "read_toml", "read_bodies_table", "scene_toml", "write_scene_toml", "tomllib",
           "files", "specs", "SIDE_TYPES", "SIDES", "SHAPES", "MOTIONS", "FLUID_MODELS", "MESH_STRATEGIES",
           "PROFILE_TYPES", "CONVECTION", "SOLVERS"]
