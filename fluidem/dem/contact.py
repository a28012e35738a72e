"""Polygon contact: broad phase, overlap geometry (narrow phase) and the force law.

Everything here works on arrays of pairs; there is no Python loop over bodies or
contacts (loops run only over the, at most a few dozen, polygon edges).

Broad phase
    A uniform cell grid (cell side = largest bounding diameter of the movable bodies),
    bodies binned by centre, pairs formed with the half stencil of 5 neighbour cells by
    ``np.repeat``/``searchsorted`` and kept when their bounding circles (plus a skin)
    overlap.  The list is a Verlet list: it is rebuilt only after some body moved more
    than half the skin.  Bodies larger than a cell (big fixed obstacles) are tested
    against all bodies directly.  Cost ~N.

Narrow phase
    Sutherland–Hodgman clipping of one convex polygon by the edges of the other,
    vectorised over pairs with padded vertex arrays.  Each output vertex carries a flag
    telling whether it is a crossing of the two outlines; the two flagged vertices are the
    intersection points of Matuttis & Chen (2014), ch. 7.  Domain walls are half-planes,
    clipped with one edge.  Coordinates are taken relative to the first body's centre so
    that tiny overlaps keep their digits.

Force law (Matuttis & Chen 2014, ch. 7; REFERENCES.md "Polygonal DEM")
    * normal elastic force ``F_el = E A / l`` with ``1/l = (r_i + r_j) / (4 r_i r_j)``,
      ``r`` the distances from the centres of mass to the overlap centroid (a domain wall
      has ``r_j → ∞``: ``l = 4 r_i``, the limit a large fixed polygon tends to);
    * direction: normal to the segment ``S`` joining the two intersection points of the
      outlines; point of action: the overlap centroid;
    * damping ``F_d = γ √(m_eff E) (dA/dt) / l``, with ``dA/dt = |S| v_n`` (the overlap
      grows by the contact line times the normal approach speed, exact to first order, so
      no history of ``A`` is needed); ``F_n = max(F_el + F_d, 0)`` never attracts;
    * tangential: Cundall & Strack (1979) incremental spring ``ξ += v_t dt``,
      ``F_t = −k_t ξ − γ √(m_eff k_t) v_t`` with ``k_t = κ E`` (κ = 2/7 by default),
      capped at ``μ F_n`` (Coulomb); when capped the spring is reset to
      ``ξ = −F_t / k_t`` (sliding).  ``ξ`` is kept per contact between steps and dropped
      when the contact opens.

Elastic energy of a contact: the work done on it by the elastic normal force since it
closed, ``∫ F_el dδ = ∫ (F_el/|S|) dA`` (``dA = |S| dδ`` for a mean penetration ``δ``),
integrated by the trapezoidal rule over the steps, plus the tangential spring energy
``k_t ξ² / 2``.  (The closed form ``E A²/(2 l |S|)`` is exact only for a flat contact at
fixed ``l``; for a corner pressed into a face it is 25 % low.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fluidem import geometry as geo
from fluidem import validate

from .periodic import image_shift

__all__ = ["ContactModel", "Contacts", "WALL_IDS", "grid_pairs", "clip_convex",
           "polygon_overlaps", "wall_overlaps", "contact_forces"]

#: Ids used in :attr:`Contacts.j` for the four domain walls.
WALL_IDS = {"xmin": -1, "xmax": -2, "ymin": -3, "ymax": -4}


@dataclass(frozen=True)
class ContactModel:
    """Material parameters of the polygon contact law.

    Parameters
    ----------
    E : float
        2D "Young's modulus" of the overlap law ``F = E A / l``, force/length (> 0; N/m
        in SI, dyn/cm in CGS): a 3D modulus times the unit depth of the 2D bodies.
    mu : float
        Coulomb friction coefficient (≥ 0).
    gamma : float
        Normal damping coefficient (≥ 0, dimensionless); the damping ratio of a contact is
        about ``(γ/2) √(|S|/l)``.
    gamma_t : float or None
        Tangential damping coefficient (dimensionless, ≥ 0); ``None`` uses ``gamma``.
    kt_ratio : float
        Tangential stiffness ``k_t = kt_ratio · E`` (force/length); 2/7 after Matuttis & Chen.

    Raises
    ------
    fluidem.errors.InputError
        (a ``ValueError``) A parameter out of range, named with its value.
    """

    E: float = 1e7
    mu: float = 0.23
    gamma: float = 0.025
    gamma_t: float | None = None
    kt_ratio: float = 2.0 / 7.0

    def __post_init__(self):
        set_ = object.__setattr__  # frozen: store the checked values once
        set_(self, "E", validate.positive("ContactModel(E=...)", self.E))
        set_(self, "mu", validate.nonnegative("ContactModel(mu=...)", self.mu))
        set_(self, "gamma", validate.nonnegative("ContactModel(gamma=...)", self.gamma))
        if self.gamma_t is not None:
            set_(self, "gamma_t", validate.nonnegative("ContactModel(gamma_t=...)", self.gamma_t))
        set_(self, "kt_ratio", validate.positive("ContactModel(kt_ratio=...)", self.kt_ratio))

    @property
    def kt(self) -> float:
        """Tangential spring stiffness ``kt_ratio · E``, force/length (N/m in SI)."""
        return self.kt_ratio * self.E

    @property
    def gt(self) -> float:
        """Tangential damping coefficient in use (``gamma_t``, or ``gamma`` when that is None)."""
        return self.gamma if self.gamma_t is None else self.gamma_t


@dataclass
class Contacts:
    """Contacts of one step, one entry per touching pair.

    Attributes
    ----------
    i : (n,) int
        First body (always a body index).
    j : (n,) int
        Second body index, or a wall id < 0 (see :data:`WALL_IDS`).
    point : (n, 2) float
        Point of action (overlap centroid), length.
    normal : (n, 2) float
        Unit normal pointing from ``j`` towards ``i``.
    normal_force : (n, 2) float
        Normal force on ``i`` (``j`` feels the opposite), force (N in SI).
    tangential_force : (n, 2) float
        Tangential (friction) force on ``i``, force.
    area : (n,) float
        Overlap area, length².
    length : (n,) float
        Characteristic length ``l``, length.
    chord : (n,) float
        Distance ``|S|`` between the two intersection points, length.
    xi : (n,) float
        Tangential spring elongation, length.
    sliding : (n,) bool
        True where the Coulomb cap is active.
    work : (n,) float
        Work done so far by the elastic normal force of the contact, force·length (J in
        SI): the stored normal
        elastic energy (trapezoidal rule of ``∫ (F_el/|S|) dA``, ``dA = |S| dδ``).
    shift : (n, 2) float
        In a periodic box, the shift of body ``j`` to its image nearest ``i``
        (:mod:`fluidem.dem.periodic`), length; ``point`` lies at ``i``, so ``point − (x_j + shift)``
        is the arm of ``j``'s force.  Zero for walls and outside periodic boxes.
    """

    i: np.ndarray
    j: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    area: np.ndarray
    length: np.ndarray
    chord: np.ndarray
    xi: np.ndarray
    sliding: np.ndarray
    work: np.ndarray
    key: np.ndarray = field(repr=False, default=None)
    shift: np.ndarray = field(repr=False, default=None)

    def __post_init__(self):
        if self.shift is None:
            self.shift = np.zeros((len(self.i), 2))

    def __len__(self) -> int:
        return len(self.i)

    @classmethod
    def empty(cls) -> "Contacts":
        z = np.zeros(0)
        z2 = np.zeros((0, 2))
        zi = np.zeros(0, dtype=np.int64)
        return cls(zi, zi, z2, z2, z2, z2, z, z, z, z, np.zeros(0, bool), z, zi, z2)

    def select(self, mask) -> "Contacts":
        return Contacts(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))

    @staticmethod
    def concat(parts) -> "Contacts":
        parts = list(parts)
        return Contacts(*(np.concatenate([getattr(p, f) for p in parts])
                          for f in Contacts.__dataclass_fields__))


def pair_key(i, j):
    """Integer key of a pair for the tangential history (j may be a wall id ≥ −8)."""
    return (np.asarray(i, np.int64) << 32) | (np.asarray(j, np.int64) + 8)


# ---------------------------------------------------------------------------------------
# broad phase
# ---------------------------------------------------------------------------------------
def grid_pairs(centers: np.ndarray, radii: np.ndarray, cell: float, movable: np.ndarray,
               skin: float = 0.0, period: np.ndarray | None = None):
    """Candidate pairs whose bounding circles (grown by ``skin``) overlap.

    Parameters
    ----------
    centers : (N, 2) float
        Centres of mass, length.
    radii : (N,) float
        Bounding radii, length.
    cell : float
        Cell side, ≥ twice the largest radius of the binned bodies plus ``skin``, length.
    movable : (N,) bool
        Pairs of two non-movable bodies are skipped.
    skin : float
        Extra distance, length.
    period : (2,) float or None
        Periods of a periodic box along x and y (0 for a non-periodic axis), length: pairs are
        found across the periodic sides and measured between nearest images
        (:mod:`fluidem.dem.periodic`); the centres may be unwrapped.

    Returns
    -------
    i, j : (P,) int
        Pairs with ``i < j``.
    """
    n = len(centers)
    if n < 2:
        z = np.zeros(0, np.int64)
        return z, z
    L = np.zeros(2) if period is None else np.asarray(period, float)
    periodic = L > 0
    large = 2.0 * radii + skin > cell
    small = np.flatnonzero(~large)
    ii_all, jj_all = [], []
    if len(small) > 1:
        c = centers[small]
        ij = np.floor((c - c.min(axis=0)) / cell).astype(np.int64) + 1
        m = np.zeros(2, np.int64)  # cells along a periodic axis (its indices wrap), 0 on the others
        for a in np.flatnonzero(periodic):
            m[a] = max(int(np.floor(L[a] / cell)), 1)  # cells of side L/m >= cell
            ij[:, a] = np.floor(np.mod(c[:, a], L[a]) / (L[a] / m[a])).astype(np.int64) % m[a]
        nx = int(m[0]) if periodic[0] else int(ij[:, 0].max()) + 2
        key = ij[:, 1] * nx + ij[:, 0]
        order = np.argsort(key, kind="stable")
        skey = key[order]
        uniq, start, counts = np.unique(skey, return_index=True, return_counts=True)
        ar = np.arange(len(small))
        for off, (ox, oy) in zip((0, 1, nx - 1, nx, nx + 1), ((0, 0), (1, 0), (-1, 1), (0, 1), (1, 1))):
            if periodic.any():  # wrapped neighbour cells (a cell may then be met twice: pairs made unique below)
                cx, cy = ij[:, 0] + ox, ij[:, 1] + oy
                if periodic[0]:
                    cx = cx % m[0]
                if periodic[1]:
                    cy = cy % m[1]
                nk = cy * nx + cx
            else:
                nk = key + off
            pos = np.searchsorted(uniq, nk)
            pos = np.minimum(pos, len(uniq) - 1)
            found = uniq[pos] == nk
            cnt = np.where(found, counts[pos], 0)
            tot = int(cnt.sum())
            if tot == 0:
                continue
            a = np.repeat(ar, cnt)
            first = np.repeat(start[pos] - (np.cumsum(cnt) - cnt), cnt)
            b = order[first + np.arange(tot)]
            if off == 0 or periodic.any():
                keep = a < b if off == 0 else a != b
                a, b = a[keep], b[keep]
            ii_all.append(small[a])
            jj_all.append(small[b])
    big = np.flatnonzero(large)
    if len(big):
        a = np.repeat(big, n)
        b = np.tile(np.arange(n), len(big))
        keep = (a != b) & ~(large[b] & (b < a))  # large-large pairs once
        ii_all.append(a[keep])
        jj_all.append(b[keep])
    if not ii_all:
        z = np.zeros(0, np.int64)
        return z, z
    i = np.concatenate(ii_all)
    j = np.concatenate(jj_all)
    i, j = np.minimum(i, j), np.maximum(i, j)
    if periodic.any():  # a pair may have been met through more than one (wrapped) cell
        ij = np.unique(i * n + j)
        i, j = ij // n, ij % n
    d = centers[j] - centers[i]
    d = d + image_shift(d, L)
    reach = radii[i] + radii[j] + skin
    keep = ((d * d).sum(axis=1) < reach * reach) & (movable[i] | movable[j])
    return i[keep], j[keep]


# ---------------------------------------------------------------------------------------
# narrow phase: vectorised convex clipping
# ---------------------------------------------------------------------------------------
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


# ---------------------------------------------------------------------------------------
# force law
# ---------------------------------------------------------------------------------------
def _perp(v):
    return np.column_stack([-v[:, 1], v[:, 0]])


def contact_forces(ov: dict, pos, vel, omega, mass, free, model: ContactModel, dt: float,
                   history: dict) -> Contacts:
    """Forces of the overlap law for pairs (body–body, or body–wall when ``ov['j'] < 0``).

    Parameters
    ----------
    ov : dict
        Output of :func:`polygon_overlaps` or :func:`wall_overlaps` (with ``shift``, the
        periodic image of ``j`` is taken).
    pos, vel : (N, 2) float
        Positions (length) and velocities (length/time) of the bodies.
    omega : (N,) float
        Angular velocities, rad/time.
    mass : (N,) float
        Masses (mass units).
    free : (N,) bool
        Free bodies (the others count as infinitely heavy in ``m_eff``).
    model : ContactModel
    dt : float
        Step for the tangential spring increment, time units (0 for a force evaluation without
        advancing the spring).
    history : dict
        The contacts of the previous step: ``key`` (sorted), ``xi``, ``area``, ``g``
        (``F_el/|S|``) and ``work``, each (H,).

    Returns
    -------
    Contacts
    """
    i, j = ov["i"], ov["j"]
    wall = j < 0
    jb = np.where(wall, i, j)  # harmless index for walls
    shift = ov["shift"] if "shift" in ov else np.zeros((len(i), 2))
    pj = pos[jb] + shift  # j's centre, at its image nearest i
    c = ov["centroid"]
    ri_v = c - pos[i]
    rj_v = c - pj
    ri = np.sqrt((ri_v**2).sum(axis=1))
    rj = np.sqrt((rj_v**2).sum(axis=1))
    # characteristic length, Matuttis & Chen: 1/l = (r_i + r_j)/(4 r_i r_j); wall: r_j → ∞
    with np.errstate(invalid="ignore", divide="ignore"):
        length = np.where(wall, 4.0 * ri, 4.0 * ri * rj / (ri + rj))
    S = ov["p2"] - ov["p1"]
    chord = np.sqrt((S**2).sum(axis=1))
    # normal: perpendicular to the chord, oriented from j towards i
    with np.errstate(invalid="ignore", divide="ignore"):
        n = _perp(S) / chord[:, None]
    dji = pos[i] - pj
    bad = ~np.isfinite(n).all(axis=1) | (ov["ncross"] < 2)
    if np.any(bad):  # degenerate chord: fall back to the line of centres
        dn = np.sqrt((dji**2).sum(axis=1))[:, None]
        n[bad] = dji[bad] / np.where(dn[bad] > 0, dn[bad], 1.0)
        chord = np.where(bad, np.sqrt(ov["area"]), chord)
    if "normal" in ov:
        n = np.where(wall[:, None], ov["normal"], n)
    flip = np.einsum("ij,ij->i", n, dji) < 0
    n = np.where((flip & ~wall)[:, None], -n, n)
    t = _perp(n)
    # relative velocity of i with respect to j at the contact point
    vi = vel[i] + omega[i][:, None] * _perp(ri_v)
    vj = np.where(wall[:, None], 0.0, vel[jb] + omega[jb][:, None] * _perp(rj_v))
    vr = vi - vj
    vn = -np.einsum("ij,ij->i", vr, n)          # approach speed (> 0 when closing)
    vt = np.einsum("ij,ij->i", vr, t)
    mi, mj = mass[i], mass[jb]
    fi, fj = free[i], free[jb] & ~wall
    meff = np.where(fi & fj, mi * mj / (mi + mj), np.where(fi, mi, mj))
    A = ov["area"]
    E = model.E
    f_el = E * A / length
    f_d = model.gamma * np.sqrt(meff * E) * chord * vn / length
    fn = np.maximum(f_el + f_d, 0.0)
    # Cundall–Strack tangential spring with history
    key = pair_key(i, j)
    xi = np.zeros(len(i))
    A0 = np.zeros(len(i))
    g0 = np.zeros(len(i))
    W0 = np.zeros(len(i))
    hk = history["key"]
    if len(hk):
        p = np.minimum(np.searchsorted(hk, key), len(hk) - 1)
        hit = hk[p] == key
        ph = p[hit]
        xi[hit] = history["xi"][ph]
        A0[hit] = history["area"][ph]
        g0[hit] = history["g"][ph]
        W0[hit] = history["work"][ph]
    # stored normal elastic energy: W += ½ (g_old + g_new)(A_new − A_old), g = F_el/|S|
    g = f_el / chord
    work = W0 + 0.5 * (g0 + g) * (A - A0)
    xi = xi + vt * dt
    kt = model.kt
    ft = -kt * xi - model.gt * np.sqrt(meff * kt) * vt
    cap = model.mu * fn
    sliding = np.abs(ft) > cap
    ft = np.where(sliding, np.sign(ft) * cap, ft)
    xi = np.where(sliding, -ft / kt, xi)
    return Contacts(i=i, j=j, point=c, normal=n, normal_force=fn[:, None] * n,
                    tangential_force=ft[:, None] * t, area=A, length=length, chord=chord,
                    xi=xi, sliding=sliding, work=work, key=key, shift=shift)
