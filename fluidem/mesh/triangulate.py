"""Constrained Delaunay triangulation of a box minus polygonal obstacles (Triangle).

The fluid region is the box with the obstacles cut out.  Outlines enter Triangle as segments
with a hole point inside each obstacle, so nothing is ever triangulated inside a body.  The
box sides and obstacle outlines are subdivided at the local target size; interior triangles
are refined (Triangle's ``r`` + per-triangle area constraints) until every triangle is no
larger than an equilateral triangle of the local size, with Triangle's minimum-angle quality
bound.  Boundary edges carry integer markers from which named boundaries are built.

Curved obstacles (circles) can be returned as quadratic, isoparametric meshes
(:class:`skfem.MeshTri2`): outline edge midpoints are moved onto the circle, so a cylinder is a
cylinder and not a polygon.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import triangle as tr

from ..errors import InputError, MeshError
from ..geometry import orient_ccw, point_in_polygon, polygon_area, triangle_areas, validate_polygon
from .background import as_size_field, subdivide_segment
from .periodic import periodic_axes

__all__ = ["Obstacle", "BoxDomain", "TriangleMesh", "triangulate_box", "graded_background", "to_skfem", "SIDE_NAMES"]

#: boundary names of the box sides, in the order of their markers 1..4
SIDE_NAMES = ("bottom", "right", "top", "left")
_FIRST_OBSTACLE_MARKER = 10


@dataclass(frozen=True)
class BoxDomain:
    """Axis-aligned box ``[xmin, xmax] × [ymin, ymax]``."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float

    def __post_init__(self):
        vals = (self.xmin, self.xmax, self.ymin, self.ymax)
        if not all(np.isfinite(vals)):
            raise InputError(f"domain box must be finite numbers, got {vals}")
        if not (self.xmax > self.xmin and self.ymax > self.ymin):
            raise InputError(
                f"domain box must have xmax > xmin and ymax > ymin, got "
                f"(xmin, xmax, ymin, ymax) = {vals}"
            )

    @classmethod
    def from_any(cls, domain) -> "BoxDomain":
        if isinstance(domain, BoxDomain):
            return domain
        try:
            vals = [float(v) for v in domain]
        except (TypeError, ValueError) as exc:
            raise InputError(f"domain must be (xmin, xmax, ymin, ymax), got {domain!r}") from exc
        if len(vals) != 4:
            raise InputError(f"domain must be (xmin, xmax, ymin, ymax), got {domain!r}")
        return cls(*vals)

    @property
    def corners(self) -> np.ndarray:
        return np.array(
            [[self.xmin, self.ymin], [self.xmax, self.ymin], [self.xmax, self.ymax], [self.xmin, self.ymax]]
        )

    def contains(self, points, strict: bool = True) -> np.ndarray:
        p = np.atleast_2d(points)
        if strict:
            return (p[:, 0] > self.xmin) & (p[:, 0] < self.xmax) & (p[:, 1] > self.ymin) & (p[:, 1] < self.ymax)
        return (p[:, 0] >= self.xmin) & (p[:, 0] <= self.xmax) & (p[:, 1] >= self.ymin) & (p[:, 1] <= self.ymax)


@dataclass(frozen=True)
class Obstacle:
    """A fixed polygonal obstacle in world coordinates.

    Parameters
    ----------
    vertices : (n, 2) float array
        Counter-clockwise outline in world coordinates.
    name : str
        Boundary name given to its outline on the mesh.
    circle : (cx, cy, r) or None
        If the polygon approximates a circle, its centre and radius: used to curve the
        outline in quadratic (isoparametric) meshes.
    refine_outline : bool
        Subdivide outline edges longer than the local target size (keep ``False`` for
        circles, which already have their vertex count chosen).
    """

    vertices: np.ndarray
    name: str
    circle: tuple | None = None
    refine_outline: bool = True

    def __post_init__(self):
        object.__setattr__(self, "vertices", validate_polygon(self.vertices, f"obstacle {self.name!r}"))


@dataclass
class TriangleMesh:
    """Triangle output: ``points (n, 2)``, ``triangles (m, 3)`` (CCW) and named boundary edges."""

    points: np.ndarray
    triangles: np.ndarray
    boundary_edges: dict = field(default_factory=dict)  # name -> (k, 2) vertex index pairs
    circles: dict = field(default_factory=dict)  # name -> (cx, cy, r) for curved outlines

    @property
    def n_points(self) -> int:
        return len(self.points)


def _outline_points(obstacle: Obstacle, size) -> np.ndarray:
    v = obstacle.vertices
    if not obstacle.refine_outline:
        return v
    pieces = [subdivide_segment(v[i], v[(i + 1) % len(v)], size)[:-1] for i in range(len(v))]
    return np.vstack(pieces)


