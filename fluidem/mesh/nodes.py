"""Node kinds of the moving mesh: background, box side and corner, body outline, junction and
contact nodes, their unique ids, and the rigid body frames they move with (paper Sec. 2.1).

Every node of a :class:`fluidem.mesh.MovingMesh` has a *kind* (the constants below), and a
*uid* that survives re-triangulations (so a field can follow the node, and the mesh
velocity of :meth:`~fluidem.mesh.MovingMesh.node_velocity` is a finite difference):
background nodes keep their row in the background set, outline nodes ``UID_OUTLINE + i``
for row ``i`` of the outline table, and nodes made later (contact, junction, inserted
nodes) draw from a :class:`UidSource` starting at ``UID_NEW``.

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.nodes import classify_box, CORNER, SIDE, FREE
>>> kind, side = classify_box(np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]), (0, 1, 0, 1))
>>> kind.tolist() == [CORNER, SIDE, FREE], side.tolist()
(True, [0, 0, -1])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import rigid_transform, to_body_frame, validate_polygon
from .background import friedrichs_keller_grid, subdivide_segment
from .kinds import CONTACT, CORNER, FREE, JUNCTION, OUTLINE, SIDE
from .triangulate import graded_background

__all__ = ["FREE", "SIDE", "CORNER", "OUTLINE", "JUNCTION", "CONTACT", "UID_OUTLINE", "UID_NEW",
           "FIRST_BODY_MARKER", "UidSource", "BodyOutlines", "BackgroundNodes", "body_vertices", "world",
           "to_body", "classify_box", "box_ring", "outline_nodes", "background_nodes", "mobility"]

#: uid of outline table row ``i``: ``UID_OUTLINE + i``
UID_OUTLINE = 1 << 40
#: first uid of nodes created after the set-up
UID_NEW = 1 << 50
#: boundary marker of body ``b``: ``FIRST_BODY_MARKER + b`` (box sides are 1..4)
FIRST_BODY_MARKER = 10


class UidSource:
    """Hands out fresh node uids, ``UID_NEW, UID_NEW + 1, ...``."""

    def __init__(self, first: int = UID_NEW):
        self.next = int(first)

    def take(self, n: int) -> np.ndarray:
        """``n`` fresh uids ``(n,)`` int64."""
        out = self.next + np.arange(n)
        self.next += n
        return out


@dataclass(frozen=True)
class BodyOutlines:
    """The fixed outline nodes of every body, in body coordinates.

    Attributes
    ----------
    local : (n_outline, 2) float
        Positions in the body frame, length units.
    body : (n_outline,) int
        Body of every row.
    next : (n_outline,) int
        Row of the next node along the (counter-clockwise) outline of the same body.
    uid : (n_outline,) int or None
        Node uid of every row (periodic images of one body need their own); ``None``:
        ``UID_OUTLINE + row``.
    """

    local: np.ndarray
    body: np.ndarray
    next: np.ndarray
    uid: np.ndarray | None = None

    def row_uid(self, rows) -> np.ndarray:
        """Node uids ``(k,)`` of outline table ``rows (k,)``."""
        rows = np.asarray(rows, dtype=np.int64)
        return UID_OUTLINE + rows if self.uid is None else self.uid[rows]

    def world(self, poses) -> np.ndarray:
        """Positions ``(n_outline, 2)`` at ``poses`` ``(n_bodies, 3)``."""
        return world(self.local, self.body, poses)


@dataclass(frozen=True)
class BackgroundNodes:
    """Background candidate nodes: positions ``(n, 2)``, kinds ``(n,)`` int8, uids ``(n,)``."""

    points: np.ndarray
    kind: np.ndarray
    uid: np.ndarray


def body_vertices(b, i: int):
    """Validated outline ``(n, 2)`` and name of body ``i`` (an array or an object with
    ``.vertices`` and optionally ``.name``)."""
    v = getattr(b, "vertices", b)
    name = getattr(b, "name", None) or f"body{i}"
    return validate_polygon(v, f"body {i} ({name})"), name


def world(local, body, poses) -> np.ndarray:
    """World positions ``(m, 2)`` of body-frame points ``local (m, 2)`` of bodies ``body (m,)``
    at ``poses (n_bodies, 3)`` (x, y, angle): ``x = R(θ) local + (x, y)`` (:func:`fluidem.geometry.rigid_transform`)."""
    return rigid_transform(local, poses, body)


def to_body(points, pose_rows) -> np.ndarray:
    """Body-frame positions ``(m, 2)`` of world ``points (m, 2)``; ``pose_rows (m, 3)``:
    the pose of each point's body (the inverse of :func:`world`; :func:`fluidem.geometry.to_body_frame`)."""
    return to_body_frame(points, pose_rows)


