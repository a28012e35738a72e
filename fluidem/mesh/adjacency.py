"""Edge structure of a triangle mesh from its triangle–triangle neighbours, without sorting.

Triangle returns, with the ``n`` switch, the neighbour of every triangle across each of its
edges (``neighbors[k, j]`` lies opposite vertex ``j`` of triangle ``k``, ``-1`` on the
boundary).  Every edge is then the half-edge of the lower-numbered of its two triangles (or
of its only triangle), so the unique edges and their triangles follow from one mask, in
O(n_triangles) and without the sort of :func:`fluidem.mesh.relax.mesh_topology`.
"""

from __future__ import annotations

import numpy as np

from .junctions import split_triangles

__all__ = ["edges_from_neighbors", "split_with_neighbors"]


def edges_from_neighbors(triangles, neighbors) -> tuple[np.ndarray, np.ndarray]:
    """Unique edges and their one or two triangles.

    Parameters
    ----------
    triangles : (m, 3) int
    neighbors : (m, 3) int
        ``neighbors[k, j]``: triangle across the edge opposite vertex ``j`` of triangle ``k``,
        ``-1`` if that edge is on the boundary.

    Returns
    -------
    edges : (n_edges, 2) int
        ``edges[:, 0] < edges[:, 1]``.
    edge_tris : (n_edges, 2) int
        The triangles on both sides (a boundary edge repeats its only triangle).
    """
    tt = np.ascontiguousarray(np.asarray(triangles, dtype=np.int64).T)
    nb = np.asarray(neighbors, dtype=np.int64)
    m = tt.shape[1]
    # half-edge opposite vertex j: (t[:, j+1], t[:, j+2]), stacked j = 0, 1, 2
    a = np.concatenate([tt[1], tt[2], tt[0]])
    b = np.concatenate([tt[2], tt[0], tt[1]])
    own = np.tile(np.arange(m, dtype=np.int64), 3)
    other = np.ascontiguousarray(nb.T).ravel()
    keep = np.flatnonzero((own < other) | (other < 0))
    a, b, own, other = a.take(keep), b.take(keep), own.take(keep), other.take(keep)
    edges = np.empty((len(keep), 2), dtype=np.int64)
    np.minimum(a, b, out=edges[:, 0])
    np.maximum(a, b, out=edges[:, 1])
    edge_tris = np.empty((len(keep), 2), dtype=np.int64)
    edge_tris[:, 0] = own
    edge_tris[:, 1] = np.where(other >= 0, other, own)
    return edges, edge_tris


def split_with_neighbors(triangles, neighbors, tri, new_index) -> tuple[np.ndarray, np.ndarray]:
    """Split triangles ``tri`` at new nodes ``new_index`` into three each, neighbours kept valid.

    Triangle ``k = (a, b, c)`` becomes ``k = (a, b, j)``, ``m + i = (b, c, j)`` and
    ``m + K + i = (c, a, j)`` (``i`` its place in ``tri``, ``K = len(tri)``, orientation kept),
    by :func:`fluidem.mesh.junctions.split_triangles`.

    Returns
    -------
    triangles : (m + 2K, 3) int
    neighbors : (m + 2K, 3) int
    """
    t0 = np.asarray(triangles, dtype=np.int64)
    nb = np.asarray(neighbors, dtype=np.int64).copy()
    tri = np.asarray(tri, dtype=np.int64)
    j = np.asarray(new_index, dtype=np.int64)
    m, K = len(t0), len(tri)
    if not K:
        return t0.copy(), nb
    a, b = t0[tri, 0], t0[tri, 1]
    n_a, n_b, n_c = nb[tri, 0], nb[tri, 1], nb[tri, 2]  # across (b, c), (c, a), (a, b)
    c0, c1, c2 = tri, m + np.arange(K), m + K + np.arange(K)
    t = split_triangles(t0, tri, j)
    nb[tri] = np.column_stack([c1, c2, n_c])
    nb = np.vstack([nb, np.column_stack([c2, c0, n_a]), np.column_stack([c0, c1, n_b])])
    # outer triangles still name the split triangle k across the edges (b, c) and (c, a):
    # point them to the child that now holds that edge (a split outer triangle holds it in
    # its child's column 2, already rewritten above to name k)
    split = np.zeros(len(t), dtype=bool)
    split[tri] = True
    slot = np.full(m, -1, dtype=np.int64)
    slot[tri] = np.arange(K)
    rows, cols = np.nonzero(split[np.where(nb >= 0, nb, 0)] & (nb >= 0))
    k = nb[rows, cols]
    i = slot[k]
    # the edge of row r opposite column c
    u = t[rows, (cols + 1) % 3]
    v = t[rows, (cols + 2) % 3]
    # the child of k holding (u, v): the one without the original vertex missing from (u, v)
    ka, kb = a[i], b[i]
    has_a = (u == ka) | (v == ka)
    has_b = (u == kb) | (v == kb)
    child = np.where(has_a & has_b, c0[i], np.where(has_b, c1[i], c2[i]))
    # rows that are themselves children of k (internal edges) already point right
    internal = (u == j[i]) | (v == j[i])
    nb[rows[~internal], cols[~internal]] = child[~internal]
    return t, nb
