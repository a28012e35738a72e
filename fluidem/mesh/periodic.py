"""Periodic pairs of box sides on the meshes: matching nodes that slide in pairs.

A box ``(xmin, xmax, ymin, ymax)`` may be periodic in ``x`` (the sides ``left`` and
``right`` are one: a node at ``(xmin, y)`` has its partner at ``(xmax, y)``) and/or in ``y``
(``bottom`` and ``top``).  The fluid space identifies the degrees of freedom of partner
nodes (:mod:`fluidem.fluid.periodic`); that needs the same nodes on both sides of a pair
in every mesh the package builds:

* fixed meshes and graded backgrounds (:func:`fluidem.mesh.triangulate.triangulate_box`):
  one side of a pair is subdivided, the other gets the same points translated by the
  period, and Triangle adds no points on boundary segments (switch ``Y``);
* the moving mesh (:class:`fluidem.mesh.MovingMesh`): the nodes of periodic sides slide along
  them in matched pairs (:func:`side_partners`, :func:`slide_in_pairs`), and the node set
  handed to every re-triangulation gets the partner of every periodic side node it lacks
  (:func:`match_side_nodes`, e.g. after a refinement inserted a node on one side), and new
  side nodes where a body crossing the side took them away (:func:`fill_sides`).

Bodies may cross periodic sides: the moving mesh holds them as periodic images clipped at the
box (:mod:`fluidem.mesh.seam`).

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.nodes import SIDE, FREE, UidSource
>>> pts = np.array([[0.0, 0.25], [0.5, 0.5], [1.0, 0.5]])
>>> kind = np.array([SIDE, FREE, SIDE], np.int8)
>>> p, k, u = match_side_nodes(pts, kind, np.arange(3), (0, 1, 0, 1), ("x",), UidSource())
>>> p[3:].tolist(), k[3:].tolist()
([[0.0, 0.5], [1.0, 0.25]], [1, 1])
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError, MeshError
from .kinds import CONTACT, CORNER, SIDE

__all__ = ["AXES", "SIDE_PAIRS", "periodic_axes", "axes_of_sides", "on_periodic_sides", "match_side_nodes",
           "fill_sides", "side_partners", "slide_in_pairs", "bends_seams", "move_in_pairs", "partner_places",
           "check_matched", "check_side_pairs"]

#: the periodic directions: ``"x"`` pairs left/right, ``"y"`` bottom/top
AXES = ("x", "y")
#: (low side, high side) of each axis
SIDE_PAIRS = {"x": ("left", "right"), "y": ("bottom", "top")}
#: a span of a periodic side longer than this many target sizes without a node gets new nodes at a
#: re-triangulation (:func:`fill_sides`)
FILL_GAP = 1.5


def periodic_axes(periodic) -> tuple:
    """The validated periodic axes: a subset of ``("x", "y")`` in that order.

    ``periodic`` is ``None``, one axis name, or a sequence of axis names or of side names
    (``"left"``/``"right"`` mean ``"x"``, ``"bottom"``/``"top"`` mean ``"y"``).

    Examples
    --------
    >>> periodic_axes(None), periodic_axes("x"), periodic_axes(["top", "bottom", "left", "right"])
    ((), ('x',), ('x', 'y'))
    """
    if periodic is None:
        return ()
    items = (periodic,) if isinstance(periodic, str) else tuple(periodic)
    side_axis = {s: a for a, pair in SIDE_PAIRS.items() for s in pair}
    out = set()
    for it in items:
        if it in AXES:
            out.add(it)
        elif it in side_axis:
            out.add(side_axis[it])
        else:
            raise InputError(f"periodic = {it!r}: expected 'x' (left/right), 'y' (bottom/top) or a side name "
                             f"({', '.join(side_axis)})")
    return tuple(a for a in AXES if a in out)


def axes_of_sides(side_types: dict) -> tuple:
    """Periodic axes of a box from its side types ``{"left": "periodic", ...}``."""
    return tuple(a for a in AXES if side_types.get(SIDE_PAIRS[a][0]) == "periodic")


def _tolerance(box) -> float:
    xmin, xmax, ymin, ymax = box
    return 1e-9 * max(xmax - xmin, ymax - ymin)


def on_periodic_sides(points, box, axes) -> np.ndarray:
    """Mask ``(k,)``: ``points (k, 2)`` on a side of the periodic ``axes`` of ``box`` (to the
    matching tolerance, 1e-9 of the box).

    >>> on_periodic_sides(np.array([[0.0, 0.5], [0.5, 0.0], [1.0, 0.2]]), (0, 1, 0, 1), ("x",)).tolist()
    [True, False, True]
    """
    xmin, xmax, ymin, ymax = box
    tol = _tolerance(box)
    on = np.zeros(len(points), dtype=bool)
    if "x" in axes:
        on |= (np.abs(points[:, 0] - xmin) < tol) | (np.abs(points[:, 0] - xmax) < tol)
    if "y" in axes:
        on |= (np.abs(points[:, 1] - ymin) < tol) | (np.abs(points[:, 1] - ymax) < tol)
    return on


def match_side_nodes(points, kind, uid, box, axes, uids, merge: float = 0.0):
    """The node set with the side nodes of every periodic side pair matched.

    Along each pair the places of the ``SIDE`` nodes of both sides are grouped (places closer
    than ``merge`` are one group, sorted, vectorised); each group becomes one place, the mean
    of its members, with one node on each side: the side's first member moved there (it keeps
    its uid), its other members dropped, a new node added where the side had none.

    Parameters
    ----------
    points : (n, 2) float
        Candidate nodes, length units.
    kind : (n,) int8
        Node kinds (:mod:`fluidem.mesh.nodes`); side nodes are ``SIDE``.
    uid : (n,) int
        Node uids.
    box : (xmin, xmax, ymin, ymax)
    axes : tuple of {"x", "y"}
        Periodic axes.
    uids : UidSource
        Source of the uids of added partners.
    merge : float
        Places of side nodes closer than this are one (length units; side nodes slide in
        pairs, and a pair broken by a re-triangulation would otherwise leave two nodes almost
        on top of each other).  At most the matching tolerance (1e-9 of the box) by default.

    Returns
    -------
    points, kind, uid
        The matched node set (``SIDE`` partners exactly at ``xmax`` for a ``left`` node, and so
        on).
    """
    points = np.array(points, dtype=float)
    kind, uid = np.asarray(kind), np.asarray(uid)
    if not axes:
        return points, kind, uid
    xmin, xmax, ymin, ymax = box
    tol = _tolerance(box)
    gap = max(merge, tol)
    for a in axes:
        c = 0 if a == "x" else 1  # the coordinate fixed on the side
        lo, hi = (xmin, xmax) if a == "x" else (ymin, ymax)
        on_side = kind == SIDE
        low = np.flatnonzero(on_side & (np.abs(points[:, c] - lo) < tol))
        high = np.flatnonzero(on_side & (np.abs(points[:, c] - hi) < tol))
        idx = np.concatenate([low, high])
        if not len(idx):
            continue
        side = np.concatenate([np.zeros(len(low), dtype=np.int64), np.ones(len(high), dtype=np.int64)])
        along = points[idx, 1 - c]
        order = np.argsort(along, kind="stable")
        idx, side, along = idx[order], side[order], along[order]
        group = np.concatenate([[0], np.cumsum(np.diff(along) > gap)])
        n_groups = int(group[-1]) + 1
        place = np.bincount(group, weights=along, minlength=n_groups) / np.bincount(group, minlength=n_groups)
        # the first member of each (group, side) stays and moves to the group's place
        key = group * 2 + side
        _, first = np.unique(key, return_index=True)
        keep = np.zeros(len(idx), dtype=bool)
        keep[first] = True
        points[idx[keep], 1 - c] = place[group[keep]]
        drop = idx[~keep]
        # groups without a node on a side get one there
        has = np.zeros((n_groups, 2), dtype=bool)
        has[group[keep], side[keep]] = True
        add = []
        for sd, level in ((0, lo), (1, hi)):
            g = np.flatnonzero(~has[:, sd])
            q = np.zeros((len(g), 2))
            q[:, c] = level
            q[:, 1 - c] = place[g]
            add.append(q)
        add = np.vstack(add)
        alive = np.ones(len(points), dtype=bool)
        alive[drop] = False
        points = np.vstack([points[alive], add])
        kind = np.concatenate([kind[alive], np.full(len(add), SIDE, dtype=kind.dtype)])
        uid = np.concatenate([uid[alive], uids.take(len(add))])
    return points, kind, uid


def fill_sides(points, kind, uid, box, axes, size, uids, max_gap: float = FILL_GAP):
    """The node set with new ``SIDE`` nodes where the nodes along a periodic side are farther
    apart than ``max_gap`` times the target size there.

    A re-triangulation drops the side nodes under a body that crosses the side and near its
    seam nodes (:mod:`fluidem.mesh.seam`), and nothing puts them back when the body has passed:
    in a sheared suspension the side of a 2 × 1 cell kept 9 of its 23 nodes after 50 steps, its
    elements spanning up to 3.3 h, born with their angles at the bounds and firing the quality
    trigger a few steps later.  Along each pair the places of the nodes of both sides (``SIDE``
    and ``CORNER``) and the box's ends split the side into spans; a span longer than
    ``max_gap`` · h (``size`` at its middle) gets evenly spaced nodes, a spacing at most h, on
    the low side (:func:`match_side_nodes` adds their partners).  New nodes under a body are
    dropped with the others by the triangulation.

    Parameters
    ----------
    points : (n, 2) float
    kind : (n,) int8
    uid : (n,) int
    box : (xmin, xmax, ymin, ymax)
    axes : tuple of {"x", "y"}
    size : callable
        ``points (k, 2) -> (k,)`` target element size, length units.
    uids : UidSource
    max_gap : float
        Longest span without a node, in multiples of the target size there (> 1).

    Returns
    -------
    points, kind, uid
        With the new nodes appended.

    Examples
    --------
    >>> from fluidem.mesh.nodes import UidSource
    >>> pts = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0], [1.0, 1.0], [0.0, 0.2]])
    >>> kind = np.array([CORNER, CORNER, CORNER, CORNER, SIDE], np.int8)
    >>> p, k, u = fill_sides(pts, kind, np.arange(5), (0, 1, 0, 1), ("x",), lambda q: np.full(len(q), 0.25),
    ...                      UidSource(5))
    >>> p[5:].tolist()   # the span from 0.2 to 1 (3.2 h) in four
    [[0.0, 0.4], [0.0, 0.6000000000000001], [0.0, 0.8]]
    """
    points = np.asarray(points, dtype=float)
    kind, uid = np.asarray(kind), np.asarray(uid)
    xmin, xmax, ymin, ymax = box
    for a in axes:
        c = 0 if a == "x" else 1  # the coordinate fixed on the side
        lo = xmin if a == "x" else ymin
        start, end = (ymin, ymax) if a == "x" else (xmin, xmax)
        on = ((kind == SIDE) | (kind == CORNER)) & on_periodic_sides(points, box, (a,))
        places = np.unique(np.concatenate([[start, end], np.clip(points[on, 1 - c], start, end)]))
        span = np.diff(places)
        mid = np.zeros((len(span), 2))
        mid[:, c] = lo
        mid[:, 1 - c] = places[:-1] + 0.5 * span
        h = np.asarray(size(mid), dtype=float)
        n_new = np.where(span > max_gap * h, np.ceil(span / h).astype(np.int64) - 1, 0)
        if not n_new.sum():
            continue
        which = np.repeat(np.arange(len(span)), n_new)
        k = np.arange(len(which)) - np.repeat(np.cumsum(n_new) - n_new, n_new) + 1  # 1..n_new in each span
        add = np.zeros((len(which), 2))
        add[:, c] = lo
        add[:, 1 - c] = places[which] + span[which] * k / (n_new[which] + 1)
        points = np.vstack([points, add])
        kind = np.concatenate([kind, np.full(len(add), SIDE, dtype=kind.dtype)])
        uid = np.concatenate([uid, uids.take(len(add))])
    return points, kind, uid


def side_partners(points, kind, box, axes) -> np.ndarray:
    """Pairs ``(k, 2)`` of matched nodes of periodic sides (kinds ``SIDE`` and ``CONTACT``, the
    seam nodes of :mod:`fluidem.mesh.seam`; corners left out) across the periodic ``axes``:
    ``[low side node, high side node]`` at the same place along the side."""
    if not axes:
        return np.zeros((0, 2), dtype=np.int64)
    xmin, xmax, ymin, ymax = box
    tol = _tolerance(box)
    out = []
    for a in axes:
        c = 0 if a == "x" else 1
        lo, hi = (xmin, xmax) if a == "x" else (ymin, ymax)
        side = (kind == SIDE) | (kind == CONTACT)
        low = np.flatnonzero(side & (np.abs(points[:, c] - lo) < tol))
        high = np.flatnonzero(side & (np.abs(points[:, c] - hi) < tol))
        if not len(low) or not len(high):
            continue
        s_hi = points[high, 1 - c]
        order = np.argsort(s_hi)
        pos = np.clip(np.searchsorted(s_hi[order], points[low, 1 - c]), 0, len(high) - 1)
        j = high[order[pos]]
        ok = np.abs(points[j, 1 - c] - points[low, 1 - c]) < tol
        out.append(np.column_stack([low[ok], j[ok]]))
    return np.vstack(out) if out else np.zeros((0, 2), dtype=np.int64)


def bends_seams(mesh) -> bool:
    """``mesh`` has periodic sides that bend between re-triangulations (``seams="bend"``,
    :class:`~fluidem.mesh.params.MeshParams`; :mod:`fluidem.mesh.seam`): one periodic axis
    (a doubly periodic box keeps straight sides)."""
    return len(mesh.periodic) == 1 and mesh.params.seams == "bend"


def move_in_pairs(old, new, pairs) -> np.ndarray:
    """``new (n, 2)`` with every pair of matched periodic side nodes ``pairs (k, 2)`` moved from
    ``old (n, 2)`` by the mean of the two displacements (bent seams, :mod:`fluidem.mesh.seam`):
    partners ``L`` apart stay so, their coordinate along the side equal exactly."""
    if not len(pairs):
        return new
    p = np.array(new, dtype=float)
    a, b = pairs[:, 0], pairs[:, 1]
    d = 0.5 * ((p[a] - old[a]) + (p[b] - old[b]))
    p[a] = old[a] + d
    p[b] = old[b] + d
    return p


def slide_in_pairs(points, pairs, box, lead=None) -> np.ndarray:
    """``points (n, 2)`` with every pair of matched side nodes ``pairs (k, 2)`` put at the mean
    of their places along the side (each slid with its own neighbourhood; the pair stays
    matched exactly, as the periodic degrees of freedom need).  ``lead (n,)`` bool: nodes
    placed by their bodies (seam nodes); a pair with one takes its place."""
    if not len(pairs):
        return points
    p = np.array(points, dtype=float)
    # a left/right pair (partners a period apart in x) slides in y; so do the corner pairs of a
    # box periodic in x alone (bent seams), and those of one periodic in y slide in x
    along = 1 - np.argmax(np.abs(p[pairs[:, 1]] - p[pairs[:, 0]]), axis=1)
    k = np.arange(len(pairs))
    a, b = p[pairs[:, 0], :][k, along], p[pairs[:, 1], :][k, along]
    mean = 0.5 * (a + b)
    if lead is not None:
        la, lb = lead[pairs[:, 0]], lead[pairs[:, 1]]
        mean = np.where(la & ~lb, a, np.where(lb & ~la, b, mean))
    p[pairs[k, 0], along] = mean
    p[pairs[k, 1], along] = mean
    return p


def partner_places(points, side, box) -> np.ndarray:
    """The places ``(k, 2)`` across the side pair of ``points (k, 2)`` on periodic sides ``side (k,)``
    (0 bottom, 1 right, 2 top, 3 left): the same place along the side, on the partner side (the
    coordinate across set exactly to its level).

    Examples
    --------
    >>> partner_places([[0.0, 0.25], [0.5, 1.0]], [3, 2], (0, 2, 0, 1)).tolist()
    [[2.0, 0.25], [0.5, 0.0]]
    """
    xmin, xmax, ymin, ymax = box
    q = np.array(points, dtype=float).reshape(-1, 2)
    side = np.asarray(side)
    level = np.select([side == 0, side == 1, side == 2, side == 3], [ymax, xmin, ymin, xmax])
    across = np.where((side == 1) | (side == 3), 0, 1)  # the coordinate across the side
    q[np.arange(len(q)), across] = level
    return q


def check_matched(points, box, axes, boundary_nodes=None) -> None:
    """Raise :class:`~fluidem.errors.MeshError` unless every node on a periodic side has its
    partner (nodes ``points (n, 2)``; ``boundary_nodes``: the indices to check, default all)."""
    if not axes:
        return
    p = np.asarray(points, dtype=float)
    if boundary_nodes is not None:
        p = p[boundary_nodes]
    xmin, xmax, ymin, ymax = box
    tol = _tolerance(box)
    for a in axes:
        c = 0 if a == "x" else 1
        lo, hi = (xmin, xmax) if a == "x" else (ymin, ymax)
        s_lo = np.sort(p[np.abs(p[:, c] - lo) < tol, 1 - c])
        s_hi = np.sort(p[np.abs(p[:, c] - hi) < tol, 1 - c])
        if len(s_lo) != len(s_hi) or np.any(np.abs(s_lo - s_hi) > tol):
            lo_name, hi_name = SIDE_PAIRS[a]
            raise MeshError(f"periodic sides {lo_name!r} and {hi_name!r} do not have matching nodes "
                            f"({len(s_lo)} and {len(s_hi)} nodes)")


def check_side_pairs(points, segments, markers, box, axes) -> None:
    """Raise :class:`~fluidem.errors.MeshError` unless, for each periodic side pair, the nodes of
    the facets of the high side are those of the low side shifted by the period, to round-off
    (nodes ``points (n, 2)``; boundary facets ``segments (k, 2)`` with ``markers (k,)``, 1 bottom,
    2 right, 3 top, 4 left).  Unlike :func:`check_matched` it holds for sides that bend between
    re-triangulations (:mod:`fluidem.mesh.seam`), whose nodes leave the side lines."""
    if not axes:
        return
    p = np.asarray(points, dtype=float)
    xmin, xmax, ymin, ymax = box
    tol = _tolerance(box)
    for a in axes:
        c = 0 if a == "x" else 1
        lo_mark, hi_mark = (4, 2) if a == "x" else (1, 3)
        shift = np.zeros(2)
        shift[c] = (xmax - xmin) if a == "x" else (ymax - ymin)
        q_lo = p[np.unique(segments[markers == lo_mark])]
        q_hi = p[np.unique(segments[markers == hi_mark])] - shift
        q_lo = q_lo[np.lexsort((q_lo[:, c], q_lo[:, 1 - c]))]
        q_hi = q_hi[np.lexsort((q_hi[:, c], q_hi[:, 1 - c]))]
        if len(q_lo) != len(q_hi) or np.any(np.abs(q_lo - q_hi) > tol):
            lo_name, hi_name = SIDE_PAIRS[a]
            raise MeshError(f"periodic sides {lo_name!r} and {hi_name!r} do not have matching nodes "
                            f"({len(q_lo)} and {len(q_hi)} nodes)")
