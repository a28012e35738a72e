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
from .adjacency import edges_from_neighbors, split_with_neighbors
from .contact_outline import ContactOutline
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
    UID_OUTLINE,
    BodyOutlines,
    UidSource,
    box_ring,
    to_body,
)
from .relax import MeshTopology, signed_areas

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


def triangulate(points, kind, uid, outline_world, outlines: BodyOutlines, contact: ContactOutline, poses, polys,
                tree, box, uids: UidSource, junctions: bool, junction_clearance: float, target) -> Triangulation:
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

    Raises
    ------
    MeshError
        The outlines intersect (bodies overlap by more than the contact policy handles).
    """
    n_bodies = len(polys)
    olw = outline_world
    n_ol = len(olw)
    extra_pts, extra_body = contact.contact_points, contact.contact_body
    ol_keep = contact.keep_outline
    # assemble nodes: [candidates | outline | contact nodes | junctions]
    ol_idx = np.flatnonzero(ol_keep)
    allpts = np.vstack([points, olw[ol_keep], extra_pts])
    n_c = len(points)
    # map of outline table index -> node index
    ol_map = np.full(n_ol + len(extra_pts), -1, dtype=np.int64)
    ol_map[ol_idx] = n_c + np.arange(len(ol_idx))
    ol_map[n_ol:] = n_c + len(ol_idx) + np.arange(len(extra_pts))
    segs_b = ol_map[contact.segments]
    if (segs_b < 0).any():
        raise MeshError("outline segment refers to a removed outline node")
    kind = np.concatenate([kind, np.full(len(ol_idx), OUTLINE, np.int8), np.full(len(extra_pts), CONTACT, np.int8)])
    body_of = np.concatenate([np.full(n_c, -1), outlines.body[ol_idx], extra_body])
    ol_id = np.concatenate([np.full(n_c, -1), ol_idx, np.full(len(extra_pts), -1)])
    uid = np.concatenate([uid, UID_OUTLINE + ol_idx, uids.take(len(extra_pts))])
    # contact nodes: body coordinates for rigid motion
    ex_local = to_body(extra_pts, poses[extra_body]) if len(extra_pts) else np.zeros((0, 2))
    ring_seg, ring_mark = box_ring(allpts, kind, box)
    mid = 0.5 * (allpts[segs_b[:, 0]] + allpts[segs_b[:, 1]])
    if len(segs_b):
        owner = body_of[segs_b[:, 0]]
        same = owner == body_of[segs_b[:, 1]]
        if not same.all():
            dd = shapely.distance(polys[None, :], shapely.points(mid[~same])[:, None])
            owner = owner.copy()
            owner[~same] = np.argmin(dd, axis=1)
        bmark = FIRST_BODY_MARKER + owner
    else:
        bmark = np.zeros(0, dtype=np.int64)
    pslg = {
        "vertices": allpts,
        "segments": np.vstack([ring_seg, segs_b]).astype(np.int32),
        "segment_markers": np.concatenate([ring_mark, bmark]).astype(np.int32)[:, None],
    }
    if len(contact.holes):
        pslg["holes"] = contact.holes
    out = tr.triangulate(pslg, "pQn")
    t = out["triangles"].astype(np.int64)
    nbr = out["neighbors"].astype(np.int64)
    if len(out["vertices"]) != len(allpts):
        raise MeshError(
            f"Triangle added {len(out['vertices']) - len(allpts)} points: outlines intersect "
            "(bodies overlap by more than the contact policy handles)"
        )
    segs_out = out["segments"].astype(np.int64)
    marks_out = out["segment_markers"].ravel().astype(np.int64)
    # drop unused nodes (none expected; duplicates or points in holes)
    used = np.zeros(len(allpts), dtype=bool)
    used[t.ravel()] = True
    if not used.all():
        remap = np.cumsum(used) - 1
        t = remap[t]
        segs_out = remap[segs_out]
        allpts, kind, body_of, ol_id, uid = allpts[used], kind[used], body_of[used], ol_id[used], uid[used]
        ex_local = ex_local[used[n_c + len(ol_idx): n_c + len(ol_idx) + len(extra_pts)]]
    # Triangle returns counter-clockwise triangles; make sure (swap vertices 1, 2 and
    # the neighbours opposite them together)
    cw = signed_areas(allpts, t) < 0
    if cw.any():
        t[cw] = t[cw][:, [0, 2, 1]]
        nbr[cw] = nbr[cw][:, [0, 2, 1]]
    j_nodes = np.zeros(0, dtype=np.int64)
    j_verts = np.zeros((0, 3), dtype=np.int64)
    j_bary = np.zeros((0, 3))
    if junctions and n_bodies >= 3:
        # Voronoi junction points (Sec. 3.2): split junction triangles at a new node
        owner = np.where((kind == OUTLINE) | (kind == CONTACT), body_of, -1)
        jt, jp = junction_points(allpts, t, owner, poses[:, :2], polys, target, clearance=junction_clearance,
                                 tree=tree)
        if len(jp):
            n0 = len(allpts)
            # junction nodes follow their junction: fixed barycentric coordinates in
            # the triangle of outline nodes they split
            jv = t[jt]
            P = allpts[jv]
            e1, e2, r = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0], jp - P[:, 0]
            det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
            l1 = (r[:, 0] * e2[:, 1] - r[:, 1] * e2[:, 0]) / det
            l2 = (e1[:, 0] * r[:, 1] - e1[:, 1] * r[:, 0]) / det
            j_bary = np.column_stack([1 - l1 - l2, l1, l2])
            j_verts = jv
            j_nodes = n0 + np.arange(len(jp))
            t, nbr = split_with_neighbors(t, nbr, jt, j_nodes)
            allpts = np.vstack([allpts, jp])
            kind = np.concatenate([kind, np.full(len(jp), JUNCTION, np.int8)])
            body_of = np.concatenate([body_of, np.full(len(jp), -1)])
            ol_id = np.concatenate([ol_id, np.full(len(jp), -1)])
            uid = np.concatenate([uid, uids.take(len(jp))])
    edges, edge_tris = edges_from_neighbors(t, nbr)
    return Triangulation(
        points=allpts, kind=kind, body_of=body_of.astype(np.int64), outline_row=ol_id.astype(np.int64),
        uid=uid.astype(np.int64), triangles=t,
        topo=MeshTopology(t, edges, edge_tris, edge_tris[:, 0] != edge_tris[:, 1]),
        boundary_segments=segs_out, boundary_markers=marks_out, contact_local=ex_local,
        junction_nodes=j_nodes, junction_verts=j_verts, junction_bary=j_bary)
