"""Planar geometry shared by the mesh, fluid and DEM layers: one kernel for each formula.

All polygons are ``(n, 2)`` float arrays of vertices in counter-clockwise order, without
repeating the first vertex; batches of polygons are ``(P, K, 2)`` arrays padded by
repeating each polygon's first vertex.  Units are whatever the caller uses (one
consistent system, e.g. m or cm); areas come out in length², second moments in length⁴.

The kernels, each vectorised over bodies, points, triangles or polygons:

* rigid transforms of many bodies — :func:`rotate`, :func:`rigid_transform` (body -> world
  ``x = R(θ) ξ + X``) and :func:`to_body_frame` (world -> body ``ξ = R(−θ)(x − X)``), poses
  ``(x, y, θ)``; :func:`transform` is the one-body form;
* orientation and signed areas — :func:`orient2d` (twice the signed area of triangles given
  by their corners), :func:`triangle_areas` (of a triangle mesh), :func:`orient_ccw` (make a
  mesh's triangles counter-clockwise);
* barycentric coordinates of points in triangles — :func:`barycentric`;
* polygons — :func:`polygon_area`, :func:`polygon_centroid`, :func:`polygon_polar_moment`
  (about the origin) and :func:`polygon_area_centroid` (batches of padded polygons, about
  each first vertex so that small polygons far from the origin keep their digits).

Formulas: the shoelace formula for area and centroid, and the polygon second moment
``J = (1/12) Σ (x_i y_{i+1} − x_{i+1} y_i)(x_i² + x_i x_{i+1} + x_{i+1}² + y_i² + y_i y_{i+1} + y_{i+1}²)``
(e.g. Bourke, "Calculating the area and centroid of a polygon", 1988); the orientation
predicate ``(b − a) × (c − a)`` and barycentric coordinates by Cramer's rule on
``p − a = λ₁ (b − a) + λ₂ (c − a)`` (e.g. Ericson, *Real-Time Collision Detection*, 2005,
Sec. 3.4).  The operation order of each kernel is fixed (see each function): callers that
replace a hand-written copy get bit-identical results.

Examples
--------
>>> import numpy as np
>>> from fluidem import geometry as geo
>>> square = geo.rectangle(2.0, 2.0)                         # (4, 2), CCW
>>> poses = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, np.pi / 2]])  # (N, 3): x, y, angle
>>> geo.rigid_transform(np.stack([square, square]), poses)[1].round(12).tolist()
[[11.0, -1.0], [11.0, 1.0], [9.0, 1.0], [9.0, -1.0]]
>>> p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
>>> tri = np.array([[0, 1, 2], [1, 2, 3]])                  # the second one is clockwise
>>> geo.triangle_areas(p, tri).tolist(), geo.orient_ccw(p, tri).tolist()
([0.5, -0.5], [[0, 1, 2], [1, 3, 2]])
>>> geo.barycentric([0.25, 0.25], p[0], p[1], p[2]).tolist()
[0.5, 0.25, 0.25]
"""

from __future__ import annotations

import numpy as np

from . import validate
from .errors import InputError

__all__ = [
    "minimum_image",
    "wrap_into_box",
    "as_polygon",
    "polygon_area",
    "polygon_centroid",
    "polygon_polar_moment",
    "is_convex",
    "regular_polygon",
    "rectangle",
    "ellipse_polygon",
    "rotation_matrix",
    "rotate",
    "rigid_transform",
    "to_body_frame",
    "transform",
    "orient2d",
    "triangle_areas",
    "orient_ccw",
    "barycentric",
    "polygon_area_centroid",
    "point_in_polygon",
    "validate_polygon",
]


