"""The plan: which effects a scene needs, and why.

A :class:`fluidem.scene.Scene` says *what* to simulate; :func:`make_plan` (also
:meth:`Scene.plan`) decides which parts a run needs — fluid, inertia, moving bodies, mesh,
ALE, contacts, gravity, buoyancy, rotation, remeshing, solver — and gives the reason for
each; :class:`fluidem.Simulation` builds only those.  Scene -> plan -> simulation.

Contacts are off when no two bodies (one of them movable), or a movable body and a wall,
can meet before ``t_end`` at the speeds the scene allows: prescribed speed plus |ω| r for
prescribed bodies, |v₀| t + |g| t²/2 for free bodies in a dry scene (until the first
contact only gravity acts), zero for fixed bodies (:func:`contact_candidates`).

Examples
--------
>>> from fluidem.scene import Scene
>>> from fluidem.plan import make_plan
>>> s = Scene.from_dict({"gravity": [0.0, -9.81], "domain": {"box": [0, 1, 0, 1]},
...                      "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.08]}],
...                      "contact": {"E": 1e5}, "time": {"dt": 1e-3, "t_end": 0.1}})
>>> p = make_plan(s)
>>> p.mesh, p.on("contacts"), p.contact_pairs
('none', True, 1)
>>> print(p.effect("contacts"))  # doctest: +ELLIPSIS
  contacts        on  [E=100000, mu=0.23, gamma=0.025]  — 0 body pair(s) and 1 body–wall pair(s) may meet ...
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import names
from .errors import InputError

if TYPE_CHECKING:  # pragma: no cover
    from .scene import Scene

__all__ = ["Plan", "Effect", "make_plan", "moving_mesh_available", "contact_candidates", "prescribed_collisions",
           "mesh_estimate", "machine_memory", "boundary_fluxes", "FLUX_TOLERANCE", "contact_sub_steps",
           "MAX_CONTACT_SUBSTEPS", "REFUSED_CONTACT_SUBSTEPS"]

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
        coupling, rotation, remeshing, periodic, solver.
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
    #: things the run will do but should not go unsaid (a coarse or degenerate mesh, memory)
    warnings: list = field(default_factory=list)
    #: fluid scenes: rough size of the mesh and its solve before anything is built (:func:`mesh_estimate`)
    estimate: dict | None = None

    def effect(self, name) -> Effect:
        for e in self.effects:
            if e.name == name:
                return e
        raise InputError(f"effect = {name!r}: expected one of {', '.join(repr(e.name) for e in self.effects)}")

    def on(self, name) -> bool:
        return self.effect(name).on

    def __str__(self):
        lines = [f"plan for scene {self.scene_name!r}: {self.n_steps} steps"]
        lines += [str(e) for e in self.effects]
        if self.estimate:
            e = self.estimate
            if np.isfinite(e["peak_bytes"]):
                lines.append(f"  estimate: about {e['triangles']:.2g} triangles, {e['nodes']:.2g} nodes, "
                             f"{e['dofs']:.2g} DOFs, peak memory {_bytes(e['peak_bytes'])} (this machine: "
                             f"{_bytes(e['machine_bytes'])})")
            else:
                lines.append(f"  estimate: beyond 1e308 triangles (this machine: {_bytes(e['machine_bytes'])})")
        lines += [f"  note: {n}" for n in self.notes]
        lines += [f"  warning: {w}" for w in self.warnings]
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
             scene.domain.side(k).type != "outflow") for k in names.choices("side")}
    hit = {"left": lo[:, 0] <= x0, "right": hi[:, 0] >= x1, "bottom": lo[:, 1] <= y0, "top": hi[:, 1] >= y1}
    n_wall = int(sum((hit[k] & moving).sum() for k in names.choices("side") if solid[k]))
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
        reach = [s for s, hit in (("left", lo[k, 0] <= x0), ("right", hi[k, 0] >= x1), ("bottom", lo[k, 1] <= y0),
                                  ("top", hi[k, 1] >= y1)) if hit]
        periodic = [s for s in reach if scene.domain.side(s).type == "periodic"]
        if periodic:
            out.append(f"{B[k].name} to the periodic side {periodic[0]!r} (crossing a periodic side is not "
                       "supported: the run stops when the body comes closer than mesh.h to it)")
        elif reach:
            out.append(f"{B[k].name} to a side of the box")
        others = [j for j, b in enumerate(B) if j != k and b.motion != "free"]
        if others:
            o = np.array(others)
            d = _min_distance_linear(p0[o] - p0[k], v[o] - v[k], T)
            out += [f"{B[k].name} onto {B[j].name}" for j in o[d < r[o] + r[k]] if j > k or B[j].motion == "fixed"]
    return out




#: relative tolerance of a zero net boundary flux: |Σ Q| <= this × Σ |Q| (the fluxes' round-off)
FLUX_TOLERANCE = 1e-9

#: outward unit normal of each side of the box
_OUTWARD = {"bottom": (0.0, -1.0), "right": (1.0, 0.0), "top": (0.0, 1.0), "left": (-1.0, 0.0)}


def boundary_fluxes(scene: Scene) -> list:
    """The flux into the box through each side that imposes one, exactly, at full speed.

    An inflow side of length L carries ∫ u·(−n) ds = umax L (uniform profile) or 2/3 umax L
    (parabolic, 4 umax s (L − s) / L²), reached after its ``ramp``; a moving wall −(v·n) L at
    once (only its normal velocity counts).  Walls and periodic sides carry none, and the rigid
    outlines of bodies none in total (a rigid motion is divergence-free).

    Returns
    -------
    list of (side, flux, ramp, what)
        ``flux`` into the box, length²/time (per unit depth), ``ramp`` its rise time, ``what``
        a short description of the side; only ``inflow`` and ``moving-wall`` sides.

    Examples
    --------
    >>> from fluidem.scene import Scene
    >>> s = Scene.from_dict({"fluid": {}, "domain": {"box": [0, 2, 0, 1], "left": "inflow", "right": "outflow",
    ...                      "inflow_profile": {"type": "parabolic", "umax": 1.5}}})
    >>> boundary_fluxes(s)
    [('left', 1.0, 0.0, 'inflow, parabolic umax = 1.5')]
    """
    x0, x1, y0, y1 = scene.domain.box
    out = []
    for s in names.choices("side"):
        side = scene.domain.side(s)
        L = x1 - x0 if s in ("bottom", "top") else y1 - y0
        if side.type == "moving-wall":
            n = _OUTWARD[s]
            q = -(side.velocity[0] * n[0] + side.velocity[1] * n[1]) * L
            out.append((s, q + 0.0, 0.0, f"moving-wall, velocity {list(side.velocity)}"))
        elif side.type == "inflow":
            p = scene.domain.profile_of(s)
            mean = 2.0 / 3.0 if p["type"] == "parabolic" else 1.0
            out.append((s, mean * p["umax"] * L, p["ramp"], f"inflow, {p['type']} umax = {p['umax']:g}"))
    return out


def _flux_refusal(scene: Scene) -> str | None:
    """Why an incompressible flow cannot exist in ``scene``'s box, or None: without an ``outflow``
    side the fluxes of :func:`boundary_fluxes` must sum to zero at every instant (those that ramp
    up together, over the same ``ramp``, among themselves)."""
    if any(scene.domain.side(s).type == "outflow" for s in names.choices("side")):
        return None
    flux = boundary_fluxes(scene)
    total = sum(q for _, q, _, _ in flux)
    tol = FLUX_TOLERANCE * sum(abs(q) for _, q, _, _ in flux) + 1e-300
    parts = [f"{s} ({what}{f', ramp {r:g}' if r else ''}: {q:+.4g})" for s, q, r, what in flux if q != 0.0]
    if not parts:
        return None
    sides = ("domain side " if len(parts) == 1 else "domain sides ") + (
        parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1])
    if abs(total) > tol:
        return (f"{sides} {'carries' if len(parts) == 1 else 'carry'} a net flux of {abs(total):.4g} "
                f"{'into' if total > 0 else 'out of'} the box (length²/time), and no side is 'outflow': an "
                "incompressible flow cannot exist; expected a net flux of 0 (periodic pairs carry none), or a side "
                "of type 'outflow'")
    for r in sorted({r for _, _, r, _ in flux}):
        part = sum(q for _, q, rr, _ in flux if rr == r)
        if abs(part) > tol:
            return (f"{sides} balance at full speed but ramp up differently (a moving wall at once, an inflow over "
                    f"its ramp): those with ramp {r:g} carry a net flux of {part:+.4g} into the box (length²/time) "
                    "on their own, and no side is 'outflow': an incompressible flow cannot exist while they ramp; "
                    "expected the same ramp on the sides that balance each other, or a side of type 'outflow'")
    return None


#: DEM sub-steps per pass over one step above which the plan warns, and above which it refuses
#: (such a step would not end in any useful time)
MAX_CONTACT_SUBSTEPS, REFUSED_CONTACT_SUBSTEPS = 10_000, 1_000_000


def contact_sub_steps(scene: Scene) -> tuple[float, float, str] | None:
    """DEM sub-steps per pass over one step ``time.dt`` of ``scene`` where an overlap may form: ``(n, dt_max, set_by)``.

    The most a pass takes (in a fluid, passes where no overlap can form and the repulsion is far take
    fewer: :meth:`fluidem.coupling.contacts.FluidContacts.sub_steps`):
    ``n = ceil(dt / dt_max)`` with the DEM's bound ``dt_max = 0.1 π √(m / k)``
    (:func:`fluidem.dem.system.stable_sub_step`): ``m`` the lightest free body's DEM mass (ρ_s A dry,
    (ρ_s + ρ_f) A in a fluid), ``k`` the stiffer of ``contact.E`` and, for free bodies in an
    inertial fluid, the repulsion's stiffness at contact 2c/(ερ)
    (:func:`fluidem.coupling.contacts.repulsion_for`).  ``set_by`` names the parameter; ``n``
    is ``inf`` beyond floating point.  None without contacts or free bodies, and for Stokes
    bodies (their repulsion is implicit in the mobility solve: no sub-steps).

    Examples
    --------
    >>> from fluidem.scene import Scene
    >>> s = Scene.from_dict({"gravity": [0, -9.81], "domain": {"box": [0, 1, 0, 1]},
    ...     "bodies": [{"shape": "rectangle", "width": 0.1, "height": 0.1, "position": [0.5, 0.5], "density": 1.0}],
    ...     "contact": {"E": 1e4}, "time": {"dt": 0.01, "t_end": 0.1}})
    >>> n, dt_max, by = contact_sub_steps(s)   # m = 0.01: dt_max = 0.1π√(1e-6) = 3.14e-4
    >>> n, round(dt_max, 7), by
    (32.0, 0.0003142, 'contact.E = 1e+04 force/length')
    """
    c, fl = scene.contact, scene.fluid
    free = [b for b in scene.bodies if b.motion == "free"]
    if c is None or not c.enabled or not free or (fl is not None and fl.model == "stokes"):
        return None
    from .dem.system import stable_sub_step
    from .geometry import polygon_area

    areas = np.array([abs(polygon_area(b.local_vertices(scene.default_segments(b)))) for b in free])
    dens = np.array([b.density for b in free], float)
    mass = float(((dens + (fl.density if fl is not None else 0.0)) * areas).min())
    rep = None
    if fl is not None:
        from .coupling.contacts import repulsion_for

        rep = repulsion_for(scene, areas, dens)
    dt_max, by = stable_sub_step(mass, c.E, rep)
    with np.errstate(all="ignore"):
        n = scene.time.dt / dt_max
    return (float(np.ceil(n - 1e-9)) if np.isfinite(n) and n < 1e15 else float("inf")), dt_max, by


def _sub_step_check(scene: Scene) -> tuple[str | None, str | None]:
    """``(warning, refusal)`` for a scene whose contacts take too many DEM sub-steps a step."""
    sub = contact_sub_steps(scene)
    if sub is None or sub[0] <= MAX_CONTACT_SUBSTEPS:
        return None, None
    n, dt_max, by = sub
    text = (f"contacts take up to {n:.3g} DEM sub-steps per pass over each step of time.dt = {scene.time.dt:g} "
            f"(dt_max = {dt_max:.3g}, set by {by}, with the lightest free body); expected at most "
            f"{MAX_CONTACT_SUBSTEPS}: "
            "lower that stiffness (a smaller E or repulsion_force, a larger repulsion_epsilon or repulsion_range), "
            "or time.dt")
    return (None, text) if n > REFUSED_CONTACT_SUBSTEPS else (text, None)


#: Density ratio below which ``coupling = "explicit"`` is warned about: a disk settling in a
#: channel blew up at 1.01 and ran stably at 1.5 (tests/coupling/test_free_flow.py).
EXPLICIT_COUPLING_MIN_RATIO = 1.5


def make_plan(scene: Scene) -> Plan:
    """The effects ``scene`` needs and why, see :class:`Plan` (:meth:`fluidem.scene.Scene.plan` calls this).

    Parameters
    ----------
    scene : fluidem.scene.Scene
        A validated scene.

    Returns
    -------
    Plan
    """
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
    periodic = [s for s in names.choices("side") if scene.domain.side(s).type == "periodic"]

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
            E.append(Effect("inertia", True, "model = 'navier-stokes': time derivative and convection "
                            f"{fl.convection}", "navier-stokes"))
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
        if fl.model != "navier-stokes":
            E.append(Effect("ale", False, "Stokes has no convection: the mesh velocity does not enter"))
        elif fl.ale_form == "conservative":
            E.append(Effect("ale", True, "conservative form: each time level's mass matrix, convection "
                                         "div(u ⊗ (u − w)); momentum kept to solver tolerance",
                            "conservative"))
        else:
            E.append(Effect("ale", True, "mesh velocity enters convection (u − w)·∇u (non-conservative form: "
                                         "uniform flow kept exactly, momentum to discretisation error)",
                            "non-conservative"))
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
    # fluid-body coupling
    if fl is None or not free:
        E.append(Effect("coupling", False, "no free bodies in a fluid" if fl is not None else "no fluid"))
    elif fl.model == "stokes":
        E.append(Effect("coupling", True, f"{len(free)} free bodies: Stokes mobility, force and torque balance "
                        "solved with the fluid in one bordered saddle-point system", "mobility"))
    else:
        E.append(Effect("coupling", True, f"{len(free)} free bodies: fluid and Newton-Euler rows in one implicit "
                        "BDF2 solve (added mass inside the matrix)", "implicit"))
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
    # periodic sides
    if not periodic:
        E.append(Effect("periodic", False, "no periodic sides"))
    else:
        x0, x1, y0, y1 = scene.domain.box
        pairs = [f"{a}/{b} (period {p:g} in {ax})" for a, b, p, ax in
                 (("left", "right", x1 - x0, "x"), ("bottom", "top", y1 - y0, "y")) if a in periodic]
        drive = ""
        if fl is not None:
            drive = (f"; driven by body_force = {list(fl.body_force)}" if any(fl.body_force) else
                     "; no body_force (driven by moving walls or bodies only)")
        E.append(Effect("periodic", True, "periodic pairs " + ", ".join(pairs) + ": matching mesh nodes, "
                        "identified velocity (and continuous pressure) DOFs" + drive,
                        "+".join(ax for a, ax in (("left", "x"), ("bottom", "y")) if a in periodic)))
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
        E.append(Effect("solver", True, f"one Stokes saddle-point solve per step, solver {fl.solver}", "stokes"))
    else:
        scheme = scene.time.bdf_scheme(moving_mesh=mesh == "moving")
        auto = scene.time.scheme == "auto"
        why = f" (time.scheme = 'auto': {scheme.upper()} on a {'moving' if mesh == 'moving' else 'fixed'} mesh)" \
            if auto else ""
        E.append(Effect("solver", True, f"{scheme.upper()}{why}, {fl.convection} convection, solver {fl.solver}",
                        scheme))

    hit = prescribed_collisions(scene)
    if hit:
        notes.append("prescribed motion brings " + "; ".join(hit[:3]) + (" ..." if len(hit) > 3 else "")
                     + " before t_end (prescribed bodies feel no contact forces)")
    contact_warnings = []
    # what this version cannot do (the plan still says what would be needed)
    if periodic and fl is None:
        unsupported.append(f"periodic sides ({', '.join(periodic)}) are not supported yet by the DEM "
                           "(a dry scene); use 'wall' or 'outflow'")
    if fl is not None:
        if free and not moving_mesh_available():
            unsupported.append(f"free bodies in a fluid ({len(free)}) need the moving-mesh layer "
                               "(fluidem.mesh.MovingMesh), which is not available in this installation")
        elif free:
            if fl.solver == "iterative" and fl.model == "stokes":
                notes.append("solver = 'iterative': the Stokes mobility problem of free bodies uses the lagged LU")
            elif fl.solver == "iterative":
                notes.append("solver = 'iterative': the coupled fluid-body system is solved by block-preconditioned "
                             "GMRES with the body velocities in the velocity block")
            if c_on and fl.model == "stokes":
                from .coupling.contacts import repulsion_for

                rep = repulsion_for(scene, np.zeros(0), np.zeros(0))
                notes.append(f"contacts of Stokes free bodies: the short-range repulsion (Glowinski et al. 2001) "
                             f"below {rep.range:g}, epsilon {rep.epsilon:g}, in the mobility problem, linearly "
                             "implicit in the poses (Euler in the steps where it acts); no lubrication correction, "
                             "no DEM contact law or friction (bodies pressed together harder than the repulsion's "
                             "largest force overlap, and the run stops with a message)")
            elif c_on:
                c = scene.contact
                if c.repulsion_force is None and (not g_on or all(b.density == fl.density for b in free)):
                    contact_warnings.append(
                        "contacts in a fluid with neither gravity nor a density difference: the default repulsion "
                        "force scale (the largest buoyant weight) is 0, so bodies that meet overlap and the run stops; "
                        "expected contact.repulsion_force > 0 (a force per unit depth, e.g. the largest load that "
                        "presses bodies together)")
                from .coupling.contacts import lubrication_for, repulsion_for

                rep = repulsion_for(scene, np.zeros(0), np.zeros(0))
                lub = lubrication_for(scene)
                force = (f"{c.repulsion_force:g}" if c.repulsion_force is not None
                         else "the largest buoyant weight of a free body")
                if lub is not None:
                    what = ("the squeeze-film law" if lub.resolved_gap is None
                            else f"the part of the squeeze-film law the mesh misses (resolved-film length "
                                 f"{lub.resolved_gap:g})")
                    lub_text = f"a lubrication correction, {what}, below the gap {lub.range:g}"
                else:
                    lub_text = "no lubrication correction (contact.lubrication off or resolved_gap = 0)"
                notes.append(f"contacts inside the fluid step: {lub_text}; a short-range repulsion (Glowinski et "
                             f"al. 2001) below {rep.range:g} as a backstop, force scale {force}, epsilon "
                             f"{rep.epsilon:g}; the DEM contact law on overlaps; sub-stepped with the fluid's force "
                             "held whenever outlines come within reach")
            elif nb + nw:
                notes.append("no [contact] table: free bodies must stay apart and off the walls (the run stops with "
                             "a message if they overlap); add [contact] for contacts and short-range repulsion")
        elif mesh == "moving":
            if not moving_mesh_available():
                unsupported.append("moving bodies in fluid need the moving-mesh layer (fluidem.mesh.MovingMesh), "
                                   "which is not available in this installation")
            else:
                notes.append("prescribed translating bodies use fluidem.mesh.MovingMesh (ALE)")
        if scene.time.scheme == "bdf3" and mesh == "moving" and fl.model == "navier-stokes":
            unsupported.append("time.scheme = 'bdf3' needs a fixed mesh (the moving mesh keeps two time levels); "
                               "expected 'bdf2' or 'auto' for a scene whose bodies move")
        if fl.model == "stokes" and n_steps == 1 and outline_moving:
            notes.append("quasi-steady Stokes at t = 0 only: forces are those of the initial geometry")
        if mesh == "moving" and scene.mesh.strategy == "fixed":
            unsupported.append(f"mesh.strategy = 'fixed' keeps the mesh still, but {len(outline_moving)} body "
                               f"outline(s) move ({', '.join(b.name for b in outline_moving[:3])}); use strategy "
                               "'drag' or 'regenerate'")
    else:
        bad = [s for s in names.choices("side") if scene.domain.side(s).type in ("inflow", "moving-wall")]
        if bad:
            unsupported.append(f"domain sides {', '.join(bad)} are fluid conditions; a dry scene allows "
                               "'wall' and 'outflow' (open)")
    estimate, warnings = None, []
    if fl is not None:
        flux = _flux_refusal(scene)
        if flux:
            unsupported.append(flux)
        estimate = mesh_estimate(scene)
        warnings, refuse = _mesh_warnings(scene, estimate)
        warnings = contact_warnings + warnings
        unsupported += refuse
        if free and fl.coupling == "explicit" and fl.model != "stokes":
            light = min(free, key=lambda b: b.density)
            ratio = light.density / fl.density
            if ratio < EXPLICIT_COUPLING_MIN_RATIO:
                warnings.append(f"fluid.coupling = 'explicit' with body {light.name!r} at density ratio "
                                f"rho_s/rho_f = {ratio:g}: a staggered step blows up when the fluid's added mass "
                                f"(about rho_f A for a disk, more near walls) exceeds the body mass; expected "
                                f"a ratio >= {EXPLICIT_COUPLING_MIN_RATIO:g}, or coupling = 'implicit'")
            if c_on:
                warnings.append("fluid.coupling = 'explicit' with contacts: the staggered step applies the resolved "
                                "squeeze film a step late, so a body approaching a wall or another body overshoots "
                                "into the backstop and bounces (measured: a disk of density ratio 10 draining onto "
                                "a floor bounces off it at half its fall speed); expected coupling = 'implicit' "
                                "where bodies meet")
    if c_on:
        warn, refuse = _sub_step_check(scene)
        warnings += [warn] if warn else []
        unsupported += [refuse] if refuse else []
    if fl is None and scene.contact is None and nb + nw:  # a dry scene moves bodies in closed form: nothing stops them
        warnings.append(f"no [contact] table: {nb} body pair(s) and {nw} body–wall pair(s) can meet before t_end = "
                        f"{scene.time.t_end:g}, and without contacts bodies pass through each other and through the "
                        "walls; expected a [contact] table (E, mu, gamma) for bodies that meet")
    from .rheology import plan_note

    rheo = plan_note(scene)
    if rheo:
        notes.append(rheo)
    defaulted = getattr(scene, "defaulted", ())
    if "time" in defaulted:
        notes.append(f"no [time] table: default dt = {scene.time.dt:g}, t_end = {scene.time.t_end:g}")
    if "mesh.h" in defaulted and fl is not None:
        notes.append(f"no mesh.h: default h = {scene.mesh.h:g}")
    return Plan(scene.name, E, mesh, nb + nw, n_steps, unsupported, notes, warnings, estimate)


# ---------------------------------------------------------------------------------------
# mesh size before the mesh: estimates and warnings
# ---------------------------------------------------------------------------------------
#: DOFs per mesh vertex of each element pair on a triangle mesh (E ≈ 3V edges, T ≈ 2V triangles)
DOFS_PER_VERTEX = {"th": 9.0, "p2b": 18.0, "p3": 22.0, "mini": 7.0}
#: measured: triangles ≈ this × area / h² (an equilateral mesh has 2.31; the boundary refinement adds the rest)
TRIANGLES_PER_AREA = 3.6
#: measured peak memory per DOF of a run (matrices, the LU factors, the moving mesh), bytes; plus a base
BYTES_PER_DOF, BYTES_BASE = 11e3, 150e6
#: smallest mesh edges along a body's outline, and smallest thickness / h, before a warning
MIN_EDGES_PER_BODY, MIN_THICKNESS_PER_H = 8, 0.1


def _bytes(b: float) -> str:
    if not np.isfinite(b):
        return "beyond 1e308 bytes"
    for unit, f in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= f:
            return f"{b / f:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def machine_memory() -> tuple[float, float]:
    """(total, available) physical memory of this machine, bytes (``inf`` when unknown)."""
    import os

    try:
        page = os.sysconf("SC_PAGE_SIZE")
        return float(page * os.sysconf("SC_PHYS_PAGES")), float(page * os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not a POSIX system
        return float("inf"), float("inf")


def _outline_stats(scene):
    """(areas (n,), perimeters (n,)) of the bodies' initial outlines, length² and length."""
    outlines = scene.world_outlines()
    area = np.array([0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
                     for p in outlines])  # once per plan
    perim = np.array([np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum() for p in outlines])
    return area, perim


