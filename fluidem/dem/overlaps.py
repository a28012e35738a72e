"""Narrow phase of polygon contact: the overlap geometry of convex polygon pairs
(:func:`polygon_overlaps`) and of bodies with the domain walls (:func:`wall_overlaps`).

Everything works on arrays of pairs; loops run only over the, at most a few dozen,
polygon edges.

Sutherland–Hodgman clipping of one convex polygon by the edges of the other,
vectorised over pairs with padded vertex arrays.  Each output vertex carries a flag
telling whether it is a crossing of the two outlines; the two flagged vertices are the
intersection points of Matuttis & Chen (2014), ch. 7.  Domain walls are half-planes,
clipped with one edge.  Coordinates are taken relative to the first body's centre so
that tiny overlaps keep their digits.
"""

from __future__ import annotations

import numpy as np

from fluidem import geometry as geo

__all__ = ["WALL_IDS", "clip_convex", "polygon_overlaps", "wall_overlaps"]

#: Ids used in :attr:`fluidem.dem.contact.Contacts.j` for the four domain walls.
WALL_IDS = {"xmin": -1, "xmax": -2, "ymin": -3, "ymax": -4}


def clip_convex(subj: np.ndarray, n_subj: np.ndarray, edge_a: np.ndarray, edge_d: np.ndarray,
                capacity: int, n_edges: np.ndarray | None = None):
    """Clip convex polygons by half-planes (Sutherland–Hodgman), vectorised over rows.

    Parameters
    ----------
    subj : (P, W0, 2) float
        Subject polygons (CCW), first ``n_subj[p]`` rows valid.
    n_subj : (P,) int
        Vertex counts.
    edge_a, edge_d : (P, K, 2) float
        Clip edges: start point and direction; the kept side is the left one
        (``cross(d, x − a) ≥ 0``).
    capacity : int
        Width of the work arrays, ≥ ``W0`` + ``K``.
    n_edges : (P,) int, optional
        Number of clip edges used per row (the first ones); default all ``K``.  Edge
        ``k`` touches only the rows with ``n_edges > k``, so rows cut by few edges cost
        little.

    Returns
    -------
    poly : (P, capacity, 2) float
        Clipped polygons; rows past ``count`` repeat the first vertex.
    count : (P,) int
        Vertex counts (0: empty).
    crossing : (P, capacity) bool
        True for the vertices where an original subject edge crosses a clip edge, i.e.
        the intersection points of the two outlines.
    """
    P, W0, _ = subj.shape
    K = edge_a.shape[1]
    W = capacity
    # x and y in separate contiguous arrays: numpy is much faster on them than on (..., 2)
    SX = np.empty((P, W))
    SY = np.empty((P, W))
    SX[:, :W0], SY[:, :W0] = subj[..., 0], subj[..., 1]
    SX[:, W0:], SY[:, W0:] = subj[:, :1, 0], subj[:, :1, 1]
    n = n_subj.astype(np.int64).copy()
    on_subj = np.ones((P, W), bool)     # edge following the vertex lies on the subject outline
    cross = np.zeros((P, W), bool)
    q = np.arange(W)[None, :]
    if n_edges is None:
        n_edges = np.full(P, K)
    # round-off length of each row: 1e-12 of its coordinates' magnitude
    eps_len = 1e-12 * (np.abs(subj).max(axis=(1, 2)) + np.abs(edge_a).max(axis=(1, 2)))[:, None]
    for k in range(K):
        rows = np.flatnonzero(n_edges > k)
        if len(rows) == 0:
            break
        X, Y, nr = SX[rows], SY[rows], n[rows]
        ax, ay = edge_a[rows, k, 0][:, None], edge_a[rows, k, 1][:, None]
        ex, ey = edge_d[rows, k, 0][:, None], edge_d[rows, k, 1][:, None]
        d = ex * (Y - ay) - ey * (X - ax)
        # a vertex within round-off of the clip line lies on it: collinear faces (stacked
        # equal squares) then give the same intersection points on both sides instead of
        # points anywhere along the shared line, whose tilted chord pushed sideways
        d = np.where(np.abs(d) <= (np.abs(ex) + np.abs(ey)) * eps_len[rows], 0.0, d)
        valid = q < nr[:, None]
        ins = (d >= 0.0) & valid
        r = ins.sum(axis=1)
        part = (r < nr) & (r > 0)       # rows the edge really cuts
        n[rows[r == 0]] = 0
        if not part.any():
            continue
        rows, X, Y, d, ins, r, nr = (v[part] for v in (rows, X, Y, d, ins, r, nr))
        lab, cr = on_subj[rows], cross[rows]
        Pr = len(rows)
        ar = np.arange(Pr)
        nc = nr[:, None]
        prev = np.where(q == 0, nc - 1, q - 1)
        prev = np.where(prev < nc, prev, 0)
        arc = ar[:, None]
        start = ins & ~ins[arc, prev]
        s0 = np.argmax(start, axis=1)   # first vertex of the (single, convex) inside run
        e0 = (s0 + r - 1) % nr          # last inside vertex; edge e0 leaves the half-plane
        e1 = (e0 + 1) % nr
        p0 = (s0 - 1) % nr              # outside vertex; edge p0 enters the half-plane
        t_out = d[ar, e0] / (d[ar, e0] - d[ar, e1])
        t_in = d[ar, p0] / (d[ar, p0] - d[ar, s0])
        xo = X[ar, e0] + t_out * (X[ar, e1] - X[ar, e0])
        yo = Y[ar, e0] + t_out * (Y[ar, e1] - Y[ar, e0])
        xi = X[ar, p0] + t_in * (X[ar, s0] - X[ar, p0])
        yi = Y[ar, p0] + t_in * (Y[ar, s0] - Y[ar, p0])
        g = (s0[:, None] + q) % nc
        rc = r[:, None]
        run, at_out = q < rc, q == rc
        SX[rows] = np.where(run, X[arc, g], np.where(at_out, xo[:, None], xi[:, None]))
        SY[rows] = np.where(run, Y[arc, g], np.where(at_out, yo[:, None], yi[:, None]))
        lab_p0 = lab[ar, p0][:, None]
        on_subj[rows] = np.where(run, lab[arc, g], ~at_out & lab_p0)
        cross[rows] = np.where(run, cr[arc, g], np.where(at_out, lab[ar, e0][:, None], lab_p0))
        n[rows] = r + 2
    valid = q < n[:, None]
    SX = np.where(valid, SX, SX[:, :1])
    SY = np.where(valid, SY, SY[:, :1])
    cross &= valid
    return np.stack([SX, SY], axis=-1), n, cross


