"""Limits a scene can break before anything is built: boundary fluxes that no incompressible
flow can carry, contacts too stiff for the step, an explicit coupling too light to be stable."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import names

if TYPE_CHECKING:  # pragma: no cover
    from ..scene import Scene

__all__ = ["FLUX_TOLERANCE", "boundary_fluxes", "flux_refusal", "MAX_CONTACT_SUBSTEPS", "REFUSED_CONTACT_SUBSTEPS",
           "contact_sub_steps", "sub_step_check", "EXPLICIT_COUPLING_MIN_RATIO"]


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


def flux_refusal(scene: Scene) -> str | None:
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
#: sub-step counts from here on are reported as infinite (beyond the float's integer precision)
COUNTED_CONTACT_SUBSTEPS = 1e15


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
    from ..dem.system import stable_sub_step
    from ..geometry import polygon_area

    areas = np.array([abs(polygon_area(b.local_vertices(scene.default_segments(b)))) for b in free])
    dens = np.array([b.density for b in free], float)
    mass = float(((dens + (fl.density if fl is not None else 0.0)) * areas).min())
    rep = None
    if fl is not None:
        from ..coupling.contacts import repulsion_for

        rep = repulsion_for(c, areas, dens, h=scene.mesh.h, fluid_density=fl.density, gravity=scene.gravity)
    dt_max, by = stable_sub_step(mass, c.E, rep)
    with np.errstate(all="ignore"):
        n = scene.time.dt / dt_max
    return (float(np.ceil(n - 1e-9)) if np.isfinite(n) and n < COUNTED_CONTACT_SUBSTEPS else float("inf")), dt_max, by


def sub_step_check(scene: Scene) -> tuple[str | None, str | None]:
    """``(warning, refusal)`` for a scene whose contacts take too many DEM sub-steps a step."""
    sub = contact_sub_steps(scene)
    if sub is None or sub[0] <= MAX_CONTACT_SUBSTEPS:
        return None, None
    n, dt_max, by = sub
    count = f"up to {n:.3g}" if np.isfinite(n) else f"more than {COUNTED_CONTACT_SUBSTEPS:.0e}"
    text = (f"contacts take {count} DEM sub-steps per pass over each step of time.dt = {scene.time.dt:g} "
            f"(dt_max = {dt_max:.3g}, set by {by}, with the lightest free body); expected at most "
            f"{MAX_CONTACT_SUBSTEPS}: "
            "lower that stiffness (a smaller E or repulsion_force, a larger repulsion_epsilon or repulsion_range), "
            "or time.dt")
    return (None, text) if n > REFUSED_CONTACT_SUBSTEPS else (text, None)


#: Density ratio below which ``coupling = "explicit"`` is warned about: a disk settling in a
#: channel blew up at 1.01 and ran stably at 1.5 (tests/coupling/test_free_flow.py).
EXPLICIT_COUPLING_MIN_RATIO = 1.5
