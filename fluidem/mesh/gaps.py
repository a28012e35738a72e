"""Narrow gaps of the moving mesh: gap widths and the classification of narrow-gap elements.

A gap narrower than the target size cannot hold elements within the angle bounds: it is
spanned by one layer of elements between the outline nodes on its two sides, and those
elements are reported apart (:mod:`fluidem.mesh.quality`).  An element counts as
*narrow-gap* when

* the gap at its centroid (distance to the nearest plus the second-nearest distinct
  boundary; the box counts as one boundary) is narrower than ``NARROW_GAP · h`` with ``h``
  the mean target size of its vertices (:func:`narrow_gap`), or
* one of its edges joins two different boundaries with one end closer than
  ``NARROW_GAP · h`` to the other end's boundary: it is anchored across the gap
  (:func:`anchored_across_gap`).

The re-triangulation trigger uses the cheaper :func:`narrow_gap_owners` (the gap measured
between the boundaries the element's own vertices lie on) and :func:`structural_narrow`
(all three vertices on boundaries, not all of one owner).

*Boundary owner* of a node: its body for outline and contact nodes, ``BOX`` (-2) for box
side and corner nodes, ``NOT_ON_BOUNDARY`` (-3) for free and junction nodes.

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.gaps import gap_width
>>> from fluidem.mesh.proximity import PolygonTable
>>> square = np.array([[0.4, 0.3], [0.6, 0.3], [0.6, 0.5], [0.4, 0.5]])   # one body
>>> pts = np.array([[0.5, 0.1], [0.9, 0.9]])
>>> np.round(gap_width(pts, 0.25, PolygonTable(square, [4]), (0.0, 1.0, 0.0, 1.0)), 12)
array([0.3, inf])

Between the body and the bottom wall the gap is 0.2 + 0.1; at the second point the body is
out of reach and the box alone is one boundary.
"""

from __future__ import annotations

import numpy as np

from .nodes import FREE, JUNCTION

__all__ = ["NARROW_GAP", "BOX", "NOT_ON_BOUNDARY", "boundary_owner", "box_distance", "owner_distance",
           "gap_from_pairs", "gap_width", "non_free_count", "anchored_across_gap", "narrow_gap",
           "narrow_gap_owners", "structural_narrow"]

#: a gap narrower than ``NARROW_GAP · h`` is narrow (the definition of :mod:`fluidem.mesh.quality`)
NARROW_GAP = 0.5
#: boundary owner of box nodes
BOX = -2
#: boundary owner of free and junction nodes
NOT_ON_BOUNDARY = -3


def boundary_owner(kind, body_of) -> np.ndarray:
    """Boundary owner ``(n,)`` of every node (module docstring)."""
    return np.where((kind == FREE) | (kind == JUNCTION), NOT_ON_BOUNDARY, np.where(body_of >= 0, body_of, BOX))


def box_distance(points, box) -> np.ndarray:
    """Distance ``(k,)`` of ``points (k, 2)`` inside ``box`` to its nearest side."""
    xmin, xmax, ymin, ymax = box
    return np.min(np.column_stack([points[:, 1] - ymin, xmax - points[:, 0], ymax - points[:, 1],
                                   points[:, 0] - xmin]), axis=1)


def owner_distance(points, owner, table, box) -> np.ndarray:
    """Distance ``(k,)`` from ``points (k, 2)`` to boundary ``owner (k,)`` (a body index of the
    :class:`~fluidem.mesh.proximity.PolygonTable` ``table``, or ``BOX``)."""
    d = np.empty(len(points))
    on = owner >= 0
    if on.any():
        d[on] = table.distance(points[on], owner[on])
    if (~on).any():
        d[~on] = box_distance(points[~on], box)
    return d


def gap_from_pairs(points, point_index, distance, box) -> np.ndarray:
    """Gap width ``(k,)`` at ``points (k, 2)`` from the (point, body) pairs of
    :meth:`PolygonTable.pairs_within <fluidem.mesh.proximity.PolygonTable.pairs_within>`:
    ``point_index`` sorted, ``distance`` their distances; ``inf`` with fewer than two boundaries."""
    pi, d = point_index, distance
    k = len(points)
    m1, m2 = np.full(k, np.inf), np.full(k, np.inf)
    if len(pi):
        # per point the smallest and second smallest body distance
        starts = np.flatnonzero(np.concatenate([[True], pi[1:] != pi[:-1]]))
        g = pi[starts]
        lo = np.minimum.reduceat(d, starts)
        is_min = d == np.repeat(lo, np.diff(np.append(starts, len(d))))
        second = np.minimum.reduceat(np.where(is_min, np.inf, d), starts)
        m1[g] = lo
        m2[g] = np.where(np.add.reduceat(is_min, starts) >= 2, lo, second)
    # ... and the box as one more boundary: the two smallest of {m1 ≤ m2, box}
    dbox = box_distance(points, box)
    return np.minimum(m1, dbox) + np.minimum(np.maximum(m1, dbox), m2)


