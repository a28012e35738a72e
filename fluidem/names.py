"""One table of every name a user types, with its meaning, and one lookup for all of them.

Scene files, the command line (``choices=``) and the Python factories read the same table,
so a name means the same everywhere and an unknown one gets the same one-line error::

    fluid.solver = 'lu': expected one of 'auto', 'direct', 'iterative', 'lagged' (solver)

Old spellings stay accepted as *aliases* (``"lagged-lu"`` is ``"lagged"``).

Examples
--------
>>> from fluidem import names
>>> names.lookup("solver", "lagged-lu", where="fluid.solver")
'lagged'
>>> names.choices("side")
('bottom', 'right', 'top', 'left')
>>> names.lookup("element", "p4", where="--element")
Traceback (most recent call last):
...
fluidem.errors.InputError: --element = 'p4': expected one of 'p2b', 'th', 'p3', 'mini' (element pair)
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .errors import InputError

__all__ = ["Kind", "REGISTRY", "lookup", "choices", "meaning", "kinds"]


@dataclass(frozen=True)
class Kind:
    """A family of user-typed names: ``entries`` name -> meaning, ``aliases`` old name -> name."""

    title: str
    entries: dict
    aliases: dict = field(default_factory=dict)


REGISTRY: dict[str, Kind] = {
    "element": Kind("element pair", {
        "p2b": "P2 + cubic bubble velocity / discontinuous P1 pressure (Crouzeix-Raviart); default for particle flows",
        "th": "P2 velocity / P1 pressure (Taylor-Hood)",
        "p3": "P3 velocity / P2 pressure",
        "mini": "P1 + cubic bubble velocity / P1 pressure (MINI), first order",
    }),
    "solver": Kind("solver", {
        "auto": "chosen by problem kind and size (fluidem.fluid.solvers.choose_solver)",
        "direct": "a fresh sparse LU every solve (bit-for-bit reproducible restarts)",
        "iterative": "block-preconditioned Krylov (FGMRES, pyamg on the velocity block)",
        "lagged": "an LU reused as a GMRES preconditioner while its iterations stay low",
    }, aliases={"lagged-lu": "lagged"}),
    "LU backend": Kind("LU backend", {
        "auto": "PARDISO for systems of 20 000 DOFs and more when pypardiso is installed, else SuperLU",
        "superlu": "SuperLU (scipy.sparse.linalg.splu)",
        "pardiso": "Intel MKL PARDISO (the optional pypardiso: pip install 'fluidem[pardiso]')",
    }),
    "convection": Kind("convection scheme", {
        "semi-implicit": "linear in u^{n+1}, extrapolated convecting velocity (2u^n - u^{n-1} with BDF2)",
        "newton": "fully implicit, Newton's method every step",
        "explicit": "extrapolated convection term (BDF/EXT), CFL-bounded time step",
    }),
    "time scheme": Kind("time scheme", {
        "auto": "bdf3 on a fixed mesh, bdf2 when the mesh moves",
        "bdf2": "BDF2 (second order), BDF1 on the first step",
        "bdf3": "BDF3 (third order), BDF1 and BDF2 on the first steps; fixed meshes only",
    }),
    "coupling": Kind("fluid-body coupling", {
        "implicit": "fluid and free bodies in one solve per step (added mass inside; stable at density ratio 1)",
        "explicit": "staggered: bodies moved by the fluid forces of the last step (unstable when the added "
                    "mass exceeds the body mass)",
    }),
    "ALE form": Kind("ALE form", {
        "non-conservative": "mass matrix of the new time level, convection (u - w)·∇u; keeps a uniform flow exactly",
        "conservative": "mass matrix of each time level, convection in divergence form; keeps momentum exactly",
    }),
    "strategy": Kind("mesh strategy", {
        "drag": "nodes move with nearby bodies; re-triangulate every K steps or when quality drops",
        "regenerate": "a new triangulation every step",
        "fixed": "the mesh never changes (outlines must not move)",
    }),
    "shape": Kind("body shape", {
        "disk": "circle of `radius` (curved outline in fluid scenes)",
        "polygon": "convex or simple polygon from `vertices` (body coordinates)",
        "rectangle": "`width` x `height`",
        "ellipse": "semi-axes `a`, `b`",
    }),
    "motion": Kind("body motion", {
        "free": "moved by gravity, contacts and the fluid",
        "fixed": "never moves",
        "prescribed": "constant `velocity` and `omega`",
    }),
    "side type": Kind("side type", {
        "wall": "no-slip wall at rest",
        "inflow": "velocity profile into the box (`inflow_profile`)",
        "outflow": "do-nothing outflow",
        "periodic": "periodic with the opposite side",
        "moving-wall": "no-slip wall moving with `velocity`",
    }),
    "side": Kind("box side", {
        "bottom": "y = ymin", "right": "x = xmax", "top": "y = ymax", "left": "x = xmin",
    }),
    "fluid model": Kind("fluid model", {
        "navier-stokes": "unsteady incompressible Navier-Stokes",
        "stokes": "quasi-steady Stokes flow (no inertia)",
    }),
    "profile": Kind("inflow profile", {
        "parabolic": "4 umax s (L - s) / L^2 across the side",
        "uniform": "umax across the side",
    }),
    "case": Kind("benchmark case", {
        "dfg-2d1": "DFG flow around a cylinder, steady, Re = 20",
        "dfg-2d2": "DFG flow around a cylinder, periodic, Re = 100",
        "dfg-2d3": "DFG flow around a cylinder, unsteady inflow, 0 <= t <= 8",
        "square-cylinder": "square cylinder at Re = 100 (Sohankar et al. 1998)",
        "settling-disk": "a free disk settling in a channel, against its steady terminal velocity",
        "dkt": "drafting, kissing and tumbling of two disks (Glowinski et al. 2001), event times",
    }),
    "example": Kind("example scene", {
        "dfg-cylinder": "DFG 2D-1 channel as a scene: Navier-Stokes past a fixed cylinder, Re = 20",
        "wall-correction": "Stokes drag of a disk between two walls (Faxen)",
        "dry-heap": "granular heap, DEM only",
        "column-collapse": "granular column collapse, DEM only",
        "settling-disk": "a free disk settling from rest in a closed channel (Navier-Stokes), against its steady "
                         "terminal velocity",
        "jeffery-orbit": "a free ellipse (aspect ratio 2) turning in a Stokes shear cell, half a Jeffery period",
        "dkt": "drafting, kissing and tumbling of two disks settling in a channel (Glowinski et al. 2001)",
        "suspension": "105 disks, rectangles, triangles and hexagons settling into a bed in a closed box of fluid "
                      "(a 'fluidem fill' body table)",
        "sheared-suspension": "20 free disks at area fraction 0.1 crossing the periodic sides of a Stokes shear cell; "
                              "the effective viscosity in run.json",
        "column-collapse-fluid": "200 polygons of a granular step collapsing in a viscous liquid on a graded moving "
                                 "mesh (its dry twin: column-collapse-fluid-dry)",
        "column-collapse-fluid-dry": "the grains and box of column-collapse-fluid without the liquid, DEM only",
    }),
    "schur": Kind("Schur-complement approximation", {
        "auto": "cahouet-chabard when a time step is given, mass otherwise",
        "mass": "nu M_p^-1 (Stokes)",
        "cahouet-chabard": "nu M_p^-1 + (alpha/dt) (B D_u^-1 B^T)^-1 (unsteady)",
        "lsc": "least-squares commutator",
    }),
    "units": Kind("unit system", {
        "SI": "m, kg, s, N (labels only: the numbers must be in this system, nothing converts)",
        "CGS": "cm, g, s, dyn (labels only: the numbers must be in this system, nothing converts)",
    }, aliases={"si": "SI", "cgs": "CGS"}),
}


def kinds() -> tuple:
    """The kinds of names in the registry."""
    return tuple(REGISTRY)


def choices(kind: str) -> tuple:
    """The canonical names of ``kind``, in the registry's order (aliases excluded)."""
    return tuple(REGISTRY[kind].entries)


def meaning(kind: str, name: str) -> str:
    """What name ``name`` of ``kind`` means (aliases resolved)."""
    return REGISTRY[kind].entries[lookup(kind, name)]


def lookup(kind: str, value, where: str | None = None, error=InputError) -> str:
    """The canonical name for ``value`` (a name or an alias) of ``kind``.

    Raises ``error`` (default :class:`fluidem.errors.InputError`, a ``ValueError``) naming
    ``where`` the value was typed (default: the kind), the value and the allowed names.
    """
    k = REGISTRY[kind]
    if isinstance(value, str):
        if value in k.entries:
            return value
        if value in k.aliases:
            return k.aliases[value]
    allowed = ", ".join(repr(n) for n in k.entries)
    raise error(f"{where or kind} = {value!r}: expected one of {allowed} ({k.title})")