def as_polygon(vertices, name: str = "polygon") -> np.ndarray:
    """Return ``vertices`` as a float ``(n, 2)`` array, or raise :class:`~fluidem.errors.InputError`
    (a ``ValueError``) naming ``name``."""
    try:
        v = np.asarray(vertices, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: vertices must be numbers, got {vertices!r}") from exc
    if v.ndim != 2 or v.shape[1] != 2:
        raise InputError(f"{name}: vertices must have shape (n, 2), got shape {v.shape}")
    if v.shape[0] < 3:
        raise InputError(f"{name}: a polygon needs at least 3 vertices, got {v.shape[0]}")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{name}: vertices must be finite, got {v.tolist()}")
    return v


def _cross_terms(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Next vertices ``w`` and shoelace terms ``x_i y_{i+1} − x_{i+1} y_i`` of polygons ``v`` (..., n, 2)."""
    w = np.roll(v, -1, axis=-2)
    return w, v[..., 0] * w[..., 1] - w[..., 0] * v[..., 1]


def polygon_area(vertices):
    """Signed area (positive for counter-clockwise vertices), shoelace formula.

    ``vertices`` (n, 2) gives a float; a padded batch (P, K, 2) gives (P,) areas.
    """
    v = np.asarray(vertices, dtype=float)
    _, c = _cross_terms(v)
    return 0.5 * float(c.sum()) if v.ndim == 2 else 0.5 * c.sum(axis=-1)


def polygon_centroid(vertices) -> np.ndarray:
    """Centroid (centre of mass of a uniform lamina), shape ``(2,)`` (``(P, 2)`` for a padded batch)."""
    v = np.asarray(vertices, dtype=float)
    w, c = _cross_terms(v)
    a = 0.5 * c.sum(axis=-1)
    return ((v + w) * c[..., None]).sum(axis=-2) / (6.0 * a[..., None])


def polygon_area_centroid(vertices) -> tuple[np.ndarray, np.ndarray]:
    """Signed areas and centroids of padded polygons, shoelace about each polygon's first vertex.

    Parameters
    ----------
    vertices : (..., K, 2) float
        Polygons, counter-clockwise for positive areas; rows past a polygon's own vertex
        count repeat its first vertex (they add nothing).

    Returns
    -------
    area : (...) float
        Signed areas, length².
    centroid : (..., 2) float
        Centroids (NaN for zero area).

    Notes
    -----
    Coordinates are taken relative to the first vertex, so a tiny polygon far from the
    origin (a contact overlap) keeps its digits.  This is the overlap geometry of the DEM
    narrow phase (:func:`fluidem.dem.contact.polygon_overlaps`).

    Examples
    --------
    >>> import numpy as np
    >>> sq = rectangle(2.0, 2.0) + 1e6                          # far from the origin
    >>> tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])  # padded to 4 rows
    >>> a, c = polygon_area_centroid(np.stack([sq, tri]))
    >>> a.tolist(), c.round(9).tolist()
    ([4.0, 0.5], [[1000000.0, 1000000.0], [0.333333333, 0.333333333]])
    """
    S = np.asarray(vertices, dtype=float)
    o = S[..., :1, :]
    Q = S - o
    Qn, c = _cross_terms(Q)
    A = 0.5 * c.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cen = ((Q + Qn) * c[..., None]).sum(axis=-2) / (6.0 * A[..., None])
    return A, cen + o[..., 0, :]


def polygon_polar_moment(vertices) -> float:
    """Polar second moment of area about the origin, ∫(x² + y²) dA, for CCW vertices.

    Multiply by the density to get the moment of inertia of a lamina; shift with the
    parallel-axis theorem ``J_c = J_0 − A |c|²`` to get it about the centroid ``c``.
    """
    v = np.asarray(vertices, dtype=float)
    w, c = _cross_terms(v)
    x0, y0, x1, y1 = v[:, 0], v[:, 1], w[:, 0], w[:, 1]
    return float((c * (x0**2 + x0 * x1 + x1**2 + y0**2 + y0 * y1 + y1**2)).sum() / 12.0)


def is_convex(vertices, tol: float = 1e-12) -> bool:
    """True when every turn of the CCW outline is a left turn (collinear within ``tol``)."""
    v = np.asarray(vertices, dtype=float)
    d1 = np.roll(v, -1, axis=0) - v
    d2 = np.roll(d1, -1, axis=0)
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    scale = np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1)
    return bool(np.all(cross >= -tol * scale))


def _segments_intersect_properly(v: np.ndarray) -> bool:
    """True if two non-adjacent edges of the closed outline ``v`` cross (vectorised O(n²))."""
    n = len(v)
    if n < 4:
        return False
    a, b = v, np.roll(v, -1, axis=0)
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # first and last edges share a vertex
    i, j = i[keep], j[keep]

    o1 = orient2d(a[i], b[i], a[j])
    o2 = orient2d(a[i], b[i], b[j])
    o3 = orient2d(a[j], b[j], a[i])
    o4 = orient2d(a[j], b[j], b[i])
    return bool(np.any((o1 * o2 < 0) & (o3 * o4 < 0)))


def validate_polygon(vertices, name: str = "polygon", require_convex: bool = False) -> np.ndarray:
    """Check a body outline and return it as a float array.

    Raises :class:`~fluidem.errors.InputError` (a ``ValueError``; naming ``name`` and the
    offending values) for fewer than three
    vertices, non-finite values, zero area, clockwise order, self-intersection, or — with
    ``require_convex`` — a non-convex outline.
    """
    v = as_polygon(vertices, name)
    area = polygon_area(v)
    scale = np.ptp(v, axis=0).max() ** 2
    if abs(area) <= 1e-14 * max(scale, 1e-300):
        raise InputError(f"{name}: polygon has zero area (vertices {v.tolist()})")
    if area < 0:
        raise InputError(
            f"{name}: vertices are clockwise (signed area {area:.6g}); "
            "give them counter-clockwise"
        )
    if _segments_intersect_properly(v):
        raise InputError(f"{name}: polygon outline intersects itself")
    if require_convex and not is_convex(v):
        raise InputError(f"{name}: polygon is not convex; only convex polygons are allowed here")
    return v


def regular_polygon(radius: float, segments: int, phase: float = 0.0) -> np.ndarray:
    """Regular N-gon inscribed in a circle of ``radius`` centred at the origin, CCW, shape ``(segments, 2)``.

    This is how fluidem represents a disk: ``segments`` straight edges.
    """
    radius = validate.positive("regular_polygon(radius=...)", radius)
    segments = validate.integer("regular_polygon(segments=...)", segments, lo=3)
    t = phase + 2.0 * np.pi * np.arange(segments) / segments
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def rectangle(width: float, height: float) -> np.ndarray:
    """Axis-aligned rectangle centred at the origin, CCW, shape ``(4, 2)``."""
    w = 0.5 * validate.positive("rectangle(width=...)", width)
    h = 0.5 * validate.positive("rectangle(height=...)", height)
    return np.array([[-w, -h], [w, -h], [w, h], [-w, h]], dtype=float)


def ellipse_polygon(a: float, b: float, segments: int) -> np.ndarray:
    """Polygon with ``segments`` vertices on the ellipse with semi-axes ``a`` (x) and ``b`` (y)."""
    a = validate.positive("ellipse_polygon(a=...)", a)
    b = validate.positive("ellipse_polygon(b=...)", b)
    segments = validate.integer("ellipse_polygon(segments=...)", segments, lo=3)
    return regular_polygon(1.0, segments) * np.array([a, b])


def rotation_matrix(angle: float) -> np.ndarray:
    """2×2 counter-clockwise rotation by ``angle`` radians."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def rotate(vectors, angles) -> np.ndarray:
    """Vectors turned counter-clockwise by ``angles`` (rad).

    Parameters
    ----------
    vectors : (..., 2) float
    angles : float or array broadcasting against ``vectors[..., 0]``
        E.g. (N, 1) angles for (N, K, 2) vectors, or (M,) angles for (M, 2) vectors.

    Returns
    -------
    (..., 2) float
        ``(c x − s y, s x + c y)`` with ``c, s = cos, sin(angle)`` (in this operation order).
    """
    v = np.asarray(vectors, dtype=float)
    c, s = np.cos(angles), np.sin(angles)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x - s * y, s * x + c * y], axis=-1)


