"""Adaptation and clean-up of the moving mesh at re-triangulation (paper Sec. 4.2, Fig. 6).

* :func:`adapt`: an independent set of free nodes is removed where the incident edges are
  on average shorter than ``coarsen_ratio`` of their target (and of box-side nodes closer
  than ``SIDE_MERGE`` of their target to a neighbour along their side), and a node is added at the
  centroid of triangles larger than ``refine_area`` target areas (``√3/4 h²``): vacated
  regions coarsen again, regions a body moved into refine.  A large triangle with an edge
  on a box side gets a side node at that edge's midpoint instead (a centroid a third of
  the way off the wall makes an element of about 140° there).  With a node budget
  (``hold_node_count``) the count is held: a stretched region is split once per pair of
  large neighbours, and the most compressed free nodes go while the count is above it.
* :func:`cleanup_candidates`: after a triangulation, free vertices of elements still
  outside the angle bounds (outside narrow gaps) are removed and a node is added in such
  elements without free vertices; the caller triangulates the new candidates once more.

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.adaptation import Adapted
>>> Adapted(np.zeros((0, 2)), np.zeros(0, np.int8), np.zeros(0, np.int64), np.zeros(0), 0, 0).n_inserted
0
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from .gaps import gap_width
from .nodes import CORNER, FREE, SIDE, UidSource, classify_box
from .relax import MeshTopology, signed_areas
from .triggers import ElementShape, element_shape

__all__ = ["Adapted", "Cleanup", "adapt", "cleanup_candidates", "SIDE_MERGE"]

#: box-side nodes closer than ``SIDE_MERGE`` times their target along their side are coarsened
SIDE_MERGE = 0.5


@dataclass(frozen=True)
class Adapted:
    """Candidate nodes after the adaptation.

    Attributes
    ----------
    points : (n, 2) float
    kind : (n,) int8
    uid : (n,) int
    h : (n,) float
        Target size at the new candidates.
    n_removed, n_inserted : int
        Nodes removed by coarsening and inserted by refinement.
    """

    points: np.ndarray
    kind: np.ndarray
    uid: np.ndarray
    h: np.ndarray
    n_removed: int
    n_inserted: int


@dataclass(frozen=True)
class Cleanup:
    """Result of :func:`cleanup_candidates`.

    Attributes
    ----------
    candidates : (points (n, 2), kind (n,), uid (n,)) or None
        The nodes to triangulate again, ``None`` when nothing needs fixing.
    shape : ElementShape
        Angle cosines and areas of the mesh that was checked.
    """

    candidates: tuple | None
    shape: ElementShape


def adapt(points, kind, uid, mesh_points, topo: MeshTopology, mesh_h, mesh_kind, candidate_row, solid_tree, target,
          uids: UidSource, seed: int, refine_area: float, coarsen_ratio: float, clearance: float,
          box=None, budget: float | None = None,
          budget_tolerance: float = 0.02) -> Adapted:
    """Coarsen where edges are much shorter than the target, refine where triangles are too big.

    Parameters
    ----------
    points, kind, uid : (n,) arrays
        The candidate nodes (the current nodes kept by the cut-out).
    mesh_points : (n_nodes, 2) float
        The current mesh: node positions, with ``topo`` its topology, ``mesh_h`` its
        per-node targets and ``mesh_kind`` its node kinds.
    candidate_row : (n_nodes,) int
        Row in ``points`` of every current node, -1 where the cut-out dropped it.
    solid_tree : shapely.STRtree or None
        The bodies and closed contact outlines; new nodes closer than ``clearance · h`` to
        them are not inserted.
    target : callable
        Target size ``points (k, 2) -> (k,)``.
    uids : UidSource
    seed : int
        Seed of the random priorities of the independent set (the step count: reproducible).
    refine_area, coarsen_ratio, clearance : float
        :class:`fluidem.mesh.params.MeshParams` fields.
    budget : float or None
        Free and box nodes to aim at (``hold_node_count``): above ``budget · (1 +
        budget_tolerance)`` the most compressed free nodes are removed as well, below
        ``budget · (1 − budget_tolerance)`` the largest elements are split; with a budget, of
        two large elements across an edge only the larger is split.  ``None``: no aim.
    budget_tolerance : float
    box : (xmin, xmax, ymin, ymax) or None
        The box: large triangles on its sides are split at the side (module docstring);
        ``None``: at the centroid.
    """
    # coarsening: an independent set of free nodes whose incident edges are all short
    t = topo.triangles
    e0, e1 = topo.e0, topo.e1
    old = mesh_points
    z = old[:, 0] + 1j * old[:, 1]
    L = np.abs(z[e1] - z[e0])
    L0 = 0.5 * (mesh_h[e0] + mesh_h[e1])
    n_old = len(old)
    # mean ratio of incident edge lengths to their targets
    ratio = L / L0
    deg = np.bincount(e0, minlength=n_old) + np.bincount(e1, minlength=n_old)
    mean_ratio = (np.bincount(e0, ratio, n_old) + np.bincount(e1, ratio, n_old)) / np.maximum(deg, 1)
    has_long = mean_ratio >= coarsen_ratio
    area = signed_areas(old, t)
    ht = (mesh_h[topo.t0] + mesh_h[topo.t1] + mesh_h[topo.t2]) / 3.0
    area_ratio = area / ((np.sqrt(3) / 4) * ht**2)
    n_tri = np.bincount(t.ravel(), minlength=n_old)
    mean_area = np.bincount(t.ravel(), np.repeat(area_ratio, 3), n_old) / np.maximum(n_tri, 1)
    row = candidate_row
    present = row >= 0
    cand = present & (mesh_kind == FREE) & ~has_long
    if box is not None:
        # box-side nodes closer than half their target along their side go too (a body moving
        # along a wall drags the side nodes ahead of it together: without this they pile up)
        on_box = (mesh_kind == SIDE) | (mesh_kind == CORNER)
        along = on_box[e0] & on_box[e1] & (L < SIDE_MERGE * L0)
        if along.any():
            along[along] = classify_box(0.5 * (old[e0[along]] + old[e1[along]]), box)[0] == SIDE
            short_side = np.zeros(n_old, dtype=bool)
            short_side[e0[along]] = True
            short_side[e1[along]] = True
            cand |= present & (mesh_kind == SIDE) & short_side
    rng = np.random.default_rng(seed)
    prio = np.where(cand, rng.random(n_old), -1.0)
    nb_max = np.full(n_old, -1.0)
    np.maximum.at(nb_max, e0, prio[e1])
    np.maximum.at(nb_max, e1, prio[e0])
    remove_old = cand & (prio > nb_max)
    keep = np.ones(len(points), dtype=bool)
    keep[row[remove_old]] = False
    # refinement: centroids of triangles much larger than the target
    big = area_ratio > refine_area
    if budget is not None:
        # one new node per pair of neighbouring large elements: of two large elements across an
        # edge only the larger is split (after the Delaunay triangulation and relaxation the new
        # node serves both; splitting every one of a stretched region overshoots its density)
        ea, eb = topo.edge_tris[:, 0], topo.edge_tris[:, 1]
        both = big[ea] & big[eb] & (ea != eb)
        lose = np.where(area_ratio[ea] < area_ratio[eb], ea, eb)[both]
        big[lose] = False
    newp, newk = _split_points(t[big], old, mesh_kind, box, solid_tree, target, clearance)
    if budget is not None:
        # hold the node count: the most compressed free nodes go (an independent set, not next
        # to a removed node or a refined element, only where removing them cannot make an
        # element above refine_area) while the count is above the budget, the largest elements
        # are split while it is below
        n_proj = int(keep.sum()) + len(newp)
        hi, lo = budget * (1.0 + budget_tolerance), budget * (1.0 - budget_tolerance)
        if n_proj > hi:
            blocked = remove_old.copy()
            blocked[t[big].ravel()] = True
            nb_removed = np.zeros(n_old, dtype=bool)
            nb_removed[e0[remove_old[e1]]] = True
            nb_removed[e1[remove_old[e0]]] = True
            extra = present & (mesh_kind == FREE) & ~blocked & ~nb_removed & (mean_area * 1.5 < refine_area)
            prio2 = np.where(extra, -mean_area, -np.inf)
            nb2 = np.full(n_old, -np.inf)
            np.maximum.at(nb2, e0, prio2[e1])
            np.maximum.at(nb2, e1, prio2[e0])
            sel = np.flatnonzero(extra & (prio2 > nb2))
            sel = sel[np.argsort(mean_area[sel], kind="stable")[: int(np.ceil(n_proj - hi))]]
            keep[row[sel]] = False
        elif n_proj < lo:
            order = np.argsort(-area_ratio, kind="stable")
            order = order[~big[order] & (area_ratio[order] > 1.0)][: int(np.ceil(lo - n_proj))]
            p2, k2 = _split_points(t[order], old, mesh_kind, box, solid_tree, target, clearance)
            newp, newk = np.vstack([newp, p2]), np.concatenate([newk, k2])
    n_ins = len(newp)
    pts = np.vstack([points[keep], newp])
    kind = np.concatenate([kind[keep], newk])
    uid = np.concatenate([uid[keep], uids.take(n_ins)])
    return Adapted(points=pts, kind=kind, uid=uid, h=target(pts), n_removed=int((~keep).sum()), n_inserted=n_ins)


def _split_points(tb, old, mesh_kind, box, solid_tree, target, clearance):
    """New nodes ``(k, 2)`` and kinds splitting triangles ``tb (m, 3)``: centroids, or the
    midpoint of an edge on a box side; those closer than ``clearance · h`` to a solid dropped."""
    newp = old[tb].mean(axis=1) if len(tb) else np.zeros((0, 2))
    newk = np.full(len(newp), FREE, np.int8)
    if box is not None and len(tb):
        # an edge on a box side: both ends on the box and its midpoint on a side
        on_box = (mesh_kind[tb] == SIDE) | (mesh_kind[tb] == CORNER)
        for a, b in ((0, 1), (1, 2), (2, 0)):
            sel = np.flatnonzero(on_box[:, a] & on_box[:, b] & (newk == FREE))
            if len(sel):
                mid = 0.5 * (old[tb[sel, a]] + old[tb[sel, b]])
                on_side = classify_box(mid, box)[0] == SIDE
                newp[sel[on_side]] = mid[on_side]
                newk[sel[on_side]] = SIDE
    if solid_tree is not None and len(newp):
        hn = target(newp)
        ii, _ = solid_tree.query(shapely.points(newp), predicate="dwithin", distance=clearance * hn)
        ok = np.ones(len(newp), dtype=bool)
        ok[ii] = False
        newp, newk = newp[ok], newk[ok]
    return newp, newk


def cleanup_candidates(points, topo: MeshTopology, kind, uid, h_node, table, body_tree, box, target, uids: UidSource,
                       min_angle: float, max_angle: float, clearance: float) -> Cleanup:
    """New candidate nodes after removing free vertices of bad elements / adding nodes in them.

    Bad: an angle below ``min_angle`` or above ``max_angle`` (degrees) outside narrow gaps.
    ``table``, ``body_tree``: the bodies' PolygonTable and STR tree (``None`` without
    bodies); a node added in a bad element without free vertices must keep
    ``clearance · h`` from the bodies.
    """
    shape = element_shape(points, topo)
    bad = np.flatnonzero((shape.cos_max > np.cos(np.radians(min_angle)))
                         | (shape.cos_min < np.cos(np.radians(max_angle))))
    if not len(bad):
        return Cleanup(None, shape)
    triangles = topo.triangles
    t = triangles[bad]
    c = points[t].mean(axis=1)
    hh = 0.5 * h_node[t].mean(axis=1)  # narrow gap: narrower than h/2
    bad = bad[~(gap_width(c, hh, table, box) < hh)]
    if not len(bad):
        return Cleanup(None, shape)
    t = triangles[bad]
    free_v = kind[t] == FREE
    remove = np.zeros(len(points), dtype=bool)
    remove[t[free_v]] = True
    no_free = ~free_v.any(axis=1)
    newp = np.zeros((0, 2))
    if no_free.any():
        P = points[t[no_free]]
        cen = P.mean(axis=1)
        hq = target(cen)
        if body_tree is not None:
            ix, dist = body_tree.query_nearest(shapely.points(cen), return_distance=True, all_matches=False)
            dn = np.zeros(len(cen))
            dn[ix[0]] = dist
        else:
            dn = np.full(len(cen), np.inf)
        newp = cen[dn >= clearance * hq]
    keep = ((kind == FREE) | (kind == SIDE) | (kind == CORNER)) & ~remove
    cpts = np.vstack([points[keep], newp])
    ckind = np.concatenate([kind[keep], np.full(len(newp), FREE, np.int8)])
    cuid = np.concatenate([uid[keep], uids.take(len(newp))])
    if not remove.any() and not len(newp):
        return Cleanup(None, shape)
    return Cleanup((cpts, ckind, cuid), shape)