def triangulate_box(domain, obstacles=(), size=0.1, min_angle: float = 30.0, max_refinements: int = 12,
                    periodic=()) -> TriangleMesh:
    """Quality constrained Delaunay triangulation of ``domain`` minus ``obstacles``.

    Parameters
    ----------
    domain : (xmin, xmax, ymin, ymax) or BoxDomain
    obstacles : sequence of :class:`Obstacle`
        Must lie strictly inside the box and must not overlap each other.
    size : float, SizeField or callable ``points (m, 2) -> h (m,)``
        Target edge length field.
    min_angle : float
        Triangle's quality bound on the smallest angle, degrees (≤ 33).
    periodic : sequence of {"x", "y"}
        Periodic axes (:mod:`fluidem.mesh.periodic`): the ``left`` side gets the nodes of the
        ``right`` side translated by the period (``x``), the ``bottom`` side those of the
        ``top`` (``y``), so partner nodes match exactly (Triangle adds no boundary points).

    Returns
    -------
    TriangleMesh
        Boundary edges named ``bottom, right, top, left`` and by obstacle name.
    """
    box = BoxDomain.from_any(domain)
    size = as_size_field(size)
    obstacles = list(obstacles)
    names = [o.name for o in obstacles]
    if len(set(names)) != len(names) or set(names) & set(SIDE_NAMES):
        raise InputError(f"obstacle names must be unique and differ from {SIDE_NAMES}, got {names}")
    for o in obstacles:
        outside = ~box.contains(o.vertices)
        if outside.any():
            raise InputError(
                f"obstacle {o.name!r} is not inside the domain {tuple(box.__dict__.values())}: "
                f"vertex {o.vertices[outside][0].tolist()} lies outside"
            )
    for i, a in enumerate(obstacles):
        for b in obstacles[i + 1:]:
            if point_in_polygon(a.vertices, b.vertices).any() or point_in_polygon(b.vertices, a.vertices).any():
                raise InputError(f"obstacles {a.name!r} and {b.name!r} overlap")

    pts, segs, marks = [], [], []
    offset = 0
    corners = box.corners
    side_pts = []
    for k in range(4):
        side_pts.append(subdivide_segment(corners[k], corners[(k + 1) % 4], size)[:-1])
    axes = periodic_axes(periodic)
    # periodic pairs: side k runs corner k -> k+1 (bottom, right, top, left); the low side of
    # a pair is the high one reversed and translated (without its first point, a corner)
    for lo_k, hi_k, shift in ((3, 1, (box.xmin - box.xmax, 0.0)), (0, 2, (0.0, box.ymin - box.ymax))):
        if ("x" if lo_k == 3 else "y") in axes:
            hi = np.vstack([side_pts[hi_k], corners[(hi_k + 1) % 4]])  # both ends
            side_pts[lo_k] = (hi[::-1] + np.array(shift))[:-1]
            side_pts[lo_k][0] = corners[lo_k]
    ring = np.vstack(side_pts)
    side_mark = np.concatenate([np.full(len(p), k + 1) for k, p in enumerate(side_pts)])
    n = len(ring)
    pts.append(ring)
    segs.append(np.column_stack([np.arange(n), (np.arange(n) + 1) % n]))
    marks.append(side_mark)
    offset = n
    holes = []
    for j, o in enumerate(obstacles):
        ring = _outline_points(o, size)
        n = len(ring)
        pts.append(ring)
        segs.append(offset + np.column_stack([np.arange(n), (np.arange(n) + 1) % n]))
        marks.append(np.full(n, _FIRST_OBSTACLE_MARKER + j))
        holes.append(_interior_point(o.vertices))
        offset += n

    pslg = {
        "vertices": np.vstack(pts),
        "segments": np.vstack(segs).astype(np.int32),
        "segment_markers": np.concatenate(marks).astype(np.int32)[:, None],
    }
    if holes:
        pslg["holes"] = np.array(holes)
    opts = f"pq{min_angle:g}Y"
    mesh = tr.triangulate(pslg, opts)
    for _ in range(max_refinements):
        p, t = mesh["vertices"], mesh["triangles"]
        centroids = p[t].mean(axis=1)
        target = np.sqrt(3.0) / 4.0 * np.asarray(size(centroids)) ** 2
        area = triangle_areas(p, t)
        too_big = area > 1.05 * target
        if not too_big.any():
            break
        mesh["triangle_max_area"] = np.where(too_big, target, -1.0)[:, None]
        mesh = tr.triangulate(mesh, f"rpq{min_angle:g}Ya")

    p, t = mesh["vertices"], mesh["triangles"].astype(np.int64)
    t = orient_ccw(p, t)
    edges = mesh.get("edges")
    if edges is None:
        edges, emarks = _boundary_from_segments(mesh)
    boundary = {}
    all_names = list(SIDE_NAMES) + names
    all_marks = [1, 2, 3, 4] + [_FIRST_OBSTACLE_MARKER + j for j in range(len(obstacles))]
    for name, mk in zip(all_names, all_marks):
        boundary[name] = edges[emarks == mk]
    circles = {o.name: tuple(o.circle) for o in obstacles if o.circle is not None}
    return TriangleMesh(points=p, triangles=t, boundary_edges=boundary, circles=circles)


