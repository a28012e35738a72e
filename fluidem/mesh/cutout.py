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
from .periodic import on_periodic_sides, partner_places
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


def _hole_points(solids, box, nodes) -> np.ndarray:
    """One point ``(k, 2)`` inside every part of the ``solids`` within the box and within the convex
    hull of the PSLG ``nodes (n, 2)``: where a body covers a corner of a doubly periodic box the
    corner is no node, the triangulation ends at the hull (the chord between the two seam nodes
    around the corner), and a hole point beyond it would be ignored (the body's part left meshed)."""
    xmin, xmax, ymin, ymax = box
    hull = shapely.convex_hull(shapely.multipoints(np.asarray(nodes, dtype=float)))
    inner = shapely.intersection(np.asarray(solids, dtype=object),
                                 shapely.intersection(shapely.box(xmin, ymin, xmax, ymax), hull))
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
    points, kind, uid = _box_nodes_kept(points, kind, uid, contact, box, uids)
    oc = _outline_nodes(outline_world, outlines, contact, poses, uids)
    if seams is not None and len(oc.nodes):
        points, kind, uid = _clip_at_seams(oc, points, kind, uid, contact, box, uids, seams)
    # assemble nodes: [candidates | outline | contact and seam nodes | junctions]
    n_cand = len(points)
    nodes = np.vstack([points, oc.nodes])
    outline_segments = n_cand + oc.segments
    n_contact = len(oc.nodes) - oc.n_outline
    kind = np.concatenate([kind, np.full(oc.n_outline, OUTLINE, np.int8), np.full(n_contact, CONTACT, np.int8)])
    body_of = np.concatenate([np.full(n_cand, -1), oc.body])
    outline_row = np.concatenate([np.full(n_cand, -1), oc.row])
    uid = np.concatenate([uid, oc.uid])
    # contact nodes: body coordinates for rigid motion
    contact_local = oc.local[oc.n_outline:]
    contact_wall_all = oc.wall[oc.n_outline:]
    seam_outer_body, seam_outer_local = oc.outer_body[oc.n_outline:], oc.outer_local[oc.n_outline:]
    first_contact = n_cand + oc.n_outline
    wall_nodes = first_contact + np.flatnonzero(contact_wall_all >= 0)
    has_seam_nodes = seams is not None and (contact_wall_all >= SEAM_CODE).any()
    ring_seg, ring_mark = _box_segments(nodes, kind, box, wall_nodes, contact, seams[0] if has_seam_nodes else None)
    contact_wall = contact_wall_all.copy()
    # with seam nodes: hole points inside the parts of the bodies in the box
    holes = _hole_points(contact.solids, box, nodes) if has_seam_nodes else contact.holes
    t, neighbors, boundary_segments, boundary_markers, used = _run_triangle(
        nodes, np.vstack([ring_seg, outline_segments]),
        np.concatenate([ring_mark, _outline_markers(nodes, outline_segments, body_of, polys)]), holes)
    if used is not None:
        nodes, kind, body_of, outline_row, uid = nodes[used], kind[used], body_of[used], outline_row[used], uid[used]
        contact_used = used[first_contact: first_contact + n_contact]
        contact_local, contact_wall = contact_local[contact_used], contact_wall[contact_used]
        seam_outer_body, seam_outer_local = seam_outer_body[contact_used], seam_outer_local[contact_used]
    _make_counter_clockwise(nodes, t, neighbors)
    junction_nodes = np.zeros(0, dtype=np.int64)
    junction_verts = np.zeros((0, 3), dtype=np.int64)
    junction_bary = np.zeros((0, 3))
    if junctions and len(polys) >= 3:
        # Voronoi junction points (Sec. 3.2): split junction triangles at a new node
        owner = np.where((kind == OUTLINE) | (kind == CONTACT), body_of, -1)
        junction_tris, junction_pts = junction_points(nodes, t, owner, poses[:, :2], polys, target,
                                                      clearance=junction_clearance, tree=tree)
        if len(junction_pts):
            junction_nodes, junction_verts, junction_bary, t, neighbors = _split_at_junctions(
                nodes, t, neighbors, junction_tris, junction_pts)
            k = len(junction_pts)
            nodes = np.vstack([nodes, junction_pts])
            kind = np.concatenate([kind, np.full(k, JUNCTION, np.int8)])
            body_of = np.concatenate([body_of, np.full(k, -1)])
            outline_row = np.concatenate([outline_row, np.full(k, -1)])
            uid = np.concatenate([uid, uids.take(k)])
    edges, edge_tris = edges_from_neighbors(t, neighbors)
    return Triangulation(
        points=nodes, kind=kind, body_of=body_of.astype(np.int64), outline_row=outline_row.astype(np.int64),
        uid=uid.astype(np.int64), triangles=t,
        topo=MeshTopology(t, edges, edge_tris, edge_tris[:, 0] != edge_tris[:, 1]),
        boundary_segments=boundary_segments, boundary_markers=boundary_markers, contact_local=contact_local,
        junction_nodes=junction_nodes, junction_verts=junction_verts, junction_bary=junction_bary,
        contact_wall=contact_wall, seam_outer_body=seam_outer_body, seam_outer_local=seam_outer_local)


