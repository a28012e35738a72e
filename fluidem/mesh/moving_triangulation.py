"""One triangulation of a :class:`~fluidem.mesh.moving.MovingMesh` from candidate nodes (the
"cut-out", paper Sec. 2.1), and the node budget of its adaptation.

:func:`triangulate_from` composes the stages on the mesh's bodies at their current poses
(the periodic images to mesh first, :mod:`fluidem.mesh.moving_images`).  The pipeline:

1. candidate nodes: the background (Friedrichs–Keller square grid for a uniform size, a
   graded Delaunay point set for a graded one; Sec. 2.1, 2.3) or, when dragging, the
   current nodes;
2. nodes inside a body or closer than ``clearance · h`` to its outline are removed, and so
   are nodes in gaps narrower than ``gap_purge · h`` (such a gap is spanned by one layer
   of elements between the outline nodes);
3. outline nodes are added: every body carries a fixed set of outline nodes in body
   coordinates (its polygon edges subdivided at the target size around it);
4. Triangle's constrained Delaunay triangulation of all nodes, with the outlines and the
   box sides as segments and a hole point in every body: nothing is triangulated inside a
   body;
5. Voronoi junction points (Sec. 3.2, :mod:`fluidem.mesh.junctions`): triangles spanning
   three bodies are split at a junction node;
6. spring relaxation (:mod:`fluidem.mesh.relax`, eq. 1–3), then up to ``cleanup_passes``
   (2) clean-up passes: free nodes of elements still outside the angle bounds (outside
   narrow gaps) are removed, a node is added in such elements without free nodes, and
   steps 4–6 run once more.

Then the drag association (:mod:`fluidem.mesh.drag`) and the quality trigger's baseline
(:func:`set_quality_baseline`) of the new connectivity are set.

At a re-triangulation (``adapt``, :func:`fluidem.mesh.adaptation.adapt`, between steps 2 and 3)
nodes swallowed by (or closer than ``purge_clearance · h`` to) a body are purged, an
independent set of nodes is removed where the incident edges are on average shorter than
``coarsen_ratio`` (0.7) of their target and nodes are added in triangles larger than
``refine_area`` (1.6) target areas (at the midpoint of an edge on a box side, else at the
centroid; so vacated regions coarsen again, Fig. 6), and junction points are recomputed.  The
number of free and box nodes is held within ``node_count_tolerance`` (2 %) of a budget, the
first mesh's count per unit of ``∫ h⁻² dA`` (``hold_node_count``, :func:`node_budget`): of two
large neighbours only the larger is split, and above the budget the most compressed free nodes
are removed as well (the harmonic drag compresses the whole region ahead of a body only mildly,
below the coarsening threshold, while it stretches the region behind it beyond the refinement
one).

The functions take the mesh (``mesh``) and read or set its attributes; they add none.

Examples
--------
>>> from fluidem.geometry import rectangle
>>> from fluidem.mesh import MovingMesh
>>> mm = MovingMesh((0, 2, 0, 1), [rectangle(0.3, 0.2)], [[0.6, 0.5, 0.0]], h=0.1)
>>> info = triangulate_from(mm, mm.points, mm.kind, mm.uid, purge=0.5, adapt=True, n_relax=0, h_cand=mm.h_node)
>>> sorted(info), movable_count(mm) == int((mm.kind <= 2).sum())   # free, side and corner nodes
(['n_inserted', 'n_junctions', 'n_purged', 'n_removed'], True)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import shapely

from .adaptation import adapt as adapt_nodes
from .adaptation import cleanup_candidates
from .contact_outline import contact_outline, contact_pairs
from .cutout import Triangulation, cut_out, triangulate
from .drag import DragAssociation, drag_association
from .gaps import NOT_ON_BOUNDARY, anchored_across_gap, boundary_owner, structural_narrow
from .moving_images import image_set, set_images, wrap_into_box
from .nodes import CONTACT, CORNER, FREE, JUNCTION, SIDE, mobility, to_body
from .periodic import bends_seams, fill_sides, match_side_nodes, on_periodic_sides, side_partners, slide_in_pairs
from .relax import relax, signed_areas
from .seam import SEAM_CODE, SEAM_MERGE
from .triggers import QualityBaseline, element_shape, quality_baseline

if TYPE_CHECKING:
    from .moving import MovingMesh

__all__ = ["triangulate_from", "install", "set_quality_baseline", "movable_count", "size_integral", "node_budget"]


def movable_count(mesh: MovingMesh) -> int:
    """Free and box nodes of the current mesh (what the adaptation adds and removes)."""
    return int(((mesh.kind == FREE) | (mesh.kind == SIDE) | (mesh.kind == CORNER)).sum())


def size_integral(mesh: MovingMesh) -> float:
    """``∫ h⁻² dA`` over the current mesh (elements, mean per-node target), dimensionless."""
    t = mesh.triangles
    h_t = mesh.h_node[t].mean(axis=1)
    return float((np.abs(signed_areas(mesh.points, t)) / h_t**2).sum())


def node_budget(mesh: MovingMesh) -> float | None:
    """Free and box nodes the adaptation aims at (``hold_node_count``), ``None``: no aim."""
    density = mesh.__dict__.get("_node_density")
    if not mesh.params.hold_node_count or density is None:
        return None
    return density * size_integral(mesh)


def triangulate_from(mesh: MovingMesh, cand, cand_kind, cand_uid, purge, adapt, n_relax, h_cand=None):
    """Contacts + cut-out (+ adaptation) + CDT + junctions + relaxation + clean-up from
    candidate nodes (Sec. 2.1, module docstring); returns the counts of
    :class:`~fluidem.mesh.moving.MeshEvent` (``n_purged``, ``n_removed``, ``n_inserted``, ``n_junctions``)."""
    p = mesh.params
    if mesh.periodic:
        set_images(mesh, image_set(mesh, mesh.body_poses), nudge=True)
    poses = mesh.poses
    outline_world = mesh.outlines.world(poses)
    polys = mesh._polygons(poses)
    tree = shapely.STRtree(polys) if mesh.n_bodies else None
    table = mesh._bodies_table(poses)

    def target(q):
        return mesh._target(q, outline_world)

    contact = contact_outline(polys, tree, outline_world, mesh.outlines, mesh.h, mesh.min_gap, p, box=mesh.box,
                              wall_sides=mesh._wall_sides)
    mesh.contacts = contact.contacts
    mesh.walls = contact.walls
    mesh.pore_areas = contact.pore_areas

    cand = np.asarray(cand, dtype=float)
    h_candidates = target(cand) if h_cand is None else h_cand
    cut = cut_out(cand, cand_kind, h_candidates, table, purge, p.gap_purge, mesh.box)
    info = {"n_purged": cut.n_purged, "n_removed": 0, "n_inserted": 0}
    keep = cut.keep
    kept_points, kept_kind, kept_uid = cand[keep], cand_kind[keep], cand_uid[keep]
    if adapt:
        # adaptation works on the current mesh: the candidates are its nodes
        if len(cand) != len(mesh.points):
            raise RuntimeError("adaptation needs the current nodes as candidates")
        solid_tree = shapely.STRtree(np.asarray(contact.solids, dtype=object)) if mesh.n_bodies else None
        ad = adapt_nodes(kept_points, kept_kind, kept_uid, mesh.points, mesh.topo, mesh.h_node, mesh.kind,
                         np.where(keep, np.cumsum(keep) - 1, -1), solid_tree, target, mesh._uids,
                         mesh.step_count, p.refine_area, p.coarsen_ratio, p.clearance, box=mesh.box,
                         budget=node_budget(mesh),
                         budget_tolerance=p.node_count_tolerance)
        kept_points, kept_kind, kept_uid = ad.points, ad.kind, ad.uid
        if bends_seams(mesh):  # nodes added in the old elements beyond a bent seam
            kept_points = wrap_into_box(mesh, kept_points, kept_kind)
        info["n_removed"], info["n_inserted"] = ad.n_removed, ad.n_inserted
        if mesh.periodic:  # side nodes a body crossing the side took away
            n_kept = len(kept_points)
            kept_points, kept_kind, kept_uid = fill_sides(kept_points, kept_kind, kept_uid, mesh.box,
                                                          mesh.periodic, target, mesh._uids)
            info["n_inserted"] += len(kept_points) - n_kept

    final_shape = None
    for attempt in range(p.cleanup_passes + 1):
        kept_points, kept_kind, kept_uid = match_side_nodes(kept_points, kept_kind, kept_uid, mesh.box,
                                                            mesh.periodic, mesh._uids, merge=0.25 * mesh.h)
        tri = triangulate(kept_points, kept_kind, kept_uid, outline_world, mesh.outlines, contact, poses, polys,
                          tree, mesh.box, mesh._uids, p.junctions, p.junction_clearance, target,
                          seams=(mesh.periodic, SEAM_MERGE * mesh.h) if mesh.periodic else None)
        install(mesh, tri, outline_world)
        if n_relax:
            mesh.points, _ = relax(mesh.points, mesh.topo, mesh.h_node, mesh._mobility, n_relax,
                                   p.relax_params, bounds=mesh.box)
            mesh.points = slide_in_pairs(mesh.points, mesh._side_pairs, mesh.box, lead=mesh.kind == CONTACT)
        if attempt == p.cleanup_passes:
            break
        # clean-up: bad elements outside narrow gaps lose their free nodes, or get one
        cleanup = cleanup_candidates(mesh.points, mesh.topo, mesh.kind, mesh.uid, mesh.h_node, table, tree,
                                     mesh.box, target, mesh._uids, p.min_angle_trigger, p.max_angle_trigger,
                                     p.cleanup_clearance)
        if cleanup.candidates is None:
            final_shape = cleanup.shape  # of the mesh kept
            break
        kept_points, kept_kind, kept_uid = cleanup.candidates
    mesh._steps_since = 0
    mesh._near_pairs = contact_pairs(polys, tree, mesh.h)
    mesh.drag: DragAssociation = drag_association(mesh.points, mesh.h_node, mesh._drag_mobility, table,
                                                  p.drag_reach, p.drag_full, p.drag_stiffness)
    mesh._harmonic = None  # built by the first drag step on this connectivity
    set_quality_baseline(mesh, final_shape)
    info["n_junctions"] = mesh.n_junctions
    return info


def install(mesh: MovingMesh, tri: Triangulation, outline_world):
    """Make ``tri`` the current mesh (node data, topology, targets, mobility)."""
    mesh.points = tri.points
    mesh.kind = tri.kind
    mesh.body_of = tri.body_of
    mesh.outline_row = tri.outline_row
    mesh.uid = tri.uid
    mesh.triangles = tri.triangles
    mesh.topo = tri.topo
    mesh.boundary_segments = tri.boundary_segments
    mesh.boundary_markers = tri.boundary_markers
    mesh.junction_nodes = tri.junction_nodes
    mesh.junction_verts = tri.junction_verts
    mesh.junction_bary = tri.junction_bary
    mesh.n_junctions = int(len(tri.junction_nodes))
    mesh._contact_local = tri.contact_local
    mesh._contact_idx = np.flatnonzero(tri.kind == CONTACT)
    mesh._contact_wall = (np.full(len(mesh._contact_idx), -1, dtype=np.int64) if tri.contact_wall is None
                          else tri.contact_wall)
    nc = len(mesh._contact_idx)
    mesh._seam_outer_body = (np.full(nc, -1, dtype=np.int64) if tri.seam_outer_body is None
                             else tri.seam_outer_body)
    mesh._seam_outer_local = np.zeros((nc, 2)) if tri.seam_outer_local is None else tri.seam_outer_local
    mesh.h_node = mesh._target(tri.points, outline_world)
    # periodic side nodes slide along their side in matched pairs (:func:`slide_in_pairs`)
    mesh._mobility = mobility(tri.kind, tri.points, mesh.box)
    mesh._side_pairs = side_partners(tri.points, tri.kind, mesh.box, mesh.periodic)
    # junction nodes are dragged (they are not relaxed)
    mesh._drag_mobility = mesh._mobility.copy()
    mesh._drag_mobility[tri.kind == JUNCTION] = 1.0
    if bends_seams(mesh):
        # bent seams (:mod:`fluidem.mesh.seam`): seam nodes stay where they are on their body,
        # periodic side nodes are dragged like free nodes (in pairs)
        seam = mesh._contact_wall >= SEAM_CODE
        if seam.any():
            idx = mesh._contact_idx[seam]
            mesh._contact_local = np.array(mesh._contact_local, dtype=float)
            mesh._contact_local[seam] = to_body(tri.points[idx], mesh.poses[tri.body_of[idx]])
        on = np.unique(mesh._side_pairs)
        mesh._drag_mobility[on[tri.kind[on] == SIDE]] = 1.0
        if len(mesh.periodic) == 1:
            # the corners where a periodic side meets a wall slide along the wall in pairs
            c = 0 if mesh.periodic[0] == "x" else 1
            corner = np.flatnonzero(tri.kind == CORNER)
            lo = corner[tri.points[corner, c] == mesh.box[2 * c]]
            hi = corner[tri.points[corner, c] == mesh.box[2 * c + 1]]
            lo, hi = lo[np.argsort(tri.points[lo, 1 - c])], hi[np.argsort(tri.points[hi, 1 - c])]
            if len(lo) == len(hi):
                mesh._side_pairs = np.vstack([mesh._side_pairs, np.column_stack([lo, hi])]).astype(np.int64)
                mesh._drag_mobility[np.concatenate([lo, hi]), c] = 1.0
    mesh._osc.reset()
    mesh._damping = None


def _anchored_apart_from_seams(mesh: MovingMesh, tri_idx) -> np.ndarray:
    """Mask ``(len(tri_idx),)``: elements anchored across a narrow gap between two bodies, or a body
    and a wall (:func:`fluidem.mesh.gaps.anchored_across_gap` with the periodic sides' nodes on no
    boundary: a body crossing the side has no gap to it)."""
    owner = boundary_owner(mesh.kind, mesh.body_of)
    owner[on_periodic_sides(mesh.points, mesh.box, mesh.periodic) & (mesh.kind == SIDE)] = NOT_ON_BOUNDARY
    return anchored_across_gap(tri_idx, mesh.triangles, mesh.points, owner, mesh.h_node, mesh._bodies_table(),
                               mesh.box)


def set_quality_baseline(mesh: MovingMesh, shape=None):
    """Thresholds of the quality trigger after a triangulation (:func:`quality_baseline`).

    Narrow-gap elements (the cheap geometric flag evaluated now, gaps change little
    between re-triangulations, or'ed with the structural one) are left out.
    ``shape``: :func:`element_shape` of the current mesh if the caller has it.
    """
    p = mesh.params
    narrow = mesh._narrow_gap_owners() | structural_narrow(mesh.topo, mesh.kind, mesh.body_of)
    shape = element_shape(mesh.points, mesh.topo) if shape is None else shape
    mesh.baseline: QualityBaseline = quality_baseline(shape, narrow, p.min_angle_trigger, p.max_angle_trigger,
                                                      p.angle_margin, p.min_angle_margin)
    if bends_seams(mesh):
        # an element at a seam node moves with its body (seam and outline nodes fixed on it, the
        # free node dragged with it): its smallest angle fires ``angle_margin`` below the smaller of
        # its birth angle and ``min_angle_trigger`` (a body vertex by the side line gives slivers),
        # not at its first change; its largest angle as any element's
        base = mesh.baseline
        seam = np.zeros(len(mesh.points), dtype=bool)
        seam[mesh._contact_idx[mesh._contact_wall >= SEAM_CODE]] = True
        at = seam[mesh.triangles].any(axis=1)
        # one flagged narrow only for its vertices on the side (no wall) is watched so too, not as
        # a narrow-gap element (:func:`quality_dropped`): those fired 26 of 65 quality firings of a
        # sheared suspension (2 × 1 cell, 125 steps) at the first change of a sliver born at 0.1-15°
        seam_only = at & base.narrow
        if seam_only.any():
            idx = np.flatnonzero(seam_only)
            seam_only[idx[_anchored_apart_from_seams(mesh, idx)]] = False
        if seam_only.any():
            base.narrow[seam_only] = False
            born_max = np.degrees(np.arccos(np.clip(shape.cos_min[seam_only], -1.0, 1.0)))
            hi = np.maximum(born_max, p.max_angle_trigger) + p.angle_margin
            base.cos_hi[seam_only] = np.cos(np.radians(np.clip(hi, 0.0, 180.0)))
        at &= ~base.narrow
        if at.any():
            born_min = np.degrees(np.arccos(np.clip(shape.cos_max[at], -1.0, 1.0)))
            theta = np.minimum(born_min, p.min_angle_trigger) - p.angle_margin
            base.cos_lo[at] = np.cos(np.radians(np.clip(theta, 0.0, 180.0)))
