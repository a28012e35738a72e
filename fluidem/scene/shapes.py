"""Shapes of :func:`fluidem.scene.fill.fill`: names, outlines of equal area, their radii.

A body of *equal-area radius* r has the area π r² whatever its shape: a rectangle of aspect
ratio α is r √(π/α) by α r √(π/α), a regular n-gon has the circumradius
r √(2π / (n sin(2π/n))).

Examples
--------
>>> from fluidem.scene.shapes import shape_outline, bounding_factor
>>> shape_outline("square", 1.0).round(4).tolist()[0]
[-0.8862, -0.8862]
>>> round(bounding_factor("triangle", 2.0), 4)
1.5551
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..validate import fail

__all__ = ["SHAPES", "shape_outline", "bounding_factor", "inradius", "check_shape", "disk_area_factor"]

#: shape names :func:`fluidem.scene.fill.fill` takes, and what each is; also ``"<N>-gon"`` for a
#: regular N-gon, 3 <= N <= 64
SHAPES = {
    "disk": "circle (the curved outline of a fluid scene; the inscribed regular polygon with `segments`)",
    "rectangle": "rectangle of aspect ratio `aspect` (width / height)",
    "square": "square",
    "triangle": "equilateral triangle",
    "pentagon": "regular pentagon",
    "hexagon": "regular hexagon",
    "octagon": "regular octagon",
}
_NGON = {"triangle": 3, "pentagon": 5, "hexagon": 6, "octagon": 8}
_NGON_RE = re.compile(r"^(\d+)-gon$")
_MAX_NGON = 64


def _ngon_sides(name: str) -> int | None:
    """Sides of a regular polygon named ``name`` (``"hexagon"``, ``"7-gon"``), or None."""
    if name in _NGON:
        return _NGON[name]
    m = _NGON_RE.match(name)
    return int(m.group(1)) if m else None


def check_shape(name, key: str) -> str:
    """``name`` if it is a shape of :data:`SHAPES` or ``"<N>-gon"`` (3 <= N <= 64); otherwise an
    :class:`~fluidem.errors.InputError` naming ``key``, the value and the allowed shapes."""
    if isinstance(name, str) and name in SHAPES:
        return name
    n = _ngon_sides(name) if isinstance(name, str) else None
    if n is not None and 3 <= n <= _MAX_NGON:
        return name
    allowed = ", ".join(repr(s) for s in SHAPES)
    raise fail(key, name, f"one of {allowed} or '<N>-gon' with N from 3 to {_MAX_NGON}")


def shape_outline(name: str, radius: float, aspect: float = 2.0) -> np.ndarray:
    """The outline of a body of shape ``name`` and equal-area radius ``radius``, unrotated.

    Parameters
    ----------
    name : str
        A polygonal name of :data:`SHAPES` (not ``"disk"``) or ``"<N>-gon"``.
    radius : float
        Equal-area radius r, length: the outline's area is π r².
    aspect : float
        Width / height of a ``"rectangle"``.

    Returns
    -------
    (n, 2) float
        Vertices counter-clockwise, centroid at the origin, length.

    Examples
    --------
    >>> from fluidem.geometry import polygon_area
    >>> import math
    >>> v = shape_outline("hexagon", 0.1)
    >>> v.shape, abs(float(polygon_area(v)) / (math.pi * 0.01) - 1) < 1e-12
    ((6, 2), True)
    """
    if name in ("rectangle", "square"):
        a = aspect if name == "rectangle" else 1.0
        h = radius * math.sqrt(math.pi / a)
        w, h = 0.5 * a * h, 0.5 * h
        return np.array([[-w, -h], [w, -h], [w, h], [-w, h]])
    n = _ngon_sides(name)
    R = radius * math.sqrt(2.0 * math.pi / (n * math.sin(2.0 * math.pi / n)))
    t = 2.0 * math.pi * np.arange(n) / n
    return R * np.column_stack([np.cos(t), np.sin(t)])


def inradius(v: np.ndarray) -> float:
    """Distance from the origin (inside) to the nearest edge line of the convex polygon ``v`` (n, 2),
    length: the radius of the largest disk about the origin inside it."""
    e = np.roll(v, -1, axis=0) - v
    cross = v[:, 0] * e[:, 1] - v[:, 1] * e[:, 0]
    return float((cross / np.hypot(e[:, 0], e[:, 1])).min())


def bounding_factor(name: str, aspect: float) -> float:
    """Bounding radius over equal-area radius of the shape ``name`` (1 for a disk); ``aspect`` is a
    rectangle's width / height."""
    if name == "disk":
        return 1.0
    return float(np.hypot(*shape_outline(name, 1.0, aspect).T).max())


def disk_area_factor(weights: dict, segments) -> float:
    """Mean area of a drawn body over π r² for the shape probabilities ``weights`` (name -> p):
    disks with ``segments`` are the inscribed polygon, every other shape has exactly π r²."""
    f = 1.0 if segments is None else 0.5 * segments * math.sin(2.0 * math.pi / segments) / math.pi
    return sum(w * (f if s == "disk" else 1.0) for s, w in weights.items())
