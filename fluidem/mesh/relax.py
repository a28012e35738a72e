"""Spring relaxation of a triangle mesh (paper Sec. 2.2, eq. 1–3), vectorised over edges.

Every edge is a spring.  Its rest length is the side of an equilateral triangle of the
*local* size: for each triangle ``T`` the target side is the geometric blend

    s_T = s_own(T)^(1 − β) · h_T^β,      s_own(T) = sqrt(4 A_T / √3),

of the side of the equilateral triangle with the triangle's own area ``A_T`` (the paper's
"local mesh size of each element", which removes global tension) and the target size
``h_T`` (mean of the per-node target sizes, which pulls the mesh towards the requested
grading).  The rest length of an edge is the mean of ``s_T`` over its one or two triangles.

Position update: the Störmer–Verlet step (eq. 1)
``r_{n+1} = 2 r_n − r_{n−1} + τ² a_n`` written with an iteration time ι (eq. 2) and with the
velocity term ``v_n`` dropped, so ``r_{n+1} = r_n + τ² a_n``: an order-zero integrator that
only finds equilibria.  ``a_n`` is the spring force (in length units; the spring constant
is absorbed into ``τ²``, a dimensionless step ≲ 0.3 for stability of this Jacobi sweep)
plus the area grow/shrink term of eq. 3,

    a_{T,gs} = Σ_i sgn(A_{T,i} − A_T) · sqrt(|A_{T,i} − A_T|),

summed over the edge neighbours ``i`` of ``T`` and applied to the three vertices of ``T``
along the direction from the centroid (outwards: grow, inwards: shrink), times a weight κ.

Constraints: every node has a mobility mask ``(mx, my)`` ∈ {0, 1}²; body outline nodes and
box corners are fixed (0, 0), nodes on the bottom/top sides slide in x (1, 0), on the
left/right sides in y (0, 1).  A move that would invert an element (or shrink it below a
the shape floor ``min_quality`` of ``q = 4√3 A / Σ l²``, or worsen one already below) is
halved for the vertices of that element, up to ``max_halvings`` times, then dropped:
relaxation never inverts an element nor flattens it.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geometry import triangle_areas as signed_areas  # signed areas (n_triangles,), length²

__all__ = ["RelaxParams", "MeshTopology", "mesh_topology", "signed_areas", "relax"]

_SQRT3 = np.sqrt(3.0)


@dataclass(frozen=True)
class RelaxParams:
    """Parameters of the spring relaxation.

    Parameters
    ----------
    step : float
        τ² of eq. 2 (dimensionless, the spring constant absorbed); 0 < step ≤ 0.3.
    target_weight : float
        β in ``s_T = s_own^(1−β) h_T^β``: 0 uses the element's own size only (paper
        Sec. 2.2), 1 the target size field only.
    area_weight : float
        κ, weight of the area grow/shrink force of eq. 3 (≥ 0).
    max_halvings : int
        How often a move that would invert an element is halved before it is dropped.
    min_quality : float
        Shape floor: no move may bring an element's quality ``q = 4√3 A / Σ l²`` (1 for
        equilateral, ≤ 0 inverted) below this value, or lower it if already below.
    """

    step: float = 0.2
    target_weight: float = 0.75
    area_weight: float = 0.05
    max_halvings: int = 5
    min_quality: float = 0.4

    def __post_init__(self):
        if not (np.isfinite(self.step) and 0 < self.step <= 0.3):
            raise InputError(f"relaxation step τ² must be in (0, 0.3], got {self.step!r}")
        if not (0.0 <= self.target_weight <= 1.0):
            raise InputError(f"target_weight must be in [0, 1], got {self.target_weight!r}")
        if not (np.isfinite(self.area_weight) and self.area_weight >= 0):
            raise InputError(f"area_weight must be a number >= 0, got {self.area_weight!r}")
        if int(self.max_halvings) != self.max_halvings or self.max_halvings < 0:
            raise InputError(f"max_halvings must be an integer >= 0, got {self.max_halvings!r}")


@dataclass(frozen=True)
class MeshTopology:
    """Edge structure of a triangle mesh, with contiguous index arrays for fast gathers.

    Attributes
    ----------
    triangles : (n_triangles, 3) int
    edges : (n_edges, 2) int
        Unique edges, ``edges[:, 0] < edges[:, 1]``.
    edge_tris : (n_edges, 2) int
        The one or two triangles of each edge (boundary edges repeat their only triangle).
    interior : (n_edges,) bool
        True for edges shared by two triangles.
    """

    triangles: np.ndarray
    edges: np.ndarray
    edge_tris: np.ndarray
    interior: np.ndarray

    def __post_init__(self):
        # numpy gathers of single columns are much faster than of (n, 2) rows
        # (one transposed copy per array; the columns are its contiguous rows)
        tt = np.ascontiguousarray(self.triangles.T)
        object.__setattr__(self, "tcat", tt.ravel())
        object.__setattr__(self, "t0", tt[0])
        object.__setattr__(self, "t1", tt[1])
        object.__setattr__(self, "t2", tt[2])
        et = np.ascontiguousarray(self.edges.T)
        object.__setattr__(self, "e0", et[0])
        object.__setattr__(self, "e1", et[1])
        ett = np.ascontiguousarray(self.edge_tris.T)
        object.__setattr__(self, "et0", ett[0])
        object.__setattr__(self, "et1", ett[1])
        object.__setattr__(self, "ie0", np.compress(self.interior, ett[0]))
        object.__setattr__(self, "ie1", np.compress(self.interior, ett[1]))

    def __getstate__(self):
        # relax()'s scratch buffers (cached on the topology) are not part of its state
        state = dict(self.__dict__)
        state.pop(_WS_ATTR, None)
        return state


def mesh_topology(triangles) -> MeshTopology:
    """Unique edges and edge–triangle incidence of ``triangles`` ``(n_triangles, 3)``."""
    t = np.ascontiguousarray(triangles, dtype=np.int64)
    m = len(t)
    he = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    tri = np.repeat(np.arange(m), 1)
    tri = np.concatenate([tri, tri, tri])
    he.sort(axis=1)
    n = int(t.max()) + 1 if m else 0
    key = he[:, 0] * n + he[:, 1]
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    first = np.ones(len(key_s), dtype=bool)
    first[1:] = key_s[1:] != key_s[:-1]
    idx = np.cumsum(first) - 1
    n_e = int(idx[-1]) + 1 if len(idx) else 0
    edges = he[order][first]
    edge_tris = np.empty((n_e, 2), dtype=np.int64)
    t_s = tri[order]
    edge_tris[:, 0] = t_s[first]
    edge_tris[:, 1] = edge_tris[:, 0]
    second = ~first
    edge_tris[idx[second], 1] = t_s[second]
    interior = edge_tris[:, 0] != edge_tris[:, 1]
    return MeshTopology(t, edges, edge_tris, interior)


def _areas(x, y, t0, t1, t2):
    ax, ay = x[t0], y[t0]
    return 0.5 * ((x[t1] - ax) * (y[t2] - ay) - (y[t1] - ay) * (x[t2] - ax))


def _shape(x, y, t0, t1, t2, area, qual, tmp):
    """Signed areas and shape quality ``q = 4√3 A / (l1² + l2² + l3²)`` (1 equilateral, ≤ 0 inverted).

    Written into ``area`` and ``qual`` (one entry per row of ``t0, t1, t2``); ``tmp`` is
    scratch of shape ``(6, len(t0))``.
    """
    xa, ya, ux, uy, vx, vy = tmp
    _take(x, t0, xa)
    _take(y, t0, ya)
    np.subtract(_take(x, t1, ux), xa, out=ux)
    np.subtract(_take(y, t1, uy), ya, out=uy)
    np.subtract(_take(x, t2, vx), xa, out=vx)
    np.subtract(_take(y, t2, vy), ya, out=vy)
    np.multiply(ux, vy, out=area)  # area = (u × v) / 2
    area -= np.multiply(uy, vx, out=xa)
    area *= 0.5
    l2 = np.multiply(ux, ux, out=ya)  # l2 = |u|² + |v|² + |v − u|²
    l2 += np.multiply(uy, uy, out=xa)
    l2 += np.multiply(vx, vx, out=xa)
    l2 += np.multiply(vy, vy, out=xa)
    wx = np.subtract(vx, ux, out=ux)
    l2 += np.multiply(wx, wx, out=xa)
    wy = np.subtract(vy, uy, out=uy)
    l2 += np.multiply(wy, wy, out=xa)
    np.maximum(l2, 1e-300, out=l2)
    np.multiply(area, 4.0 * _SQRT3, out=qual)
    qual /= l2
    return area, qual


def _take(a, idx, out):
    """``out[:] = a[idx]`` without a temporary (``mode='clip'`` skips numpy's buffered copy;
    the indices are valid by construction)."""
    return np.take(a, idx, out=out, mode="clip")


def _root_power(a, p, out):
    """``out = a**p``, by square-root chains for p = 1/2, 1/4, 1/8 (``out`` may be ``a``)."""
    if p == 0.5:
        return np.sqrt(a, out=out)
    if p == 0.25:
        return np.sqrt(np.sqrt(a, out=out), out=out)
    if p == 0.125:
        return np.sqrt(np.sqrt(np.sqrt(a, out=out), out=out), out=out)
    return np.power(a, p, out=out)


class _Workspace:
    """Preallocated buffers for :func:`relax` on one topology and node count.

    A sweep on a large mesh was dominated not by arithmetic but by page faults: numpy
    allocated a fresh multi-MB temporary for every operation and glibc returned it to the OS.
    With these buffers and ``out=`` arguments a sweep allocates no float array of the mesh's
    size (only boolean masks of the triangles, and the returned positions).  About 65
    doubles per node; cached on the topology, so dropped with it at re-triangulation.
    """

    def __init__(self, topo: MeshTopology, n: int):
        n_t, n_e, n_i = len(topo.t0), len(topo.e0), len(topo.ie0)
        self.n = n
        self.lock = threading.Lock()
        # nodes: positions (current, moved), accelerations then moves, step factors, scratch
        self.x, self.y, self.xn, self.yn, self.dx, self.dy, self.mx, self.my, self.node_tmp = np.empty((9, n))
        self.z = np.empty(n, dtype=complex)
        # triangles: (area, quality) of the current and of the moved positions, scratch of _shape
        self.shape, self.shape_n = np.empty((2, 2, n_t))
        self.shape_tmp = np.empty((6, n_t))
        self.h_beta, self.floor, self.a_pos, self.s_t, self.g_t, self.tri_tmp = np.empty((6, n_t))
        # interior edges (eq. 3) and all edges (springs)
        self.diff, self.g = np.empty((2, n_i))
        self.rest, self.edge_tmp, self.edge_tmp2 = np.empty((3, n_e))
        self.dz, self.dz_tmp = np.empty((2, n_e), dtype=complex)
        # h_T^β depends only on h_node, which is fixed between re-triangulations: keep it
        self.h_key, self.beta_key = None, None

    def h_beta_for(self, topo: MeshTopology, h, beta):
        """``h_T^β`` per triangle (``h_T`` the mean of the node sizes), recomputed only if ``h`` or β changed."""
        if self.beta_key == beta and np.array_equal(self.h_key, h):
            return self.h_beta
        h_t = np.add(_take(h, topo.t0, self.h_beta), _take(h, topo.t1, self.tri_tmp), out=self.h_beta)
        h_t += _take(h, topo.t2, self.tri_tmp)
        h_t /= 3.0
        if beta != 1.0:
            np.power(h_t, beta, out=h_t)
        self.h_key, self.beta_key = h.copy(), beta
        return h_t


_WS_ATTR = "_relax_workspace"


@contextmanager
def _workspace(topo: MeshTopology, n: int):
    """The topology's cached :class:`_Workspace` for ``n`` nodes (a private one if it is in use)."""
    ws = getattr(topo, _WS_ATTR, None)
    if ws is None or ws.n != n:
        ws = _Workspace(topo, n)
        object.__setattr__(topo, _WS_ATTR, ws)
    if not ws.lock.acquire(blocking=False):  # relax running on this topology in another thread
        ws = _Workspace(topo, n)
        ws.lock.acquire()
    try:
        yield ws
    finally:
        ws.lock.release()


