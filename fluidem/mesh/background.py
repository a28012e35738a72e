"""Target mesh size fields: uniform, and graded away from obstacles (paper Sec. 2.3, Fig. 3).

A size field maps points ``(m, 2)`` to a target edge length ``(m,)`` (same length unit as the
coordinates).  The graded field grows linearly with the distance ``d`` from the region of
interest, ``h(d) = min(h_max, h_min + (growth − 1) d)``, so that neighbouring cells differ in
size by about the factor ``growth`` (a geometric progression of cell sizes away from the
obstacle).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import shapely

from ..errors import InputError

__all__ = ["SizeField", "UniformSize", "GradedSize", "as_size_field", "size_from_grading", "friedrichs_keller_grid"]


class SizeField:
    """Base class: ``field(points) -> h`` with ``points`` of shape ``(m, 2)``, returns ``(m,)``."""

    h_min: float

    def __call__(self, points: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


@dataclass(frozen=True)
class UniformSize(SizeField):
    """The same target edge length ``h`` everywhere."""

    h: float

    def __post_init__(self):
        if not (np.isfinite(self.h) and self.h > 0):
            raise InputError(f"mesh size h must be a positive number, got {self.h!r}")

    @property
    def h_min(self) -> float:
        return float(self.h)

    def __call__(self, points):
        return np.full(np.asarray(points).shape[0], float(self.h))


@dataclass(frozen=True)
class GradedSize(SizeField):
    """Fine near a region of interest, coarser with distance (paper Sec. 2.3).

    Parameters
    ----------
    h_min : float
        Edge length on and inside the region of interest.
    growth : float
        Size ratio between neighbouring cells away from the region, > 1 (1.1–1.3 typical).
    h_max : float
        Cap on the edge length far away.
    region : sequence of (n_i, 2) arrays, or a rectangle ``(xmin, xmax, ymin, ymax)``
        Polygons (e.g. obstacle outlines) or a box; the distance is measured to them.
    """

    h_min: float
    growth: float
    h_max: float
    region: object

    def __post_init__(self):
        if not (np.isfinite(self.h_min) and self.h_min > 0):
            raise InputError(f"h_min must be a positive number, got {self.h_min!r}")
        if not (np.isfinite(self.growth) and self.growth >= 1.0):
            raise InputError(f"growth must be a number >= 1, got {self.growth!r}")
        if not (np.isfinite(self.h_max) and self.h_max >= self.h_min):
            raise InputError(f"h_max must be >= h_min = {self.h_min}, got {self.h_max!r}")
        object.__setattr__(self, "_geom", _region_geometry(self.region))

    def __call__(self, points):
        p = np.asarray(points, dtype=float)
        d = shapely.distance(self._geom, shapely.points(p))
        return np.minimum(self.h_max, self.h_min + (self.growth - 1.0) * d)


def _region_geometry(region):
    if isinstance(region, (tuple, list)) and len(region) == 4 and np.isscalar(region[0]):
        x0, x1, y0, y1 = map(float, region)
        return shapely.box(x0, y0, x1, y1)
    polys = [shapely.Polygon(np.asarray(r, dtype=float)) for r in region]
    return shapely.union_all(polys)


def as_size_field(h: float | SizeField | Callable) -> SizeField | Callable:
    """Accept a number (uniform size), a :class:`SizeField`, or a callable ``points -> h``."""
    if isinstance(h, SizeField) or callable(h):
        return h
    return UniformSize(float(h))


def size_from_grading(grading, h: float) -> tuple[SizeField | Callable, float, bool]:
    """The size field of a moving mesh's ``grading`` (:class:`~fluidem.mesh.moving.MovingMesh`)
    at target size ``h``: ``(field, growth, graded)``, ``growth`` the factor per cell of the zone
    the bodies tow (1 without grading).

    ``None``: uniform ``h``; a dict ``{"region", "growth" (1.2), "h_max" (8 h)}``: a
    :class:`GradedSize`; a :class:`UniformSize`; a :class:`SizeField` or a callable, used as is
    (its ``growth`` attribute, if any, else 1.2).

    Examples
    --------
    >>> f, growth, graded = size_from_grading({"region": (0, 1, 0, 1), "growth": 1.1}, 0.1)
    >>> type(f).__name__, growth, graded
    ('GradedSize', 1.1, True)
    """
    if grading is None:
        return UniformSize(h), 1.0, False
    if isinstance(grading, dict):
        allowed = {"region", "growth", "h_max"}
        bad = set(grading) - allowed
        if bad or "region" not in grading:
            raise InputError(f"grading dict needs 'region' and may have 'growth', 'h_max'; "
                             f"got keys {sorted(grading)}")
        growth = float(grading.get("growth", 1.2))
        h_max = float(grading.get("h_max", 8 * h))
        return GradedSize(h, growth, h_max, grading["region"]), growth, True
    if isinstance(grading, UniformSize):
        return grading, 1.0, False
    if isinstance(grading, SizeField) or callable(grading):
        growth = float(getattr(grading, "growth", 1.2))
        return grading, growth, True
    raise InputError(f"grading = {grading!r}: expected None, a dict, a SizeField or a callable")


def subdivide_segment(a: Sequence[float], b: Sequence[float], size, min_pieces: int = 1) -> np.ndarray:
    """Points from ``a`` to ``b`` (inclusive) spaced by the size field along the segment.

    The number of pieces is ``ceil(∫ ds / h(s))`` and the points are placed at equal
    increments of that integral, so spacing follows ``h`` along the segment.
    Returns an array of shape ``(k + 1, 2)``.
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    s = np.linspace(0.0, 1.0, 201)
    pts = a + s[:, None] * (b - a)
    length = np.linalg.norm(b - a)
    inv_h = 1.0 / np.asarray(size(pts), dtype=float)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (inv_h[1:] + inv_h[:-1]) * np.diff(s) * length)])
    n = max(min_pieces, int(np.ceil(cum[-1] - 1e-9)))
    targets = np.linspace(0.0, cum[-1], n + 1)
    st = np.interp(targets, cum, s)
    return a + st[:, None] * (b - a)


def friedrichs_keller_grid(domain, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Friedrichs–Keller grid of a box (paper Sec. 2.1, Fig. 2b): square cells of side ≈ ``h``.

    Every square is split along the same diagonal (lower left to upper right), so all
    interior nodes have the same connectivity.  The spacing is adjusted per axis so that the
    box is filled exactly.

    Parameters
    ----------
    domain : (xmin, xmax, ymin, ymax)
        Box, length units.
    h : float
        Target spacing, length units, > 0.

    Returns
    -------
    points : (n_nodes, 2) float
    triangles : (n_triangles, 3) int
        Counter-clockwise.
    """
    xmin, xmax, ymin, ymax = (float(v) for v in domain)
    if not (np.isfinite(h) and h > 0):
        raise InputError(f"mesh size h must be a positive number, got {h!r}")
    if not (xmax > xmin and ymax > ymin):
        raise InputError(f"domain must have xmax > xmin and ymax > ymin, got {tuple(domain)!r}")
    nx = max(1, int(round((xmax - xmin) / h)))
    ny = max(1, int(round((ymax - ymin) / h)))
    x = np.linspace(xmin, xmax, nx + 1)
    y = np.linspace(ymin, ymax, ny + 1)
    X, Y = np.meshgrid(x, y)  # (ny + 1, nx + 1)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    a = (j * (nx + 1) + i).ravel()
    b, c, d = a + 1, a + nx + 2, a + nx + 1
    tris = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return pts, tris
