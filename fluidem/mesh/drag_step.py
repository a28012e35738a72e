"""One drag step of a :class:`~fluidem.mesh.moving.MovingMesh` (paper Sec. 4.2) and the decision
to re-triangulate.

:func:`drag_step` moves the nodes with the bodies (:func:`fluidem.mesh.drag.dragged_positions`),
and then, in this order:

1. on periodic sides that bend (``seams="bend"``, :mod:`fluidem.mesh.seam`): the side nodes
   move in matched pairs (:func:`fluidem.mesh.periodic.move_in_pairs`), the seam nodes with their
   bodies, and nodes are not held in the box across the periodic axis.  With ``seams="clip"``:
   seam nodes slide with the crossings of their segments; a segment that no longer crosses its
   side, or a body reaching into the box without its image, re-triangulates (``"seam"``,
   :mod:`fluidem.mesh.moving_images`);
2. nodes dragged out of the box (:func:`put_back_in_box`): movable ones are put back on it, and
   so are outline nodes of a body meshed with a wall pressed past it by at most
   :func:`contact_slack`; any other outline node past a side re-triangulates at once (``"seam"``
   across a periodic side, else ``"contact"``, or ``"inverted"``/``"degenerate"`` if the rigid
   motion broke an element);
3. relaxation with the per-step iteration limit, the step of oscillating nodes halved
   (:func:`relax_dragged`, Sec. 3.3);
4. the triggers (:func:`fluidem.mesh.triggers.retriangulation_reason`): every
   ``retriangulate_every`` steps (K, default 30), or earlier when

   - an element is inverted by the rigid motion (``"inverted"``) or shrank below a tenth of
     its area (``"degenerate"``, typically a narrow-gap element whose anchor passes a
     corner),
   - bodies came within ``min_gap`` of each other, or a contact changed (``"contact"``;
     a wall contact may breathe by ``contact_slack · h``, 0.02 h, first: a resting body
     whose overlap or gap changes by a little more than ``min_gap`` keeps its outline),
   - an element outside narrow gaps degraded ``angle_margin`` (10°) past 135°, or
     ``min_angle_margin`` (0° by default; 3° is available) below ``min_angle_trigger`` (15°), or
     as far past its own angles after the last triangulation if it was born outside them (``"quality"``, with
     hysteresis: an element born near a bound does not fire as soon as it crosses it,
     :func:`fluidem.mesh.triggers.quality_baseline`);
5. before a ``"quality"`` or ``"degenerate"`` re-triangulation (:data:`REPAIRED_REASONS`), the
   repair (:func:`repair_step`, :mod:`fluidem.mesh.repair`): the nodes around the fired elements
   move to bring them back within their thresholds and above ``degenerate_area``, and the mesh is
   re-triangulated only if that fails (or a narrow-gap element fired or collapsed, more than
   :data:`MAX_REPAIR_ELEMENTS` fired, more than :data:`MAX_STRETCHED_SHARE` of the elements have
   grown past ``refine_area``, or, for ``"degenerate"``, a contact changed or the scheduled
   re-triangulation is due).

Oscillating nodes (Sec. 3.3) are detected from the relaxation displacements
(:class:`fluidem.mesh.quality.OscillationDetector`), reported, and their relaxation step is
halved each time they are flagged, on top of the per-step iteration limit.

The functions take the mesh (``mesh``) and read or set its attributes; they add none.

Examples
--------
>>> from fluidem.geometry import rectangle
>>> from fluidem.mesh import MovingMesh
>>> mm = MovingMesh((0, 2, 0, 1), [rectangle(0.3, 0.2)], [[0.6, 0.5, 0.0]], h=0.1)
>>> contact_slack(mm) == 0.02 * mm.h, contacts_changed(mm)
(True, False)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .contact_outline import wall_depths
from .drag import HarmonicDrag, dragged_positions, harmonic_drag
from .moving_images import needs_new_images, place_seam_nodes
from .nodes import CONTACT, world
from .periodic import bends_seams, move_in_pairs, slide_in_pairs
from .relax import relax
from .repair import nodes_to_repair, repair_nodes
from .seam import SEAM_CODE
from .triggers import contacts_changed as body_contacts_changed
from .triggers import (ElementShape, element_shape, fired_elements, outside_opened_gap_bounds, past_thresholds,
                       quality_dropped, retriangulation_reason)

if TYPE_CHECKING:
    from .moving import MeshEvent, MovingMesh

__all__ = ["drag_step", "put_back_in_box", "relax_dragged", "repair_step", "retriangulate_step", "harmonic_drag_of",
           "contacts_changed", "contact_slack", "MAX_REPAIR_ELEMENTS", "MAX_STRETCHED_SHARE", "REPAIRED_REASONS"]

#: the quality trigger's elements repaired by moving nodes at most (more: a storm of shear the
#: node positions cannot undo, re-triangulate)
MAX_REPAIR_ELEMENTS = 16
#: share of the elements grown past ``refine_area`` target areas above which a fired quality
#: trigger re-triangulates instead of repairing: a repair restores angles, not sizes, and the
#: adaptation at a re-triangulation holds the node count only for a mildly stretched mesh (a plate
#: going there and back: +8 % nodes in 300 steps when only the scheduled re-triangulations
#: remained, +3 % with this rule; a settling pile of 100 polygons has 0.3–0.6 % of such elements)
MAX_STRETCHED_SHARE = 0.02

#: the re-triangulation reasons a repair may avert: elements past their angle thresholds, or
#: shrunk below ``degenerate_area`` (not inverted: no node move is small for an element turned over)
REPAIRED_REASONS = ("quality", "degenerate")

_NO_PAIRS = np.zeros((0, 2), dtype=np.int64)


def drag_step(mesh: MovingMesh, new, ev: MeshEvent) -> None:
    """Drag the nodes of ``mesh`` to the image poses ``new (n_bodies, 3)``, relax, and
    re-triangulate if a trigger fires (module docstring); ``ev`` records it."""
    p = mesh.params
    xd = dragged_positions(mesh.points, mesh.triangles, mesh.kind, mesh.outline_row, mesh.outlines.local,
                           mesh.outlines.body, mesh._contact_idx, mesh._contact_local, mesh.body_of,
                           mesh._drag_mobility, mesh.drag, mesh.junction_nodes, mesh.junction_verts,
                           mesh.junction_bary, mesh.poses, new, p.drag_halvings, harmonic_drag_of(mesh),
                           wall_side=mesh.__dict__.get("_contact_wall"), box=mesh.box)
    mesh.poses = new
    if bends_seams(mesh):
        # the periodic sides bend with the bodies: side nodes in matched pairs, seam nodes
        # fixed on their bodies (:mod:`fluidem.mesh.seam`)
        xd = move_in_pairs(mesh.points, xd, mesh._side_pairs)
    elif mesh.periodic:
        seam_broken = place_seam_nodes(mesh, xd, new)
        if seam_broken or needs_new_images(mesh):
            # an outline left its seam or a body reached a side without its image: the
            # clipped outlines change (:mod:`fluidem.mesh.seam`)
            _retriangulate_now(mesh, xd, ev, "seam")
            return
    pressed, seam = put_back_in_box(mesh, xd)
    if pressed and seam:
        # an outline node passed a periodic side: the body is clipped anew there
        _retriangulate_now(mesh, xd, ev, "seam")
        return
    if pressed:
        shape = element_shape(xd, mesh.topo)
        reason = retriangulation_reason(shape, mesh.baseline, p.degenerate_area, 0, p.retriangulate_every,
                                        lambda: False, lambda: False)
        reason = reason if reason in ("inverted", "degenerate") else "contact"
        _record_fired(mesh, ev, shape, xd, reason)
        _retriangulate_now(mesh, xd, ev, reason)
        return
    xr = relax_dragged(mesh, xd, ev)
    mesh._steps_since += 1
    # re-triangulate?  (one pass over the elements gives areas and angle cosines)
    shape = element_shape(xr, mesh.topo)
    reason = retriangulation_reason(
        shape, mesh.baseline, p.degenerate_area, mesh._steps_since, p.retriangulate_every,
        lambda: contacts_changed(mesh), lambda: quality_dropped(shape, mesh.baseline, mesh._anchored_across_gap))
    if reason in REPAIRED_REASONS and p.repair_sweeps and repair_step(mesh, shape, ev):
        reason = ""
    if reason:
        _record_fired(mesh, ev, shape, xr, reason)
        retriangulate_step(mesh, ev, reason)


def _record_fired(mesh: MovingMesh, ev: MeshEvent, shape: ElementShape, x, reason: str) -> None:
    """``ev.fired_at``: the centroids at ``x (n, 2)`` of the elements that fired ``reason``
    (:func:`fluidem.mesh.triggers.fired_elements`)."""
    idx = fired_elements(shape, mesh.baseline, reason, mesh.params.degenerate_area, mesh._anchored_across_gap)
    ev.fired_at = x[mesh.triangles[idx]].mean(axis=1)


def repair_step(mesh: MovingMesh, shape: ElementShape, ev: MeshEvent) -> bool:
    """Move the nodes around the elements that fired the quality trigger or shrank below
    ``degenerate_area`` of their area (``shape``: the elements at ``mesh.points``) until none
    does (:mod:`fluidem.mesh.repair`).  True: repaired,
    ``mesh.points`` moved and ``ev.repaired_nodes`` set; False: nothing changed (re-triangulate), and
    ``ev.repair_declined`` says why."""
    base, p = mesh.baseline, mesh.params
    floor = p.degenerate_area * base.area  # the area an element must keep
    shrunk = shape.area < floor
    if shrunk.any():
        # "degenerate": the reasons after it in retriangulation_reason were not evaluated, and a
        # repair averts none of them
        if contacts_changed(mesh) or mesh._steps_since >= p.retriangulate_every:
            return _declined(ev, "a contact changed or the scheduled re-triangulation is due")
        if (shrunk & base.narrow).any():
            return _declined(ev, "a narrow-gap element collapsed")  # its vertices are on outlines
    fired = np.flatnonzero(past_thresholds(shape, base) | shrunk)
    if not len(fired):
        return _declined(ev, "only narrow-gap elements fired")  # not repaired here
    if len(fired) > MAX_REPAIR_ELEMENTS:
        return _declined(ev, f"more than {MAX_REPAIR_ELEMENTS} elements fired")
    topo, h = mesh.topo, mesh.h_node
    target_area = (np.sqrt(3.0) / 36.0) * (h[topo.t0] + h[topo.t1] + h[topo.t2]) ** 2  # √3/4 of the mean h²
    if np.count_nonzero(shape.area > p.refine_area * target_area) > MAX_STRETCHED_SHARE * len(shape.area):
        # sizes drifted: the adaptation of a re-triangulation restores them
        return _declined(ev, f"more than {MAX_STRETCHED_SHARE:.0%} of the elements grown past refine_area")
    movable = mesh._mobility.any(axis=1)
    pairs = mesh.__dict__.get("_side_pairs")
    if pairs is not None and len(pairs):
        movable[np.asarray(pairs).ravel()] = False  # periodic side nodes move in pairs
    nodes = nodes_to_repair(mesh.triangles, fired, movable, base.narrow)
    if not len(nodes):
        return _declined(ev, "no movable node around the fired elements")
    lo = np.degrees(np.arccos(np.clip(base.cos_lo, -1.0, 1.0)))
    hi = np.degrees(np.arccos(np.clip(base.cos_hi, -1.0, 1.0)))
    x, moved = repair_nodes(mesh.points, mesh.triangles, mesh._mobility, nodes, lo, hi, floor, mesh.h_node,
                            p.repair_sweeps)
    if not moved:
        return _declined(ev, "no move met the bounds")
    after = element_shape(x, mesh.topo)
    if (after.area < floor).any() or quality_dropped(after, base, mesh._anchored_across_gap):
        still = past_thresholds(after, base) | (after.area < floor)
        return _declined(ev, "elements still outside the bounds after the moves" if still.any() else
                         "a narrow-gap element fired too")
    # an element born in a narrow gap whose gap has opened, outside the bounds but no worse than it
    # was born, does not fire; a re-triangulation would replace it, so a repair must not keep it
    stale = np.flatnonzero(outside_opened_gap_bounds(after, base))
    if len(stale) and (~mesh._anchored_across_gap(stale)).any():
        return _declined(ev, "a narrow-gap element whose gap opened would stay outside the bounds")
    ev.repaired_from, ev.repaired_nodes = mesh.points, np.flatnonzero((x != mesh.points).any(axis=1))
    mesh.points = x
    return True


def _declined(ev: MeshEvent, why: str) -> bool:
    """False, with ``why`` the repair did not avert the re-triangulation in ``ev.repair_declined``."""
    ev.repair_declined = why
    return False


def _retriangulate_now(mesh: MovingMesh, xd, ev: MeshEvent, reason: str) -> None:
    """The dragged nodes ``xd`` without relaxation, then :func:`retriangulate_step`."""
    mesh.points = xd
    mesh._steps_since += 1
    retriangulate_step(mesh, ev, reason)


def put_back_in_box(mesh: MovingMesh, xd) -> tuple[bool, bool]:
    """Put the nodes of ``xd (n, 2)`` dragged out of the box back on it, in place: movable ones,
    and outline nodes of a body meshed with a wall pressed past it by at most
    :func:`contact_slack` (a resting body's overlap breathing).  Returns ``(pressed, seam)``: an
    outline node is past a side by more (it cannot be put back: re-triangulate now, the outline
    is rebuilt with the wall, :mod:`fluidem.mesh.contact_outline`), and one of them passed a
    periodic side."""
    xmin, xmax, ymin, ymax = _bounds(mesh)
    lo, hi = np.array([xmin, ymin]), np.array([xmax, ymax])
    outside = ((xd < lo) | (xd > hi)).any(axis=1)
    pressed = seam = False
    if outside.any():
        movable = outside & mesh._mobility.any(axis=1)
        xd[movable] = np.clip(xd[movable], lo, hi)
        over = np.flatnonzero(outside & ~movable)
        if len(over):
            # per node and side (bottom, right, top, left) how far past it
            past = np.column_stack([ymin - xd[over, 1], xd[over, 0] - xmax, xd[over, 1] - ymax,
                                    xmin - xd[over, 0]])
            walls = mesh.__dict__.get("walls", np.zeros((0, 2), dtype=np.int64))
            meshed = np.zeros((mesh.n_bodies, 4), dtype=bool)
            meshed[walls[:, 0], walls[:, 1]] = True
            ok = np.where(past > 0, meshed[mesh.body_of[over]] & (past <= contact_slack(mesh)), True)
            if ok.all():
                xd[over] = np.clip(xd[over], lo, hi)
            else:
                pressed = True
                if ((past > 0) & ~mesh._wall_sides[None, :]).any():
                    seam = True
    return pressed, seam


def relax_dragged(mesh: MovingMesh, xd, ev: MeshEvent) -> np.ndarray:
    """Relax the dragged nodes ``xd (n, 2)`` with the per-step iteration limit (Sec. 3.3): dragged
    nodes with the drag's reduced step, oscillating ones (recorded in ``ev``) halved once more
    each time they are flagged; periodic side nodes slide in pairs.  Sets ``mesh.points`` and
    returns the relaxed positions before the pairs slid."""
    p = mesh.params
    damp = mesh.drag.relax_damping if mesh._damping is None else mesh.drag.relax_damping * mesh._damping
    bend = bends_seams(mesh)
    mob = mesh._mobility
    # bent: periodic side nodes relax along their side, in pairs (the mean of the two moves).  Relaxed
    # in both directions as one node of the periodic strip, they cut a sheared suspension's
    # re-triangulations by a sixth (28.0 against 33.1 per 100 steps) but doubled the drag error of a
    # disk crossing the side at a re-triangulation (0.37-0.90 % against 0.28-0.36 % over three
    # crossings, benchmarks/bench_periodic_crossing.py)
    if not bend:
        xd = slide_in_pairs(xd, mesh.__dict__.get("_side_pairs", _NO_PAIRS), mesh.box, lead=mesh.kind == CONTACT)
    xr, nb = relax(xd, mesh.topo, mesh.h_node, mob, mesh.relax_iterations, p.relax_params,
                   bounds=_bounds(mesh), damping=damp)
    ev.n_blocked = nb
    if bend:
        xr = move_in_pairs(xd, xr, mesh._side_pairs)
    osc = mesh._osc.update(xr - xd, mesh.h_node)
    if len(osc):
        if mesh._damping is None:
            mesh._damping = np.ones(len(xd))
        mesh._damping[osc] *= 0.5
    ev.oscillating = osc
    mesh.points = xr if bend else slide_in_pairs(xr, mesh.__dict__.get("_side_pairs", _NO_PAIRS), mesh.box,
                                                 lead=mesh.kind == CONTACT)
    return xr


def _bounds(mesh: MovingMesh) -> tuple:
    """The box that holds the nodes between re-triangulations: unbounded across periodic sides
    that bend (:mod:`fluidem.mesh.seam`)."""
    if not bends_seams(mesh):
        return mesh.box
    xmin, xmax, ymin, ymax = mesh.box
    if "x" in mesh.periodic:
        xmin, xmax = -np.inf, np.inf
    if "y" in mesh.periodic:
        ymin, ymax = -np.inf, np.inf
    return (xmin, xmax, ymin, ymax)


def retriangulate_step(mesh: MovingMesh, ev: MeshEvent, reason: str) -> None:
    """Re-triangulate the current nodes in a drag step and record it in ``ev``."""
    ev.old_points, ev.old_triangles = mesh.points.copy(), mesh.triangles.copy()
    ev.prev_points = mesh._prev_points
    info = mesh.retriangulate()
    ev.retriangulated, ev.reason = True, reason
    ev.n_purged, ev.n_removed, ev.n_inserted = info["n_purged"], info["n_removed"], info["n_inserted"]
    ev.n_junctions = info["n_junctions"]


def harmonic_drag_of(mesh: MovingMesh) -> HarmonicDrag | None:
    """The harmonic extension of the connectivity of ``mesh`` (``drag_field="harmonic"``),
    factorised once per triangulation (held in ``mesh._harmonic``); ``None`` for the ramp."""
    if mesh.params.drag_field != "harmonic":
        return None
    if mesh.__dict__.get("_harmonic") is None:
        pairs = mesh._side_pairs if bends_seams(mesh) else None
        mesh._harmonic = harmonic_drag(mesh.topo, mesh.kind, mesh._drag_mobility, mesh.drag, pairs)
    return mesh._harmonic


def contacts_changed(mesh: MovingMesh) -> bool:
    """:func:`fluidem.mesh.triggers.contacts_changed` at the current poses, or a body
    came within ``min_gap`` of a wall, or one meshed with a wall left it by more than
    :func:`contact_slack` (hysteresis: a body resting on a wall whose gap breathes
    around ``min_gap`` does not re-trigger every step)."""
    if mesh.n_bodies:
        depth = wall_depths(world(mesh._vcat, mesh._vbody, mesh.poses), mesh._vbody, mesh.n_bodies, mesh.box)
        depth[:, ~mesh._wall_sides] = np.inf
        before = mesh.__dict__.get("walls", np.zeros((0, 2), dtype=np.int64))
        was = np.zeros(depth.shape, dtype=bool)
        was[before[:, 0], before[:, 1]] = True
        if ((depth < mesh.min_gap) & ~was).any() or (was & (depth > contact_slack(mesh))).any():
            return True
        # a wall node held on its side while its body lifted off there (a body rocking on
        # the wall): the closed outline no longer fits
        wall = mesh.__dict__.get("_contact_wall")
        if wall is not None and ((wall >= 0) & (wall < SEAM_CODE)).any():
            sel = (wall >= 0) & (wall < SEAM_CODE)
            idx = mesh._contact_idx[sel]
            rigid = world(mesh._contact_local[sel], mesh.body_of[idx], mesh.poses)
            if (np.abs(rigid - mesh.points[idx]).max() > contact_slack(mesh)):
                return True
    return body_contacts_changed(mesh._polygons(), mesh._near_pairs, mesh.contacts, mesh.min_gap, mesh.points,
                                 mesh.body_of)


def contact_slack(mesh: MovingMesh) -> float:
    """How far (length units) a wall contact may breathe between re-triangulations:
    ``max(min_gap, contact_slack · h)`` (:class:`~fluidem.mesh.params.MeshParams`)."""
    return max(mesh.min_gap, mesh.params.contact_slack * mesh.h)
