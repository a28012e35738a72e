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

from dataclasses import dataclass

import numpy as np

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
            raise ValueError(f"relaxation step τ² must be in (0, 0.3], got {self.step!r}")
        if not (0.0 <= self.target_weight <= 1.0):
            raise ValueError(f"target_weight must be in [0, 1], got {self.target_weight!r}")
        if not (np.isfinite(self.area_weight) and self.area_weight >= 0):
            raise ValueError(f"area_weight must be a number >= 0, got {self.area_weight!r}")
        if int(self.max_halvings) != self.max_halvings or self.max_halvings < 0:
            raise ValueError(f"max_halvings must be an integer >= 0, got {self.max_halvings!r}")


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
        c = np.ascontiguousarray
        object.__setattr__(self, "t0", c(self.triangles[:, 0]))
        object.__setattr__(self, "t1", c(self.triangles[:, 1]))
        object.__setattr__(self, "t2", c(self.triangles[:, 2]))
        object.__setattr__(self, "tcat", c(self.triangles.T.ravel()))
        object.__setattr__(self, "e0", c(self.edges[:, 0]))
        object.__setattr__(self, "e1", c(self.edges[:, 1]))
        object.__setattr__(self, "et0", c(self.edge_tris[:, 0]))
        object.__setattr__(self, "et1", c(self.edge_tris[:, 1]))
        ie = self.edge_tris[self.interior]
        object.__setattr__(self, "ie0", c(ie[:, 0]))
        object.__setattr__(self, "ie1", c(ie[:, 1]))


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