def _forces(x, y, area, topo: MeshTopology, h_beta, params: RelaxParams, ws: _Workspace, ax, ay):
    """Spring + area-force (eq. 3) accelerations, written into ``ax, ay`` (length units).

    ``area`` are the current signed triangle areas, ``h_beta`` is ``h_T^β`` per triangle
    (fixed while the target sizes are).  The grow/shrink force of eq. 3 acts "on all edges
    uniformly" (paper Sec. 2.2): every edge of triangle ``T`` is pushed apart by
    ``κ g_T`` (pulled together if ``g_T < 0``), edges shared by two triangles get the mean.

    Every operation writes into a buffer of ``ws``.  Their order is kept operation for
    operation: ``sqrt|A_i − A_T|`` of eq. 3 turns a last-bit change of an area into a
    relative change of ~1e-8 in the next sweep, so reordering sums is not "just round-off".
    """
    a_pos = np.maximum(area, 0.0, out=ws.a_pos)
    # per-triangle target side s_T = s_own^(1−β) h_T^β, s_own = sqrt(4 A / √3)
    beta = params.target_weight
    if beta == 1.0:
        s_t = h_beta
    else:
        s_t = np.multiply(a_pos, 4.0 / _SQRT3, out=ws.s_t)
        _root_power(s_t, 0.5 * (1.0 - beta), out=s_t)
        if beta != 0.0:
            s_t *= h_beta
    # rest length of an edge: mean over its one or two triangles of s_T + κ g_T
    rest, tmp, tmp2 = ws.rest, ws.edge_tmp, ws.edge_tmp2
    np.add(_take(s_t, topo.et0, rest), _take(s_t, topo.et1, tmp), out=rest)
    if params.area_weight > 0.0:
        # eq. 3: g_T = Σ_i sgn(A_i − A_T) sqrt|A_i − A_T| over edge neighbours
        diff, g = ws.diff, ws.g
        np.subtract(_take(a_pos, topo.ie1, diff), _take(a_pos, topo.ie0, g), out=diff)
        np.sqrt(np.abs(diff, out=g), out=g)
        np.copysign(g, diff, out=g)
        g_t = _scatter_diff(topo.ie0, topo.ie1, g, ws.g_t, ws.tri_tmp)
        np.add(_take(g_t, topo.et0, tmp), _take(g_t, topo.et1, tmp2), out=tmp)
        tmp *= params.area_weight
        rest += tmp
    rest *= 0.5
    # spring force of every edge, k (r_1 − r_0) with k = 1 − rest / length
    np.copyto(ws.z.real, x)
    np.copyto(ws.z.imag, y)
    dz = np.subtract(_take(ws.z, topo.e1, ws.dz), _take(ws.z, topo.e0, ws.dz_tmp), out=ws.dz)
    length = np.abs(dz, out=tmp)
    np.maximum(length, 1e-300, out=length)
    k = np.divide(rest, length, out=rest)
    np.subtract(1.0, k, out=k)  # > 0: stretched, pull together
    _scatter_diff(topo.e0, topo.e1, np.multiply(k, dz.real, out=tmp), ax, ws.node_tmp)
    _scatter_diff(topo.e0, topo.e1, np.multiply(k, dz.imag, out=tmp), ay, ws.node_tmp)
    return ax, ay


