"""Bodies across periodic sides: periodic images, outlines clipped at the seam, seam nodes.

On a box periodic in ``x`` (sides ``left`` and ``right`` one, :mod:`fluidem.mesh.periodic`)
a body may cross the seam.  The mesh then holds it as its *periodic images*: the body at
``(x + i L_x, y + j L_y)`` for the few ``(i, j)`` that put it in or near the box.  Each
image is meshed like a body (contacts, cut-out, dragging), and the outlines are clipped by
the box:

* an outline segment with both ends outside the box is dropped;
* a segment with one end outside ends at a *seam node*: its exact crossing with the side
  (a contact node of kind ``CONTACT`` with side code ``SEAM_CODE + side``).  The image
  shifted by the period crosses the partner side on the same segment, so the seam nodes of
  a side pair match to round-off, as the periodic degrees of freedom need;
* box nodes inside an image (the seam under a body) are no boundary and are dropped, and so
  are box nodes closer than ``SEAM_MERGE · h`` to a seam node or its partner (no sliver);
* between re-triangulations, with one periodic axis (``seams="bend"``, the default of
  :class:`~fluidem.mesh.params.MeshParams`), the sides *bend* with the bodies: a seam node stays
  where it is on its body (it moves rigidly, like an outline node), and the other nodes of the
  periodic sides, with the corners where they meet a wall, are dragged like free nodes (the
  harmonic extension over the periodic strip, each pair one node of it) and relaxed along the
  side, in matched pairs (each pair moves by the mean of its two moves, so the partners
  stay one period apart and equal along the side to round-off: the mesh is one mesh of the
  periodic strip, cut along a line of its edges that need not be straight).  Nodes
  may so lie beyond a periodic side, and an outline node passing the side line changes
  nothing; the usual triggers (quality, contacts, every K steps) re-triangulate.  Then the
  nodes beyond a side are put back in the box by the period and the side nodes back on their
  lines (:func:`fluidem.mesh.moving_images.unbend_seams`), where a body that has passed took side
  nodes away new ones are put (:func:`fluidem.mesh.periodic.fill_sides`); node trajectories and fields are
  found in the old mesh or its copies a period away.  With ``seams="clip"`` (and on a doubly
  periodic box) the sides stay straight: a seam node slides along its side at the crossing of
  its segment, whose ends move rigidly with their bodies (:func:`seam_positions`), and a
  segment that no longer crosses its side (an outline node passed the seam) re-triangulates;
* a body with an outline node within ``SEAM_BAND · h`` of a seam line is held nudged off it
  (:func:`seam_nudge`): an edge or a vertex exactly on the seam would be meshed on one side.

An image outside the box is kept when it comes within ``margin`` of the box: the fluid by
the seam then sees the bodies across it (purge, contacts, dragging).

All images of a body carry its rigid motion: the velocity at a point ``x`` of image
``(i, j)`` is ``U + ω e_z × (x − X − (i L_x, j L_y))``, the minimum-image arm of
:func:`fluidem.geometry.minimum_image` when every vertex of a body lies within half a period
of its centre.

Examples
--------
>>> import numpy as np
>>> img = periodic_images(np.array([[1.95, 0.5, 0.0]]), np.array([[-0.1, 0.1, -0.1, 0.1]]),
...                       (0, 2, 0, 1), ("x",), margin=0.0)
>>> img.body.tolist(), img.shift.tolist()
([0, 0], [[0.0, 0.0], [-2.0, 0.0]])
>>> from fluidem.geometry import minimum_image
>>> minimum_image(np.array([[1.9, 0.0]]), (2.0, None)).tolist()
[[-0.10000000000000009, 0.0]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from .periodic import partner_places

__all__ = ["SEAM_CODE", "SEAM_MERGE", "SEAM_BAND", "PeriodicImages", "periodic_images", "period_of",
           "clip_at_seams", "seam_nudge", "pair_seam_nodes", "covered_side_nodes", "seam_positions"]

#: box nodes closer than this many ``h`` to a seam node are dropped (no sliver element)
SEAM_MERGE = 0.4
#: a body with an outline node closer than this many ``h`` to a periodic side is meshed
#: nudged off it (:func:`seam_nudge`)
SEAM_BAND = 1e-3

#: side code of a seam node in the contact-node side array: ``SEAM_CODE + side`` (0 bottom,
#: 1 right, 2 top, 3 left); wall nodes use 0..3
SEAM_CODE = 4


def period_of(box, axes) -> tuple:
    """``(L_x or None, L_y or None)``: the periods of the periodic ``axes`` of ``box``."""
    xmin, xmax, ymin, ymax = box
    return (xmax - xmin if "x" in axes else None, ymax - ymin if "y" in axes else None)


@dataclass(frozen=True)
class PeriodicImages:
    """The bodies the mesh holds: ``body (m,)`` the real body of each image, ``cell (m, 2)``
    int its period offsets ``(i, j)``, ``shift (m, 2)`` = ``(i L_x, j L_y)`` (length units)."""

    body: np.ndarray
    cell: np.ndarray
    shift: np.ndarray

    def key(self) -> np.ndarray:
        """One int per image (body and cell), for comparing two image sets."""
        return (self.body.astype(np.int64) << 24) + ((self.cell[:, 0] + 2048) << 12) + (self.cell[:, 1] + 2048)


def periodic_images(poses, extent, box, axes, margin: float) -> PeriodicImages:
    """The images of bodies at ``poses (n, 3)`` (unwrapped) to mesh in ``box``.

    Parameters
    ----------
    poses : (n, 3) float
        ``x, y, angle``; positions may lie outside the box (a body that crossed a seam).
    extent : (n, 4) float
        Per body ``(dx_min, dx_max, dy_min, dy_max)``: its outline's extent about its
        position at ``poses``, length units.
    box : (xmin, xmax, ymin, ymax)
    axes : tuple of {"x", "y"}
        Periodic axes.
    margin : float
        Images outside the box but closer than this are kept, length units.

    Returns
    -------
    PeriodicImages
        For every body first the image whose position lies in the box (cell offsets that
        wrap it), then the others in or within ``margin`` of the box, sorted by body.
    """
    poses = np.asarray(poses, dtype=float)
    n = len(poses)
    xmin, xmax, ymin, ymax = box
    L = period_of(box, axes)
    lo = np.array([xmin, ymin])
    home = np.zeros((n, 2), dtype=np.int64)
    for c in range(2):
        if L[c]:
            home[:, c] = -np.floor((poses[:, c] - lo[c]) / L[c]).astype(np.int64)
    offsets = [(0, 0)]
    if L[0]:
        offsets += [(-1, 0), (1, 0)]
    if L[1]:
        offsets += [(o[0], s) for o in list(offsets) for s in (-1, 1)]
    body, cell = [], []
    for di, dj in offsets:  # at most 9 offsets, vectorised over bodies
        ij = home + np.array([di, dj])
        shift = ij * np.array([L[0] or 0.0, L[1] or 0.0])
        p = poses[:, :2] + shift
        # the image's bounding box within margin of the box
        near = ((p[:, 0] + extent[:, 1] > xmin - margin) & (p[:, 0] + extent[:, 0] < xmax + margin)
                & (p[:, 1] + extent[:, 3] > ymin - margin) & (p[:, 1] + extent[:, 2] < ymax + margin))
        if di == 0 and dj == 0:
            near[:] = True
        sel = np.flatnonzero(near)
        body.append(sel)
        cell.append(ij[sel])
    body = np.concatenate(body)
    cell = np.vstack(cell)
    order = np.argsort(body, kind="stable")
    body, cell = body[order], cell[order]
    shift = cell * np.array([L[0] or 0.0, L[1] or 0.0])
    return PeriodicImages(body=body.astype(np.int64), cell=cell.astype(np.int64), shift=shift)


def _exit_point(p, q, box, axes=("x", "y")):
    """Where segments from ``p (k, 2)`` (inside) to ``q (k, 2)`` (outside) leave the box through
    a side of the periodic ``axes``: the points ``(k, 2)`` and the side ``(k,)`` (0 bottom,
    1 right, 2 top, 3 left)."""
    xmin, xmax, ymin, ymax = box
    d = q - p
    py, px = "y" in axes, "x" in axes
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.column_stack([np.where(py & (d[:, 1] < 0), (ymin - p[:, 1]) / d[:, 1], np.inf),
                             np.where(px & (d[:, 0] > 0), (xmax - p[:, 0]) / d[:, 0], np.inf),
                             np.where(py & (d[:, 1] > 0), (ymax - p[:, 1]) / d[:, 1], np.inf),
                             np.where(px & (d[:, 0] < 0), (xmin - p[:, 0]) / d[:, 0], np.inf)])
    side = np.argmin(t, axis=1)
    tt = np.clip(t[np.arange(len(p)), side], 0.0, 1.0)
    x = p + tt[:, None] * d
    x[side == 0, 1] = ymin
    x[side == 1, 0] = xmax
    x[side == 2, 1] = ymax
    x[side == 3, 0] = xmin
    return x, side


@dataclass(frozen=True)
class SeamClip:
    """An outline PSLG clipped by the box (:func:`clip_at_seams`).

    Attributes
    ----------
    keep : (n_nodes,) bool
        Nodes kept (outline and contact nodes outside the box are dropped).
    segments : (s, 2) int
        Outline segments in the numbering *after* appending the seam nodes (old nodes keep
        their index; seam node ``k`` is ``n_nodes + k``), not yet renumbered for ``keep``.
    seam_points : (k, 2) float
        The seam nodes, on the box sides.
    seam_side : (k,) int
        Their side (0 bottom, 1 right, 2 top, 3 left).
    seam_inner, seam_outer : (k,) int
        The ends of the clipped segment: the node inside and the one outside the box.
    """

    keep: np.ndarray
    segments: np.ndarray
    seam_points: np.ndarray
    seam_side: np.ndarray
    seam_inner: np.ndarray
    seam_outer: np.ndarray


def clip_at_seams(nodes, segments, box, axes) -> SeamClip:
    """Clip the outline segments ``(s, 2)`` over ``nodes (n, 2)`` (outline and contact nodes)
    at the periodic sides of ``box`` (module docstring).  No node lies on a periodic side
    (the images are nudged off it, :func:`seam_nudge`)."""
    xmin, xmax, ymin, ymax = box
    p = np.asarray(nodes, dtype=float)
    inside = np.ones(len(p), dtype=bool)
    if "x" in axes:
        inside &= (p[:, 0] > xmin) & (p[:, 0] < xmax)
    if "y" in axes:
        inside &= (p[:, 1] > ymin) & (p[:, 1] < ymax)
    a, b = segments[:, 0], segments[:, 1]
    ia, ib = inside[a], inside[b]
    both = ia & ib
    cross = ia ^ ib
    inner = np.where(ia, a, b)[cross]
    outer = np.where(ia, b, a)[cross]
    x, side = _exit_point(p[inner], p[outer], box, axes)
    seam = len(p) + np.arange(len(inner))
    cs = segments[cross].copy()
    # keep the orientation of the outline: replace the outside end by the seam node
    cs[:, 0] = np.where(ia[cross], cs[:, 0], seam)
    cs[:, 1] = np.where(ia[cross], seam, cs[:, 1])
    # a segment with both ends outside that cuts a corner of the box: two seam nodes and the
    # piece between them (an image's edge next to a corner of a doubly periodic box)
    out = np.flatnonzero(~ia & ~ib)
    t_in, t_out, side_in, side_out = _through_box(p[a[out]], p[b[out]], box, axes)
    thru = out[t_out - t_in > 1e-9]
    if len(thru):
        keep = t_out - t_in > 1e-9
        d = p[b[thru]] - p[a[thru]]
        x_in = _on_side(p[a[thru]] + t_in[keep, None] * d, side_in[keep], box)
        x_out = _on_side(p[a[thru]] + t_out[keep, None] * d, side_out[keep], box)
        m = len(thru)
        first = len(p) + len(inner)
        x = np.vstack([x, x_in, x_out])
        side = np.concatenate([side, side_in[keep], side_out[keep]])
        inner = np.concatenate([inner, a[thru], a[thru]])
        outer = np.concatenate([outer, b[thru], b[thru]])
        cs = np.vstack([cs, np.column_stack([first + np.arange(m), first + m + np.arange(m)])])
    return SeamClip(keep=inside, segments=np.vstack([segments[both], cs]), seam_points=x, seam_side=side,
                    seam_inner=inner, seam_outer=outer)


def _through_box(p, q, box, axes):
    """Where segments ``p (k, 2)`` – ``q (k, 2)`` enter and leave the box across its periodic
    ``axes`` (Liang & Barsky 1984): parameters ``t_in``, ``t_out (k,)`` (``t_out <= t_in``: the
    segment misses the box) and the sides ``(k,)`` it enters and leaves by."""
    xmin, xmax, ymin, ymax = box
    d = q - p
    k = len(p)
    t_in, t_out = np.zeros(k), np.ones(k)
    side_in, side_out = np.zeros(k, dtype=np.int64), np.zeros(k, dtype=np.int64)
    for c, ax, lo, hi, lo_side, hi_side in ((0, "x", xmin, xmax, 3, 1), (1, "y", ymin, ymax, 0, 2)):
        if ax not in axes:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            t_lo, t_hi = (lo - p[:, c]) / d[:, c], (hi - p[:, c]) / d[:, c]
        flat = d[:, c] == 0.0
        enter = np.where(flat, np.where((p[:, c] > lo) & (p[:, c] < hi), -np.inf, np.inf), np.minimum(t_lo, t_hi))
        leave = np.where(flat, np.where((p[:, c] > lo) & (p[:, c] < hi), np.inf, -np.inf), np.maximum(t_lo, t_hi))
        later, sooner = enter > t_in, leave < t_out
        side_in = np.where(later, np.where(d[:, c] > 0, lo_side, hi_side), side_in)
        side_out = np.where(sooner, np.where(d[:, c] > 0, hi_side, lo_side), side_out)
        t_in, t_out = np.maximum(t_in, enter), np.minimum(t_out, leave)
    return t_in, t_out, side_in, side_out


def _on_side(x, side, box):
    """Points ``x (k, 2)`` put exactly on their ``side (k,)`` line (0 bottom, 1 right, 2 top, 3 left)."""
    xmin, xmax, ymin, ymax = box
    x = x.copy()
    x[side == 0, 1] = ymin
    x[side == 1, 0] = xmax
    x[side == 2, 1] = ymax
    x[side == 3, 0] = xmin
    return x


def seam_nudge(points, body, n_bodies: int, box, axes, band: float) -> np.ndarray:
    """Per body a shift ``(n_bodies, 2)`` (length units, a few ``band``) that puts every one of its
    outline ``points (m, 2)`` (bodies ``body (m,)``) at least ``band`` off the periodic side
    lines: an edge or a vertex of a body exactly on a seam would be meshed on one side and
    not the other.  Zero for the bodies clear of them; the mesh holds the body nudged by it
    until the next triangulation (a geometric change of ~1e-3 h)."""
    xmin, xmax, ymin, ymax = box
    out = np.zeros((n_bodies, 2))
    for c, (a, lo, L) in enumerate((("x", xmin, xmax - xmin), ("y", ymin, ymax - ymin))):
        if a not in axes or not len(points):
            continue
        r = np.mod(points[:, c] - lo + 0.5 * L, L) - 0.5 * L  # signed distance to the nearest seam line
        need = np.zeros(n_bodies, dtype=bool)
        np.logical_or.at(need, body, np.abs(r) <= band)
        todo = need.copy()
        for k in (2, -2, 4, -4, 6, -6, 8, -8):  # a few tries; bodies have few nodes near a seam
            if not todo.any():
                break
            bad = np.zeros(n_bodies, dtype=bool)
            np.logical_or.at(bad, body, np.abs(r + k * band) <= band)
            ok = todo & ~bad
            out[ok, c] = k * band
            todo &= ~ok
    return out


def pair_seam_nodes(points, side, box, tol: float):
    """Seam nodes ``points (k, 2)`` on their ``side (k,)`` put exactly on the place of their
    partner across the side pair (the mean of the two), and the places ``(m, 2)`` on the other
    side where a seam node has none within ``tol`` (length units).

    The two images of a body cross a side pair on the same segment, so partners agree to
    round-off; the closed outline of bodies in contact across a seam is built from each
    side's bodies and may differ by more (a simplification step on other coordinates): the
    partners are then made equal here, and a seam node without one gets a box node at its
    partner's place (:func:`fluidem.mesh.periodic.check_matched` needs every node matched).
    """
    p = np.array(points, dtype=float)
    side = np.asarray(side)
    alone = []
    for lo_side, hi_side, c in ((3, 1, 1), (0, 2, 0)):
        a = np.flatnonzero(side == lo_side)
        b = np.flatnonzero(side == hi_side)
        paired_b = np.zeros(len(b), dtype=bool)
        if len(a) and len(b):
            d = np.abs(p[a, c][:, None] - p[b, c][None, :])  # along the side: few seam nodes
            j = np.argmin(d, axis=1)
            ok = d[np.arange(len(a)), j] <= tol
            mean = 0.5 * (p[a[ok], c] + p[b[j[ok]], c])
            p[a[ok], c] = mean
            p[b[j[ok]], c] = mean
            paired_b[j[ok]] = True
            a_alone = a[~ok]
        else:
            a_alone = a
        alone += [a_alone, b[~paired_b]]
    idx = np.concatenate(alone)
    return p, partner_places(p[idx], side[idx], box)


def covered_side_nodes(points, solids, seam_points, merge, box) -> np.ndarray:
    """Mask ``(k,)`` of box nodes ``points (k, 2)`` that are no fluid boundary: inside one of
    the ``solids`` (shapely geometries, partly outside the box), or closer than
    ``merge`` (length units, scalar or ``(k,)``) to a seam node ``seam_points (c, 2)``."""
    out = np.zeros(len(points), dtype=bool)
    if not len(points):
        return out
    if len(solids):
        # the closed solids: a box node on a body's edge along the side is none either
        xmin, xmax, ymin, ymax = box
        tol = 1e-9 * max(xmax - xmin, ymax - ymin)
        u = shapely.union_all(np.asarray(solids, dtype=object))
        shapely.prepare(u)
        out |= shapely.dwithin(u, shapely.points(points), tol)
    if len(seam_points):
        from scipy.spatial import cKDTree

        d, _ = cKDTree(seam_points).query(points)
        out |= d < merge
    return out


def seam_positions(p_inner, p_outer, side, box, old) -> np.ndarray:
    """Seam nodes ``(k, 2)`` at the crossing of the segments ``p_inner (k, 2)`` – ``p_outer (k, 2)``
    with their ``side (k,)`` line; where a segment no longer crosses that line (parallel to
    it) the ``old (k, 2)`` position is kept.  Between re-triangulations the seam nodes so
    stay on the moving outlines and on their sides (exactly: the coordinate across the side
    is set, not computed)."""
    xmin, xmax, ymin, ymax = box
    d = p_outer - p_inner
    c = np.where((side == 1) | (side == 3), 0, 1)  # coordinate across the side
    level = np.select([side == 0, side == 1, side == 2, side == 3], [ymin, xmax, ymax, xmin])
    k = np.arange(len(side))
    den = d[k, c]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (level - p_inner[k, c]) / den
    ok = np.isfinite(t) & (np.abs(den) > 0)
    x = p_inner + np.where(ok, t, 0.0)[:, None] * d
    x[k, c] = level
    return np.where(ok[:, None], x, old)
