"""Cut-out and triangulation of the moving mesh (paper Sec. 2.1, 3.2).

1. :func:`cut_out`: free candidate nodes inside a body or closer than ``purge · h`` to its
   outline are removed, and so are free nodes in gaps narrower than ``gap_purge · h`` (such
   a gap is spanned by one layer of elements);
2. :func:`triangulate`: Triangle's constrained Delaunay triangulation of the kept nodes,
   the outline and contact nodes (:mod:`fluidem.mesh.contact_outline`), with the outlines
   and the box sides as segments and a hole point in every body; then Voronoi junction
   points (:mod:`fluidem.mesh.junctions`) split the triangles spanning three bodies.

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.cutout import cut_out
>>> from fluidem.mesh.nodes import FREE, CORNER
>>> cand = np.array([[0.0, 0.0], [0.5, 0.5]])
>>> cut = cut_out(cand, np.array([CORNER, FREE], np.int8), np.full(2, 0.1), None, 0.5, 1.1, (0, 1, 0, 1))
>>> cut.keep.tolist(), cut.n_purged
([True, True], 0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
import triangle as tr

from ..errors import MeshError
from ..geometry import barycentric
from .adjacency import edges_from_neighbors, split_with_neighbors
from .contact_outline import ContactOutline, covered_box_nodes
from .gaps import gap_from_pairs
from .junctions import junction_points
from .nodes import (
    CONTACT,
    CORNER,
    FIRST_BODY_MARKER,
    FREE,
    JUNCTION,
    OUTLINE,
    SIDE,
    BodyOutlines,
    UidSource,
    box_ring,
    to_body,
)
from .periodic import partner_places
from .relax import MeshTopology, signed_areas
from .seam import SEAM_CODE, clip_at_seams, covered_side_nodes, pair_seam_nodes

__all__ = ["CutOut", "Triangulation", "cut_out", "triangulate"]


@dataclass(frozen=True)
class CutOut:
    """Which candidate nodes survive the cut-out.

    Attributes
    ----------
    keep : (n_candidates,) bool
        Free and box nodes kept (outline, contact and junction candidates are always
        dropped: they are rebuilt).
    n_purged : int
        Free candidates removed inside or near a body or in a narrow gap.
    """

    keep: np.ndarray
    n_purged: int


@dataclass(frozen=True)
class Triangulation:
    """A new triangulation and the node data that goes with it.

    Attributes
    ----------
    points : (n_nodes, 2) float
    kind : (n_nodes,) int8
        :mod:`fluidem.mesh.nodes` kinds.
    body_of : (n_nodes,) int
        Body of outline and contact nodes, -1 otherwise.
    outline_row : (n_nodes,) int
        Row of an outline node in the outline table, -1 otherwise.
    uid : (n_nodes,) int
    triangles : (n_triangles, 3) int
        Counter-clockwise.
    topo : MeshTopology
    boundary_segments : (s, 2) int
    boundary_markers : (s,) int
        1..4 for the box sides, ``FIRST_BODY_MARKER + b`` for body ``b``.
    contact_local : (n_contact, 2) float
        Body-frame positions of the contact nodes (in node order).
    contact_wall : (n_contact,) int
        Box side a contact node slides along (a wall node), ``SEAM_CODE + side`` for a seam
        node (:mod:`fluidem.mesh.seam`), ``-1`` for the others.
    seam_outer_body, seam_outer_local : (n_contact,) int, (n_contact, 2) float
        For a seam node the body and body-frame position of the outer end of its segment
        (``contact_local`` holds the inner end); ``-1`` and zeros for other contact nodes.
    junction_nodes : (k,) int
    junction_verts : (k, 3) int
        The triangle of outline nodes each junction node split.
    junction_bary : (k, 3) float
        Barycentric coordinates of each junction node in that triangle.
    """

    points: np.ndarray
    kind: np.ndarray
    body_of: np.ndarray
    outline_row: np.ndarray
    uid: np.ndarray
    triangles: np.ndarray
    topo: MeshTopology
    boundary_segments: np.ndarray
    boundary_markers: np.ndarray
    contact_local: np.ndarray
    junction_nodes: np.ndarray
    junction_verts: np.ndarray
    junction_bary: np.ndarray
    contact_wall: np.ndarray = None
    seam_outer_body: np.ndarray = None
    seam_outer_local: np.ndarray = None


def cut_out(cand, cand_kind, h_cand, table, purge: float, gap_purge: float, box) -> CutOut:
    """The cut-out of candidate nodes ``cand (n, 2)`` of kinds ``cand_kind (n,)`` with target
    sizes ``h_cand (n,)`` (module docstring).

    ``table``: the bodies' :class:`~fluidem.mesh.proximity.PolygonTable` (``None`` without
    bodies); ``purge``, ``gap_purge``: multiples of ``h``.
    """
    cand = np.asarray(cand, dtype=float)
    box_nodes = (cand_kind == SIDE) | (cand_kind == CORNER)
    keep = np.ones(len(cand), dtype=bool)
    if table is not None:
        # one query serves both tests (the closed contact outlines lie within min_gap
        # of the bodies, well inside the purge distance)
        qi = np.flatnonzero(cand_kind == FREE)
        ii, _, dd = table.pairs_within(cand[qi], max(purge, gap_purge) * h_cand[qi], solid=True)
        close = dd < purge * h_cand[qi[ii]]
        keep[qi[ii[close]]] = False
        # no room in gaps narrower than gap_purge · h: the gap is spanned by one layer
        gap = gap_from_pairs(cand[qi], ii, dd, box)
        keep[qi[gap < gap_purge * h_cand[qi]]] = False
    # junction nodes from before are recomputed
    movable = (cand_kind == FREE) | box_nodes
    n_purged = int((~keep & (cand_kind == FREE)).sum())
    return CutOut(keep=keep & movable, n_purged=n_purged)


def _on_periodic_sides(points, box, axes) -> np.ndarray:
    """Mask ``(k,)``: ``points (k, 2)`` on a side of the periodic ``axes``."""
    xmin, xmax, ymin, ymax = box
    tol = 1e-9 * max(xmax - xmin, ymax - ymin)
    on = np.zeros(len(points), dtype=bool)
    if "x" in axes:
        on |= (np.abs(points[:, 0] - xmin) < tol) | (np.abs(points[:, 0] - xmax) < tol)
    if "y" in axes:
        on |= (np.abs(points[:, 1] - ymin) < tol) | (np.abs(points[:, 1] - ymax) < tol)
    return on


def _hole_points(solids, box) -> np.ndarray:
    """One point ``(k, 2)`` inside every part of the ``solids`` within the box."""
    xmin, xmax, ymin, ymax = box
    inner = shapely.intersection(np.asarray(solids, dtype=object), shapely.box(xmin, ymin, xmax, ymax))
    tiny = (1e-6 * max(xmax - xmin, ymax - ymin)) ** 2  # slivers along a side are no hole (a body edge on it)
    parts = [p for g in inner for p in shapely.get_parts(g)
             if shapely.get_type_id(p) == 3 and shapely.area(p) > tiny]
    if not parts:
        return np.zeros((0, 2))
    return shapely.get_coordinates(shapely.point_on_surface(np.asarray(parts, dtype=object)))


def triangulate(points, kind, uid, outline_world, outlines: BodyOutlines, contact: ContactOutline, poses, polys,
                tree, box, uids: UidSource, junctions: bool, junction_clearance: float, target,
                seams: tuple | None = None) -> Triangulation:
    """Constrained Delaunay triangulation of the kept candidate nodes and the outlines, then
    junction points.

    Parameters
    ----------
    points, kind, uid : (n,) arrays
        The candidate nodes kept by :func:`cut_out` (and the adaptation).
    outline_world : (n_outline, 2) float
        The outline table at ``poses``.
    outlines : BodyOutlines
    contact : ContactOutline
        The outlines to mesh (:func:`fluidem.mesh.contact_outline.contact_outline`).
    poses : (n_bodies, 3) float
    polys : (n_bodies,) shapely Polygons
        The bodies at ``poses``; ``tree`` their STR tree (``None`` without bodies).
    box : (xmin, xmax, ymin, ymax)
    uids : UidSource
        Draws the uids of the contact and junction nodes.
    junctions : bool
        Insert junction points (with three bodies or more).
    junction_clearance : float
        Multiple of ``h`` a junction node keeps from the bodies.
    target : callable
        Target size ``points (k, 2) -> (k,)``.
    seams : (axes, merge) or None
        Periodic axes across which bodies may reach, and the distance (length units) within
        which box nodes next to a seam node are dropped: the outlines are clipped at the box
        (:mod:`fluidem.mesh.seam`).  ``None``: every outline lies in the box.

    Raises
    ------
    MeshError
        The outlines intersect (bodies overlap by more than the contact policy handles).
    """
    n_bodies = len(polys)
    outline_world = outline_world
    n_outline = len(outline_world)
    xmin, xmax, ymin, ymax = box
    corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    have = (np.abs(points[kind == CORNER][:, None, :] - corners[None]).max(axis=2) == 0).any(axis=0)
    if not have.all():
        # a box corner dropped under a body in contact with two walls comes back once the body left
        k = int((~have).sum())
        points = np.vstack([points, corners[~have]])
        kind = np.concatenate([kind, np.full(k, CORNER, np.int8)])
        uid = np.concatenate([uid, uids.take(k)])
    if contact.wall_solids:
        # box nodes under a body in contact with a wall (or next to its wall nodes) are no boundary
        is_box = (kind == SIDE) | (kind == CORNER)
        drop = np.zeros(len(points), dtype=bool)
        drop[is_box] = covered_box_nodes(points[is_box], contact, 1e-9 * max(xmax - xmin, ymax - ymin),
                                         corner=kind[is_box] == CORNER)
        points, kind, uid = points[~drop], kind[~drop], uid[~drop]
    contact_points, contact_body = contact.contact_points, contact.contact_body
    keep_outline = contact.keep_outline
    outline_rows = np.flatnonzero(keep_outline)
    # outline and contact nodes (the outline PSLG), numbered from 0
    oc_nodes = np.vstack([outline_world[keep_outline], contact_points])
    n_oc_outline = len(outline_rows)
    node_of_row = np.full(n_outline + len(contact_points), -1, dtype=np.int64)
    node_of_row[outline_rows] = np.arange(len(outline_rows))
    node_of_row[n_outline:] = len(outline_rows) + np.arange(len(contact_points))
    oc_segments = node_of_row[contact.segments]
    if (oc_segments < 0).any():
        raise MeshError("outline segment refers to a removed outline node")
    oc_body = np.concatenate([outlines.body[outline_rows], contact_body]).astype(np.int64)
    contact_local = to_body(contact_points, poses[contact_body]) if len(contact_points) else np.zeros((0, 2))
    oc_local = np.vstack([outlines.local[outline_rows], contact_local])
    oc_row = np.concatenate([outline_rows, np.full(len(contact_points), -1)])
    oc_uid = np.concatenate([outlines.row_uid(outline_rows), uids.take(len(contact_points))])
    oc_wall = np.concatenate([np.full(len(outline_rows), -2), contact.contact_wall]).astype(np.int64)
    oc_outer_body = np.full(len(oc_nodes), -1, dtype=np.int64)
    oc_outer_local = np.zeros((len(oc_nodes), 2))
    if seams is not None and len(oc_nodes):
        # bodies across periodic sides: outlines clipped at the box, seam nodes where they leave it
        axes, merge = seams
        clip = clip_at_seams(oc_nodes, oc_segments, box, axes)
        if len(clip.seam_points) or not clip.keep.all():
            k = len(clip.seam_points)
            keep = np.concatenate([clip.keep, np.ones(k, dtype=bool)])
            # partners across a side pair at one place; a seam node without one gets a box node there
            seam_points, lonely = pair_seam_nodes(clip.seam_points, clip.seam_side, box, 1e-3 * merge)
            oc_nodes = np.vstack([oc_nodes, seam_points])
            oc_body = np.concatenate([oc_body, oc_body[clip.seam_inner]])
            oc_local = np.vstack([oc_local, oc_local[clip.seam_inner]])
            oc_row = np.concatenate([oc_row, np.full(k, -1)])
            oc_uid = np.concatenate([oc_uid, uids.take(k)])
            oc_wall = np.concatenate([oc_wall, SEAM_CODE + clip.seam_side])
            oc_outer_body = np.concatenate([oc_outer_body, oc_body[clip.seam_outer]])
            oc_outer_local = np.vstack([oc_outer_local, oc_local[clip.seam_outer]])
            remap = np.cumsum(keep) - 1
            oc_segments = remap[clip.segments]
            oc_nodes, oc_body, oc_local, oc_row, oc_uid = (oc_nodes[keep], oc_body[keep], oc_local[keep],
                                                          oc_row[keep], oc_uid[keep])
            oc_wall, oc_outer_body, oc_outer_local = oc_wall[keep], oc_outer_body[keep], oc_outer_local[keep]
            n_oc_outline = int((oc_row >= 0).sum())
            # box nodes on periodic sides under a body or next to a seam node (on both sides
            # of the pair) are no boundary
            ends = np.vstack([seam_points, partner_places(seam_points, clip.seam_side, box)])
            on_periodic = _on_periodic_sides(points, box, axes) & ((kind == SIDE) | (kind == CORNER))
            if on_periodic.any():
                drop = np.zeros(len(points), dtype=bool)
                drop[on_periodic] = covered_side_nodes(points[on_periodic], contact.solids, ends, merge, box)
                points, kind, uid = points[~drop], kind[~drop], uid[~drop]
            if len(lonely):
                points = np.vstack([points, lonely])
                kind = np.concatenate([kind, np.full(len(lonely), SIDE, dtype=kind.dtype)])
                uid = np.concatenate([uid, uids.take(len(lonely))])
    # assemble nodes: [candidates | outline | contact and seam nodes | junctions]
    n_cand = len(points)
    nodes = np.vstack([points, oc_nodes])
    outline_segments = n_cand + oc_segments
    n_contact = len(oc_nodes) - n_oc_outline
    kind = np.concatenate([kind, np.full(n_oc_outline, OUTLINE, np.int8), np.full(n_contact, CONTACT, np.int8)])
    body_of = np.concatenate([np.full(n_cand, -1), oc_body])
    outline_row = np.concatenate([np.full(n_cand, -1), oc_row])
    uid = np.concatenate([uid, oc_uid])
    # contact nodes: body coordinates for rigid motion
    contact_local = oc_local[n_oc_outline:]
    contact_wall_all = oc_wall[n_oc_outline:]
    seam_outer_body, seam_outer_local = oc_outer_body[n_oc_outline:], oc_outer_local[n_oc_outline:]
    first_contact = n_cand + n_oc_outline
    wall_nodes = first_contact + np.flatnonzero(contact_wall_all >= 0)
    ring_seg, ring_mark = box_ring(nodes, kind, box, extra=wall_nodes)
    if seams is not None and (contact_wall_all >= SEAM_CODE).any():
        # the seam under a body is no boundary: ring segments lying wholly on a body
        mid = 0.5 * (nodes[ring_seg[:, 0]] + nodes[ring_seg[:, 1]])
        under = np.zeros(len(ring_seg), dtype=bool)
        on_periodic = np.flatnonzero(_on_periodic_sides(mid, box, seams[0]))
        if len(on_periodic) and len(contact.solids):
            tol = 1e-9 * max(box[1] - box[0], box[3] - box[2])
            u = shapely.buffer(shapely.union_all(np.asarray(contact.solids, dtype=object)), tol)
            lines = shapely.linestrings(np.stack([nodes[ring_seg[on_periodic, 0]], nodes[ring_seg[on_periodic, 1]]],
                                                 axis=1))
            under[on_periodic] = shapely.covers(u, lines)
        ring_seg, ring_mark = ring_seg[~under], ring_mark[~under]
    if len(wall_nodes):
        # the box segments under a body in contact are no fluid boundary
        mid_pts = shapely.points(0.5 * (nodes[ring_seg[:, 0]] + nodes[ring_seg[:, 1]]))
        xmin, xmax, ymin, ymax = box
        tol = 1e-9 * max(xmax - xmin, ymax - ymin)
        covered = np.zeros(len(ring_seg), dtype=bool)
        for solid in contact.wall_solids:
            covered |= shapely.distance(solid, mid_pts) < tol
        ring_seg, ring_mark = ring_seg[~covered], ring_mark[~covered]
    contact_wall = contact_wall_all.copy()
    mid = 0.5 * (nodes[outline_segments[:, 0]] + nodes[outline_segments[:, 1]])
    if len(outline_segments):
        owner = body_of[outline_segments[:, 0]]
        same = owner == body_of[outline_segments[:, 1]]
        if not same.all():
            dd = shapely.distance(polys[None, :], shapely.points(mid[~same])[:, None])
            owner = owner.copy()
            owner[~same] = np.argmin(dd, axis=1)
        outline_markers = FIRST_BODY_MARKER + owner
    else:
        outline_markers = np.zeros(0, dtype=np.int64)
    pslg = {
        "vertices": nodes,
        "segments": np.vstack([ring_seg, outline_segments]).astype(np.int32),
        "segment_markers": np.concatenate([ring_mark, outline_markers]).astype(np.int32)[:, None],
    }
    holes = contact.holes
    if seams is not None and (contact_wall_all >= SEAM_CODE).any():
        # hole points inside the parts of the bodies in the box
        holes = _hole_points(contact.solids, box)
    if len(holes):
        pslg["holes"] = holes
    out = tr.triangulate(pslg, "pQn")
    t = out["triangles"].astype(np.int64)
    neighbors = out["neighbors"].astype(np.int64)
    if len(out["vertices"]) != len(nodes):
        raise MeshError(
            f"Triangle added {len(out['vertices']) - len(nodes)} points: outlines intersect "
            "(bodies overlap by more than the contact policy handles)"
        )
    boundary_segments = out["segments"].astype(np.int64)
    boundary_markers = out["segment_markers"].ravel().astype(np.int64)
    # drop unused nodes (none expected; duplicates or points in holes)
    used = np.zeros(len(nodes), dtype=bool)
    used[t.ravel()] = True
    if not used.all():
        remap = np.cumsum(used) - 1
        t = remap[t]
        boundary_segments = remap[boundary_segments]
        nodes, kind, body_of, outline_row, uid = nodes[used], kind[used], body_of[used], outline_row[used], uid[used]
        contact_used = used[first_contact: first_contact + n_contact]
        contact_local, contact_wall = contact_local[contact_used], contact_wall[contact_used]
        seam_outer_body, seam_outer_local = seam_outer_body[contact_used], seam_outer_local[contact_used]
    # Triangle returns counter-clockwise triangles; make sure (swap vertices 1, 2 and
    # the neighbours opposite them together)
    cw = signed_areas(nodes, t) < 0
    if cw.any():
        t[cw] = t[cw][:, [0, 2, 1]]
        neighbors[cw] = neighbors[cw][:, [0, 2, 1]]
    junction_nodes = np.zeros(0, dtype=np.int64)
    junction_verts = np.zeros((0, 3), dtype=np.int64)
    junction_bary = np.zeros((0, 3))
    if junctions and n_bodies >= 3:
        # Voronoi junction points (Sec. 3.2): split junction triangles at a new node
        owner = np.where((kind == OUTLINE) | (kind == CONTACT), body_of, -1)
        junction_tris, junction_pts = junction_points(nodes, t, owner, poses[:, :2], polys, target,
                                                      clearance=junction_clearance, tree=tree)
        if len(junction_pts):
            n0 = len(nodes)
            # junction nodes follow their junction: fixed barycentric coordinates in
            # the triangle of outline nodes they split
            jv = t[junction_tris]
            P = nodes[jv]
            junction_bary = barycentric(junction_pts, P[:, 0], P[:, 1], P[:, 2])
            junction_verts = jv
            junction_nodes = n0 + np.arange(len(junction_pts))
            t, neighbors = split_with_neighbors(t, neighbors, junction_tris, junction_nodes)
            nodes = np.vstack([nodes, junction_pts])
            kind = np.concatenate([kind, np.full(len(junction_pts), JUNCTION, np.int8)])
            body_of = np.concatenate([body_of, np.full(len(junction_pts), -1)])
            outline_row = np.concatenate([outline_row, np.full(len(junction_pts), -1)])
            uid = np.concatenate([uid, uids.take(len(junction_pts))])
    edges, edge_tris = edges_from_neighbors(t, neighbors)
    return Triangulation(
        points=nodes, kind=kind, body_of=body_of.astype(np.int64), outline_row=outline_row.astype(np.int64),
        uid=uid.astype(np.int64), triangles=t,
        topo=MeshTopology(t, edges, edge_tris, edge_tris[:, 0] != edge_tris[:, 1]),
        boundary_segments=boundary_segments, boundary_markers=boundary_markers, contact_local=contact_local,
        junction_nodes=junction_nodes, junction_verts=junction_verts, junction_bary=junction_bary,
        contact_wall=contact_wall, seam_outer_body=seam_outer_body, seam_outer_local=seam_outer_local)