def _graded_cells(scene, fluid_area: float) -> float:
    """∫ dA / h(x)² over the fluid for the graded size h = min(h_max, h + (growth − 1) d)
    (:class:`fluidem.mesh.background.GradedSize`), d the distance to the grading region (the
    bodies' bounding circles, or a box), by the midpoint rule on a grid of ~40k cells scaled to
    the fluid area."""
    from scipy.spatial import cKDTree

    x0, x1, y0, y1 = scene.domain.box
    g, h = scene.mesh.grading, scene.mesh.h
    n = 200
    nx = max(8, int(round(n * np.sqrt((x1 - x0) / (y1 - y0)))))
    ny = max(8, int(round(n * n / nx)))
    X, Y = np.meshgrid(x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx, y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny)
    P = np.column_stack([X.ravel(), Y.ravel()])
    reg = g["region"]
    if reg == "bodies":
        if not scene.bodies:
            return fluid_area / h / h
        C = np.array([b.position for b in scene.bodies], float)
        R = np.array([b.bounding_radius for b in scene.bodies])
        k = min(8, len(C))
        dist, idx = cKDTree(C).query(P, k=k)
        dist, idx = dist.reshape(len(P), k), idx.reshape(len(P), k)
        d = np.maximum((dist - R[idx]).min(axis=1), 0.0)
    else:
        dx = np.maximum(np.maximum(reg[0] - P[:, 0], P[:, 0] - reg[1]), 0.0)
        dy = np.maximum(np.maximum(reg[2] - P[:, 1], P[:, 1] - reg[3]), 0.0)
        d = np.hypot(dx, dy)
    size = np.minimum(g["h_max"], h + (g["growth"] - 1.0) * d)
    box_area = (x1 - x0) * (y1 - y0)
    with np.errstate(over="ignore"):  # an absurdly small h: inf, which the plan refuses
        return float(np.mean((1.0 / size) / size)) * fluid_area if box_area > 0 else 0.0


