"""The fluid fields at the points the VTU output holds: the mesh vertices
(:func:`fluid_point_data`) or the barycentric lattice that represents the element's own
basis (:func:`full_order_fields`).  Units: those of the scene (see :mod:`fluidem.io`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["fluid_point_data", "full_order_fields", "FULL_ORDER_DIVISIONS"]


def fluid_point_data(space, x: np.ndarray, rho: float = 1.0) -> dict[str, np.ndarray]:
    """Velocity, speed and pressure at the mesh vertices, for VTU output.

    Velocity: the vertex DOFs (all element pairs here have nodal vertex values).  Pressure:
    the pressure basis evaluated at each element's vertices, averaged over the elements
    around a vertex (exact for a continuous pressure).

    Parameters
    ----------
    space : fluidem.fluid.space.FlowSpace
        Velocity/pressure spaces on the mesh (``n_u`` velocity DOFs first, then pressure).
    x : (space.n_dofs,) float
        Velocity (length/time) and kinematic pressure (p/ρ, length²/time²) DOFs.
    rho : float
        Fluid density (mass/length² in 2D): ``pressure`` is ρ times the kinematic one, the
        convention of the loads in history.csv.

    Returns
    -------
    dict
        ``"velocity"`` (n_vertices, 3) length/time with a zero z column, ``"speed"``
        (n_vertices,) length/time, ``"pressure"`` (n_vertices,) dynamic pressure (ρ p/ρ) and
        ``"kinematic_pressure"`` (n_vertices,) length²/time².
    """
    mesh = space.mesh
    nv = mesh.nvertices
    u = x[: space.n_u]
    nd = space.ub.nodal_dofs
    vel = np.zeros((nv, 3))
    vel[:, 0], vel[:, 1] = u[nd[0]], u[nd[1]]
    pb = space.pb
    Xref = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    Phi = np.array([pb.elem.lbasis(Xref, i)[0] for i in range(pb.Nbfun)])  # (Nbfun, 3)
    P = x[space.n_u:][pb.element_dofs]  # (Nbfun, n_elements)
    pv = Phi.T @ P  # (3, n_elements): value at local vertex k of each element
    t = mesh.t
    s = np.bincount(t.ravel(), pv.ravel(), minlength=nv)
    c = np.bincount(t.ravel(), minlength=nv)
    p = s / np.maximum(c, 1)
    return {"velocity": vel, "speed": np.hypot(vel[:, 0], vel[:, 1]), "pressure": rho * p, "kinematic_pressure": p}


#: subdivision of each triangle for the full-order output: 2 (quadratic "triangle6" cells) for a
#: P2 velocity with a P1 pressure, 3 (nine linear sub-triangles, nodes at the points i/3 of the
#: barycentric lattice) for cubic velocity spaces (P3, P2 + cubic bubble, P1 + cubic bubble)
FULL_ORDER_DIVISIONS = {"th": 2, "p3": 3, "p2b": 3, "mini": 3}


def _lattice(r: int):
    """Reference points (2, n_loc) of the barycentric lattice of order ``r`` on the triangle
    (0,0), (1,0), (0,1), their ``(a, b)`` indices (x = a/r, y = b/r) and the linear
    sub-triangles (r², 3) as local point indices, counter-clockwise."""
    ab = [(a, b) for b in range(r + 1) for a in range(r + 1 - b)]
    index = {q: k for k, q in enumerate(ab)}
    sub = [(index[a, b], index[a + 1, b], index[a, b + 1]) for (a, b) in ab if a + b <= r - 1]
    sub += [(index[a + 1, b], index[a + 1, b + 1], index[a, b + 1]) for (a, b) in ab if a + b <= r - 2]
    ab = np.array(ab)
    return ab.T / r, ab, np.array(sub)


def _lattice_numbering(t: np.ndarray, nv: int, ab: np.ndarray, r: int) -> np.ndarray:
    """Global indices (n_elements, n_loc) of the lattice points of every triangle ``t`` (3, m),
    shared between neighbours: a vertex point is its vertex, an edge point is numbered by the
    edge and its distance from the edge's lower-numbered vertex, interior points per element."""
    m = t.shape[1]
    a, b = ab[:, 0], ab[:, 1]
    c = r - a - b
    ids = np.empty((m, len(ab)), dtype=np.int64)
    corner = {(0, 0): 0, (r, 0): 1, (0, r): 2}
    for k, (ak, bk) in enumerate(ab):
        if (ak, bk) in corner:
            ids[:, k] = t[corner[ak, bk]]
    # edges: local (0,1) where b = 0, (1,2) where c = 0, (2,0) where a = 0; position from the first vertex
    local_edges = ((0, 1, (b == 0) & (a > 0) & (a < r), a), (1, 2, (c == 0) & (b > 0) & (b < r), b),
                   (2, 0, (a == 0) & (c > 0) & (c < r), c))
    pairs = np.concatenate([np.sort(t[[i, j]], axis=0) for i, j, _, _ in local_edges], axis=1)  # (2, 3m)
    _, edge_id = np.unique(pairs, axis=1, return_inverse=True)
    edge_id = edge_id.reshape(3, m)
    for e, (i, j, on, pos) in enumerate(local_edges):
        ks = np.flatnonzero(on)
        s = np.where((t[i] < t[j])[:, None], pos[ks][None, :], r - pos[ks][None, :])  # (m, len(ks))
        ids[:, ks] = nv + edge_id[e][:, None] * (r - 1) + (s - 1)
    inner = np.flatnonzero((a > 0) & (b > 0) & (c > 0))
    n_edges = int(edge_id.max()) + 1
    ids[:, inner] = nv + n_edges * (r - 1) + np.arange(m)[:, None] * len(inner) + np.arange(len(inner))[None, :]
    return ids