def _boundary_from_segments(mesh):
    segs = mesh["segments"].astype(np.int64)
    marks = mesh["segment_markers"].ravel()
    return segs, marks


def _interior_point(v: np.ndarray) -> np.ndarray:
    """A point strictly inside a simple polygon (centroid of an ear triangle if needed)."""
    c = v.mean(axis=0)
    if point_in_polygon(c[None], v)[0]:
        return c
    n = len(v)
    for i in range(n):  # runs once per obstacle, at set-up only
        tri = v[[i - 1, i, (i + 1) % n]]
        if polygon_area(tri) > 0:
            c = tri.mean(axis=0)
            if point_in_polygon(c[None], v)[0]:
                return c
    raise InputError("could not find an interior point of the obstacle")


def to_skfem(tmesh: TriangleMesh, curved: bool = False):
    """Convert to a scikit-fem mesh with named boundaries.

    Parameters
    ----------
    tmesh : TriangleMesh
    curved : bool
        Return a quadratic :class:`skfem.MeshTri2` whose outline edges of circular obstacles
        follow the circle (isoparametric geometry); otherwise a straight-sided
        :class:`skfem.MeshTri`.

    Returns
    -------
    skfem.MeshTri or skfem.MeshTri2
        ``mesh.boundaries[name]`` are facet indices for every side and obstacle.
    """
    from skfem import MeshTri, MeshTri2

    m = MeshTri(tmesh.points.T.copy(), tmesh.triangles.T.copy())
    facet_lookup = _facet_lookup(m)
    boundaries = {name: facet_lookup(edges) for name, edges in tmesh.boundary_edges.items()}
    if curved and tmesh.circles:
        M = MeshTri2.from_mesh(m)
        doflocs = M.doflocs.copy()
        nv = m.nvertices
        for name, (cx, cy, r) in tmesh.circles.items():
            f = boundaries[name]
            d = doflocs[:, nv + f] - np.array([[cx], [cy]])
            doflocs[:, nv + f] = np.array([[cx], [cy]]) + r * d / np.linalg.norm(d, axis=0)
        M = MeshTri2(doflocs, M.t)  # re-created so cached geometry is consistent
        return M.with_boundaries(boundaries)
    return m.with_boundaries(boundaries)


def _facet_lookup(m):
    """Map vertex-index pairs to scikit-fem facet indices (vectorised through a sorted key)."""
    f = np.sort(m.facets, axis=0)
    nv = m.nvertices
    keys = f[0].astype(np.int64) * nv + f[1]
    order = np.argsort(keys)
    sorted_keys = keys[order]

    def lookup(edges):
        e = np.sort(np.asarray(edges, dtype=np.int64), axis=1)
        k = e[:, 0] * nv + e[:, 1]
        pos = np.searchsorted(sorted_keys, k)
        beyond = np.any(pos >= len(sorted_keys))
        if len(k) and (beyond or np.any(sorted_keys[np.minimum(pos, len(sorted_keys) - 1)] != k)):
            raise MeshError("boundary edge not found among mesh facets")
        return order[pos].astype(np.int32)

    return lookup


def graded_background(domain, size, min_angle: float = 30.0, periodic=()) -> np.ndarray:
    """Background nodes of a box graded by a size field (paper Sec. 2.3, Fig. 3).

    A quality Delaunay refinement (Triangle) of the empty box with triangles no larger
    than an equilateral triangle of the local size; only the nodes are returned.

    Parameters
    ----------
    domain : (xmin, xmax, ymin, ymax)
    size : float, SizeField or callable ``points (m, 2) -> h (m,)``
    min_angle : float
        Triangle's minimum-angle bound, degrees.
    periodic : sequence of {"x", "y"}
        Periodic axes: the nodes of the paired sides match (:mod:`fluidem.mesh.periodic`).
        The Friedrichs–Keller grid matches them by construction.

    Returns
    -------
    points : (n_nodes, 2) float
    """
    return triangulate_box(domain, (), size=size, min_angle=min_angle, periodic=periodic).points