def mesh_estimate(scene) -> dict:
    """Rough size of a fluid scene's mesh and solve, before anything is built.

    Triangles ≈ :data:`TRIANGLES_PER_AREA` × (fluid area) / h² (graded: × the mean of
    (h/h(x))² over the box for the graded size h(x)); nodes ≈ triangles / 2; DOFs by
    :data:`DOFS_PER_VERTEX`; peak memory ≈ :data:`BYTES_BASE` + :data:`BYTES_PER_DOF` × DOFs
    (measured for a Taylor–Hood channel with the default solver).  Within a factor of ~2.

    Returns
    -------
    dict
        ``triangles``, ``nodes``, ``dofs``, ``peak_bytes``, ``machine_bytes``,
        ``available_bytes`` (floats).
    """
    x0, x1, y0, y1 = scene.domain.box
    area_b, _ = _outline_stats(scene) if scene.bodies else (np.zeros(0), None)
    A = max((x1 - x0) * (y1 - y0) - float(area_b.sum()), 0.0)
    h = scene.mesh.h
    g = scene.mesh.grading
    if g is None:  # in ratios to h: inf, not an error, for an absurdly small h (the plan refuses it)
        with np.errstate(over="ignore"):
            tri = TRIANGLES_PER_AREA * max(((x1 - x0) / h) * ((y1 - y0) / h) - float(area_b.sum() / h / h), 0.0)
    else:
        tri = TRIANGLES_PER_AREA * _graded_cells(scene, A)
    n_boundary = 2.0 * ((x1 - x0) + (y1 - y0)) / h + sum(scene.default_segments(b) for b in scene.bodies)
    tri = max(tri, n_boundary)  # at least the outline nodes, however coarse h is
    nodes = max(tri / 2.0, n_boundary)
    dofs = DOFS_PER_VERTEX.get(scene.fluid.element, 9.0) * nodes
    total, avail = machine_memory()
    return {"triangles": tri, "nodes": nodes, "dofs": dofs, "peak_bytes": BYTES_BASE + BYTES_PER_DOF * dofs,
            "machine_bytes": total, "available_bytes": avail}


