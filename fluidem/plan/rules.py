"""The plan's rules: one small named function per effect, note, warning or refusal.

Each rule is ``rule(scene, ctx)`` and yields what it adds to the plan: an :class:`Effect`, a
:class:`Note`, a :class:`Caution` (a warning) or a :class:`Refusal` (a reason the scene cannot
run); it yields nothing when it does not apply.  :func:`fluidem.plan.make_plan` applies
:data:`RULES` in order, and each kind keeps that order in the plan (effects in the order of
:class:`Plan`'s ``effects``; notes, warnings and refusals in the order they are listed here).
``ctx`` is the :class:`Context`: what every rule reads about the scene, worked out once.

Examples
--------
>>> from fluidem.scene import Scene
>>> s = Scene.from_dict({"domain": {"box": [0, 1, 0, 1]}, "time": {"dt": 0.1, "t_end": 1.0}})
>>> ctx = Context.of(s)
>>> [str(c) for c in gravity(s, ctx)]
['  gravity         off  — gravity = [0, 0]']
>>> RULES.index(fluid) < RULES.index(solver)
True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Callable

import numpy as np

from .. import names
from .effects import Effect, Plan
from .estimate import machine_memory, mesh_estimate, mesh_warnings
from .limits import EXPLICIT_COUPLING_MIN_RATIO, flux_refusal, sub_step_check
from .reach import contact_candidates, prescribed_collisions

if TYPE_CHECKING:  # pragma: no cover
    from ..scene import Scene

__all__ = ["Context", "Note", "Caution", "Refusal", "RULES", "apply_rules", "moving_mesh_available"]


class Note(str):
    """A note of the plan: something the run does that is worth saying."""


class Caution(str):
    """A warning of the plan: something the run will do but should not go unsaid."""


class Refusal(str):
    """A reason this version cannot run the scene (the plan's ``unsupported``)."""


def moving_mesh_available() -> bool:
    """True when the moving-mesh layer (:class:`fluidem.mesh.MovingMesh`) can be imported."""
    try:
        from ..mesh import MovingMesh  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass
class Context:
    """What the rules read about a scene, worked out once (:meth:`of`).

    Attributes
    ----------
    free, moving, outline_moving, rotating : list of BodySpec
        Free bodies; bodies that move; bodies whose outline moves (not a disk spinning in
        place); bodies that can rotate (free, or prescribed with ``omega``).
    gravity_on : bool
    periodic : list of str
        The periodic sides.
    mesh : {"none", "once", "moving"}
    quasi_static_once : bool
        Stokes at a single instant (one step): the mesh is built once whatever moves.
    n_body_pairs, n_wall_pairs : int
        Pairs that may meet before ``t_end`` (:func:`fluidem.plan.contact_candidates`).
    contacts_on : bool
        A ``[contact]`` table, enabled, and a pair that may meet.
    estimate : dict or None
        Fluid scenes: :func:`fluidem.plan.mesh_estimate`.
    """

    free: list
    moving: list
    outline_moving: list
    rotating: list
    gravity_on: bool
    periodic: list
    mesh: str
    quasi_static_once: bool
    n_body_pairs: int
    n_wall_pairs: int
    contacts_on: bool
    estimate: dict | None
    available: Callable[[], bool] = field(default=moving_mesh_available, repr=False)

    @classmethod
    def of(cls, scene: Scene, available: Callable[[], bool] = moving_mesh_available,
           memory: Callable[[], tuple] = machine_memory) -> Context:
        """The context of ``scene``.

        ``available`` says whether the moving-mesh layer is there and ``memory`` gives the
        machine's (total, available) memory in bytes; :func:`fluidem.plan.make_plan` passes the
        package's :func:`fluidem.plan.moving_mesh_available` and :func:`fluidem.plan.machine_memory`,
        so that replacing either there reaches the plan.
        """
        fl, bodies = scene.fluid, scene.bodies
        outline_moving = [b for b in bodies if b.outline_moves]
        quasi_static_once = fl is not None and fl.model == "stokes" and scene.time.n_steps == 1
        mesh = "none" if fl is None else "once" if not outline_moving or quasi_static_once else "moving"
        nb, nw = contact_candidates(scene)
        c = scene.contact
        return cls(free=[b for b in bodies if b.motion == "free"], moving=[b for b in bodies if b.moves],
                   outline_moving=outline_moving,
                   rotating=[b for b in bodies if (b.motion == "prescribed" and b.omega) or (b.motion == "free")],
                   gravity_on=any(scene.gravity),
                   periodic=[s for s in names.choices("side") if scene.domain.side(s).type == "periodic"],
                   mesh=mesh, quasi_static_once=quasi_static_once, n_body_pairs=nb, n_wall_pairs=nw,
                   contacts_on=c is not None and c.enabled and nb + nw > 0,
                   estimate=mesh_estimate(scene, memory()) if fl is not None else None, available=available)

    @cached_property
    def moving_mesh(self) -> bool:
        """Whether the moving-mesh layer can be imported (asked once, and only by rules that need it)."""
        return self.available()

    @property
    def free_in_fluid(self) -> bool:
        """Free bodies in a fluid, and the moving mesh they need is there."""
        return bool(self.free) and self.moving_mesh


# ---------------------------------------------------------------------------------------
# effects, in the order of Plan.effects
# ---------------------------------------------------------------------------------------
def fluid(scene, ctx):
    """Fluid: on with a ``[fluid]`` table (its model and element), off for a dry scene."""
    fl = scene.fluid
    if fl is None:
        yield Effect("fluid", False, "no [fluid] table: a dry scene (no mesh, no fluid solver)")
    else:
        yield Effect("fluid", True, f"[fluid] model = {fl.model!r}", f"{fl.model}, element {fl.element}")


def inertia(scene, ctx):
    """Inertia: rigid bodies' alone when dry; the fluid's for Navier–Stokes, none for Stokes."""
    fl = scene.fluid
    if fl is None:
        yield Effect("inertia", bool(ctx.moving), "rigid-body inertia only (DEM)" if ctx.moving else "nothing moves",
                     "bodies")
    elif fl.model == "stokes":
        yield Effect("inertia", False, "model = 'stokes': quasi-steady, no convection and no time derivative")
    else:
        yield Effect("inertia", True, "model = 'navier-stokes': time derivative and convection "
                     f"{fl.convection}", "navier-stokes")


def moving_bodies(scene, ctx):
    """Moving bodies: how many of the bodies move, and how (free, prescribed)."""
    n = len(scene.bodies)
    if not ctx.moving:
        yield Effect("moving-bodies", False, "all bodies fixed (or none)" if n else "no bodies")
    else:
        kinds = sorted({b.motion for b in ctx.moving})
        yield Effect("moving-bodies", True, f"{len(ctx.moving)} of {n} bodies move ({', '.join(kinds)})",
                     f"{len(ctx.moving)}")


def mesh(scene, ctx):
    """Mesh: none when dry; built once while no outline moves (or for one quasi-steady Stokes
    step); else a moving mesh that follows the outlines."""
    if ctx.mesh == "none":
        yield Effect("mesh", False, "dry scene: no fluid, no mesh")
    elif not ctx.outline_moving:
        why = "no body outline moves" + (" (spinning disks keep their outline)" if ctx.moving else "")
        yield Effect("mesh", True, why + ": the mesh is built once", "once")
    elif ctx.quasi_static_once:
        yield Effect("mesh", True, "Stokes at one instant (a single step): the geometry at t = 0 is all a "
                     "quasi-steady solve needs; the mesh is built once", "once")
    else:
        yield Effect("mesh", True, f"{len(ctx.outline_moving)} body outline(s) move: the mesh follows them",
                     f"moving, strategy {scene.mesh.strategy}")


def ale(scene, ctx):
    """ALE: on for Navier–Stokes on a moving mesh (conservative or not), else why the mesh
    velocity does not enter."""
    if ctx.mesh == "none":
        yield Effect("ale", False, "no fluid")
    elif not ctx.outline_moving:
        yield Effect("ale", False, "the mesh never moves")
    elif ctx.quasi_static_once:
        yield Effect("ale", False, "one quasi-steady step: the mesh never moves")
    elif scene.fluid.model != "navier-stokes":
        yield Effect("ale", False, "Stokes has no convection: the mesh velocity does not enter")
    elif scene.fluid.ale_form == "conservative":
        yield Effect("ale", True, "conservative form: each time level's mass matrix, convection "
                                  "div(u ⊗ (u − w)); momentum kept to solver tolerance", "conservative")
    else:
        yield Effect("ale", True, "mesh velocity enters convection (u − w)·∇u (non-conservative form: "
                                  "uniform flow kept exactly, momentum to discretisation error)", "non-conservative")


def contacts(scene, ctx):
    """Contacts: on when a ``[contact]`` table is enabled and some pair may meet before ``t_end``."""
    c, nb, nw = scene.contact, ctx.n_body_pairs, ctx.n_wall_pairs
    if c is None:
        yield Effect("contacts", False, "no [contact] table")
    elif not c.enabled:
        yield Effect("contacts", False, "contact.enabled = false")
    elif nb + nw == 0:
        yield Effect("contacts", False, "no two bodies, or body and wall, can meet before t_end = "
                     f"{scene.time.t_end:g} at the speeds the scene allows")
    else:
        yield Effect("contacts", True, f"{nb} body pair(s) and {nw} body–wall pair(s) may meet before t_end",
                     f"E={c.E:g}, mu={c.mu:g}, gamma={c.gamma:g}")


def gravity(scene, ctx):
    """Gravity: on when it is not zero and there are free bodies to move."""
    if not ctx.gravity_on:
        yield Effect("gravity", False, "gravity = [0, 0]")
    elif not ctx.free:
        yield Effect("gravity", False, "no free bodies: gravity moves nothing" +
                     (" (in the fluid it only adds a hydrostatic pressure)" if scene.fluid else ""))
    else:
        yield Effect("gravity", True, f"{len(ctx.free)} free bodies", f"{list(scene.gravity)}")


def buoyancy(scene, ctx):
    """Buoyancy: on for free bodies under gravity in a fluid."""
    if not ctx.gravity_on:
        yield Effect("buoyancy", False, "no gravity")
    elif not ctx.free:
        yield Effect("buoyancy", False, "no free bodies")
    else:
        yield Effect("buoyancy", scene.fluid is not None, "free bodies in a fluid" if scene.fluid
                     else "dry scene: no fluid")


def coupling(scene, ctx):
    """Coupling of free bodies and fluid: the Stokes mobility problem, or implicit BDF2."""
    fl = scene.fluid
    if fl is None or not ctx.free:
        yield Effect("coupling", False, "no free bodies in a fluid" if fl is not None else "no fluid")
    elif fl.model == "stokes":
        yield Effect("coupling", True, f"{len(ctx.free)} free bodies: Stokes mobility, force and torque balance "
                     "solved with the fluid in one bordered saddle-point system", "mobility")
    else:
        yield Effect("coupling", True, f"{len(ctx.free)} free bodies: fluid and Newton-Euler rows in one implicit "
                     "BDF2 solve (added mass inside the matrix)", "implicit")


def rotation(scene, ctx):
    """Rotation: on when a body is free or prescribed with ``omega``."""
    yield Effect("rotation", bool(ctx.rotating),
                 f"{len(ctx.rotating)} bodies can rotate (free or prescribed omega)" if ctx.rotating
                 else "no body rotates")


def remeshing(scene, ctx):
    """Remeshing: a moving mesh re-triangulates unless ``mesh.strategy = 'fixed'``."""
    if ctx.mesh == "moving":
        st = scene.mesh.strategy
        yield Effect("remeshing", st != "fixed", f"strategy {st!r}, re-triangulate every "
                     f"{scene.mesh.retriangulate_every} steps or when quality drops", st)
    else:
        yield Effect("remeshing", False, "no moving mesh: never re-triangulated")


def periodic(scene, ctx):
    """Periodic sides: the pairs and their periods, and what drives a periodic flow."""
    if not ctx.periodic:
        yield Effect("periodic", False, "no periodic sides")
        return
    fl = scene.fluid
    x0, x1, y0, y1 = scene.domain.box
    pairs = [f"{a}/{b} (period {p:g} in {ax})" for a, b, p, ax in
             (("left", "right", x1 - x0, "x"), ("bottom", "top", y1 - y0, "y")) if a in ctx.periodic]
    if fl is None:
        how = (": the DEM takes every pair of bodies at its nearest periodic image; positions in the box in the "
               "outputs, x_unwrapped and y_unwrapped continuous")
    else:
        how = (": matching mesh nodes, identified velocity (and continuous pressure) DOFs"
               + (f"; driven by body_force = {list(fl.body_force)}" if any(fl.body_force) else
                  "; no body_force (driven by moving walls or bodies only)"))
    yield Effect("periodic", True, "periodic pairs " + ", ".join(pairs) + how,
                 "+".join(ax for a, ax in (("left", "x"), ("bottom", "y")) if a in ctx.periodic))


def solver(scene, ctx):
    """Solver: DEM or closed-form motion when dry; Stokes per step; BDF2/BDF3 for Navier–Stokes."""
    fl = scene.fluid
    if fl is None:
        if not ctx.moving:
            s = "nothing to integrate: bodies never move"
        elif ctx.contacts_on:
            s = "DEM, Gear predictor-corrector with contact sub-steps"
        else:
            s = "ballistic: closed-form rigid motion (no contacts, no search)"
        yield Effect("solver", bool(ctx.moving), s)
    elif fl.model == "stokes":
        yield Effect("solver", True, f"one Stokes saddle-point solve per step, solver {fl.solver}{_lu_text(fl)}",
                     "stokes")
    else:
        moving_mesh = ctx.mesh == "moving"
        scheme = scene.time.bdf_scheme(moving_mesh=moving_mesh)
        why = (f" (time.scheme = 'auto': {scheme.upper()} on a {'moving' if moving_mesh else 'fixed'} mesh)"
               if scene.time.scheme == "auto" else "")
        yield Effect("solver", True, f"{scheme.upper()}{why}, {fl.convection} convection, solver {fl.solver}"
                     f"{_lu_text(fl)}", scheme)


def _lu_text(fl) -> str:
    """Which sparse LU ``fluid.lu_backend`` means here (PARDISO when installed, from its threshold)."""
    from ..fluid.solvers.direct import PARDISO_MIN_DOFS
    from ..fluid.solvers.pardiso import pardiso_available

    if fl.solver == "iterative":
        return ""
    if fl.lu_backend != "auto":
        return f", LU {fl.lu_backend}"
    if pardiso_available():
        return f", LU PARDISO from {PARDISO_MIN_DOFS} DOFs (SuperLU below)"
    return ", LU SuperLU (PARDISO, faster from 20 000 DOFs: pip install 'fluidem[pardiso]')"


# ---------------------------------------------------------------------------------------
# notes, warnings and refusals
# ---------------------------------------------------------------------------------------
def prescribed_collision_note(scene, ctx):
    """Note prescribed bodies that run into a side or another non-free body before ``t_end``."""
    hit = prescribed_collisions(scene)
    if hit:
        yield Note("prescribed motion brings " + "; ".join(hit[:3]) + (" ..." if len(hit) > 3 else "")
                   + " before t_end (prescribed bodies feel no contact forces)")


def free_bodies_need_moving_mesh(scene, ctx):
    """Refuse free bodies in a fluid when the moving-mesh layer is missing."""
    if scene.fluid is not None and ctx.free and not ctx.moving_mesh:
        yield Refusal(f"free bodies in a fluid ({len(ctx.free)}) need the moving-mesh layer "
                      "(fluidem.mesh.MovingMesh), which is not available in this installation")


def iterative_free_bodies_note(scene, ctx):
    """Note how ``solver = 'iterative'`` solves a system with free bodies."""
    fl = scene.fluid
    if fl is None or not ctx.free_in_fluid or fl.solver != "iterative":
        return
    if fl.model == "stokes":
        yield Note("solver = 'iterative': the Stokes mobility problem of free bodies uses the lagged LU")
    else:
        yield Note("solver = 'iterative': the coupled fluid-body system is solved by block-preconditioned "
                   "GMRES with the body velocities in the velocity block")


def stokes_contacts_note(scene, ctx):
    """Note the repulsion that stands for contacts between Stokes free bodies."""
    fl = scene.fluid
    if fl is None or not ctx.free_in_fluid or not ctx.contacts_on or fl.model != "stokes":
        return
    from ..coupling.contacts import repulsion_for

    rep = repulsion_for(scene.contact, np.zeros(0), np.zeros(0), h=scene.mesh.h, fluid_density=fl.density,
                        gravity=scene.gravity)
    yield Note(f"contacts of Stokes free bodies: the short-range repulsion (Glowinski et al. 2001) "
               f"below {rep.range:g}, epsilon {rep.epsilon:g}, in the mobility problem, linearly "
               "implicit in the poses (Euler in the steps where it acts); no lubrication correction, "
               "no DEM contact law or friction (bodies pressed together harder than the repulsion's "
               "largest force overlap, and the run stops with a message)")


def _inertial_contacts(scene, ctx) -> bool:
    """Free bodies with contacts in a Navier–Stokes fluid."""
    fl = scene.fluid
    return fl is not None and ctx.free_in_fluid and ctx.contacts_on and fl.model != "stokes"


def zero_repulsion_warning(scene, ctx):
    """Warn when the default repulsion force scale (the largest buoyant weight) is 0."""
    if not _inertial_contacts(scene, ctx) or scene.contact.repulsion_force is not None:
        return
    if not ctx.gravity_on or all(b.density == scene.fluid.density for b in ctx.free):
        yield Caution("contacts in a fluid with neither gravity nor a density difference: the default repulsion "
                      "force scale (the largest buoyant weight) is 0, so bodies that meet overlap and the run "
                      "stops; expected contact.repulsion_force > 0 (a force per unit depth, e.g. the largest load "
                      "that presses bodies together)")


def fluid_contacts_note(scene, ctx):
    """Note how contacts act inside a Navier–Stokes step: lubrication, repulsion, DEM law."""
    if not _inertial_contacts(scene, ctx):
        return
    from ..coupling.contacts import lubrication_for, repulsion_for

    c, fl = scene.contact, scene.fluid
    rep = repulsion_for(c, np.zeros(0), np.zeros(0), h=scene.mesh.h, fluid_density=fl.density, gravity=scene.gravity)
    lub = lubrication_for(c, fl, scene.mesh.h)
    force = f"{c.repulsion_force:g}" if c.repulsion_force is not None else "the largest buoyant weight of a free body"
    if lub is not None:
        what = ("the squeeze-film law" if lub.resolved_gap is None
                else f"the part of the squeeze-film law the mesh misses (resolved-film length {lub.resolved_gap:g})")
        lub_text = f"a lubrication correction, {what}, below the gap {lub.range:g}"
    else:
        lub_text = "no lubrication correction (contact.lubrication off or resolved_gap = 0)"
    yield Note(f"contacts inside the fluid step: {lub_text}; a short-range repulsion (Glowinski et "
               f"al. 2001) below {rep.range:g} as a backstop, force scale {force}, epsilon "
               f"{rep.epsilon:g}; the DEM contact law on overlaps; sub-stepped with the fluid's force "
               "held whenever outlines come within reach")


def free_bodies_without_contacts_note(scene, ctx):
    """Note that free bodies in a fluid that may meet, without contacts, must stay apart."""
    if (scene.fluid is not None and ctx.free_in_fluid and not ctx.contacts_on
            and ctx.n_body_pairs + ctx.n_wall_pairs):
        yield Note("no [contact] table: free bodies must stay apart and off the walls (the run stops with "
                   "a message if they overlap); add [contact] for contacts and short-range repulsion")


def prescribed_moving_mesh(scene, ctx):
    """Prescribed translating bodies in a fluid: note the moving mesh, or refuse without it."""
    if scene.fluid is None or ctx.free or ctx.mesh != "moving":
        return
    if not ctx.moving_mesh:
        yield Refusal("moving bodies in fluid need the moving-mesh layer (fluidem.mesh.MovingMesh), "
                      "which is not available in this installation")
    else:
        yield Note("prescribed translating bodies use fluidem.mesh.MovingMesh (ALE)")


def bdf3_moving_mesh_refusal(scene, ctx):
    """Refuse BDF3 on a moving mesh (which keeps two time levels)."""
    fl = scene.fluid
    if fl is not None and scene.time.scheme == "bdf3" and ctx.mesh == "moving" and fl.model == "navier-stokes":
        yield Refusal("time.scheme = 'bdf3' needs a fixed mesh (the moving mesh keeps two time levels); "
                      "expected 'bdf2' or 'auto' for a scene whose bodies move")


def quasi_steady_note(scene, ctx):
    """Note that one Stokes step with moving outlines gives the forces of the initial geometry."""
    fl = scene.fluid
    if fl is not None and fl.model == "stokes" and scene.time.n_steps == 1 and ctx.outline_moving:
        yield Note("quasi-steady Stokes at t = 0 only: forces are those of the initial geometry")


def fixed_strategy_refusal(scene, ctx):
    """Refuse ``mesh.strategy = 'fixed'`` when body outlines move."""
    if scene.fluid is not None and ctx.mesh == "moving" and scene.mesh.strategy == "fixed":
        om = ctx.outline_moving
        yield Refusal(f"mesh.strategy = 'fixed' keeps the mesh still, but {len(om)} body "
                      f"outline(s) move ({', '.join(b.name for b in om[:3])}); use strategy "
                      "'drag' or 'regenerate'")


def dry_fluid_sides_refusal(scene, ctx):
    """Refuse fluid side conditions (inflow, moving wall) in a dry scene."""
    if scene.fluid is not None:
        return
    bad = [s for s in names.choices("side") if scene.domain.side(s).type in ("inflow", "moving-wall")]
    if bad:
        yield Refusal(f"domain sides {', '.join(bad)} are fluid conditions; a dry scene allows "
                      "'wall', 'outflow' (open) and 'periodic'")


def net_flux_refusal(scene, ctx):
    """Refuse boundary fluxes that no incompressible flow can carry (:func:`fluidem.plan.limits.flux_refusal`)."""
    if scene.fluid is not None:
        why = flux_refusal(scene)
        if why:
            yield Refusal(why)


def mesh_size(scene, ctx):
    """Warn about, or refuse, the mesh the estimate foresees: memory, a coarse box, coarse or thin bodies."""
    if scene.fluid is None:
        return
    warn, refuse = mesh_warnings(scene, ctx.estimate)
    yield from map(Caution, warn)
    yield from map(Refusal, refuse)


def explicit_coupling_ratio(scene, ctx):
    """Warn about explicit coupling of a body lighter than :data:`fluidem.plan.limits.EXPLICIT_COUPLING_MIN_RATIO`."""
    fl = scene.fluid
    if fl is None or not ctx.free or fl.coupling != "explicit" or fl.model == "stokes":
        return
    light = min(ctx.free, key=lambda b: b.density)
    ratio = light.density / fl.density
    if ratio < EXPLICIT_COUPLING_MIN_RATIO:
        yield Caution(f"fluid.coupling = 'explicit' with body {light.name!r} at density ratio "
                      f"rho_s/rho_f = {ratio:g}: a staggered step blows up when the fluid's added mass "
                      f"(about rho_f A for a disk, more near walls) exceeds the body mass; expected "
                      f"a ratio >= {EXPLICIT_COUPLING_MIN_RATIO:g}, or coupling = 'implicit'")


def explicit_coupling_contacts(scene, ctx):
    """Warn about explicit coupling with contacts (the squeeze film comes a step late)."""
    fl = scene.fluid
    if fl is not None and ctx.free and fl.coupling == "explicit" and fl.model != "stokes" and ctx.contacts_on:
        yield Caution("fluid.coupling = 'explicit' with contacts: the staggered step applies the resolved "
                      "squeeze film a step late, so a body approaching a wall or another body overshoots "
                      "into the backstop and bounces (measured: a disk of density ratio 10 draining onto "
                      "a floor bounces off it at half its fall speed); expected coupling = 'implicit' "
                      "where bodies meet")


def contact_sub_step_limit(scene, ctx):
    """Warn about, or refuse, contacts that take too many DEM sub-steps a step."""
    if ctx.contacts_on:
        warn, refuse = sub_step_check(scene)
        if warn:
            yield Caution(warn)
        if refuse:
            yield Refusal(refuse)


def dry_without_contacts_warning(scene, ctx):
    """Warn that bodies of a dry scene without ``[contact]`` pass through each other and the walls."""
    nb, nw = ctx.n_body_pairs, ctx.n_wall_pairs
    if scene.fluid is None and scene.contact is None and nb + nw:
        yield Caution(f"no [contact] table: {nb} body pair(s) and {nw} body–wall pair(s) can meet before t_end = "
                      f"{scene.time.t_end:g}, and without contacts bodies pass through each other and through the "
                      "walls; expected a [contact] table (E, mu, gamma) for bodies that meet")


def rheology_note(scene, ctx):
    """Note the rheometer's shear rate and window, or why there is none (:func:`fluidem.rheology.plan_note`)."""
    from ..rheology import plan_note

    rheo = plan_note(scene)
    if rheo:
        yield Note(rheo)


def defaults_note(scene, ctx):
    """Note the time step, end time and mesh size a scene left to their defaults."""
    defaulted = getattr(scene, "defaulted", ())
    if "time" in defaulted:
        yield Note(f"no [time] table: default dt = {scene.time.dt:g}, t_end = {scene.time.t_end:g}")
    if "mesh.h" in defaulted and scene.fluid is not None:
        yield Note(f"no mesh.h: default h = {scene.mesh.h:g}")


#: The plan's rules, applied in this order by :func:`fluidem.plan.make_plan`.
RULES = [
    fluid, inertia, moving_bodies, mesh, ale, contacts, gravity, buoyancy, coupling, rotation, remeshing, periodic,
    solver,
    prescribed_collision_note, free_bodies_need_moving_mesh, iterative_free_bodies_note,
    stokes_contacts_note, zero_repulsion_warning, fluid_contacts_note, free_bodies_without_contacts_note,
    prescribed_moving_mesh, bdf3_moving_mesh_refusal, quasi_steady_note, fixed_strategy_refusal,
    dry_fluid_sides_refusal, net_flux_refusal, mesh_size, explicit_coupling_ratio, explicit_coupling_contacts,
    contact_sub_step_limit, dry_without_contacts_warning, rheology_note, defaults_note,
]


def apply_rules(scene: Scene, ctx: Context, rules=None) -> Plan:
    """The plan of ``scene``: every rule of ``rules`` (:data:`RULES`) in order, each kind in its own list.

    Parameters
    ----------
    scene : fluidem.scene.Scene
        A validated scene.
    ctx : Context
        ``Context.of(scene)``.
    rules : list of callables, optional
        ``rule(scene, ctx)`` yielding :class:`Effect`, :class:`Note`, :class:`Caution` or
        :class:`Refusal`; :data:`RULES` when not given.

    Returns
    -------
    Plan
    """
    out = {Effect: [], Note: [], Caution: [], Refusal: []}
    for rule in RULES if rules is None else rules:
        for item in rule(scene, ctx):
            out[type(item)].append(item if type(item) is Effect else str(item))
    return Plan(scene.name, out[Effect], ctx.mesh, ctx.n_body_pairs + ctx.n_wall_pairs, scene.time.n_steps,
                out[Refusal], out[Note], out[Caution], ctx.estimate)
