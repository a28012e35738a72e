"""Field transfer from an old mesh to a new one at re-triangulation (paper Sec. 3.3).

While the connectivity is unchanged, fields stay attached to the moving nodes (ALE) and no
transfer happens.  At a re-triangulation the fields are carried over in one of two ways:

:func:`interpolate`
    The new degrees of freedom are the old finite element function evaluated at the new
    DOF locations (nodal DOFs); interior bubble DOFs (P2+bubble, MINI), which are not point
    values, are set so that the new function matches the old one at the element centroid.
    Cheap and local; every transfer adds interpolation noise (Sec. 3.3, Fig. 5).
:func:`project_l2`
    The L2 projection ``M_new u_new = M_mixed u_old`` with the mixed mass matrix integrated
    exactly on the *supermesh* (the intersections of old and new triangles,
    :func:`supermesh`), so ``∫ u`` is conserved whenever constants are in the new space and
    both meshes cover the same region (parts of the new mesh outside the old one take the
    interpolated field) (use it where conservation matters: e.g. the
    discontinuous pressure or a concentration).  The supermesh is built with shapely 2
    vectorised intersections and fan-triangulated; its quadrature comes from
    :func:`skfem.supermeshing.elementwise_quadrature`.

:func:`move_with_nodes`
    A few nodes moved without a change of connectivity (the repair of
    :mod:`fluidem.mesh.repair`): the DOFs of the elements around them are interpolated from
    the mesh before the move, the rest keep their values.

Both take scikit-fem bases (any scalar element, or :class:`skfem.ElementVector` of one)
and work for the fluid element pairs (P2+bubble / P1-discontinuous, Taylor–Hood, P3/P2,
MINI).  Points of the new mesh outside the old one (regions a body has left) take the value
at the nearest point of the old mesh.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

__all__ = ["locate", "locate_clustered", "locate_near", "locate_all", "probe_matrix", "basis_values_matrix",
           "values_at", "interpolate", "supermesh", "project_l2", "elements_around", "submesh",
           "move_with_nodes"]


def _candidates(mesh, x, k: int):
    """Nearest-centroid candidate triangles (n, k) of points ``x`` (2, n) and their reference coordinates."""
    p, t = mesh.p, mesh.t
    c = p[:, t[:3]].mean(axis=1).T
    k = min(k, t.shape[1])
    _, cand = cKDTree(c).query(np.asarray(x).T, k=k)
    cand = cand.reshape(len(cand), -1)
    return (cand, *_reference_coordinates(mesh, x, cand))


def _reference_coordinates(mesh, x, cand):
    """Reference coordinates ``l1, l2`` (n, k) of points ``x`` (2, n) in their candidate triangles ``cand`` (n, k),
    or (n, m, k) of clusters of points ``x`` (2, n, m) whose points share their cluster's candidates."""
    p, t = mesh.p, mesh.t
    a, b, d = p[:, t[0, cand]], p[:, t[1, cand]], p[:, t[2, cand]]  # (2, n, k)
    x = np.asarray(x)
    if x.ndim == 3:  # each cluster's cells broadcast over its points
        a, b, d = a[:, :, None, :], b[:, :, None, :], d[:, :, None, :]
    e1, e2 = b - a, d - a
    r = x[..., None] - a
    det = e1[0] * e2[1] - e1[1] * e2[0]
    with np.errstate(divide="ignore", invalid="ignore"):  # a collapsed cell scores -inf below
        l1 = (r[0] * e2[1] - r[1] * e2[0]) / det
        l2 = (e1[0] * r[1] - e1[1] * r[0]) / det
    return l1, l2


def _best_candidate(mesh, x, k: int):
    """The candidate triangle of largest smallest barycentric coordinate per point: cells, bary (n, 3), score."""
    return _best_of(*_candidates(mesh, x, k))


def _best_of(cand, l1, l2):
    """:func:`_best_candidate` of candidates ``cand`` (n, k) with reference coordinates ``l1``, ``l2`` (n, k)."""
    with np.errstate(invalid="ignore"):
        l0 = 1 - l1 - l2
        score = np.minimum(np.minimum(l0, l1), l2)  # (n, k): ≥ 0 inside
    score = np.where(np.isfinite(score), score, -np.inf)
    j = np.argmax(score, axis=1)
    n = np.arange(len(j))
    bary = np.stack([l0[n, j], l1[n, j], l2[n, j]], axis=-1)
    return cand[n, j], bary, score[n, j]