def _crossing_points(S: np.ndarray, cross: np.ndarray):
    """The two intersection points of the outlines (the farthest pair if more than two)."""
    P, W, _ = S.shape
    cnt = cross.sum(axis=1)
    first = np.argmax(cross, axis=1)
    last = W - 1 - np.argmax(cross[:, ::-1], axis=1)
    r = np.arange(P)
    p1, p2 = S[r, first], S[r, last]
    many = np.flatnonzero(cnt > 2)
    if len(many):
        Sm = S[many]
        D = ((Sm[:, :, None, :] - Sm[:, None, :, :]) ** 2).sum(axis=-1)
        ok = cross[many][:, :, None] & cross[many][:, None, :]
        D = np.where(ok, D, -1.0).reshape(len(many), -1)
        a, b = np.divmod(np.argmax(D, axis=1), W)
        p1[many] = Sm[np.arange(len(many)), a]
        p2[many] = Sm[np.arange(len(many)), b]
    return p1, p2, cnt


_ONES8 = np.frombuffer(b"\x01" * 8, dtype=np.uint64)[0]


def _words(b: np.ndarray):
    """View a C-contiguous bool array whose last axis is a multiple of 8 as uint64 words."""
    if b.shape[-1] % 8 or not b.flags.c_contiguous:
        return None
    return b.view(np.uint64)