def classify_box(points, box):
    """Kinds ``(n,)`` int8 (``CORNER``, ``SIDE`` or ``FREE``) and side ``(n,)`` (0 bottom, 1 right,
    2 top, 3 left; -1 off the box) of ``points (n, 2)`` in ``box = (xmin, xmax, ymin, ymax)``."""
    xmin, xmax, ymin, ymax = box
    tol = 1e-9 * max(xmax - xmin, ymax - ymin)
    on = np.column_stack([
        np.abs(points[:, 1] - ymin) < tol, np.abs(points[:, 0] - xmax) < tol,
        np.abs(points[:, 1] - ymax) < tol, np.abs(points[:, 0] - xmin) < tol,
    ])
    cnt = on.sum(axis=1)
    kind = np.where(cnt >= 2, CORNER, np.where(cnt == 1, SIDE, FREE)).astype(np.int8)
    side = np.where(cnt >= 1, np.argmax(on, axis=1), -1)
    return kind, side


def box_ring(points, kind, box, extra=None):
    """Segments ``(k, 2)`` of the box outline through the side/corner nodes, counter-clockwise,
    and their markers ``(k,)`` (1 bottom, 2 right, 3 top, 4 left).

    ``extra``: indices of further nodes on the box sides taken into the ring (the wall
    contact nodes of :mod:`fluidem.mesh.contact_outline`)."""
    xmin, xmax, ymin, ymax = box
    W, H = xmax - xmin, ymax - ymin
    idx = np.flatnonzero((kind == SIDE) | (kind == CORNER))
    if extra is not None and len(extra):
        idx = np.concatenate([idx, np.asarray(extra, dtype=np.int64)])
    p = points[idx]
    _, side = classify_box(p, box)
    s = np.select(
        [side == 0, side == 1, side == 2, side == 3],
        [p[:, 0] - xmin, W + p[:, 1] - ymin, W + H + xmax - p[:, 0], 2 * W + H + ymax - p[:, 1]],
    )
    # corners: the side that starts at them
    order = np.argsort(s, kind="stable")
    ring = idx[order]
    seg = np.column_stack([ring, np.roll(ring, -1)])
    mid = 0.5 * (points[seg[:, 0]] + points[seg[:, 1]])
    _, mside = classify_box(mid, box)
    return seg, mside + 1


def outline_nodes(verts_local, poses, size, h: float) -> BodyOutlines:
    """Outline nodes of every body: its polygon edges subdivided at ``min(size, h)`` around
    the body at ``poses``, corners exactly as given (set-up, once per body).

    ``verts_local``: the outlines ``(n_i, 2)`` in body coordinates; ``size``: the size field
    ``points (m, 2) -> (m,)``.
    """
    loc, body, nxt = [], [], []
    off = 0
    clipped = lambda p: np.minimum(np.asarray(size(p), float), h)  # noqa: E731
    for b, v in enumerate(verts_local):  # set-up only, once per body
        w = world(v, np.zeros(len(v), dtype=np.int64), poses[b:b + 1])
        pieces = [subdivide_segment(w[i], w[(i + 1) % len(w)], clipped)[:-1] for i in range(len(w))]
        ring = to_body(np.vstack(pieces), np.repeat(poses[b:b + 1], sum(len(pc) for pc in pieces), axis=0))
        # corners exactly as given
        k = 0
        for i, pc in enumerate(pieces):
            ring[k] = v[i]
            k += len(pc)
        n = len(ring)
        loc.append(ring)
        body.append(np.full(n, b))
        nxt.append(off + (np.arange(n) + 1) % n)
        off += n
    return BodyOutlines(
        local=np.vstack(loc) if loc else np.zeros((0, 2)),
        body=np.concatenate(body) if body else np.zeros(0, dtype=np.int64),
        next=np.concatenate(nxt) if nxt else np.zeros(0, dtype=np.int64),
    )


def background_nodes(box, h: float, size, kind: str, periodic=()) -> BackgroundNodes:
    """Background nodes: the Friedrichs–Keller grid of spacing ``h`` (``kind == "fk"``) or a
    graded Delaunay point set of the size field ``size`` (``"delaunay"``), Sec. 2.1, 2.3;
    nodes matched on the sides of the ``periodic`` axes (:mod:`fluidem.mesh.periodic`)."""
    if kind == "fk":
        pts, _ = friedrichs_keller_grid(box, h)
    else:
        pts = graded_background(box, size, periodic=periodic)
    node_kind, _ = classify_box(pts, box)
    return BackgroundNodes(points=pts, kind=node_kind, uid=np.arange(len(pts), dtype=np.int64))


def mobility(kind, points, box) -> np.ndarray:
    """Relaxation mobility mask ``(n, 2)`` in {0, 1}: outline, contact, junction nodes and box
    corners are fixed, side nodes slide along their side (:mod:`fluidem.mesh.relax`)."""
    mob = np.ones((len(kind), 2))
    # junction nodes sit where the junction has no room for a relaxed node: they are
    # placed (Sec. 3.2) and dragged, not relaxed
    mob[(kind == OUTLINE) | (kind == CONTACT) | (kind == CORNER) | (kind == JUNCTION)] = 0.0
    side_idx = np.flatnonzero(kind == SIDE)
    _, side = classify_box(points[side_idx], box)
    if len(side_idx):
        horiz = (side == 0) | (side == 2)
        mob[side_idx[horiz], 1] = 0.0
        mob[side_idx[~horiz], 0] = 0.0
    return mob