def _pose_parts(poses, body, ndim):
    """Angles and positions of ``poses`` laid out to broadcast against points of ``ndim`` dims."""
    P = np.asarray(poses, dtype=float)
    if P.shape[-1] != 3:
        raise InputError(f"poses: expected shape (3,) or (N, 3) of (x, y, angle), got shape {P.shape}")
    if body is not None:
        th = P[:, 2]
        b = np.asarray(body)
        return np.cos(th)[b], np.sin(th)[b], P[b, 0], P[b, 1]
    if P.ndim == 1:
        return np.cos(P[2]), np.sin(P[2]), P[0], P[1]
    # (N, 3) poses for (N, K, 2) points: one pose per leading row
    shape = (P.shape[0],) + (1,) * (ndim - 2)
    th = P[:, 2].reshape(shape)
    return np.cos(th), np.sin(th), P[:, 0].reshape(shape), P[:, 1].reshape(shape)


def rigid_transform(local, poses, body=None) -> np.ndarray:
    """Body coordinates -> world coordinates ``x = R(θ) ξ + X`` for many bodies at once.

    Parameters
    ----------
    local : (N, K, 2), (M, 2) or (K, 2) float
        Points in body coordinates: per body (``N`` bodies, ``K`` points each, e.g. padded
        outlines), one body each (with ``body``), or of a single body (with one pose).
    poses : (N, 3) or (3,) float
        ``(x, y, θ)`` per body: position (length) and angle (rad).
    body : (M,) int, optional
        The body of each of the ``M`` points of a ``(M, 2)`` array.

    Returns
    -------
    world : float, shape of ``local``
        ``(c ξ − s η + X, s ξ + c η + Y)`` (in this operation order).

    Examples
    --------
    >>> import numpy as np
    >>> xi = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    >>> poses = np.array([[0.0, 0.0, np.pi / 2], [5.0, 5.0, 0.0]])
    >>> rigid_transform(xi, poses, body=[0, 1, 1]).round(12).tolist()
    [[0.0, 1.0], [6.0, 5.0], [5.0, 7.0]]
    """
    v = np.asarray(local, dtype=float)
    c, s, px, py = _pose_parts(poses, body, v.ndim)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x - s * y + px, s * x + c * y + py], axis=-1)


