"""Voronoi junction points between bodies (paper Sec. 3.2, Fig. 4).

Where three bodies enclose a junction of the pore space, a continuous finite element field
on the few triangles spanning the junction cannot split the flow into different
directions; a mesh node in the junction lets it do so.  After the cut-out, a junction
without a node shows up as a *junction triangle*: a triangle whose three vertices lie on the
outlines of three different bodies.  Its new node is the Voronoi vertex of the three body
centres (the circumcentre of the centres, as in the paper) when that lies inside the
triangle (else the incentre or the centroid, whichever splits the triangle into better
shaped pieces).  The node is added only if it keeps at least ``clearance · h`` from every
body and the three triangles of the split have their angles within
``[min_angle, max_angle]`` (a junction too tight for that is left without a node).
"""

from __future__ import annotations

import numpy as np
import shapely

from ..geometry import barycentric

__all__ = ["junction_triangles", "junction_points", "split_triangles"]


def junction_triangles(triangles, owner) -> np.ndarray:
    """Indices of triangles whose three vertices lie on three different bodies.

    Parameters
    ----------
    triangles : (m, 3) int
    owner : (n_nodes,) int
        Body of every outline node, ``-1`` for other nodes.
    """
    o = np.asarray(owner)[np.asarray(triangles)]
    ok = (o >= 0).all(axis=1) & (o[:, 0] != o[:, 1]) & (o[:, 1] != o[:, 2]) & (o[:, 0] != o[:, 2])
    return np.flatnonzero(ok)


def junction_points(points, triangles, owner, centres, polygons, h, clearance: float = 0.3,
                    min_angle: float = 25.0, max_angle: float = 125.0,
                    tree: shapely.STRtree | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Junction nodes for the junction triangles of a mesh.

    Parameters
    ----------
    points : (n_nodes, 2) float
        Node positions, length units.
    triangles : (m, 3) int
    owner : (n_nodes,) int
        Body of every outline node, ``-1`` for other nodes.
    centres : (n_bodies, 2) float
        Body centres of mass, length units.
    polygons : (n_bodies,) array of shapely Polygons
        Body outlines in world coordinates.
    h : float or callable ``points (k, 2) -> (k,)``
        Local target size, length units.
    clearance : float
        Minimum distance of a junction node from every body, in multiples of ``h``.
    min_angle, max_angle : float
        Range of angles (degrees) the three triangles of the split must keep to.
    tree : shapely.STRtree or None
        Tree over ``polygons`` if the caller has one.

    Returns
    -------
    tri : (k,) int
        Junction triangles that get a node.
    new_points : (k, 2) float
        Their junction nodes.
    """
    p = np.asarray(points, dtype=float)
    t = np.asarray(triangles)
    jt = junction_triangles(t, owner)
    if not len(jt):
        return jt, np.zeros((0, 2))
    o = np.asarray(owner)[t[jt]]
    c = np.asarray(centres, dtype=float)
    a, b, d = c[o[:, 0]], c[o[:, 1]], c[o[:, 2]]
    # circumcentre of the three body centres = their Voronoi vertex
    bax, bay = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    dax, day = d[:, 0] - a[:, 0], d[:, 1] - a[:, 1]
    den = 2.0 * (bax * day - bay * dax)
    safe = np.where(np.abs(den) > 1e-300, den, 1.0)
    b2, d2 = bax**2 + bay**2, dax**2 + day**2
    v = np.column_stack([a[:, 0] + (day * b2 - bay * d2) / safe, a[:, 1] + (bax * d2 - dax * b2) / safe])
    # is it inside the junction triangle? (barycentric coordinates)
    P = p[t[jt]]
    l1, l2 = barycentric(v, P[:, 0], P[:, 1], P[:, 2])[:, 1:].T
    inside = (np.abs(den) > 1e-300) & (l1 > 0.05) & (l2 > 0.05) & (l1 + l2 < 0.95)
    # incentre as the fallback
    la = np.linalg.norm(P[:, 2] - P[:, 1], axis=1)
    lb = np.linalg.norm(P[:, 0] - P[:, 2], axis=1)
    lc = np.linalg.norm(P[:, 1] - P[:, 0], axis=1)
    inc = (la[:, None] * P[:, 0] + lb[:, None] * P[:, 1] + lc[:, None] * P[:, 2]) / (la + lb + lc)[:, None]
    cen = P.mean(axis=1)
    # candidates: Voronoi vertex (paper), incentre, centroid; keep the one whose three
    # sub-triangles have the largest minimum angle
    cands = [np.where(inside[:, None], v, inc), inc, cen]
    best_q = cands[0]
    best_ang, best_max = _split_angles(P, cands[0])
    for qc in cands[1:]:
        ang, amax = _split_angles(P, qc)
        better = ang > best_ang
        best_q = np.where(better[:, None], qc, best_q)
        best_ang = np.where(better, ang, best_ang)
        best_max = np.where(better, amax, best_max)
    q = best_q
    hq = np.asarray(h(q), dtype=float) if callable(h) else np.full(len(q), float(h))
    polygons = np.asarray(polygons)
    tree = shapely.STRtree(polygons) if tree is None else tree
    pts = shapely.points(q)
    ix, dist = tree.query_nearest(pts, return_distance=True, all_matches=False)
    dn = np.zeros(len(q))
    dn[ix[0]] = dist
    ok = (dn >= clearance * hq) & (best_ang >= min_angle) & (best_max <= max_angle)
    return jt[ok], q[ok]


def _split_angles(P, q):
    """Smallest and largest angle (degrees) of the three triangles made by splitting ``P`` (k, 3, 2) at ``q``."""
    lo = np.full(len(q), 180.0)
    hi = np.zeros(len(q))
    for i in range(3):  # the three sub-triangles
        a, b = P[:, i], P[:, (i + 1) % 3]
        for u, v, w in ((a, b, q), (b, q, a), (q, a, b)):
            d1, d2 = v - u, w - u
            c = (d1 * d2).sum(axis=1) / np.maximum(np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1), 1e-300)
            ang = np.degrees(np.arccos(np.clip(c, -1, 1)))
            lo = np.minimum(lo, ang)
            hi = np.maximum(hi, ang)
    return lo, hi


def split_triangles(triangles, tri, new_index) -> np.ndarray:
    """Split triangles ``tri`` at new nodes ``new_index`` into three each (orientation kept)."""
    t = np.asarray(triangles).copy()
    a, b, c = t[tri, 0], t[tri, 1], t[tri, 2]
    j = np.asarray(new_index)
    t[tri] = np.column_stack([a, b, j])
    return np.vstack([t, np.column_stack([b, c, j]), np.column_stack([c, a, j])])