def _split_at_junctions(nodes, t, neighbors, junction_tris, junction_pts):
    """Split the triangles ``junction_tris`` of ``t`` at the junction points ``junction_pts (k, 2)``, new
    nodes after ``nodes``: ``(junction_nodes (k,), junction_verts (k, 3), junction_bary (k, 3), t,
    neighbors)``.  Junction nodes follow their junction: fixed barycentric coordinates in the
    triangle of outline nodes they split."""
    jv = t[junction_tris]
    P = nodes[jv]
    junction_bary = barycentric(junction_pts, P[:, 0], P[:, 1], P[:, 2])
    junction_nodes = len(nodes) + np.arange(len(junction_pts))
    t, neighbors = split_with_neighbors(t, neighbors, junction_tris, junction_nodes)
    return junction_nodes, jv, junction_bary, t, neighbors


def _box_nodes_kept(points, kind, uid, contact: ContactOutline, box, uids: UidSource):
    """The candidate nodes ``(points, kind, uid)`` with the box corners back (a corner dropped under
    a body in contact with two walls comes back once the body left), less the box nodes under a
    body in contact with a wall or next to its wall nodes (no boundary)."""
    xmin, xmax, ymin, ymax = box
    corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    have = (np.abs(points[kind == CORNER][:, None, :] - corners[None]).max(axis=2) == 0).any(axis=0)
    if not have.all():
        k = int((~have).sum())
        points = np.vstack([points, corners[~have]])
        kind = np.concatenate([kind, np.full(k, CORNER, np.int8)])
        uid = np.concatenate([uid, uids.take(k)])
    if contact.wall_solids:
        is_box = (kind == SIDE) | (kind == CORNER)
        drop = np.zeros(len(points), dtype=bool)
        drop[is_box] = covered_box_nodes(points[is_box], contact, 1e-9 * max(xmax - xmin, ymax - ymin),
                                         corner=kind[is_box] == CORNER)
        points, kind, uid = points[~drop], kind[~drop], uid[~drop]
    return points, kind, uid


@dataclass
class _OutlineNodes:
    """The outline PSLG: the kept outline nodes, then the contact (and seam) nodes, numbered from 0.

    ``segments (s, 2)`` over ``nodes (m, 2)``; per node its ``body``, body-frame ``local``
    position, outline ``row`` (-1: none), ``uid``, ``wall`` side (-2 outline nodes, else the
    contact node's ``contact_wall``), and for seam nodes ``outer_body``/``outer_local``, the outer
    end of their segment; ``n_outline``: the outline nodes first.
    """

    nodes: np.ndarray
    segments: np.ndarray
    body: np.ndarray
    local: np.ndarray
    row: np.ndarray
    uid: np.ndarray
    wall: np.ndarray
    outer_body: np.ndarray
    outer_local: np.ndarray
    n_outline: int

    def take(self, keep) -> None:
        """Keep the nodes ``keep (m,)`` (bool) of the per-node arrays (``segments`` untouched)."""
        self.nodes, self.body, self.local, self.row, self.uid = (self.nodes[keep], self.body[keep],
                                                                 self.local[keep], self.row[keep], self.uid[keep])
        self.wall, self.outer_body, self.outer_local = self.wall[keep], self.outer_body[keep], self.outer_local[keep]


