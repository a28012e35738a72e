"""When the dragged mesh is re-triangulated (paper Sec. 4.2), checked in this order after each step:

``"inverted"``
    an element has area <= 0 (the old mesh at the new positions is invalid);
``"degenerate"``
    an element shrank below ``degenerate_area`` of its area at the last triangulation
    (typically a narrow-gap element whose anchor passes a corner);
``"contact"``
    bodies came within ``min_gap`` of each other, or a contact changed
    (:func:`contacts_changed`);
``"periodic"``
    ``retriangulate_every`` steps since the last triangulation;
``"quality"``
    an element outside narrow gaps degraded by a margin past the angle bounds, or past its
    own angles after the last triangulation if it was born outside them (hysteresis: an
    element born near a bound does not fire; :func:`quality_dropped`, thresholds from
    :func:`quality_baseline`).

Everything per step works on angle cosines (:func:`element_shape`): no ``arccos``.

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.relax import mesh_topology
>>> from fluidem.mesh.triggers import element_shape
>>> pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
>>> s = element_shape(pts, mesh_topology(np.array([[0, 1, 2]])))
>>> (np.round([s.cos_max[0], s.cos_min[0], s.area[0]], 6) + 0.0).tolist()   # 45°, 90°, ½
[0.707107, 0.0, 0.5]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

__all__ = ["ElementShape", "QualityBaseline", "element_shape", "quality_baseline", "quality_dropped",
           "outside_opened_gap_bounds", "past_thresholds", "fired_elements", "contacts_changed",
           "retriangulation_reason"]


@dataclass(frozen=True)
class ElementShape:
    """Per element: the largest and smallest cosine of its angles and its signed area.

    Attributes
    ----------
    cos_max, cos_min : (n_triangles,) float
        Cosine of the smallest and of the largest angle.
    area : (n_triangles,) float
        Signed area (positive for counter-clockwise), length units².
    """

    cos_max: np.ndarray
    cos_min: np.ndarray
    area: np.ndarray


@dataclass(frozen=True)
class QualityBaseline:
    """Per-element thresholds of the quality trigger, set after each triangulation.

    Attributes
    ----------
    cos_lo, cos_hi : (n_triangles,) float
        An element triggers when ``cos_max > cos_lo`` or ``cos_min < cos_hi``
        (narrow-gap elements: 2 and −2, never).
    area : (n_triangles,) float
        Signed areas after the triangulation (for ``"degenerate"``).
    narrow : (n_triangles,) bool
        Narrow-gap elements at the triangulation.
    cos_max, cos_min : (n_triangles,) float
        Their angle cosines then.
    cos_bound_lo, cos_bound_hi : float
        Cosines of the angle bounds.
    cos_trigger_lo, cos_trigger_hi : float
        Cosines of the bounds widened by the margins (``min_angle − min_margin``,
        ``max_angle + margin``): a narrow-gap element whose gap opened triggers past them
        (``nan``: the bounds themselves, as in meshes pickled before the margins).
    """

    cos_lo: np.ndarray
    cos_hi: np.ndarray
    area: np.ndarray
    narrow: np.ndarray
    cos_max: np.ndarray
    cos_min: np.ndarray
    cos_bound_lo: float
    cos_bound_hi: float
    cos_trigger_lo: float = float("nan")
    cos_trigger_hi: float = float("nan")


def element_shape(points, topo) -> ElementShape:
    """Angle cosines and signed areas of the elements of ``topo`` at ``points (n, 2)``, one pass."""
    x, y = points[:, 0], points[:, 1]
    t = topo
    ax, ay = x[t.t0], y[t.t0]
    ux, uy = x[t.t1] - ax, y[t.t1] - ay  # u = b − a
    wx, wy = ax - x[t.t2], ay - y[t.t2]  # w = a − c
    vx, vy = -(ux + wx), -(uy + wy)  # v = c − b
    lu2, lv2, lw2 = ux * ux + uy * uy, vx * vx + vy * vy, wx * wx + wy * wy
    # cos at a: (b − a)·(c − a)/(|b − a||c − a|) = −u·w/(|u||w|), and likewise at b, c
    ca = -(ux * wx + uy * wy) / np.sqrt(np.maximum(lu2 * lw2, 1e-300))
    cb = -(ux * vx + uy * vy) / np.sqrt(np.maximum(lu2 * lv2, 1e-300))
    cc = -(vx * wx + vy * wy) / np.sqrt(np.maximum(lv2 * lw2, 1e-300))
    cmax = np.maximum(np.maximum(ca, cb), cc)
    cmin = np.minimum(np.minimum(ca, cb), cc)
    return ElementShape(cmax, cmin, 0.5 * (uy * wx - ux * wy))  # ½ (b − a) × (c − a)


def quality_baseline(shape: ElementShape, narrow, min_angle: float, max_angle: float, margin: float,
                     min_margin: float | None = None) -> QualityBaseline:
    r"""Thresholds of the quality trigger for the mesh just triangulated: a margin past the
    bounds, with hysteresis.

    The bounds are the rule of thumb of the paper (Sec. 3.1: no angle above 135°) and the
    smallest angle the clean-up pass aims at; a fresh triangulation meets them except for a
    few elements it could not improve, and many of its elements are born just inside them.
    An element therefore triggers only when it has degraded by a stated margin past the
    bound, or past its own angle after the triangulation if it was born outside (its baseline):

    .. math::

        \theta_\max > \max(\Theta_\max, \theta_\max^0) + m_\max, \qquad
        \theta_\min < \min(\Theta_\min, \theta_\min^0) - m_\min,

    with :math:`\Theta` ``max_angle``/``min_angle``, :math:`\theta^0` the element's angles
    now, :math:`m_\max` ``margin`` and :math:`m_\min` ``min_margin`` (default ``margin``),
    all in degrees.  An element born at 134° so fires at 135° + m, not at 135°; one born at
    140° fires at 140° + m.  The thresholds are clipped to [0°, 180°].  (More relaxation
    sweeps while an element is past the bound, before the margin is used up, did not repair
    it: 11 against 12 re-triangulations in 100 steps of 20 polygons settling; what degrades
    there is the shear between bodies moving differently, which relaxation keeps.)
    Narrow-gap elements ``narrow (n_triangles,)`` are left out here and watched by
    :func:`quality_dropped` instead.  ``arccos`` runs only for the elements born outside.

    (Before, an element born just inside a bound fired as soon as it crossed it: 44 of 56
    re-triangulations in 74 steps of 40 polygons settling in a box were "quality" ones.)
    """
    min_margin = margin if min_margin is None else min_margin
    cmax, cmin = shape.cos_max, shape.cos_min
    c_lo = np.cos(np.radians(min_angle))
    t_lo = np.cos(np.radians(max(min_angle - min_margin, 0.0)))
    t_hi = np.cos(np.radians(min(max_angle + margin, 180.0)))
    cos_lo = np.full(len(cmax), t_lo)
    out = np.flatnonzero(cmax > c_lo)  # smallest angle below min_angle
    lo = np.degrees(np.arccos(np.clip(cmax[out], -1, 1))) - min_margin
    cos_lo[out] = np.cos(np.radians(np.clip(lo, 0, 180)))
    c_hi = np.cos(np.radians(max_angle))
    cos_hi = np.full(len(cmin), t_hi)
    out = np.flatnonzero(cmin < c_hi)  # largest angle above max_angle
    hi = np.degrees(np.arccos(np.clip(cmin[out], -1, 1))) + margin
    cos_hi[out] = np.cos(np.radians(np.clip(hi, 0, 180)))
    cos_lo[narrow] = 2.0
    cos_hi[narrow] = -2.0
    return QualityBaseline(cos_lo=cos_lo, cos_hi=cos_hi, area=shape.area, narrow=narrow, cos_max=cmax,
                           cos_min=cmin, cos_bound_lo=c_lo, cos_bound_hi=c_hi, cos_trigger_lo=t_lo,
                           cos_trigger_hi=t_hi)


def quality_dropped(shape: ElementShape, base: QualityBaseline, anchored_across_gap) -> bool:
    """True when an element outside narrow gaps crossed its threshold of :func:`quality_baseline`
    (the margin past the bound, or past its own angle if it was born outside).

    Narrow-gap elements are watched too: once the gap has opened (the element is no longer
    anchored across a narrow gap, ``anchored_across_gap(tri_idx) -> (k,) bool``) and it got
    worse since the triangulation, it must stay within the bounds widened by the margins.
    """
    cmax, cmin = shape.cos_max, shape.cos_min
    if ((cmax > base.cos_lo) | (cmin < base.cos_hi)).any():
        return True
    idx = np.flatnonzero(_opened_and_worse(shape, base))
    if not len(idx):
        return False
    return bool((~anchored_across_gap(idx)).any())


def fired_elements(shape: ElementShape, base: QualityBaseline, reason: str, degenerate_area: float,
                   anchored_across_gap) -> np.ndarray:
    """``(k,) int``: the elements that fired the trigger ``reason`` (module docstring): area <= 0
    (``"inverted"``), below ``degenerate_area`` of the area at the last triangulation
    (``"degenerate"``), or past their thresholds (``"quality"``: :func:`quality_dropped`'s
    elements, narrow-gap ones whose gap opened included); empty for any other reason (a contact,
    the schedule, a seam: no element fired).  ``anchored_across_gap(tri_idx) -> (k,) bool``.

    >>> import numpy as np
    >>> from fluidem.mesh.relax import mesh_topology
    >>> tri = mesh_topology(np.array([[0, 1, 2], [1, 3, 2]]))
    >>> pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    >>> base = quality_baseline(element_shape(pts, tri), np.zeros(2, dtype=bool), 15.0, 135.0, 10.0)
    >>> pts[3] = [0.1, 0.1]          # the second element turns over
    >>> fired_elements(element_shape(pts, tri), base, "inverted", 0.1, None).tolist()
    [1]
    """
    if reason == "inverted":
        return np.flatnonzero(shape.area <= 0)
    if reason == "degenerate":
        return np.flatnonzero(shape.area < degenerate_area * base.area)
    if reason != "quality":
        return np.zeros(0, dtype=np.int64)
    past = past_thresholds(shape, base)
    idx = np.flatnonzero(_opened_and_worse(shape, base))
    if len(idx):
        past[idx[~anchored_across_gap(idx)]] = True
    return np.flatnonzero(past)


def past_thresholds(shape: ElementShape, base: QualityBaseline) -> np.ndarray:
    """``(n_triangles,) bool``: elements past their own angle thresholds (``base.cos_lo``,
    ``base.cos_hi``; narrow-gap elements have none)."""
    return (shape.cos_max > base.cos_lo) | (shape.cos_min < base.cos_hi)


def _opened_and_worse(shape: ElementShape, base: QualityBaseline) -> np.ndarray:
    """``(n_triangles,) bool``: :func:`outside_opened_gap_bounds` and worse since the triangulation
    (the gap of an unchanged element did not open)."""
    worse = (shape.cos_max > base.cos_max + 1e-3) | (shape.cos_min < base.cos_min - 1e-3)
    return outside_opened_gap_bounds(shape, base) & worse


def outside_opened_gap_bounds(shape: ElementShape, base: QualityBaseline) -> np.ndarray:
    """``(n_triangles,) bool``: narrow-gap elements of the last triangulation now outside the angle
    bounds widened by the margins (the bounds a narrow-gap element whose gap opened must keep)."""
    lo = base.cos_bound_lo if np.isnan(base.cos_trigger_lo) else base.cos_trigger_lo
    hi = base.cos_bound_hi if np.isnan(base.cos_trigger_hi) else base.cos_trigger_hi
    return base.narrow & ((shape.cos_max > lo) | (shape.cos_min < hi))


def contacts_changed(polys, near_pairs, contacts, min_gap: float, points, body_of) -> bool:
    """True when bodies came closer than ``min_gap`` or an outline node of a body in contact
    entered another body (the contact outlines must be rebuilt).

    Only ``near_pairs (k, 2)``, the pairs closer than ``h`` at the last triangulation, are
    checked: bodies farther apart cannot touch before the elements between them invert.
    ``contacts (c, 2)``: the pairs meshed as one outline; ``points``, ``body_of``: the nodes.
    """
    pairs = near_pairs
    if not len(pairs):
        return False
    d = shapely.distance(polys[pairs[:, 0]], polys[pairs[:, 1]])
    close = pairs[d <= min_gap]
    n = len(polys)
    now = close[:, 0] * n + close[:, 1]
    before = contacts[:, 0] * n + contacts[:, 1] if len(contacts) else now[:0]
    if len(np.setdiff1d(now, before)):
        return True
    if not len(now):
        return False
    inv = np.flatnonzero(np.isin(body_of, np.unique(close)))
    pi, bi = shapely.STRtree(polys).query(shapely.points(points[inv]), predicate="within")
    return bool((body_of[inv[pi]] != bi).any())


def retriangulation_reason(shape: ElementShape, base: QualityBaseline, degenerate_area: float,
                           steps_since: int, every: int, contact_changed, quality_dropped_now) -> str:
    """The first reason that holds (module docstring), ``""`` for none.

    ``contact_changed()`` and ``quality_dropped_now()`` are called only when needed.
    """
    area = shape.area
    if (area <= 0).any():
        return "inverted"
    if (area < degenerate_area * base.area).any():
        return "degenerate"  # an element (typically in a narrow gap) is collapsing
    if contact_changed():
        return "contact"
    if steps_since >= every:
        return "periodic"
    if quality_dropped_now():
        return "quality"
    return ""