def _mesh_warnings(scene, est) -> tuple[list, list]:
    """(warnings, refusals) about a fluid scene's mesh: memory, a coarse box, coarse or thin bodies."""
    warn, refuse = [], []
    h = scene.mesh.h
    x0, x1, y0, y1 = scene.domain.box
    L = min(x1 - x0, y1 - y0)
    size = (f"mesh.h = {h:g}: about {est['nodes']:.2g} nodes, {est['dofs']:.2g} DOFs, peak memory "
            f"{_bytes(est['peak_bytes'])}")
    if not np.isfinite(est["peak_bytes"]):
        refuse.append(f"mesh.h = {h:g} in the box {x1 - x0:g} × {y1 - y0:g}: more than 1e308 nodes (the estimate "
                      f"overflows), far beyond this machine's {_bytes(est['machine_bytes'])}: raise mesh.h (or grade "
                      "the mesh with mesh.grading)")
    elif est["peak_bytes"] > est["machine_bytes"]:
        refuse.append(f"{size}, more than this machine's {_bytes(est['machine_bytes'])}: raise mesh.h (or grade the "
                      "mesh with mesh.grading)")
    elif est["peak_bytes"] > 0.5 * est["available_bytes"]:
        warn.append(f"{size}, more than half the memory available now ({_bytes(est['available_bytes'])})")
    if h > L / 4:
        warn.append(f"mesh.h = {h:g} is coarse for the box ({x1 - x0:g} × {y1 - y0:g}): about {est['triangles']:.0f} "
                    f"triangles; results will be far off (the default is min(box / 20, body / 4) = "
                    f"{scene.default_mesh_size():g})")
    if scene.bodies:
        area, perim = _outline_stats(scene)
        nodes = np.array([scene.default_segments(b) if b.shape in ("disk", "ellipse") else len(b.local_vertices())
                          for b in scene.bodies])  # the outline's own vertices stay in the mesh
        edges = np.maximum(perim / h, nodes)
        thick = 2.0 * area / np.maximum(perim, 1e-300)
        for k in np.flatnonzero(edges < MIN_EDGES_PER_BODY)[:3]:
            b = scene.bodies[k]
            warn.append(f"body {b.name!r}: about {edges[k]:.0f} mesh edges along its outline (perimeter "
                        f"{perim[k]:.3g}, mesh.h = {h:g}); at least {MIN_EDGES_PER_BODY} resolve it (mesh.h <= "
                        f"{perim[k] / MIN_EDGES_PER_BODY:.3g})")
        for k in np.flatnonzero(thick / h < MIN_THICKNESS_PER_H)[:3]:
            b = scene.bodies[k]
            warn.append(f"body {b.name!r} is about {thick[k]:.3g} thick, {h / thick[k]:.0f} times thinner than "
                        f"mesh.h = {h:g}: expect degenerate triangles (angles of a fraction of a degree) around it; "
                        "a thicker body or a finer mesh near it (mesh.grading)")
    return warn, refuse