def _outline_nodes(outline_world, outlines: BodyOutlines, contact: ContactOutline, poses,
                   uids: UidSource) -> _OutlineNodes:
    """The outline PSLG of ``contact``: its kept outline rows and contact nodes (uids drawn for these)."""
    n_outline = len(outline_world)
    contact_points, contact_body = contact.contact_points, contact.contact_body
    keep_outline = contact.keep_outline
    outline_rows = np.flatnonzero(keep_outline)
    oc_nodes = np.vstack([outline_world[keep_outline], contact_points])
    node_of_row = np.full(n_outline + len(contact_points), -1, dtype=np.int64)
    node_of_row[outline_rows] = np.arange(len(outline_rows))
    node_of_row[n_outline:] = len(outline_rows) + np.arange(len(contact_points))
    oc_segments = node_of_row[contact.segments]
    if (oc_segments < 0).any():
        raise MeshError("outline segment refers to a removed outline node")
    contact_local = to_body(contact_points, poses[contact_body]) if len(contact_points) else np.zeros((0, 2))
    return _OutlineNodes(
        nodes=oc_nodes, segments=oc_segments,
        body=np.concatenate([outlines.body[outline_rows], contact_body]).astype(np.int64),
        local=np.vstack([outlines.local[outline_rows], contact_local]),
        row=np.concatenate([outline_rows, np.full(len(contact_points), -1)]),
        uid=np.concatenate([outlines.row_uid(outline_rows), uids.take(len(contact_points))]),
        wall=np.concatenate([np.full(len(outline_rows), -2), contact.contact_wall]).astype(np.int64),
        outer_body=np.full(len(oc_nodes), -1, dtype=np.int64), outer_local=np.zeros((len(oc_nodes), 2)),
        n_outline=len(outline_rows))


def _clip_at_seams(oc: _OutlineNodes, points, kind, uid, contact: ContactOutline, box, uids: UidSource, seams):
    """Bodies across periodic sides: the outline PSLG ``oc`` clipped at the box in place, seam nodes
    where it leaves it (partners across a side pair at one place; a seam node without one gets a
    box node there).  Returns the candidate nodes ``(points, kind, uid)`` without the box nodes on
    periodic sides under a body or next to a seam node (on both sides of the pair), with those
    box nodes added."""
    axes, merge = seams
    clip = clip_at_seams(oc.nodes, oc.segments, box, axes)
    if not (len(clip.seam_points) or not clip.keep.all()):
        return points, kind, uid
    k = len(clip.seam_points)
    keep = np.concatenate([clip.keep, np.ones(k, dtype=bool)])
    seam_points, lonely = pair_seam_nodes(clip.seam_points, clip.seam_side, box, 1e-3 * merge)
    oc.nodes = np.vstack([oc.nodes, seam_points])
    oc.body = np.concatenate([oc.body, oc.body[clip.seam_inner]])
    oc.local = np.vstack([oc.local, oc.local[clip.seam_inner]])
    oc.row = np.concatenate([oc.row, np.full(k, -1)])
    oc.uid = np.concatenate([oc.uid, uids.take(k)])
    oc.wall = np.concatenate([oc.wall, SEAM_CODE + clip.seam_side])
    oc.outer_body = np.concatenate([oc.outer_body, oc.body[clip.seam_outer]])
    oc.outer_local = np.vstack([oc.outer_local, oc.local[clip.seam_outer]])
    remap = np.cumsum(keep) - 1
    oc.segments = remap[clip.segments]
    oc.take(keep)
    oc.n_outline = int((oc.row >= 0).sum())
    ends = np.vstack([seam_points, partner_places(seam_points, clip.seam_side, box)])
    on_periodic = on_periodic_sides(points, box, axes) & ((kind == SIDE) | (kind == CORNER))
    if on_periodic.any():
        drop = np.zeros(len(points), dtype=bool)
        # a corner goes only under a body: dropped for a seam node near it, the chord between the two
        # seam nodes around it would cut a sliver of fluid off and leave the sides unmatched
        near = np.where(kind[on_periodic] == CORNER, 0.0, merge)
        drop[on_periodic] = covered_side_nodes(points[on_periodic], contact.solids, ends, near, box)
        points, kind, uid = points[~drop], kind[~drop], uid[~drop]
    if len(lonely):
        points = np.vstack([points, lonely])
        kind = np.concatenate([kind, np.full(len(lonely), SIDE, dtype=kind.dtype)])
        uid = np.concatenate([uid, uids.take(len(lonely))])
    return points, kind, uid


