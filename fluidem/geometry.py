"""Planar polygon geometry shared by the mesh and DEM layers.

All polygons are ``(n, 2)`` float arrays of vertices in counter-clockwise order, without
repeating the first vertex.  Units are whatever the caller uses (metres or centimetres);
areas come out in units², second moments in units⁴.

Formulas: the shoelace formula for area and centroid, and the polygon second moment
``J = (1/12) Σ (x_i y_{i+1} − x_{i+1} y_i)(x_i² + x_i x_{i+1} + x_{i+1}² + y_i² + y_i y_{i+1} + y_{i+1}²)``
(e.g. Bourke, "Calculating the area and centroid of a polygon", 1988).
"""

from __future__ import annotations

import numpy as np

from . import validate
from .errors import InputError

__all__ = [
    "as_polygon",
    "polygon_area",
    "polygon_centroid",
    "polygon_polar_moment",
    "is_convex",
    "regular_polygon",
    "rectangle",
    "ellipse_polygon",
    "rotation_matrix",
    "transform",
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
    w = np.roll(v, -1, axis=0)
    return w, v[:, 0] * w[:, 1] - w[:, 0] * v[:, 1]


def polygon_area(vertices) -> float:
    """Signed area (positive for counter-clockwise vertices), shoelace formula."""
    v = np.asarray(vertices, dtype=float)
    _, c = _cross_terms(v)
    return 0.5 * float(c.sum())


def polygon_centroid(vertices) -> np.ndarray:
    """Centroid (centre of mass of a uniform lamina), shape ``(2,)``."""
    v = np.asarray(vertices, dtype=float)
    w, c = _cross_terms(v)
    a = 0.5 * c.sum()
    return ((v + w) * c[:, None]).sum(axis=0) / (6.0 * a)


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

    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    o1 = orient(a[i], b[i], a[j])
    o2 = orient(a[i], b[i], b[j])
    o3 = orient(a[j], b[j], a[i])
    o4 = orient(a[j], b[j], b[i])
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


def transform(vertices, position, angle: float) -> np.ndarray:
    """Body coordinates -> world coordinates: rotate by ``angle`` (rad), then shift by ``position``."""
    v = np.asarray(vertices, dtype=float)
    return v @ rotation_matrix(angle).T + np.asarray(position, dtype=float)


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