def locate(mesh, x, k: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Triangle containing each point and its barycentric coordinates.

    Parameters
    ----------
    mesh : skfem.MeshTri
    x : (2, n) float
        Points, length units.
    k : int
        Candidate triangles per point (nearest centroids).  The 4 nearest are tried first
        and the ``k`` nearest only for points none of them contains (a third of the work
        for points inside the mesh).

    Returns
    -------
    cells : (n,) int
    bary : (n, 3) float
        Barycentric coordinates, clamped into the triangle for points outside the mesh
        (nearest point of the chosen nearby triangle).
    """
    x = np.asarray(x, dtype=float)
    k0 = min(4, k)
    cells, bary, score = _best_candidate(mesh, x, k0)
    if k > k0:
        miss = np.flatnonzero(score < -1e-12)
        if len(miss):
            cells[miss], bary[miss], _ = _best_candidate(mesh, x[:, miss], k)
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    return cells, bary


def locate_clustered(mesh, x, k: int = 8, chunk: int = 1 << 18) -> tuple[np.ndarray, np.ndarray]:
    """:func:`locate` for points that come in small clusters, e.g. the quadrature points of each element of
    another mesh.

    Every point tries the ``k`` cells whose centroids are nearest its cluster's mean (one tree search a
    cluster, not a point), with the arithmetic of :func:`locate`; the points none of them contains go to
    :func:`locate`.  The 12 quadrature points of each of 124 000 elements (1.5M points): 0.9 s against
    1.8–4.2 s for :func:`locate`, whose tree search was most of its time.

    Parameters
    ----------
    mesh : skfem.MeshTri
    x : (2, n, m) float
        ``n`` clusters of ``m`` points, length units.
    k : int
        Candidate cells per cluster.
    chunk : int
        Points handled at once (bounds the temporary arrays, about ``chunk · k`` entries each).

    Returns
    -------
    cells : (n · m,) int
    bary : (n · m, 3) float
        As :func:`locate`, points in the order of ``x.reshape(2, -1)``.
    """
    x = np.asarray(x, dtype=float)
    _, n, m = x.shape
    p, t = mesh.p, mesh.t
    tree = cKDTree(p[:, t[:3]].mean(axis=1).T)
    k = min(k, t.shape[1])
    cells = np.zeros(n * m, dtype=np.int64)
    bary = np.zeros((n * m, 3))
    score = np.zeros(n * m)
    step = max(chunk // max(m, 1), 1)
    for start in range(0, n, step):
        xs = x[:, start:start + step]
        c = xs.shape[1]
        _, cand = tree.query(xs.mean(axis=2).T, k=k)
        cand = cand.reshape(c, -1)
        l1, l2 = (v.reshape(c * m, -1) for v in _reference_coordinates(mesh, xs, cand))
        rows = slice(start * m, (start + c) * m)
        cells[rows], bary[rows], score[rows] = _best_of(np.repeat(cand, m, axis=0), l1, l2)
    miss = np.flatnonzero(score < -1e-12)
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    if len(miss):
        cells[miss], bary[miss] = locate(mesh, x.reshape(2, -1)[:, miss])
    return cells, bary


def locate_near(mesh, x, hint, k: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """:func:`locate`, trying first the cells around a vertex near each point.

    ``hint (n,)`` int: a vertex of ``mesh`` close to each point (after a re-triangulation,
    the old position of a node that survived it), ``-1`` for none.  A point inside (or on)
    one of the cells around its hint vertex gets that cell, chosen and computed as
    :func:`locate` would; the others (no hint, or moved out of the star) go to
    :func:`locate`.  Returns ``cells (n,)`` and ``bary (n, 3)`` as :func:`locate`.
    """
    x = np.asarray(x, dtype=float)
    hint = np.asarray(hint, dtype=np.int64)
    p, t = mesh.p, mesh.t
    n, m = x.shape[1], t.shape[1]
    cells = np.zeros(n, dtype=np.int64)
    bary = np.zeros((n, 3))
    done = np.zeros(n, dtype=bool)
    pts = np.flatnonzero(hint >= 0)
    if len(pts) and m:
        # the cells around every vertex, padded to the largest star: (len(pts), w)
        tv = t[:3].ravel()
        order = np.argsort(tv, kind="stable")
        vert_sorted, cell_of = tv[order], order % m
        lo = np.searchsorted(vert_sorted, hint[pts], side="left")
        cnt = np.searchsorted(vert_sorted, hint[pts], side="right") - lo
        w = int(cnt.max())
        col = np.arange(w)
        valid = col[None, :] < cnt[:, None]
        cand = cell_of[np.minimum(lo[:, None] + col[None, :], len(cell_of) - 1)]
        # the reference coordinates as in _candidates (same operations, same values)
        a, b, d = p[:, t[0, cand]], p[:, t[1, cand]], p[:, t[2, cand]]  # (2, len(pts), w)
        e1, e2 = b - a, d - a
        r = x[:, pts, None] - a
        det = e1[0] * e2[1] - e1[1] * e2[0]
        with np.errstate(divide="ignore", invalid="ignore"):  # a collapsed cell (a dragged seam node on its inner node)
            l1 = (r[0] * e2[1] - r[1] * e2[0]) / det
            l2 = (e1[0] * r[1] - e1[1] * r[0]) / det
            l0 = 1 - l1 - l2
            score = np.minimum(np.minimum(l0, l1), l2)
        score = np.where(valid & np.isfinite(score), score, -np.inf)
        j = np.argmax(score, axis=1)  # largest smallest coordinate, the first of equals
        i = np.arange(len(pts))
        ok = score[i, j] >= -1e-12
        sel, i, j = pts[ok], i[ok], j[ok]
        cells[sel] = cand[i, j]
        bb = np.clip(np.stack([l0[i, j], l1[i, j], l2[i, j]], axis=-1), 0.0, None)
        bary[sel] = bb / bb.sum(axis=1, keepdims=True)
        done[sel] = True
    rest = np.flatnonzero(~done)
    if len(rest):
        cells[rest], bary[rest] = locate(mesh, x[:, rest], k=k)
    return cells, bary


def locate_all(mesh, x, k: int = 12, tol: float = 1e-9):
    """Every cell containing each point (a vertex lies in several): for probes of discontinuous fields.

    Parameters
    ----------
    mesh : skfem.MeshTri or skfem.MeshTri2
        On a curved (quadratic) mesh the reference coordinates are refined by the inverse
        isoparametric map (scikit-fem's Newton iteration), also for points between a
        curved edge and its chord.
    x : (2, n) float
    k : int
        Candidate cells per point (nearest centroids).
    tol : float
        Tolerance on the reference coordinates for "inside".

    Returns
    -------
    cells : (m,) int
    refs : (2, m) float
        Reference coordinates in each cell.
    owner : (m,) int
        The point of each entry.

    Raises
    ------
    ValueError
        A point outside the mesh.
    """
    from skfem import MeshTri2

    pts = np.asarray(x, dtype=float).T
    cand, X, Y = _candidates(mesh, x, k)
    owner = np.repeat(np.arange(len(pts)), cand.shape[1])
    cc, X, Y = cand.ravel(), X.ravel(), Y.ravel()
    inside = (X >= -tol) & (Y >= -tol) & (X + Y <= 1 + tol)
    missing = np.setdiff1d(np.arange(len(pts)), owner[inside])
    curved = isinstance(mesh, MeshTri2)
    if len(missing) and curved:
        # a point between a curved edge and its chord: invert the isoparametric map of the
        # candidates and keep those that map back onto it
        sel = np.flatnonzero(np.isin(owner, missing))
        mapping = mesh._mapping()
        Xr = mapping.invF(pts[owner[sel]].T[:, :, None], tind=cc[sel], newton_max_iters=100, newton_tol=1e-13)
        back = mapping.F(Xr, tind=cc[sel])[:, :, 0]
        ok = np.linalg.norm(back - pts[owner[sel]].T, axis=0) < 1e-10 * max(1.0, np.abs(pts).max())
        X[sel[ok]], Y[sel[ok]] = Xr[0, ok, 0], Xr[1, ok, 0]
        inside[sel[ok]] = True
        missing = np.setdiff1d(np.arange(len(pts)), owner[inside])
    if len(missing):
        raise ValueError(f"point(s) {pts[missing].tolist()} lie outside the fluid mesh")
    cells, owner = cc[inside], owner[inside]
    refs = np.vstack([np.clip(X[inside], 0, 1), np.clip(Y[inside], 0, 1)])
    if curved:  # interior cells of a quadratic mesh may still be curved: refine every point
        refs = mesh._mapping().invF(pts[owner].T[:, :, None], tind=cells)[:, :, 0]
    return cells, refs, owner


def probe_matrix(basis, x):
    """Sparse matrix ``P`` with ``P @ u`` = values of the finite element function ``u`` at ``x`` (2, n).

    Like :meth:`skfem.CellBasis.probes`, with :func:`locate` (robust for points just outside
    the mesh).  For vector bases the rows are component-major: ``(comp · n)``.
    """
    x = np.asarray(x, dtype=float)
    cells, bary = locate(basis.mesh, x)
    return _probe_from_location(basis, x.shape[1], cells, bary)


def _probe_from_location(basis, n, cells, bary):
    """The probe matrix of ``n`` points in ``cells`` at barycentric coordinates ``bary`` (n, 3)."""
    return basis_values_matrix(basis, cells, np.stack([bary[:, 1], bary[:, 2]]), np.arange(n), n)


def basis_values_matrix(basis, cells, refs, owner, n_points: int, divisor=None, point_major: bool = False):
    """Sparse matrix of basis function values at points given by cell and reference coordinates.

    The one probe-matrix builder of the package (:func:`probe_matrix`, field transfer,
    :meth:`fluidem.fluid.space.FlowSpace.probe_matrix`).

    Parameters
    ----------
    basis : skfem.CellBasis
        Scalar or vector basis.
    cells : (m,) int
    refs : (2, m) float
        Reference coordinates of each entry in its cell.
    owner : (m,) int
        Row point of each entry (several entries of one point are summed).
    n_points : int
    divisor : (m,) float, optional
        Each entry's values are divided by it (e.g. the number of cells of its point, to
        average a discontinuous field).
    point_major : bool
        Rows ``point · comp + c`` instead of ``c · n_points + point``.

    Returns
    -------
    P : (comp · n_points, basis.N) CSR
    """
    comp = int(np.prod(basis._base_tensor_order))
    m = len(cells)
    phis = np.array([np.asarray(basis.elem.gbasis(basis.mapping, refs[:, :, None], i, tind=cells)[0]).reshape(comp, m)
                     for i in range(basis.Nbfun)])  # (Nbfun, comp, m)
    if divisor is not None:
        phis = phis / divisor
    c = np.arange(comp)[:, None]
    rows = owner[None, :] * comp + c if point_major else c * n_points + owner[None, :]
    rows = np.broadcast_to(rows, phis.shape)
    cols = np.broadcast_to(basis.element_dofs[:, None, cells], phis.shape)
    return coo_matrix((phis.ravel(), (rows.ravel().astype(np.int64), cols.ravel())),
                      shape=(comp * n_points, basis.N)).tocsr()


def values_at(basis, u: np.ndarray, x: np.ndarray, location: tuple | None = None) -> np.ndarray:
    """Values of the finite element function ``u`` (``basis.N``,) at the points ``x`` (2, n): ``probe_matrix(basis,
    x) @ u`` (the same sums, in another order) without the matrix.

    The scalar basis functions are evaluated once per point and summed with the coefficients of the point's
    cell; the probe matrix of a vector basis would hold every scalar value once per component, and its
    assembly (sorting ``2 · 14`` entries a point for P2+bubble) costs several times the evaluation: at the
    16 quadrature points of every element of a mesh the size of a 1 000-polygon one (2.9M points) it was
    about half the time of :func:`fluidem.coupling.moving_flow.transfer_change`.

    Parameters
    ----------
    basis : skfem.CellBasis
        A scalar basis or an :class:`skfem.ElementVector` of one.
    u : (basis.N,) or (basis.N, k) float
        One function, or ``k`` at once.
    x : (2, n) float
        Points inside (or just outside, :func:`locate`) the mesh, length.
    location : (cells, bary), optional
        ``locate(basis.mesh, x)`` if already known.

    Returns
    -------
    (comp, n) or (comp, n, k) float
        ``comp`` = 1 for a scalar basis, 2 for a vector one.

    Examples
    --------
    A linear field on P2 is reproduced exactly:

    >>> from skfem import Basis, ElementTriP2, MeshTri
    >>> b = Basis(MeshTri().refined(2), ElementTriP2())
    >>> u = b.project(lambda x: 1.0 + 2.0 * x[0] - x[1])
    >>> values_at(b, u, np.array([[0.3, 0.8], [0.6, 0.1]])).round(12)
    array([[1. , 2.5]])
    """
    from skfem import ElementVector

    cells, bary = locate(basis.mesh, np.asarray(x, dtype=float)) if location is None else location
    refs = np.stack([bary[:, 1], bary[:, 2]])[:, :, None]
    elem = basis.elem
    scalar, comp = (elem.elem, elem.dim) if isinstance(elem, ElementVector) else (elem, 1)
    n_scalar = basis.Nbfun // comp
    phis = np.array([np.asarray(scalar.gbasis(basis.mapping, refs, s, tind=cells)[0]).reshape(-1)
                     for s in range(n_scalar)])  # (n_scalar, n)
    dofs = basis.element_dofs[:, cells]  # (Nbfun, n): function i = comp · s + c (skfem's ElementVector order)
    u = np.asarray(u, dtype=float)
    phis = phis.reshape(phis.shape + (1,) * (u.ndim - 1))
    return np.stack([(phis * u[dofs[c::comp]]).sum(axis=0) for c in range(comp)])


def _interpolate_scalar(basis_old, u_old, basis_new, probes=None) -> np.ndarray:
    """Scalar interpolation of ``u_old`` (N_old,) or (N_old, k); ``probes`` caches point sets -> cells, bary."""
    probes = {} if probes is None else probes
    locs = basis_new.doflocs
    nodal = np.all(np.isfinite(locs), axis=0)
    u = np.zeros((basis_new.N,) + u_old.shape[1:])

    def values_at(basis, x, key):
        if key not in probes:  # one point search per point set, shared by components and fields
            probes[key] = locate(basis.mesh, x)
        return _probe_from_location(basis, x.shape[1], *probes[key])

    u[nodal] = values_at(basis_old, locs[:, nodal], ("old-dofs", int(nodal.sum()))) @ u_old
    if not nodal.all():
        # interior (bubble) DOFs: match the old function at the element centroid
        m = basis_new.mesh
        cen = m.p[:, m.t].mean(axis=1)
        target = values_at(basis_old, cen, "old-centroids") @ u_old
        P = probe_matrix(basis_new, cen).tocsc()
        bub = np.flatnonzero(~nodal)
        rest = P @ u  # bubble coefficients still zero
        Pb = P[:, bub].tocoo()
        coef = np.zeros((len(bub),) + u_old.shape[1:])
        d = Pb.data.reshape((-1,) + (1,) * (u_old.ndim - 1))
        coef[Pb.col] = (target[Pb.row] - rest[Pb.row]) / d
        u[bub] = coef
    return u


def interpolate(basis_old, u_old, basis_new) -> np.ndarray:
    """Interpolate the finite element function ``u_old`` (on ``basis_old``) into ``basis_new``.

    Parameters
    ----------
    basis_old, basis_new : skfem.CellBasis
        Same element type on the old and the new mesh (scalar or ElementVector).
    u_old : (basis_old.N,) or (basis_old.N, k) float
        One field, or ``k`` fields at once (one point search for all of them).

    Returns
    -------
    u_new : (basis_new.N,) or (basis_new.N, k) float
    """
    u_old = np.asarray(u_old, dtype=float)
    probes = {}  # the components of a vector basis share their DOF locations
    if int(np.prod(basis_new._base_tensor_order)) == 1:
        return _interpolate_scalar(basis_old, u_old, basis_new, probes)
    u = np.zeros((basis_new.N,) + u_old.shape[1:])
    for (bo, io), (bn, inew) in zip(zip(basis_old.split_bases(), basis_old.split_indices()),
                                    zip(basis_new.split_bases(), basis_new.split_indices())):
        u[inew] = _interpolate_scalar(bo, u_old[io], bn, probes)
    return u


def elements_around(triangles: np.ndarray, nodes: np.ndarray, rings: int = 1) -> np.ndarray:
    """Indices of the elements of ``triangles`` (m, 3) within ``rings`` node rings of ``nodes`` (k,):
    ``rings = 1`` the elements that have one of ``nodes`` as a vertex, each further ring adds the
    elements touching the vertices of the last.

    >>> elements_around(np.array([[0, 1, 2], [1, 3, 2], [3, 4, 2]]), np.array([0]), rings=2).tolist()
    [0, 1, 2]
    """
    triangles = np.asarray(triangles)
    mark = np.zeros(int(triangles.max(initial=-1)) + 1, dtype=bool)
    mark[np.asarray(nodes, dtype=np.int64)] = True
    for _ in range(rings - 1):
        mark[triangles[mark[triangles].any(axis=1)]] = True
    return np.flatnonzero(mark[triangles].any(axis=1))


def submesh(points: np.ndarray, triangles: np.ndarray):
    """A :class:`skfem.MeshTri` of ``triangles`` (m, 3) on ``points`` (n, 2), and its nodes (k,) in
    the whole mesh's numbering: renumbered in increasing order, so each element keeps the vertex
    order (and local DOFs) it has in the whole mesh."""
    from skfem import MeshTri

    nodes, local = np.unique(triangles, return_inverse=True)
    return MeshTri(np.asarray(points, float)[nodes].T.copy(), local.reshape(triangles.shape).T.copy()), nodes


def move_with_nodes(element, element_dofs: np.ndarray, triangles: np.ndarray, x_before: np.ndarray,
                    x_after: np.ndarray, moved: np.ndarray, fields: np.ndarray, rings: int = 3) -> np.ndarray:
    """Fields after a few nodes moved without a change of connectivity: the finite element
    functions on the mesh before the move, evaluated at the DOFs of the elements around the moved
    nodes (:func:`interpolate` on a patch), so the move is a transfer, not mesh motion.

    Parameters
    ----------
    element : skfem.Element
        The element of ``fields`` (e.g. ``ElementVector(ElementTriP2())``).
    element_dofs : (n_local, m) int
        Global DOFs of every element of the whole mesh (``Basis.element_dofs``), the numbering
        of ``fields``.
    triangles : (m, 3) int
        The connectivity, the same before and after.
    x_before, x_after : (n, 2) float
        Node positions before and after the move (length).
    moved : (k,) int
        The nodes that moved; every other row of ``x_before`` and ``x_after`` is equal.
    fields : (N,) or (N, j) float
        Finite element functions on the mesh before the move.
    rings : int
        Node rings around ``moved`` searched for the new DOF locations (a node moves by a
        fraction of the local mesh size).

    Returns
    -------
    (N,) or (N, j) float
        The functions on the mesh after the move: DOFs of elements not touching a moved node
        unchanged.

    Examples
    --------
    A quadratic field on P2 is reproduced where a node moved:

    >>> from skfem import Basis, ElementTriP2, MeshTri
    >>> m = MeshTri().refined(2)
    >>> b = Basis(m, ElementTriP2())
    >>> u = b.project(lambda x: x[0] ** 2 - x[0] * x[1])
    >>> x0 = m.p.T.copy(); x1 = x0.copy(); k = 12; x1[k] += [0.03, -0.02]
    >>> v = move_with_nodes(ElementTriP2(), b.element_dofs, m.t.T, x0, x1, np.array([k]), u)
    >>> b1 = Basis(MeshTri(x1.T, m.t), ElementTriP2())
    >>> bool(np.allclose(v, b1.project(lambda x: x[0] ** 2 - x[0] * x[1])))
    True
    """
    from skfem import Basis

    triangles = np.asarray(triangles)
    fields = np.asarray(fields, dtype=float)
    near = elements_around(triangles, moved, 1)  # the elements whose DOFs move
    patch = elements_around(triangles, moved, rings)  # where the moved DOFs are found
    old = Basis(submesh(x_before, triangles[patch])[0], element)
    new = Basis(submesh(x_after, triangles[near])[0], element)
    f_old = np.zeros((old.N,) + fields.shape[1:])
    f_old[old.element_dofs] = fields[element_dofs[:, patch]]
    out = fields.copy()
    out[element_dofs[:, near]] = interpolate(old, f_old, new)[new.element_dofs]
    return out


def supermesh(mesh_a, mesh_b, rel_tol: float = 1e-12):
    """Intersections of the triangles of two meshes, as a triangle mesh.

    Parameters
    ----------
    mesh_a, mesh_b : skfem.MeshTri

    Returns
    -------
    sm : skfem.MeshTri
        Triangles of the common refinement (fan triangulation of each convex intersection).
    ia, ib : (n_sm,) int
        The triangle of ``mesh_a`` and of ``mesh_b`` that each supermesh triangle lies in.
    """
    from skfem import MeshTri

    pa = shapely.polygons(mesh_a.p[:, mesh_a.t].transpose(2, 1, 0))
    pb = shapely.polygons(mesh_b.p[:, mesh_b.t].transpose(2, 1, 0))
    ib, ia = shapely.STRtree(pa).query(pb, predicate="intersects")
    inter = shapely.intersection(pb[ib], pa[ia])
    area_scale = shapely.area(pb[ib])
    ok = (shapely.get_type_id(inter) == 3) & (shapely.area(inter) > rel_tol * area_scale)
    inter, ia, ib = inter[ok], ia[ok], ib[ok]
    coords, idx = shapely.get_coordinates(shapely.get_exterior_ring(inter), return_index=True)
    counts = np.bincount(idx, minlength=len(inter))  # closed rings: k + 1 coordinates
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    nv = counts - 1
    ntri = nv - 2
    owner = np.repeat(np.arange(len(inter)), ntri)
    j = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri)  # 0 .. ntri-1 per polygon
    v0 = start[owner]
    tri = np.column_stack([v0, v0 + j + 1, v0 + j + 2])
    p = coords
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    sa = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri[sa < 0] = tri[sa < 0][:, [0, 2, 1]]
    keep = np.abs(sa) > 0
    tri, owner = tri[keep], owner[keep]
    return MeshTri(p.T.copy(), tri.T.copy()), ia[owner], ib[owner]


def project_l2(basis_old, u_old, basis_new, intorder: int | None = None, sm=None) -> np.ndarray:
    """Conservative L2 projection of ``u_old`` into ``basis_new`` on the supermesh.

    Parameters
    ----------
    basis_old, basis_new : skfem.CellBasis
        Scalar or vector bases on the old and the new mesh.
    u_old : (basis_old.N,) float
    intorder : int or None
        Quadrature order on supermesh triangles (default: twice the larger element degree).
    sm : tuple or None
        A precomputed ``supermesh(old_mesh, new_mesh)``.

    Returns
    -------
    u_new : (basis_new.N,) float
    """
    from skfem import BilinearForm, CellBasis
    from skfem.helpers import dot
    from skfem.supermeshing import elementwise_quadrature

    m_old, m_new = basis_old.mesh, basis_new.mesh
    smesh, i_old, i_new = supermesh(m_old, m_new) if sm is None else sm
    if intorder is None:
        intorder = 2 * max(basis_old.elem.maxdeg, basis_new.elem.maxdeg)
    b_old = CellBasis(m_old, basis_old.elem, quadrature=elementwise_quadrature(m_old, smesh, i_old, intorder),
                      elements=i_old)
    b_new = CellBasis(m_new, basis_new.elem, quadrature=elementwise_quadrature(m_new, smesh, i_new, intorder),
                      elements=i_new)

    @BilinearForm
    def mass(u, v, w):
        return dot(u, v) if len(u.shape) > 2 else u * v

    u_old = np.asarray(u_old, dtype=float)
    rhs = mass.assemble(b_old, b_new) @ u_old  # rows: new test functions
    M = mass.assemble(CellBasis(m_new, basis_new.elem, intorder=intorder))
    # parts of the new mesh outside the old one (a body moved away, a contact notch changed)
    # take the interpolated field: ∫ g φ = ∫_covered u_old φ + ∫_uncovered I(u_old) φ
    M_cov = mass.assemble(b_new)
    uncovered = M - M_cov
    if abs(uncovered).max() > 1e-12 * abs(M).max():
        rhs = rhs + uncovered @ interpolate(basis_old, u_old, basis_new)
    return spsolve(M.tocsc(), rhs)