def _box_segments(nodes, kind, box, wall_nodes, contact: ContactOutline, seam_axes):
    """The box ring's segments and markers (:func:`fluidem.mesh.nodes.box_ring`, split at the wall
    nodes ``wall_nodes``) less those that are no fluid boundary: on a periodic side of
    ``seam_axes`` wholly on a body (``None``: no seam nodes), under a body in contact with a wall."""
    ring_seg, ring_mark = box_ring(nodes, kind, box, extra=wall_nodes)
    xmin, xmax, ymin, ymax = box
    tol = 1e-9 * max(xmax - xmin, ymax - ymin)
    if seam_axes is not None:
        # the seam under a body is no boundary: ring segments lying wholly on a body
        mid = 0.5 * (nodes[ring_seg[:, 0]] + nodes[ring_seg[:, 1]])
        under = np.zeros(len(ring_seg), dtype=bool)
        on_periodic = np.flatnonzero(on_periodic_sides(mid, box, seam_axes))
        if len(on_periodic) and len(contact.solids):
            u = shapely.buffer(shapely.union_all(np.asarray(contact.solids, dtype=object)), tol)
            lines = shapely.linestrings(np.stack([nodes[ring_seg[on_periodic, 0]], nodes[ring_seg[on_periodic, 1]]],
                                                 axis=1))
            under[on_periodic] = shapely.covers(u, lines)
        ring_seg, ring_mark = ring_seg[~under], ring_mark[~under]
    if len(wall_nodes):
        # the box segments under a body in contact are no fluid boundary
        mid_pts = shapely.points(0.5 * (nodes[ring_seg[:, 0]] + nodes[ring_seg[:, 1]]))
        covered = np.zeros(len(ring_seg), dtype=bool)
        for solid in contact.wall_solids:
            covered |= shapely.distance(solid, mid_pts) < tol
        ring_seg, ring_mark = ring_seg[~covered], ring_mark[~covered]
    return ring_seg, ring_mark


def _outline_markers(nodes, outline_segments, body_of, polys) -> np.ndarray:
    """Boundary markers ``(s,)`` of the outline segments: ``FIRST_BODY_MARKER`` + the body of their
    ends, or of the body nearest their midpoint where the ends' bodies differ (a contact)."""
    if not len(outline_segments):
        return np.zeros(0, dtype=np.int64)
    mid = 0.5 * (nodes[outline_segments[:, 0]] + nodes[outline_segments[:, 1]])
    owner = body_of[outline_segments[:, 0]]
    same = owner == body_of[outline_segments[:, 1]]
    if not same.all():
        dd = shapely.distance(polys[None, :], shapely.points(mid[~same])[:, None])
        owner = owner.copy()
        owner[~same] = np.argmin(dd, axis=1)
    return FIRST_BODY_MARKER + owner


def _run_triangle(nodes, segments, markers, holes):
    """Triangle's constrained Delaunay triangulation (switches ``pQn``) of ``nodes (n, 2)``, with the
    ``segments (s, 2)`` and their ``markers (s,)`` and the ``holes (h, 2)``: triangles, neighbours,
    boundary segments and markers in the numbering of the nodes it used, and the mask of the
    nodes used (``None``: all; unused: duplicates or points in holes, none expected)."""
    pslg = {"vertices": nodes, "segments": segments.astype(np.int32),
            "segment_markers": markers.astype(np.int32)[:, None]}
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
    used = np.zeros(len(nodes), dtype=bool)
    used[t.ravel()] = True
    if used.all():
        return t, neighbors, boundary_segments, boundary_markers, None
    remap = np.cumsum(used) - 1
    return remap[t], neighbors, remap[boundary_segments], boundary_markers, used


def _make_counter_clockwise(nodes, t, neighbors) -> None:
    """Triangle returns counter-clockwise triangles; make sure, in place (swap vertices 1, 2 of
    ``t`` and the ``neighbors`` opposite them together)."""
    cw = signed_areas(nodes, t) < 0
    if cw.any():
        t[cw] = t[cw][:, [0, 2, 1]]
        neighbors[cw] = neighbors[cw][:, [0, 2, 1]]
