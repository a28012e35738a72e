"""Mesh dragging (paper Sec. 4.2): the bodies carry the mesh around them between re-triangulations.

Each step

1. outline and contact nodes move rigidly with their body;
2. free nodes within ``drag_full · h`` of a body follow its rigid motion fully, with a
   weight falling linearly to zero at ``drag_reach · h`` (:func:`drag_association`; the
   weighted rigid displacements of several bodies are averaged, divided by
   ``max(Σ w, 1)``); junction nodes keep their barycentric place between their three
   outline nodes;
3. a dragged displacement that would invert an element which the rigid motion alone keeps
   valid is halved for that element's nodes, up to ``drag_halvings`` times, then those
   nodes move rigidly only (:func:`dragged_positions`).

Relaxation then spreads the rest, with a step reduced by ``1 − drag_stiffness · w_max`` for
dragged nodes (``relax_damping``).

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.drag import rigid_displacement
>>> d = rigid_displacement(np.array([[1.0, 0.0]]), np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, np.pi / 2]]))
>>> np.round(d, 12).tolist()      # a quarter turn about the origin
[[-1.0, 1.0]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import rotate
from .nodes import OUTLINE, world
from .relax import signed_areas

__all__ = ["DragAssociation", "drag_association", "rigid_displacement", "dragged_positions"]


@dataclass(frozen=True)
class DragAssociation:
    """Which free nodes each body drags, and how strongly.

    Attributes
    ----------
    node, body : (k,) int
        Pairs (node, body) with the node within ``drag_reach · h`` of the body's outline.
    weight : (k,) float
        Drag weight in [0, 1] of every pair.
    relax_damping : (n_nodes,) float
        Relaxation step factor ``1 − drag_stiffness · max weight`` per node.
    """

    node: np.ndarray
    body: np.ndarray
    weight: np.ndarray
    relax_damping: np.ndarray


def drag_association(points, h_node, drag_mobility, table, drag_reach: float, drag_full: float,
                     drag_stiffness: float) -> DragAssociation:
    """Pairs (free node, body) within ``drag_reach · h`` and their drag weights.

    ``drag_mobility (n, 2)``: nodes with a non-zero entry are dragged; ``table``: the
    bodies' :class:`~fluidem.mesh.proximity.PolygonTable` (``None`` without bodies).
    """
    free = np.flatnonzero((drag_mobility != 0.0).any(axis=1))
    if table is None or not len(free) or drag_reach <= 0:
        return DragAssociation(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0),
                               np.ones(len(points)))
    reach = drag_reach * h_node[free]
    ii, bb, dist = table.pairs_within(points[free], reach)
    node = free[ii]
    full = drag_full * h_node[free][ii]
    weight = np.clip((reach[ii] - dist) / np.maximum(reach[ii] - full, 1e-300), 0.0, 1.0)
    wmax = np.zeros(len(points))
    np.maximum.at(wmax, node, weight)
    return DragAssociation(node, bb, weight, 1.0 - drag_stiffness * wmax)


def rigid_displacement(points, pose_old, pose_new) -> np.ndarray:
    """Displacement ``(k, 2)`` of ``points (k, 2)`` under the rigid motion of their body from
    ``pose_old (k, 3)`` to ``pose_new (k, 3)``."""
    r = points - pose_old[:, :2]
    return rotate(r, pose_new[:, 2] - pose_old[:, 2]) + pose_new[:, :2] - points


def dragged_positions(points, triangles, kind, outline_row, outline_local, outline_body, contact_nodes,
                      contact_local, body_of, drag_mobility, assoc: DragAssociation, junction_nodes, junction_verts,
                      junction_bary, poses_old, poses_new, max_halvings: int) -> np.ndarray:
    """Node positions ``(n, 2)`` after steps 1–3 of the module docstring.

    Parameters
    ----------
    points : (n, 2) float
        Current positions; ``triangles (m, 3)`` the connectivity, ``kind (n,)`` the kinds.
    outline_row : (n,) int
        Outline-table row of outline nodes; ``outline_local``, ``outline_body``: the table.
    contact_nodes : (c,) int
        Contact nodes, with ``contact_local (c, 2)`` their body-frame positions and
        ``body_of (n,)`` the body of every node.
    drag_mobility : (n, 2) float
        Zero rows: nodes that are not dragged.
    assoc : DragAssociation
    junction_nodes, junction_verts, junction_bary : (j,), (j, 3), (j, 3)
        Junction nodes, the outline triangle they split and their barycentric coordinates.
    poses_old, poses_new : (n_bodies, 3) float
    max_halvings : int
        ``drag_halvings``.
    """
    rigid = points.copy()
    # 1. outline and contact nodes move rigidly with their body (Sec. 4.2)
    outline_nodes = np.flatnonzero(kind == OUTLINE)
    rows = outline_row[outline_nodes]
    rigid[outline_nodes] = world(outline_local[rows], outline_body[rows], poses_new)
    ci = contact_nodes
    if len(ci):
        rigid[ci] = world(contact_local, body_of[ci], poses_new)
    fixed = (drag_mobility == 0.0).all(axis=1)
    n = len(rigid)
    # 2. drag: free nodes near a body follow its rigid motion, weights of several bodies averaged
    drag_disp = np.zeros_like(rigid)
    if len(assoc.node):
        rigid_disp = rigid_displacement(points[assoc.node], poses_old[assoc.body], poses_new[assoc.body])
        w = assoc.weight
        wsum = np.bincount(assoc.node, w, n)
        dx = np.bincount(assoc.node, w * rigid_disp[:, 0], n)
        dy = np.bincount(assoc.node, w * rigid_disp[:, 1], n)
        norm = np.maximum(wsum, 1.0)
        drag_disp = np.column_stack([dx / norm, dy / norm]) * drag_mobility
    dragged = rigid + np.where(fixed[:, None], 0.0, drag_disp)
    if len(junction_nodes):
        # junction nodes keep their barycentric place between their three outline nodes
        dragged[junction_nodes] = np.einsum("kj,kjd->kd", junction_bary, rigid[junction_verts])
    # 3. a dragged free node must not invert an element that rigid motion alone keeps valid
    a_rigid = signed_areas(rigid, triangles)
    bad = (signed_areas(dragged, triangles) <= 0) & (a_rigid > 0)
    for _ in range(max_halvings):
        if not bad.any():
            break
        hit = np.zeros(n, dtype=bool)
        hit[triangles[bad].ravel()] = True
        hit &= ~fixed
        drag_disp[hit] *= 0.5
        dragged = rigid + np.where(fixed[:, None], 0.0, drag_disp)
        bad = (signed_areas(dragged, triangles) <= 0) & (a_rigid > 0)
    if bad.any():
        hit = np.zeros(n, dtype=bool)
        hit[triangles[bad].ravel()] = True
        dragged[hit & ~fixed] = rigid[hit & ~fixed]
    return dragged