def _any_last(b: np.ndarray) -> np.ndarray:
    """``b.any(axis=-1)`` for bool arrays, 8 entries at a time (numpy's bool reduce is slow)."""
    w = _words(b)
    if w is None:
        return b.any(axis=-1)
    return (w != 0).any(axis=-1) if w.shape[-1] > 1 else w[..., 0] != 0


def _all_last(b: np.ndarray) -> np.ndarray:
    """``b.all(axis=-1)`` for bool arrays, 8 entries at a time."""
    w = _words(b)
    if w is None:
        return b.all(axis=-1)
    return (w == _ONES8).all(axis=-1) if w.shape[-1] > 1 else w[..., 0] == _ONES8


def _any_middle(b: np.ndarray) -> np.ndarray:
    """``b.any(axis=1)`` for a bool (P, K, M) array, OR-ing 8 entries at a time."""
    w = _words(b)
    if w is None:
        return b.any(axis=1)
    return np.bitwise_or.reduce(w, axis=1).view(np.uint8).reshape(b.shape[0], -1) != 0


def polygon_overlaps(verts: np.ndarray, nv: np.ndarray, pos: np.ndarray, i: np.ndarray,
                     j: np.ndarray, shift: np.ndarray | None = None):
    """Overlap geometry of convex polygon pairs.

    Parameters
    ----------
    verts : (N, K, 2) float
        World vertices, padded by repeating the first one; ``nv`` valid per body.
    nv : (N,) int
    pos : (N, 2) float
        Centres of mass (coordinates are taken relative to ``pos[i]``).
    i, j : (P,) int
        Candidate pairs.
    shift : (P, 2) float or None
        Added to body ``j``'s vertices (its nearest periodic image, :mod:`fluidem.dem.periodic`),
        length; None for none.

    Returns
    -------
    dict with, per overlapping pair (P' ≤ P rows): ``i``, ``j``, ``area`` (length²),
    ``centroid`` (world, at ``i``), ``p1``, ``p2`` (intersection points, world), ``ncross``,
    ``shift`` (P', 2).
    """
    K = verts.shape[1]
    # per body, in contiguous x / y arrays; edge k runs from vertex k to vertex k+1
    # (cyclic over the padded width: padding repeats vertex 0, so padded edges vanish)
    VX = np.ascontiguousarray(verts[..., 0])
    VY = np.ascontiguousarray(verts[..., 1])
    EX = np.roll(VX, -1, axis=1) - VX
    EY = np.roll(VY, -1, axis=1) - VY
    px, py = pos[i, 0][:, None], pos[i, 1][:, None]
    AX, AY = VX[i] - px, VY[i] - py                  # relative to the centre of i
    if shift is None:
        shift = np.zeros((len(i), 2))
    BX, BY = VX[j] - (px - shift[:, :1]), VY[j] - (py - shift[:, 1:])
    DXa, DYa, DXb, DYb = EX[i], EY[i], EX[j], EY[j]
    # side of every vertex of A for every edge of B: (P, K_B, K_A); an edge of B with all
    # of A outside separates the pair, an edge with all of A inside does not cut it
    # (batched 8×2 @ 2×8 products: numpy's matmul is ~6x faster here than broadcasting)
    cb = (DXb * BY - DYb * BX)[..., None]
    outside = np.matmul(np.stack([-DYb, DXb], axis=-1), np.stack([AX, AY], axis=1)) < cb
    cuts = _any_last(outside)
    separated = _all_last(outside).any(axis=1)
    # side of every vertex of B for every edge of A: (P, K_A, K_B)
    ca = (DXa * AY - DYa * AX)[..., None]
    out2 = np.matmul(np.stack([-DYa, DXa], axis=-1), np.stack([BX, BY], axis=1)) < ca
    separated |= _all_last(out2).any(axis=1)
    # only edges of B whose segment meets A bound A ∩ B (if a point of A outside B
    # existed with all those half-planes kept, the segment from it to A ∩ B would leave B
    # through an edge meeting A); a segment misses A when both ends lie beyond one edge
    # of A (separating axis test of a segment against a convex polygon)
    both_out = out2 & np.roll(out2, -1, axis=2)
    cuts &= ~_any_middle(both_out)
    keep = ~separated
    if not np.all(keep):
        i, j, AX, AY, BX, BY, DXb, DYb, cuts, shift = (
            v[keep] for v in (i, j, AX, AY, BX, BY, DXb, DYb, cuts, shift))
    nA = nv[i]
    n_cut = cuts.sum(axis=1)
    order = np.argsort(~cuts, axis=1, kind="stable")
    kc = max(int(n_cut.max()) if len(n_cut) else 0, 1)
    order = order[:, :kc]
    Bc = np.stack([np.take_along_axis(BX, order, axis=1), np.take_along_axis(BY, order, axis=1)], -1)
    Dc = np.stack([np.take_along_axis(DXb, order, axis=1), np.take_along_axis(DYb, order, axis=1)], -1)
    A_sub = np.stack([AX, AY], axis=-1)
    o = pos[i][:, None, :]
    S, cnt, cross = clip_convex(A_sub, nA, Bc, Dc, K + kc, n_cut)
    A, cen = geo.polygon_area_centroid(S)
    p1, p2, ncross = _crossing_points(S, cross)
    ok = (cnt >= 3) & (A > 0)
    oo = o[ok, 0, :]
    return dict(i=i[ok], j=j[ok], area=A[ok], centroid=cen[ok] + oo, p1=p1[ok] + oo,
                p2=p2[ok] + oo, ncross=ncross[ok], shift=shift[ok])


