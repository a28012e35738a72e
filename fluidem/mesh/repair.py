"""Repair of the few elements that fire the quality trigger (or shrink below ``degenerate_area`` of
their area), by moving their nodes, before the dragged mesh is re-triangulated for them.

In a settling, piling suspension the quality trigger (:func:`fluidem.mesh.triggers.quality_dropped`)
is set off by one element at a time, once every 5–10 steps at 100 polygons: an element with one or
two free nodes squeezed between bodies that slide past each other (its smallest angle down from
~35° to 14°, its largest up from ~95° to 145–150°), or a free node pressed towards a wall.  The
spring relaxation (:mod:`fluidem.mesh.relax`) equalises edge lengths and does not undo it.  The
node positions can: each movable node of the fired elements, then of their neighbours, moves the
least that brings the smallest angle margin of its elements to :data:`TARGET_MARGIN`, a max–min
optimisation-based smoothing (Freitag, Jones & Plassmann 1995, "An efficient parallel algorithm
for mesh smoothing", Proc. 4th International Meshing Roundtable; the max–min angle placement of
Amenta, Bern & Eppstein 1999, J. Algorithms 30) solved by a compass search (Kolda, Lewis &
Torczon 2003, SIAM Review 45, Sec. 3), Gauss–Seidel over the nodes.  The margin of an element is
its angle distance to its own trigger thresholds (:class:`~fluidem.mesh.triggers.QualityBaseline`),

.. math::

    m_T = \\min(\\theta_{\\min,T} - \\Theta^{lo}_T,\\; \\Theta^{hi}_T - \\theta_{\\max,T}),

and a move must keep every element of the star above ``degenerate_area`` of its area at the last
triangulation.  The shortest move is taken, not the best placement: the move is part of the step's
ALE mesh velocity, and large jumps of a few nodes cost momentum accuracy in the non-conservative
ALE form (a head-on collision of two disks: drift 1.75e-3 of m U placing the nodes at their best,
4.6e-4 with the shortest move, 3.3e-4 re-triangulating instead).  The connectivity is unchanged:
no field transfer, no new matrices.  The caller re-triangulates when the margins cannot all be
made non-negative (:func:`fluidem.mesh.drag_step.repair_step`).

Only nodes that move freely (free nodes, and box-side nodes along their side) are moved; nodes of
periodic sides (they move in pairs) and nodes next to a narrow-gap element (watched by another
rule) are not.  The work is a loop over the handful of nodes of the fired elements, only in a
step where the trigger fires, with the candidate positions of a node evaluated at once.

Examples
--------
A free node pushed almost onto the bottom edge of a unit square (its element there has a largest
angle of 175°) moves up by the shortest trial step (0.4 of its size 0.5) that brings every angle
of its four elements to at least 3° within the bounds 15° and 145°:

>>> import numpy as np
>>> from fluidem.mesh.repair import repair_nodes
>>> pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.02]])
>>> tri = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
>>> lo, hi = np.full(4, 15.0), np.full(4, 145.0)
>>> new, moved = repair_nodes(pts, tri, np.ones((5, 2)), np.array([4]), lo, hi, np.zeros(4), 0.5)
>>> moved, new[4].round(3).tolist()
(1, [0.5, 0.22])
"""

from __future__ import annotations

import numpy as np

from .transfer import elements_around

__all__ = ["repair_nodes", "nodes_to_repair", "DIRECTIONS", "STEP_FRACTIONS", "TARGET_MARGIN"]

#: compass directions of the search (Kolda et al. 2003: a positive spanning set; 16 for a
#: fine resolution of the best direction in one evaluation)
DIRECTIONS = 16
#: trial steps as fractions of the node's local size, evaluated at once, shortest first
STEP_FRACTIONS = (0.025, 0.05, 0.1, 0.2, 0.4)
#: degrees: the margin a repair aims at (an element just within its bounds would fire again at once)
TARGET_MARGIN = 3.0


def _star_angles(a, b, c):
    """Smallest and largest angle (degrees) and signed area of triangles ``(a, b, c)``, arrays (..., 2)."""
    u, v, w = b - a, c - b, a - c
    lu, lv, lw = (u * u).sum(-1), (v * v).sum(-1), (w * w).sum(-1)
    tiny = 1e-300
    ca = -(u * w).sum(-1) / np.sqrt(np.maximum(lu * lw, tiny))
    cb = -(u * v).sum(-1) / np.sqrt(np.maximum(lu * lv, tiny))
    cc = -(v * w).sum(-1) / np.sqrt(np.maximum(lv * lw, tiny))
    cos = np.stack([ca, cb, cc], -1)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    area = 0.5 * (u[..., 0] * (-w[..., 1]) - u[..., 1] * (-w[..., 0]))  # ½ (b − a) × (c − a)
    return ang.min(-1), ang.max(-1), area