def _values_at(basis, coeffs: np.ndarray, X: np.ndarray) -> np.ndarray:
    """A finite element function (coefficients ``coeffs`` of ``basis``) at the reference points
    ``X`` (2, n_loc) of every element: (n_elements, n_loc) for a scalar field, (2, n_elements,
    n_loc) for a vector one (scikit-fem's global basis, so edge orientations are respected)."""
    C = coeffs[basis.element_dofs]  # (Nbfun, n_elements)
    out = 0.0
    for i in range(basis.Nbfun):  # a loop over the local basis functions (<= 20), not over elements
        out = out + np.asarray(basis.elem.gbasis(basis.mapping, X, i)[0]) * C[i][:, None]
    return np.asarray(out)


def full_order_fields(space, x: np.ndarray, rho: float = 1.0):
    """Velocity and pressure at full resolution, for VTU output.

    Every triangle is split by the barycentric lattice of order ``r`` =
    :data:`FULL_ORDER_DIVISIONS` of the element pair, and the fields are evaluated with the
    element's own basis at the lattice points (mapped by the element map, curved
    elements included).  P2/P1 (``r = 2``) gives one quadratic VTK ``triangle6`` cell per
    triangle: velocity and pressure are represented *exactly* (a P1 pressure is linear on
    it).  Cubic velocity spaces (``r = 3``) give nine linear triangles per triangle whose
    nodes carry the exact point values (the field between them is linear).  Lattice points
    shared by neighbouring triangles are written once; a discontinuous pressure (P2+bubble
    pair) is averaged over the triangles around a shared point.

    Parameters
    ----------
    space : fluidem.fluid.space.FlowSpace
    x : (space.n_dofs,) float
        Velocity (length/time) and kinematic pressure (length²/time²) DOFs.
    rho : float
        Fluid density: ``pressure`` is ρ times the kinematic one (see :func:`fluid_point_data`).

    Returns
    -------
    points : (n, 3) float
        Lattice points (length), z = 0.
    cells : list of (str, (k, q) int)
        ``[("triangle6", (m, 6))]`` or ``[("triangle", (9 m, 3))]``, counter-clockwise.
    point_data : dict
        ``velocity`` (n, 3), ``speed`` (n,), ``pressure`` (n,) dynamic and
        ``kinematic_pressure`` (n,), as in :func:`fluid_point_data`.
    cell_data : dict
        ``element``: index of the mesh triangle each cell belongs to.

    Examples
    --------
    >>> import numpy as np
    >>> from skfem import MeshTri
    >>> from fluidem.fluid.space import FlowSpace
    >>> space = FlowSpace(MeshTri(), "th")  # two triangles on the unit square
    >>> x = np.zeros(space.n_dofs)
    >>> x[:space.n_u] = space.ub.project(lambda X: np.array([X[0] ** 2, X[0] * X[1]]))
    >>> points, cells, pd, cd = full_order_fields(space, x)
    >>> cells[0][0], cells[0][1].shape, points.shape
    ('triangle6', (2, 6), (9, 3))
    >>> bool(np.allclose(pd["velocity"][:, 0], points[:, 0] ** 2))  # exact at the midpoints too
    True
    """
    mesh = space.mesh
    r = FULL_ORDER_DIVISIONS[space.element]
    X, ab, sub = _lattice(r)
    t = mesh.t
    nv = mesh.nvertices
    ids = _lattice_numbering(t, nv, ab, r)
    used, inv = np.unique(ids, return_inverse=True)
    loc = inv.reshape(ids.shape)  # (m, n_loc) compact point indices
    n = len(used)
    xy = np.asarray(space.ub.mapping.F(X))  # (2, m, n_loc)
    pts = np.zeros((n, 2))
    pts[loc.ravel()] = xy.reshape(2, -1).T
    U = _values_at(space.ub, x[: space.n_u], X)  # (2, m, n_loc)
    vel = np.zeros((n, 3))
    vel[loc.ravel(), 0], vel[loc.ravel(), 1] = U[0].ravel(), U[1].ravel()
    P = _values_at(space.pb, x[space.n_u:], X)  # (m, n_loc)
    p = np.bincount(loc.ravel(), P.ravel(), minlength=n) / np.maximum(np.bincount(loc.ravel(), minlength=n), 1)
    pc = mesh.p[:, t]  # (2, 3, m) corners
    cw = ((pc[0, 1] - pc[0, 0]) * (pc[1, 2] - pc[1, 0]) - (pc[1, 1] - pc[1, 0]) * (pc[0, 2] - pc[0, 0])) < 0
    if r == 2:  # VTK triangle6: corners 0, 1, 2, then the midpoints of edges 01, 12, 20
        k = {tuple(q): i for i, q in enumerate(ab)}
        order = np.array([k[0, 0], k[2, 0], k[0, 2], k[1, 0], k[1, 1], k[0, 1]])
        flip = np.array([k[0, 0], k[0, 2], k[2, 0], k[0, 1], k[1, 1], k[1, 0]])
        conn = np.where(cw[:, None], loc[:, flip], loc[:, order])
        cells, element = [("triangle6", conn)], np.arange(len(conn))
    else:
        tri = loc[:, sub]  # (m, r², 3)
        tri = np.where(cw[:, None, None], tri[:, :, ::-1], tri)
        cells, element = [("triangle", tri.reshape(-1, 3))], np.repeat(np.arange(t.shape[1]), len(sub))
    pd = {"velocity": vel, "speed": np.hypot(vel[:, 0], vel[:, 1]), "pressure": rho * p, "kinematic_pressure": p}
    return _points3(pts), cells, pd, {"element": [element.astype(float)]}


def _points3(p2):
    p2 = np.asarray(p2, dtype=float)
    return np.column_stack([p2, np.zeros(len(p2))])