def _scatter_diff(i0, i1, w, out, tmp):
    """``out = bincount(i0, w) − bincount(i1, w)`` into preallocated ``out`` (``tmp``: scratch
    of the same length); ``np.add.at`` accumulates in the same order as ``bincount``."""
    out.fill(0.0)
    np.add.at(out, i0, w)
    tmp.fill(0.0)
    np.add.at(tmp, i1, w)
    return np.subtract(out, tmp, out=out)


def _clip(x, lo, hi):
    """Clamp ``x`` into ``[lo, hi]`` in place (like ``np.clip``, without its overhead)."""
    np.maximum(x, lo, out=x)
    return np.minimum(x, hi, out=x)


def relax(points, topo: MeshTopology, h_node, mobility, n_iter: int = 1, params: RelaxParams = RelaxParams(),
          bounds=None, damping=None) -> tuple[np.ndarray, int]:
    """Run ``n_iter`` relaxation sweeps (eq. 2 without ``v_n``, plus eq. 3).

    Parameters
    ----------
    points : (n_nodes, 2) float
        Node positions, length units; not modified.
    topo : MeshTopology
        From :func:`mesh_topology`; triangles counter-clockwise.  Scratch buffers for the
        sweeps are cached on it (about 65 doubles per node) and reused by later calls.
    h_node : (n_nodes,) float
        Target edge length at every node, length units.
    mobility : (n_nodes, 2) float
        Per-node multipliers of the x and y displacement (0 fixed, 1 free).
    n_iter : int
        Number of sweeps (the per-physical-step iteration limit of Sec. 3.3).
    params : RelaxParams
    bounds : (xmin, xmax, ymin, ymax) or None
        Sliding nodes are clamped into this box.
    damping : (n_nodes,) float or None
        Extra per-node factor on the step in [0, 1] (used to damp oscillating nodes).

    Returns
    -------
    points : (n_nodes, 2) float
        Relaxed positions.
    n_blocked : int
        Number of node moves shortened to zero because they would have inverted elements
        (summed over sweeps).
    """
    points = np.asarray(points, dtype=float)
    with _workspace(topo, len(points)) as ws:
        x, y, xn, yn, dx, dy, mx, my = ws.x, ws.y, ws.xn, ws.yn, ws.dx, ws.dy, ws.mx, ws.my
        x[:] = points[:, 0]
        y[:] = points[:, 1]
        mob = np.asarray(mobility, dtype=float)
        np.multiply(mob[:, 0], params.step, out=mx)
        np.multiply(mob[:, 1], params.step, out=my)
        if damping is not None:
            mx *= damping
            my *= damping
        t0, t1, t2 = topo.t0, topo.t1, topo.t2
        h = np.asarray(h_node, dtype=float)
        h_beta = ws.h_beta_for(topo, h, params.target_weight)
        floor = ws.floor
        n_blocked = 0
        (area, qual), (area_n, qual_n) = ws.shape, ws.shape_n
        _shape(x, y, t0, t1, t2, area, qual, ws.shape_tmp)
        minq = params.min_quality
        for _ in range(int(n_iter)):
            # eq. 2 without v_n: r_{n+1} = r_n + τ² a_n (τ², mobility and damping in mx, my)
            _forces(x, y, area, topo, h_beta, params, ws, dx, dy)
            dx *= mx
            dy *= my
            # no move may bring an element below the shape floor (or worsen one already below)
            # (elements already below the floor may lose at most 0.1 % of their quality per sweep:
            # round-off must not block every move next to them)
            # floor = min_quality; 0.999 q for 0 < q < min_quality; q for q <= 0
            np.multiply(qual, 0.999, out=floor)
            np.copyto(floor, qual, where=qual <= 0)
            np.copyto(floor, minq, where=~(qual < minq))
            np.add(x, dx, out=xn)
            np.add(y, dy, out=yn)
            if bounds is not None:
                _clip(xn, bounds[0], bounds[1])
                _clip(yn, bounds[2], bounds[3])
            _shape(xn, yn, t0, t1, t2, area_n, qual_n, ws.shape_tmp)
            bad = qual_n < floor
            k = 0
            while bad.any():
                hit = np.zeros(len(x), dtype=bool)
                b = np.flatnonzero(bad)
                hit[t0[b]] = hit[t1[b]] = hit[t2[b]] = True
                if k < params.max_halvings:
                    dx[hit] *= 0.5
                    dy[hit] *= 0.5
                else:  # give up on these nodes; repeat until no element is left worse
                    n_blocked += int((hit & ((dx != 0.0) | (dy != 0.0))).sum())
                    dx[hit] = 0.0
                    dy[hit] = 0.0
                xh, yh = x[hit] + dx[hit], y[hit] + dy[hit]
                if bounds is not None and k < params.max_halvings:
                    _clip(xh, bounds[0], bounds[1])
                    _clip(yh, bounds[2], bounds[3])
                # given up: the node stays exactly where it was (not clipped: a node outside the
                # bounds, a seam node's partner, would move on every pass and never stop the loop)
                k += 1
                xn[hit], yn[hit] = xh, yh
                # only the elements around the changed nodes need a new shape
                idx = np.flatnonzero(hit[t0] | hit[t1] | hit[t2])
                sub = np.empty((8, len(idx)))
                a_sub, q_sub = _shape(xn, yn, t0[idx], t1[idx], t2[idx], sub[0], sub[1], sub[2:])
                area_n[idx], qual_n[idx] = a_sub, q_sub
                bad = np.zeros(len(bad), dtype=bool)
                bad[idx] = q_sub < floor[idx]
            x, y, xn, yn = xn, yn, x, y
            area, qual, area_n, qual_n = area_n, qual_n, area, qual
        return np.column_stack([x, y]), n_blocked