def _star_value(points, star_tris, node, cand, lo, hi, floor):
    """Smallest margin of the star ``star_tris (s, 3)`` with ``node`` at each candidate
    ``cand (c, 2)``: ``(c,)``, ``-inf`` where an element falls below its area floor."""
    tri_pts = points[star_tris]  # (s, 3, 2)
    pts = np.broadcast_to(tri_pts, (len(cand),) + tri_pts.shape).copy()
    at = star_tris == node  # (s, 3)
    pts[:, at] = cand[:, None, :]
    mn, mx, area = _star_angles(pts[:, :, 0], pts[:, :, 1], pts[:, :, 2])
    margin = np.minimum(mn - lo, hi - mx)  # (c, s)
    margin = np.where(area > floor, margin, -np.inf)
    return margin.min(axis=1)


def repair_nodes(points, triangles, mobility, nodes, lo, hi, floor, size, sweeps: int = 2,
                 target: float = TARGET_MARGIN):
    """Move ``nodes`` the least that brings the smallest angle margin of their stars to ``target``
    (module docstring).

    Parameters
    ----------
    points : (n, 2) float
        Node positions, length units (not changed).
    triangles : (m, 3) int
        Elements, counter-clockwise.
    mobility : (n, 2) float
        Per node and axis 1 (may move) or 0 (fixed): side nodes slide along their side.
    nodes : (k,) int
        The nodes that may move, in the order they are visited.
    lo, hi : (m,) float
        Per element the smallest-angle and largest-angle thresholds, degrees
        (:class:`~fluidem.mesh.triggers.QualityBaseline`).
    floor : (m,) float
        Per element the signed area it must stay above, length units².
    size : float or (n,) float
        Local mesh size, length units: trial steps are :data:`STEP_FRACTIONS` of it.
    sweeps : int
        Gauss–Seidel sweeps over ``nodes``.
    target : float
        Degrees: a node whose star's smallest margin is below it moves by the shortest trial step
        that reaches it (the best one if none does); nodes at or above it stay.

    Returns
    -------
    points : (n, 2) float
        The new positions.
    moved : int
        Nodes that moved.
    """
    x = np.array(points, dtype=float, copy=True)
    tri = np.asarray(triangles)
    nodes = np.asarray(nodes, dtype=np.int64)
    if not len(nodes):
        return x, 0
    size = np.broadcast_to(np.asarray(size, dtype=float), (len(x),))
    near = elements_around(tri, nodes, 1)  # the stars of all nodes, one pass
    near_tri = tri[near]
    theta = np.linspace(0.0, 2.0 * np.pi, DIRECTIONS, endpoint=False)
    dirs = np.column_stack([np.cos(theta), np.sin(theta)])
    fractions = np.repeat(np.asarray(STEP_FRACTIONS), DIRECTIONS)  # shortest first
    steps = fractions[:, None] * np.tile(dirs, (len(STEP_FRACTIONS), 1))
    start = x[nodes].copy()
    for _ in range(sweeps):
        changed = False
        for p in nodes:
            rows = np.flatnonzero((near_tri == p).any(axis=1))
            star, el = near_tri[rows], near[rows]
            cand = x[p] + steps * (size[p] * mobility[p])
            value = _star_value(x, star, p, np.vstack([x[p][None, :], cand]), lo[el], hi[el], floor[el])
            now, value = value[0], value[1:]
            if now >= target:
                continue
            reach = np.flatnonzero(value >= target)
            if len(reach):  # the shortest step that reaches the target, the best of its length
                same = reach[fractions[reach] == fractions[reach[0]]]
                best = same[np.argmax(value[same])]
            else:
                best = int(np.argmax(value))
                if not value[best] > now + 1e-9:
                    continue
            x[p] = cand[best]
            changed = True
        if not changed:
            break
    return x, int((x[nodes] != start).any(axis=1).sum())


def nodes_to_repair(triangles, fired, movable, narrow) -> np.ndarray:
    """The nodes :func:`repair_nodes` moves for the fired elements ``fired (k,)``: their movable
    vertices first, then the movable vertices of the elements around those.

    ``movable (n,) bool``: nodes the repair may move; ``narrow (m,) bool``: narrow-gap elements,
    whose vertices are left alone.
    """
    tri = np.asarray(triangles)
    keep = movable.copy()
    keep[tri[narrow].ravel()] = False
    own = np.unique(tri[fired].ravel())
    own = own[keep[own]]
    if not len(own):
        return own
    ring = np.unique(tri[elements_around(tri, own, 1)].ravel())
    ring = ring[keep[ring] & ~np.isin(ring, own)]
    return np.concatenate([own, ring])