def to_body_frame(world, poses, body=None) -> np.ndarray:
    """World coordinates -> body coordinates ``ξ = R(−θ) (x − X)``, the inverse of :func:`rigid_transform`.

    Same shapes as :func:`rigid_transform`; computes ``d = x − X`` then
    ``(c d_x + s d_y, −s d_x + c d_y)``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([[0.0, 1.0], [6.0, 5.0]])
    >>> to_body_frame(x, [[0.0, 0.0, np.pi / 2], [5.0, 5.0, 0.0]], body=[0, 1]).round(12).tolist()
    [[1.0, 0.0], [1.0, 0.0]]
    """
    v = np.asarray(world, dtype=float)
    c, s, px, py = _pose_parts(poses, body, v.ndim)
    dx, dy = v[..., 0] - px, v[..., 1] - py
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def transform(vertices, position, angle: float) -> np.ndarray:
    """Body coordinates -> world coordinates of one body: rotate by ``angle`` (rad), then shift by ``position``.

    ``vertices`` (n, 2), ``position`` (2,); the one-body form of :func:`rigid_transform`.
    """
    pos = np.asarray(position, dtype=float)
    return rigid_transform(vertices, (pos[0], pos[1], angle))


def orient2d(a, b, c) -> np.ndarray:
    """Twice the signed area of triangles ``(a, b, c)``: ``(b − a) × (c − a)``.

    Positive when ``a, b, c`` turn counter-clockwise, zero when collinear.

    Parameters
    ----------
    a, b, c : (..., 2) float
        Corners (broadcasting against each other).

    Returns
    -------
    (...) float, length²
        ``(b_x − a_x)(c_y − a_y) − (b_y − a_y)(c_x − a_x)`` (in this operation order).
    """
    a, b, c = (np.asarray(v, dtype=float) for v in (a, b, c))
    ax, ay = a[..., 0], a[..., 1]
    return (b[..., 0] - ax) * (c[..., 1] - ay) - (b[..., 1] - ay) * (c[..., 0] - ax)


def triangle_areas(points, triangles) -> np.ndarray:
    """Signed areas of the triangles of a mesh (positive for counter-clockwise triangles).

    Parameters
    ----------
    points : (n, 2) float
        Node coordinates.
    triangles : (m, 3) int
        Node indices per triangle.

    Returns
    -------
    (m,) float, length²
        ``0.5 ((x₁ − x₀)(y₂ − y₀) − (y₁ − y₀)(x₂ − x₀))`` — the operation order of
        :func:`fluidem.mesh.relax.signed_areas` (whose bit-for-bit relaxation test it keeps);
        gathers from contiguous x and y arrays.
    """
    p = np.asarray(points, dtype=float)
    x, y = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
    t = np.asarray(triangles)
    t0, t1, t2 = (np.ascontiguousarray(t[:, k]) for k in range(3))
    ax, ay = x[t0], y[t0]
    return 0.5 * ((x[t1] - ax) * (y[t2] - ay) - (y[t1] - ay) * (x[t2] - ax))


