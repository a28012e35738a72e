"""Periodic boxes in the DEM: the minimum-image convention.

A box may be periodic in ``x`` (its left and right sides are one) and/or in ``y``, with
periods ``L = (L_x, L_y)`` (length; 0 below for a non-periodic axis).  Body positions stay
*unwrapped*: a body that crossed the right side has ``x > xmax`` and keeps moving
continuously.  Every pair interaction (contact detection and forces, repulsion,
lubrication, gaps) sees the *nearest periodic image* of the partner (minimum-image
convention, Allen & Tildesley 1987, §1.5.2): body ``j`` seen from body ``i`` is shifted by ::

    s = −L round((x_j − x_i) / L)          on each periodic axis (0 on the others)

applied to ``j``'s centre and vertices alike (the arm of ``j``'s force about its own centre
is unchanged by it).  The image is the only one that can interact as long as every pair
satisfies ``r_i + r_j + range < L/2`` (bounding radii about the centres of mass plus the
short-range models' range): :func:`check_pair_reach` refuses bodies wider than that.

Examples
--------
>>> import numpy as np
>>> image_shift(np.array([[0.9, 0.3], [-0.6, 0.0]]), np.array([1.0, 0.0])).tolist()
[[-1.0, 0.0], [1.0, 0.0]]
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["as_period", "image_shift", "check_pair_reach", "wrap"]


def as_period(key: str, period) -> np.ndarray:
    """``period`` ``(L_x, L_y)`` (an entry None or 0 for a non-periodic axis; None for neither) as a (2,)
    float array with 0 for the non-periodic axes, or an :class:`~fluidem.errors.InputError`."""
    allowed = "None or (L_x, L_y), each a positive finite period (length) or None for a non-periodic axis"
    if period is None:
        return np.zeros(2)
    try:
        items = list(period)
    except TypeError:
        raise InputError(f"{key} = {period!r}: expected {allowed}") from None
    if len(items) != 2:
        raise InputError(f"{key} = {period!r}: expected {allowed}")
    out = np.zeros(2)
    for c, v in enumerate(items):
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v) \
                or v < 0:
            raise InputError(f"{key} = {period!r}: expected {allowed}")
        out[c] = float(v)
    return out


def image_shift(d: np.ndarray, period: np.ndarray) -> np.ndarray:
    """Shift ``s = −L round(d / L)`` that brings body j to its nearest image of body i, (P, 2), length.

    ``d`` (P, 2) the displacements ``x_j − x_i`` (length); ``period`` (2,) with 0 for a
    non-periodic axis (no shift there).
    """
    d = np.asarray(d, float)
    L = np.asarray(period, float)
    if not L.any():
        return np.zeros_like(d)
    safe = np.where(L > 0, L, 1.0)
    return np.where(L > 0, -safe * np.round(d / safe), 0.0)


def wrap(points: np.ndarray, period: np.ndarray) -> np.ndarray:
    """Copies of ``points`` (N, 2) wrapped into ``[0, L)`` on the periodic axes (for a search with
    ``scipy.spatial.cKDTree(..., boxsize=period)``); the other axes unchanged."""
    p = np.array(points, float)
    for c in np.flatnonzero(np.asarray(period) > 0):
        L = float(period[c])
        p[:, c] = np.mod(p[:, c], L)
        p[p[:, c] >= L, c] = 0.0  # mod of a tiny negative number rounds to L
    return p


def check_pair_reach(key: str, period: np.ndarray, radii: np.ndarray, reach: float = 0.0) -> None:
    """Refuse bodies that could interact with two images of a partner: along every periodic axis
    the two largest bounding radii plus ``reach`` (length) must stay below half the period
    (one body alone: its bounding diameter plus ``reach`` below the period, no contact with itself).
    Raises a one-line :class:`~fluidem.errors.InputError` naming the bodies."""
    r = np.asarray(radii, float)
    if not len(r) or not np.any(np.asarray(period) > 0):
        return
    order = np.argsort(-r, kind="stable")
    a = int(order[0])
    b = int(order[1]) if len(r) > 1 else a
    for c in np.flatnonzero(np.asarray(period) > 0):
        L = float(period[c])
        limit = 0.5 * L if len(r) > 1 else L
        if r[a] + r[b] + reach >= limit:
            who = f"bodies {a} and {b} have bounding radii {r[a]:.4g} and {r[b]:.4g}" if a != b else \
                f"body {a} has bounding radius {r[a]:.4g}"
            raise InputError(f"{key} = {_shown(period)}: {who} (plus the short-range reach {reach:.4g}) reaching "
                             f"{r[a] + r[b] + reach:.4g} >= {'half ' if len(r) > 1 else ''}the {'xy'[c]} period "
                             f"{L:.4g}; expected bodies narrower than half the period (r_i + r_j + reach < "
                             f"{limit:.4g})")


def _shown(period) -> str:
    return "(" + ", ".join("None" if v == 0 else f"{v:g}" for v in period) + ")"