def signed_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Signed areas ``(n_triangles,)`` (positive for counter-clockwise triangles), units²."""
    x, y = np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])
    t = np.asarray(triangles)
    return _areas(x, y, np.ascontiguousarray(t[:, 0]), np.ascontiguousarray(t[:, 1]), np.ascontiguousarray(t[:, 2]))


def _areas(x, y, t0, t1, t2):
    ax, ay = x[t0], y[t0]
    return 0.5 * ((x[t1] - ax) * (y[t2] - ay) - (y[t1] - ay) * (x[t2] - ax))


def _areas_z(z, t0, t1, t2):
    """Signed areas from complex positions ``z = x + i y`` (one gather per vertex)."""
    za = z[t0]
    u = z[t1] - za
    v = z[t2] - za
    return 0.5 * (u.real * v.imag - u.imag * v.real)


def _shape_z(z, t0, t1, t2):
    """Signed areas and shape quality ``q = 4√3 A / (l1² + l2² + l3²)`` (1 equilateral, ≤ 0 inverted)."""
    za = z[t0]
    u = z[t1] - za
    v = z[t2] - za
    area = 0.5 * (u.real * v.imag - u.imag * v.real)
    w = v - u
    l2 = u.real * u.real + u.imag * u.imag + v.real * v.real + v.imag * v.imag + w.real * w.real + w.imag * w.imag
    return area, (4.0 * _SQRT3) * area / np.maximum(l2, 1e-300)


def _own_size_power(a_pos, beta):
    """``s_own^(1−β)`` with ``s_own = sqrt(4 A / √3)``; square-root chains for common β."""
    q = a_pos * (4.0 / _SQRT3)
    if beta == 0.5:
        return np.sqrt(np.sqrt(q))
    if beta == 0.75:
        return np.sqrt(np.sqrt(np.sqrt(q)))
    if beta == 0.0:
        return np.sqrt(q)
    return q ** (0.5 * (1.0 - beta))


def _forces(z, area, topo: MeshTopology, h_beta, params: RelaxParams):
    """Spring + area-force (eq. 3) accelerations, complex ``(n,)`` in length units.

    ``area`` are the current signed triangle areas, ``h_beta`` is ``h_T^β`` per triangle
    (fixed while the target sizes are).  The grow/shrink force of eq. 3 acts "on all edges
    uniformly" (paper Sec. 2.2): every edge of triangle ``T`` is pushed apart by
    ``κ g_T`` (pulled together if ``g_T < 0``), edges shared by two triangles get the mean.
    """
    n = len(z)
    a_pos = np.maximum(area, 0.0)
    beta = params.target_weight
    if beta == 1.0:
        s_t = h_beta
    else:
        s_t = _own_size_power(a_pos, beta)
        if beta != 0.0:
            s_t *= h_beta
    et0, et1 = topo.et0, topo.et1
    rest = s_t[et0]
    rest += s_t[et1]
    if params.area_weight > 0.0:
        # eq. 3: g_T = Σ_i sgn(A_i − A_T) sqrt|A_i − A_T| over edge neighbours
        diff = a_pos[topo.ie1] - a_pos[topo.ie0]
        g = np.sqrt(np.abs(diff))
        np.copysign(g, diff, out=g)
        m = len(area)
        g_t = np.bincount(topo.ie0, g, m)
        g_t -= np.bincount(topo.ie1, g, m)
        rest += params.area_weight * (g_t[et0] + g_t[et1])
    rest *= 0.5
    e0, e1 = topo.e0, topo.e1
    dz = z[e1] - z[e0]
    length = np.abs(dz)
    k = 1.0 - rest / np.maximum(length, 1e-300)  # > 0: stretched, pull together
    fx = k * dz.real
    fy = k * dz.imag
    ax = np.bincount(e0, fx, n)
    ax -= np.bincount(e1, fx, n)
    ay = np.bincount(e0, fy, n)
    ay -= np.bincount(e1, fy, n)
    return ax, ay


def relax(points, topo: MeshTopology, h_node, mobility, n_iter: int = 1, params: RelaxParams = RelaxParams(),
          bounds=None, damping=None) -> tuple[np.ndarray, int]:
    """Run ``n_iter`` relaxation sweeps (eq. 2 without ``v_n``, plus eq. 3).

    Parameters
    ----------
    points : (n_nodes, 2) float
        Node positions, length units; not modified.
    topo : MeshTopology
        From :func:`mesh_topology`; triangles counter-clockwise.
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
    z = points[:, 0] + 1j * points[:, 1]
    mob = np.asarray(mobility, dtype=float)
    mx, my = mob[:, 0] * params.step, mob[:, 1] * params.step
    if damping is not None:
        mx, my = mx * damping, my * damping
    h = np.asarray(h_node, dtype=float)
    t0, t1, t2 = topo.t0, topo.t1, topo.t2
    h_t = (h[t0] + h[t1] + h[t2]) / 3.0
    beta = params.target_weight
    h_beta = h_t if beta == 1.0 else h_t**beta
    tcat = topo.tcat
    n_blocked = 0
    area, qual = _shape_z(z, t0, t1, t2)
    for _ in range(int(n_iter)):
        ax, ay = _forces(z, area, topo, h_beta, params)
        dz = mx * ax + 1j * (my * ay)
        # no move may bring an element below the shape floor (or worsen one already below)
        # (elements already below the floor may lose at most 0.1 % of their quality per sweep:
        # round-off must not block every move next to them)
        floor = np.where(qual < params.min_quality, np.where(qual > 0, 0.999 * qual, qual), params.min_quality)
        zn = z + dz
        if bounds is not None:
            zn = np.clip(zn.real, bounds[0], bounds[1]) + 1j * np.clip(zn.imag, bounds[2], bounds[3])
        area_n, qual_n = _shape_z(zn, t0, t1, t2)
        bad = qual_n < floor
        k = 0
        while bad.any():
            hit = np.zeros(len(z), dtype=bool)
            hit[tcat[np.tile(bad, 3)]] = True
            if k < params.max_halvings:
                dz[hit] *= 0.5
            else:  # give up on these nodes; repeat until no element is left worse
                n_blocked += int((hit & (dz != 0.0)).sum())
                dz[hit] = 0.0
            k += 1
            zh = z[hit] + dz[hit]
            if bounds is not None:
                zh = np.clip(zh.real, bounds[0], bounds[1]) + 1j * np.clip(zh.imag, bounds[2], bounds[3])
            zn[hit] = zh
            # only the elements around the changed nodes need a new shape
            idx = np.flatnonzero(hit[t0] | hit[t1] | hit[t2])
            a_sub, q_sub = _shape_z(zn, t0[idx], t1[idx], t2[idx])
            area_n[idx], qual_n[idx] = a_sub, q_sub
            bad = np.zeros(len(bad), dtype=bool)
            bad[idx] = q_sub < floor[idx]
        z, area, qual = zn, area_n, qual_n
    return np.column_stack([z.real, z.imag]), n_blocked