def orient_ccw(points, triangles) -> np.ndarray:
    """A copy of ``triangles`` (m, 3) with the clockwise ones turned counter-clockwise (vertices 1 and 2 swapped).

    ``points`` (n, 2).  Zero-area triangles are left as they are.
    """
    t = np.array(triangles, copy=True)
    neg = triangle_areas(points, t) < 0
    t[neg] = t[neg][:, [0, 2, 1]]
    return t


def barycentric(points, a, b, c, axis: int = -1) -> np.ndarray:
    """Barycentric coordinates ``λ`` of points in triangles: ``p = λ₀ a + λ₁ b + λ₂ c``, ``Σ λ = 1``.

    Parameters
    ----------
    points, a, b, c : float arrays, broadcasting against each other
        Points and triangle corners, with the two coordinates along ``axis``: ``(..., 2)``
        for the default ``axis=-1``, ``(2, ...)`` with ``axis=0`` (scikit-fem's layout).
    axis : int
        The coordinate axis of the inputs.

    Returns
    -------
    (..., 3) float
        ``λ₀, λ₁, λ₂`` along the last axis; all in [0, 1] inside the triangle.  ``(λ₁, λ₂)``
        are the reference coordinates of the affine map ``a + λ₁ (b − a) + λ₂ (c − a)``.
        By Cramer's rule with ``e₁ = b − a``, ``e₂ = c − a``, ``r = p − a``,
        ``det = e₁ × e₂``: ``λ₁ = (r × e₂)/det``, ``λ₂ = (e₁ × r)/det``,
        ``λ₀ = 1 − λ₁ − λ₂`` (in this operation order).  Degenerate triangles give inf/NaN.

    Examples
    --------
    >>> import numpy as np
    >>> tri = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]])
    >>> barycentric([[0.5, 0.5], [2.0, 2.0]], *tri).tolist()
    [[0.5, 0.25, 0.25], [-1.0, 1.0, 1.0]]
    """
    p, a, b, c = (np.moveaxis(np.asarray(v, dtype=float), axis, 0) for v in (points, a, b, c))
    e1x, e1y = b[0] - a[0], b[1] - a[1]
    e2x, e2y = c[0] - a[0], c[1] - a[1]
    rx, ry = p[0] - a[0], p[1] - a[1]
    det = e1x * e2y - e1y * e2x
    with np.errstate(invalid="ignore", divide="ignore"):
        l1 = (rx * e2y - ry * e2x) / det
        l2 = (e1x * ry - e1y * rx) / det
        return np.stack([1 - l1 - l2, l1, l2], axis=-1)


def point_in_polygon(points, vertices) -> np.ndarray:
    """Boolean mask of ``points`` (m, 2) strictly inside the convex or simple polygon ``vertices``.

    Even–odd ray casting, vectorised over points and edges.
    """
    p = np.atleast_2d(np.asarray(points, dtype=float))
    v = np.asarray(vertices, dtype=float)
    a, b = v, np.roll(v, -1, axis=0)
    px, py = p[:, 0:1], p[:, 1:2]
    ay, by = a[None, :, 1], b[None, :, 1]
    straddle = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xcross = a[None, :, 0] + (py - ay) * (b[None, :, 0] - a[None, :, 0]) / (by - ay)
    hits = straddle & (px < xcross)
    return (hits.sum(axis=1) % 2) == 1


def minimum_image(d, period) -> np.ndarray:
    """Difference vectors ``d (k, 2)`` reduced to their nearest periodic image (length units).

    ``period``: ``(L_x, L_y)`` with ``None`` for a non-periodic axis.
    """
    d = np.array(d, dtype=float)
    for c, L in enumerate(period):
        if L:
            d[:, c] -= L * np.round(d[:, c] / L)
    return d


def wrap_into_box(points, box, period) -> np.ndarray:
    """``points (k, 2)`` wrapped into ``box = (xmin, xmax, ymin, ymax)`` along its periodic axes
    (``period = (L_x, L_y)``, ``None`` for a non-periodic axis), length units.

    Examples
    --------
    >>> wrap_into_box(np.array([[2.3, 0.5], [-0.25, 1.5]]), (0, 2, 0, 1), (2.0, None)).tolist()
    [[0.2999999999999998, 0.5], [1.75, 1.5]]
    """
    p = np.array(points, dtype=float).reshape(-1, 2)
    lo = (box[0], box[2])
    for c, L in enumerate(period):
        if L:
            p[:, c] = lo[c] + np.mod(p[:, c] - lo[c], L)
    return p
