"""Short-range repulsion between bodies closer than a cut-off distance (bodies in a fluid).

In 2D a no-slip body never touches another or a wall in finite time (Hillairet 2007): the
lubrication film between them thins ever more slowly.  A mesh of size h cannot resolve a
film much thinner than h, so below that distance the computed flow no longer holds bodies
apart, and a resolved fluid–body code needs an explicit model there.  fluidem uses the
repulsive force of Glowinski, Pan, Hesla & Joseph (1999, *Int. J. Multiphase Flow* 25,
§4) and Glowinski et al. (2001, *J. Comput. Phys.* 169, eq. 4.1), written for polygons with
the gap ``g`` between the outlines instead of the centre distance of two disks::

    F = (c / ε) ((ρ − g) / ρ)²   for 0 ≤ g < ρ,   0 for g ≥ ρ,          (Glowinski 2001, eq. 4.1)

``ρ`` the range (cut-off distance; fluidem's default is the mesh size at the bodies), ``c``
a force scale (default: the largest buoyant weight of a free body, as Glowinski et al.),
``ε`` a small dimensionless stiffness parameter.  The force acts along the line of the
closest points of the two outlines, equal and opposite on the two bodies (so it conserves
momentum and, about any point, angular momentum), and is conservative (potential
``c ρ s³ / (3 ε)``, ``s = (ρ − g)/ρ``).  A body resting on another under its buoyant weight
``W = c`` stops where ``s² = ε``: at ``g = ρ (1 − √ε)``, i.e. within ``√ε`` of the cut-off.
Overlapping bodies (g < 0) feel the largest repulsion ``c/ε`` along their centre line and the
contact law of :mod:`fluidem.dem.contact` on top of it.

Stiffness: ``dF/dg`` is largest at contact, ``k_max = 2 c / (ε ρ)``; the stable explicit
step ``0.1 π √(m / k_max)`` enters :attr:`fluidem.dem.DEM.dt_max`.

Gaps between convex polygons that do not overlap are attained at a vertex of one of them, so
the gap is the smallest distance of a vertex of either body to an edge of the other
(vectorised over pairs × vertices × edges).  A face parallel to a face (two squares, a square
on a wall) has several vertices at the same distance: the force acts at the mean of the
closest points weighted by their own ``s²``, along the weighted mean direction, with the
magnitude of the closest one; a single closest vertex gives exactly the formula above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validate
from .periodic import image_shift

__all__ = ["Repulsion", "approach_geometry", "pair_gaps", "repulsion_forces", "repulsion_pairs", "wall_approaches"]


@dataclass(frozen=True)
class Repulsion:
    """Parameters of the short-range repulsion (Glowinski et al. 2001, eq. 4.1).

    Parameters
    ----------
    range : float
        Cut-off distance ρ between outlines (and from a wall), length, > 0.
    force : float
        Force scale c, force (per unit depth), ≥ 0 (0 switches the repulsion off).
    epsilon : float
        Dimensionless stiffness ε, > 0: the force is ``c/ε`` at contact; a body pressed by a
        load ``c`` stops at the gap ``ρ (1 − √ε)``.

    Examples
    --------
    >>> r = Repulsion(range=0.01, force=2.0, epsilon=1e-4)
    >>> round(float(r.magnitude(np.array([0.01, 0.005, 0.0]))[1]) * r.epsilon / r.force, 6)
    0.25
    >>> round(r.rest_gap(2.0) / r.range, 6)
    0.99
    """

    range: float
    force: float
    epsilon: float = 1e-4

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "range", validate.positive("Repulsion(range=...)", self.range))
        set_(self, "force", validate.nonnegative("Repulsion(force=...)", self.force))
        set_(self, "epsilon", validate.positive("Repulsion(epsilon=...)", self.epsilon))

    def magnitude(self, gap: np.ndarray) -> np.ndarray:
        """Force magnitude at the gaps ``gap`` (length; negative = overlap), force."""
        s = np.clip((self.range - np.asarray(gap, float)) / self.range, 0.0, 1.0)
        return (self.force / self.epsilon) * s * s

    def stiffness(self, gap: np.ndarray) -> np.ndarray:
        """``−dF/dg`` at the gaps ``gap``, ``2 c s / (ε ρ)``, force/length (0 beyond the range; at
        an overlap the force no longer grows, 0)."""
        g = np.asarray(gap, float)
        s = np.clip((self.range - g) / self.range, 0.0, 1.0)
        return np.where(g < 0.0, 0.0, 2.0 * self.force / (self.epsilon * self.range) * s)

    @property
    def max_stiffness(self) -> float:
        """Largest ``dF/dg`` (at contact), ``2 c / (ε ρ)``, force/length."""
        return 2.0 * self.force / (self.epsilon * self.range)

    def rest_gap(self, load: float) -> float:
        """Gap at which the repulsion balances a steady ``load`` (force), length."""
        s = np.sqrt(min(max(load, 0.0) * self.epsilon / self.force, 1.0)) if self.force > 0 else 1.0
        return float(self.range * (1.0 - s))


def _point_segment(P, A, B):
    """Closest points on segments A–B to points P (broadcast, (..., 2)): (foot, distance)."""
    AB = B - A
    L2 = (AB * AB).sum(axis=-1)
    t = np.clip(((P - A) * AB).sum(axis=-1) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    Q = A + t[..., None] * AB
    d = np.sqrt(((P - Q) ** 2).sum(axis=-1))
    return Q, d


def _padding(W: np.ndarray) -> np.ndarray:
    """Which rows of padded outlines ``W (..., K, 2)`` are padding: (..., K) bool, True where a vertex after
    the first repeats the first exactly (:func:`fluidem.geometry.rigid_transform` maps equal body-frame
    vertices to equal world points, bit for bit)."""
    pad = (W[..., 0] == W[..., :1, 0]) & (W[..., 1] == W[..., :1, 1])  # 8x faster than np.all over the last axis
    pad[..., 0] = False
    return pad


def pair_gaps(W: np.ndarray, i: np.ndarray, j: np.ndarray, centres: np.ndarray | None = None,
              radii: np.ndarray | None = None, reach: float = np.inf, shift: np.ndarray | None = None):
    """Vertex–edge distances of body pairs, both ways.

    Parameters
    ----------
    W : (N, K, 2) float
        World outlines padded by repeating the first vertex (zero-length padding edges are
        harmless: they repeat a vertex).
    i, j : (P,) int
        Pairs.
    centres, radii : (N, 2), (N,) float or None
        Centres and bounding radii: with ``reach``, only vertices closer than ``radius + reach``
        to the other body's centre are measured (the others get distance ``inf``).  A vertex
        within ``reach`` of the other outline always passes, so distances below ``reach`` are
        exact.
    reach : float
        Length.
    shift : (P, 2) float or None
        Added to body ``j``'s outline and centre (its nearest periodic image,
        :mod:`fluidem.dem.periodic`), length; None for none.

    Returns
    -------
    p, q : (P, 2K, 2) float
        For every vertex of ``i`` (first K) and of ``j`` (last K): the vertex and its closest
        point on the other body's outline, ordered so that ``p`` lies on ``i`` and ``q`` on ``j``
        (on its shifted image).
    d : (P, 2K) float
        Their distances, length; ``inf`` for the padding rows, which are not
        measured: a weighted mean over the vertices (:func:`approach_geometry`) counts each vertex
        once, not the first vertex of a body with fewer than K vertices once for each padding row
        (:func:`_padding`).
    """
    Wi, Wj = W[i], W[j]
    if shift is not None:
        Wj = Wj + shift[:, None, :]

    pad_i, pad_j = _padding(Wi), _padding(Wj)

    def vertex_to_outline(V, pad_V, other, pad_other, c_other, r_other):  # V, other (P, K, 2); pads (P, K)
        P, K = V.shape[:2]
        Q = np.broadcast_to(V, V.shape).copy()
        d = np.full((P, K), np.inf)
        near = ~pad_V
        if c_other is not None:
            dc = V - c_other[:, None, :]
            near &= (dc * dc).sum(axis=-1) < (r_other[:, None] + reach) ** 2
        pi, vi = np.nonzero(near)
        if not len(pi):
            return Q, d
        # the other body's real edges are its first n (the n-th closes onto the first vertex, which the
        # padding repeats): measured in groups of equal n, a few per scene, not against all K rows
        n_other = (K - pad_other.sum(axis=1))[pi]
        ends = np.roll(other, -1, axis=1)  # edge k of the other body: other[:, k] to ends[:, k]
        for n in np.unique(n_other):
            g = np.flatnonzero(n_other == n)
            rows, vs = pi[g], vi[g]
            A, B = other[rows, :n], ends[rows, :n]  # (m, n, 2) edges of the other body
            Qm, dm = _point_segment(V[rows, vs][:, None, :], A, B)  # (m, n)
            k = np.argmin(dm, axis=1)
            Q[rows, vs] = Qm[np.arange(len(g)), k]
            d[rows, vs] = dm[np.arange(len(g)), k]
        return Q, d

    ci = cj = ri = rj = None
    if centres is not None and np.isfinite(reach):
        ci, cj, ri, rj = centres[i], centres[j], radii[i], radii[j]
        if shift is not None:
            cj = cj + shift
    Qj, dj = vertex_to_outline(Wi, pad_i, Wj, pad_j, cj, rj)  # vertices of i, feet on j
    Qi, di = vertex_to_outline(Wj, pad_j, Wi, pad_i, ci, ri)  # vertices of j, feet on i
    p = np.concatenate([Wi, Qi], axis=1)
    q = np.concatenate([Qj, Wj], axis=1)
    return p, q, np.concatenate([dj, di], axis=1)


def repulsion_pairs(model: Repulsion, W: np.ndarray, pos: np.ndarray, i: np.ndarray, j: np.ndarray,
                    overlapping: np.ndarray, walls=None, movable: np.ndarray | None = None,
                    radii: np.ndarray | None = None, gaps=None, period: np.ndarray | None = None):
    """The pairs and body–wall pairs within the repulsion's range, one row each.

    Parameters are those of :func:`repulsion_forces`.

    Returns
    -------
    a, b : (P,) int
        The two bodies; ``b = -1`` for a wall.
    gap : (P,) float
        Gap between the outlines (0 for overlapping pairs, which act along their centre
        line), length.
    point : (P, 2) float
        Where the force acts, length; in a periodic box at ``a`` (the arm of ``b`` is
        ``point − (x_b + s)``, ``s`` the :func:`fluidem.dem.periodic.image_shift` of ``x_b − x_a``).
    direction : (P, 2) float
        Unit vector from ``b`` (or the wall) towards ``a``: the force on ``a`` is
        ``model.magnitude(gap) * direction``, the one on ``b`` its opposite.
    """
    rows = []
    rho = model.range
    if len(i):
        shift = _shift(pos, i, j, period)
        p, q, d = gaps if gaps is not None else pair_gaps(W, i, j, pos if radii is not None else None, radii, rho,
                                                          shift)
        gap = d.min(axis=1)
        near = gap < rho
        if near.any():
            ii, jj, ov = i[near], j[near], overlapping[near]
            line = pos[ii] - pos[jj] - (0.0 if shift is None else shift[near])
            point, direction = approach_geometry(p[near], q[near], d[near], rho, line, ov)
            rows.append((ii, jj, np.where(ov, 0.0, gap[near]), point, direction))
    if walls is not None:
        for k, gap, point, normal in wall_approaches(W, walls, rho, movable):
            rows.append((k, np.full(len(k), -1), gap, point, normal))
    if not rows:
        return (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2)))
    return tuple(np.concatenate(c) for c in zip(*rows))


def repulsion_forces(model: Repulsion, W: np.ndarray, pos: np.ndarray, i: np.ndarray, j: np.ndarray,
                     overlapping: np.ndarray, walls=None, movable: np.ndarray | None = None,
                     radii: np.ndarray | None = None, gaps=None, period: np.ndarray | None = None):
    """Repulsive forces and torques on every body (module docstring).

    Parameters
    ----------
    model : Repulsion
    W : (N, K, 2) float
        Padded world outlines, length.
    pos : (N, 2) float
        Centres of mass, length.
    i, j : (P,) int
        Candidate pairs (bounding circles within the range).
    overlapping : (P,) bool
        Pairs that overlap (from the contact detection): pushed along their centre line.
    walls : (xmin, xmax, ymin, ymax) or None
        Walls (``±inf`` for none), length.
    movable : (N,) bool or None
        Bodies that may approach a wall (default all).
    radii : (N,) float or None
        Bounding radii about ``pos``: only vertices that can be within the range of the other
        body are measured (same result, less work for many-sided outlines).
    gaps : tuple or None
        ``pair_gaps(W, i, j, ...)`` already computed with a reach ≥ ``model.range`` (and the
        periodic shifts).
    period : (2,) float or None
        Periods of a periodic box (0 for a non-periodic axis), length: every pair sees the
        nearest image of its second body (:mod:`fluidem.dem.periodic`); walls then stand only
        on the non-periodic sides (the caller's ``walls``).

    Returns
    -------
    F : (N, 2) float
        Forces, force.
    T : (N,) float
        Torques about the centres of mass, force·length.
    n_active : int
        Pairs and body–wall pairs within the range.
    """
    n = len(pos)
    F = np.zeros((n, 2))
    T = np.zeros(n)
    if model.force == 0.0:
        return F, T, 0
    a, b, gap, point, direction = repulsion_pairs(model, W, pos, i, j, overlapping, walls, movable, radii, gaps,
                                                  period)
    f = model.magnitude(gap)[:, None] * direction
    _accumulate(F, T, pos, a, f, point)
    body = b >= 0
    s = _shift(pos, a[body], b[body], period)
    _accumulate(F, T, pos, b[body], -f[body], point[body] - (0.0 if s is None else s))
    return F, T, int(len(a))


def approach_geometry(p, q, d, reach, centre_line, overlapping):
    """Point of action and direction of pairs of outlines closer than ``reach``.

    The closest points ``p`` (on body i) and ``q`` (on body j) of every vertex–edge pair within
    ``reach`` are weighted by ``((reach − d)/reach)²``: a single closest vertex gives its own point
    and direction, a face parallel to a face the mean over the face (module docstring).

    Parameters
    ----------
    p, q : (P, M, 2) float
        Closest points on body i and on body j (:func:`pair_gaps`), length.
    d : (P, M) float
        Their distances, length.
    reach : float
        Length.
    centre_line : (P, 2) float
        ``x_i − x_j``: the direction taken for overlapping or degenerate pairs.
    overlapping : (P,) bool

    Returns
    -------
    point : (P, 2) float
        Where the pair's force acts, length.
    direction : (P, 2) float
        Unit vector from body j towards body i.
    """
    w = np.clip((reach - d) / reach, 0.0, 1.0) ** 2
    u = p - q
    du = np.linalg.norm(u, axis=-1)
    u = np.where(du[..., None] > 0, u / np.where(du > 0, du, 1.0)[..., None], 0.0)
    direction = (w[..., None] * u).sum(axis=1)
    point = (w[..., None] * 0.5 * (p + q)).sum(axis=1) / w.sum(axis=1)[:, None]
    c = centre_line / np.linalg.norm(centre_line, axis=1)[:, None]
    dn = np.linalg.norm(direction, axis=1)
    bad = overlapping | (dn < 1e-12)
    direction = np.where(bad[:, None], c, direction / np.where(dn > 0, dn, 1.0)[:, None])
    return point, direction


def wall_approaches(W, walls, reach, movable=None):
    """Bodies closer than ``reach`` to each wall: ``(bodies, gap, point, normal)`` per wall.

    ``W`` (N, K, 2) padded world outlines; ``walls`` (xmin, xmax, ymin, ymax), ``±inf`` for none;
    ``movable`` (N,) bool, the bodies that may approach a wall (default all).  ``gap`` (M,) is the
    smallest vertex distance from the wall (negative beyond it), ``point`` (M, 2) the mean of the
    vertices within reach weighted by ``((reach − d)/reach)²``, ``normal`` (M, 2) the wall's unit
    normal into the box.
    """
    mv = np.arange(len(W)) if movable is None else np.flatnonzero(movable)
    Wm = W[mv]
    pad = _padding(Wm)  # each vertex once: the padding repeats the first
    x0, x1, y0, y1 = walls
    for axis, wall, sign in ((0, x0, 1.0), (0, x1, -1.0), (1, y0, 1.0), (1, y1, -1.0)):
        if not np.isfinite(wall):
            continue
        d = sign * (Wm[:, :, axis] - wall)  # distance of every vertex from the wall (negative: beyond)
        d = np.where(pad, np.inf, d)
        gap = d.min(axis=1)
        near = gap < reach
        if not near.any():
            continue
        d, gap, Wn = d[near], gap[near], Wm[near]
        w = np.clip((reach - d) / reach, 0.0, 1.0) ** 2
        point = (w[..., None] * Wn).sum(axis=1) / w.sum(axis=1)[:, None]
        normal = np.zeros((len(gap), 2))
        normal[:, axis] = sign
        yield mv[near], gap, point, normal


def _shift(pos, i, j, period):
    """The periodic shifts of pairs (:func:`fluidem.dem.periodic.image_shift`), or None outside a periodic box."""
    if period is None or not np.any(np.asarray(period) > 0):
        return None
    return image_shift(pos[j] - pos[i], period)


def _accumulate(F, T, pos, k, f, point):
    r = point - pos[k]
    np.add.at(F, k, f)
    np.add.at(T, k, r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0])