# per wall (xmin, xmax, ymin, ymax): edge direction, whose left side (the kept side) is
# the outside of the domain, and the unit normal pointing into the domain
_WALL_DIR = np.array([[0.0, 1.0], [0.0, -1.0], [-1.0, 0.0], [1.0, 0.0]])
_WALL_NORMAL = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
_WALL_ID = np.array([WALL_IDS[k] for k in ("xmin", "xmax", "ymin", "ymax")])


def wall_overlaps(verts: np.ndarray, nv: np.ndarray, pos: np.ndarray, lo: np.ndarray,
                  hi: np.ndarray, walls, bodies: np.ndarray):
    """Overlap of bodies with the domain walls (half-planes beyond each side).

    Parameters
    ----------
    verts, nv, pos : as in :func:`polygon_overlaps`.
    lo, hi : (N, 2) float
        Bounding boxes of the bodies.
    walls : (xmin, xmax, ymin, ymax)
    bodies : (M,) int
        The bodies to test (movable ones).

    Returns
    -------
    dict as :func:`polygon_overlaps` plus ``normal`` (unit, into the domain); ``j`` holds
    the wall id.
    """
    xmin, xmax, ymin, ymax = walls
    hit = np.column_stack([lo[bodies, 0] < xmin, hi[bodies, 0] > xmax,
                           lo[bodies, 1] < ymin, hi[bodies, 1] > ymax])
    bk, w = np.nonzero(hit)
    if len(bk) == 0:
        return None
    b = bodies[bk]
    o = pos[b]
    # a point on the wall next to the body centre, relative to that centre
    rel = np.zeros((len(b), 2))
    vert = w < 2
    rel[:, 0] = np.where(vert, np.take([xmin, xmax, 0.0, 0.0], w) - o[:, 0], 0.0)
    rel[:, 1] = np.where(vert, 0.0, np.take([0.0, 0.0, ymin, ymax], w) - o[:, 1])
    S, cnt, cross = clip_convex(verts[b] - o[:, None, :], nv[b], rel[:, None, :],
                                _WALL_DIR[w][:, None, :], verts.shape[1] + 1)
    A, cen = geo.polygon_area_centroid(S)
    p1, p2, ncross = _crossing_points(S, cross)
    ok = (cnt >= 3) & (A > 0)
    o = o[ok]
    return dict(i=b[ok], j=_WALL_ID[w][ok], area=A[ok], centroid=cen[ok] + o,
                p1=p1[ok] + o, p2=p2[ok] + o, ncross=ncross[ok], normal=_WALL_NORMAL[w][ok])