def gap_width(points, radius, table, box) -> np.ndarray:
    """Width ``d1 + d2`` ``(k,)`` of the gap at ``points (k, 2)``: distances to the nearest and
    second-nearest distinct boundary (bodies of ``table``, ``None`` without bodies; the box
    counts as one), ``inf`` if fewer than two lie within ``radius`` (array ``(k,)`` or float)."""
    points = np.asarray(points, dtype=float)
    if not len(points):
        return np.zeros(0)
    pi = np.zeros(0, dtype=np.int64)
    d = np.zeros(0)
    if table is not None:
        pi, _, d = table.pairs_within(points, radius, solid=True)
    return gap_from_pairs(points, pi, d, box)


def non_free_count(kind, topo) -> np.ndarray:
    """Per triangle of ``topo`` (:class:`~fluidem.mesh.relax.MeshTopology`): how many of its
    vertices are not free nodes (0..3)."""
    nf = (kind != FREE).view(np.int8)
    return nf[topo.t0] + nf[topo.t1] + nf[topo.t2]


def anchored_across_gap(tri_idx, triangles, points, owner, h_node, table, box) -> np.ndarray:
    """Mask ``(len(tri_idx),)``: elements with an edge joining two different boundaries one end
    of which lies closer than ``NARROW_GAP · h`` to the other end's boundary (anchored across
    a narrow gap).  ``owner``: :func:`boundary_owner` of every node."""
    t = triangles[tri_idx]
    # the three edges of every element, stacked: (a, b) = (t[:, i], t[:, j])
    a = np.concatenate([t[:, 0], t[:, 1], t[:, 2]])
    b = np.concatenate([t[:, 1], t[:, 2], t[:, 0]])
    oa, ob = owner[a], owner[b]
    span = np.flatnonzero((oa != NOT_ON_BOUNDARY) & (ob != NOT_ON_BOUNDARY) & (oa != ob))
    out = np.zeros(len(tri_idx), dtype=bool)
    if not len(span):
        return out
    a, b, oa, ob = a[span], b[span], oa[span], ob[span]
    lim = 0.25 * (h_node[a] + h_node[b])  # NARROW_GAP times the mean target of the edge
    d = owner_distance(np.vstack([points[a], points[b]]), np.concatenate([ob, oa]), table, box)
    d = np.minimum(d[:len(span)], d[len(span):])
    out[span[d < lim] % len(tri_idx)] = True
    return out


def narrow_gap(points, triangles, topo, kind, body_of, h_node, table, box) -> np.ndarray:
    """Narrow-gap mask ``(n_triangles,)`` by the geometric definition (module docstring).

    ``table``: the bodies' :class:`~fluidem.mesh.proximity.PolygonTable`, ``None`` without bodies.
    """
    t = triangles
    narrow = np.zeros(len(t), dtype=bool)
    # free nodes are purged from gaps narrower than gap_purge · h, so a triangle in a
    # narrow gap has at most one free vertex
    cand = np.flatnonzero(non_free_count(kind, topo) >= 2)
    if not len(cand):
        return narrow
    c = points[t[cand]].mean(axis=1)
    hh = NARROW_GAP * h_node[t[cand]].mean(axis=1)
    narrow[cand] = gap_width(c, hh, table, box) < hh
    # ... or one of its edges joins two different boundaries and one end of it is closer
    # than h/2 to the other end's boundary (the element is anchored across the gap)
    owner = boundary_owner(kind, body_of)
    narrow[cand[anchored_across_gap(cand, t, points, owner, h_node, table, box)]] = True
    return narrow


def narrow_gap_owners(points, triangles, topo, kind, body_of, h_node, table, box) -> np.ndarray:
    """Cheap form of :func:`narrow_gap` for the re-triangulation trigger: the gap at the
    centroid is measured between the boundaries the element's own vertices lie on."""
    narrow = np.zeros(len(triangles), dtype=bool)
    cand = np.flatnonzero(non_free_count(kind, topo) >= 2)
    if not len(cand):
        return narrow
    x, h = points, h_node
    i0, i1, i2 = topo.t0[cand], topo.t1[cand], topo.t2[cand]
    c = (x[i0] + x[i1] + x[i2]) / 3.0
    hh = (h[i0] + h[i1] + h[i2]) / 6.0  # NARROW_GAP times the mean target
    owner = boundary_owner(kind, body_of)
    o = np.column_stack([owner[i0], owner[i1], owner[i2]])
    # the distinct boundaries among the three vertices' owners
    ok = o != NOT_ON_BOUNDARY
    ok[:, 1] &= o[:, 1] != o[:, 0]
    ok[:, 2] &= (o[:, 2] != o[:, 0]) & (o[:, 2] != o[:, 1])
    rows, cols = np.nonzero(ok)
    d = np.full(o.shape, np.inf)
    d[rows, cols] = owner_distance(c[rows], o[rows, cols], table, box)
    d.sort(axis=1)
    narrow[cand] = d[:, 0] + d[:, 1] < hh
    narrow[cand[anchored_across_gap(cand, triangles, points, owner, h_node, table, box)]] = True
    return narrow


def structural_narrow(topo, kind, body_of) -> np.ndarray:
    """Mask ``(n_triangles,)``: triangles whose three vertices are all on boundaries, not all
    of one owner."""
    bnd = kind != FREE
    bnd &= kind != JUNCTION
    owner = np.where(body_of >= 0, body_of, BOX)
    allb = bnd[topo.t0] & bnd[topo.t1] & bnd[topo.t2]
    o0, o1, o2 = owner[topo.t0], owner[topo.t1], owner[topo.t2]
    return allb & ((o0 != o1) | (o1 != o2))
