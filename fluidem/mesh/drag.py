"""Mesh dragging (paper Sec. 4.2): the bodies carry the mesh around them between re-triangulations.

Each step

1. outline and contact nodes move rigidly with their body;
2. free nodes within ``drag_full · h`` of a body follow its rigid motion fully (the
   weighted rigid displacements of several bodies averaged, divided by ``max(Σ w, 1)``,
   with the weights of :func:`drag_association`); junction nodes keep their barycentric
   place between their three outline nodes; the other free nodes

   - ``drag_field="harmonic"`` (default): get the discrete harmonic extension of these
     displacements (graph Laplacian of the mesh edges, eq. ``Σ_j (d_i − d_j) = 0`` per
     free node, Laplacian mesh motion of ALE), with the box sides as sliding walls (the
     normal component is zero, the tangential one free, also for the free nodes next to
     a side, so that wall elements are not flattened): the shear and compression that
     follow a body's motion spread over the whole fluid region, not over a band of
     ``drag_reach − drag_full`` elements (:func:`harmonic_drag`, factorised once per
     triangulation);
   - ``drag_field="ramp"``: follow with the weight falling linearly from 1 at
     ``drag_full · h`` to zero at ``drag_reach · h``;
3. a dragged displacement that would invert an element which the rigid motion alone keeps
   valid is halved for that element's nodes, up to ``drag_halvings`` times, then those
   nodes move rigidly only (:func:`dragged_positions`).

Relaxation then spreads the rest, with a step reduced by ``1 − drag_stiffness · w_max`` for
dragged nodes (``relax_damping``).

Why the harmonic field: the association is fixed between re-triangulations, so with the
ramp a body translating by ``s`` per step shears the band between ``drag_full · h`` and
``drag_reach · h`` by ``s / ((drag_reach − drag_full) h)`` more every step, and an element
of the band crosses 135° after a shear of about 0.6–1: a plate moving 0.25 h per step
re-triangulated for ``"quality"`` every 4–8 steps (23 times in 100 steps), whatever the
rotation and the relaxation (which keeps the connectivity and cannot undo a shear).  The
harmonic extension spreads the same motion over the distance to the walls.

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
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..geometry import rotate
from .nodes import FREE, JUNCTION, OUTLINE, SIDE, world
from .relax import MeshTopology, signed_areas

__all__ = ["DragAssociation", "HarmonicDrag", "drag_association", "harmonic_drag", "rigid_displacement",
           "dragged_positions", "clamp_to_sides"]


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


class HarmonicDrag:
    """Factorised discrete harmonic extension of the displacements of the constrained nodes.

    Per component ``c`` the free nodes ``F`` solve ``L_FF d_F = −L_FD d_D`` (``L`` the graph
    Laplacian of the mesh edges, ``D`` the constrained nodes of that component).

    Parameters
    ----------
    topo : MeshTopology
        The mesh (its edges).
    constrained : (n_nodes, 2) bool
        Nodes whose displacement component is given (outline, contact and junction nodes,
        fully dragged nodes, the normal component of box-side nodes, box corners).
    pairs : (k, 2) int, optional
        Matched nodes of periodic sides that bend (:mod:`fluidem.mesh.seam`): each pair is one
        node of the periodic strip, so the Laplacian is that of the strip (``P^T L P`` with
        ``P`` the map of the nodes onto the strip's) and both partners get the same
        displacement; a pair with one partner constrained takes its value (the mean if both
        are).  Without pairs a side node sees the neighbours on its side only: the two
        partners get different one-sided extensions.

    Examples
    --------
    >>> import numpy as np
    >>> from fluidem.mesh.relax import mesh_topology
    >>> topo = mesh_topology(np.array([[0, 1, 2], [1, 3, 2]]))   # four nodes, five edges
    >>> con = np.array([[True, True], [False, False], [False, False], [True, True]])
    >>> d = np.array([[0.0, 0.0], [9.0, 9.0], [9.0, 9.0], [1.0, 2.0]])
    >>> HarmonicDrag(topo, con).extend(d).tolist()   # 1 and 2: the mean of their neighbours
    [[0.0, 0.0], [0.5, 1.0], [0.5, 1.0], [1.0, 2.0]]
    """

    def __init__(self, topo: MeshTopology, constrained, pairs=None):
        e0, e1 = topo.e0, topo.e1
        n = len(constrained)
        w = sp.coo_matrix((np.ones(len(e0)), (e0, e1)), shape=(n, n)).tocsr()
        w = w + w.T
        self._factor((sp.diags(np.asarray(w.sum(axis=1)).ravel()) - w).tocsr(), np.asarray(constrained, dtype=bool),
                     pairs)

    def _factor(self, lap, constrained, pairs=None):
        self.lap, self.constrained, self.pairs = lap, constrained, pairs
        self.strip = None
        if pairs is not None and len(pairs):
            # the nodes of the periodic strip: the second partner of each pair is the first
            n = len(constrained)
            rep = np.arange(n)
            rep[np.asarray(pairs)[:, 1]] = np.asarray(pairs)[:, 0]
            keep, node_of = np.unique(rep, return_inverse=True)
            strip = sp.csr_matrix((np.ones(n), (np.arange(n), node_of)), shape=(n, len(keep)))
            lap = (strip.T @ lap @ strip).tocoo()
            # an edge along the side is there twice (once on each side): one edge of the strip
            off = lap.row != lap.col
            w = sp.coo_matrix((np.minimum(-lap.data[off], 1.0), (lap.row[off], lap.col[off])), shape=lap.shape)
            lap = (sp.diags(np.asarray(w.sum(axis=1)).ravel()) - w).tocsr()
            given = np.column_stack([strip.T @ constrained[:, c].astype(float) for c in range(2)])
            self.strip = (strip, node_of, given)
            constrained = given > 0
        self.parts = []
        for c in range(2):
            free = np.flatnonzero(~constrained[:, c])
            fixed = np.flatnonzero(constrained[:, c])
            if not len(free):
                continue
            rows = lap[free]
            # L_FF is symmetric positive definite: a symmetric fill-reducing ordering and no
            # pivoting (SuperLU's symmetric mode) give 2/3 of the fill of the default COLAMD
            # ordering, and solves 1.6 x faster (10.7k free nodes: 0.96 against 1.54 ms)
            lu = splu(rows[:, free].tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options={"SymmetricMode": True})
            self.parts.append((c, free, fixed, lu, rows[:, fixed].tocsr()))

    def __getstate__(self):
        # SuperLU objects do not pickle: the Laplacian and the constraints do, and are factorised again
        return {"lap": self.lap, "constrained": self.constrained, "pairs": self.pairs}

    def __setstate__(self, state):
        self._factor(state["lap"], state["constrained"], state.get("pairs"))

    def extend(self, disp) -> np.ndarray:
        """``disp (n_nodes, 2)`` with the free components replaced by the harmonic extension."""
        d = np.array(disp, dtype=float)
        if self.strip is None:
            for c, free, fixed, lu, coupling in self.parts:
                d[free, c] = lu.solve(-(coupling @ d[fixed, c]))
            return d
        strip, node_of, given = self.strip
        for c, free, fixed, lu, coupling in self.parts:
            # the strip's given values: the mean over the constrained partners of a node
            con = self.constrained[:, c]
            ds = (strip.T @ np.where(con, d[:, c], 0.0)) / np.maximum(given[:, c], 1.0)
            ds[free] = lu.solve(-(coupling @ ds[fixed]))
            d[~con, c] = ds[node_of[~con]]
        return d


def harmonic_drag(topo: MeshTopology, kind, mobility, assoc: DragAssociation, pairs=None) -> HarmonicDrag:
    """The :class:`HarmonicDrag` of a mesh: constrained are the components with zero
    ``mobility (n, 2)`` (outline, contact and corner nodes, the normal one of box-side
    nodes), junction nodes, free nodes fully dragged (``Σ w >= 1`` in ``assoc``, they get
    their dragged displacement) and the wall-normal component of free nodes next to a
    box-side node (it keeps its dragged value, zero away from the bodies: they slide along
    the wall).  ``pairs (k, 2)``: the matched nodes of periodic sides that bend, extended
    over the periodic strip (:class:`HarmonicDrag`)."""
    n = len(kind)
    full = np.bincount(assoc.node, assoc.weight, n) >= 1.0 - 1e-12
    mob = np.asarray(mobility)
    con = (mob == 0.0) | full[:, None] | (kind == JUNCTION)[:, None]
    # free nodes next to a box side keep their distance to it: the first layer of elements
    # on a wall slides along it instead of being flattened against it
    for a, b in ((topo.e0, topo.e1), (topo.e1, topo.e0)):
        on_side = (kind[a] == SIDE) & (kind[b] == FREE)
        for c in range(2):
            con[b[on_side & (mob[a, c] == 0.0)], c] = True
    return HarmonicDrag(topo, con, pairs)


def rigid_displacement(points, pose_old, pose_new) -> np.ndarray:
    """Displacement ``(k, 2)`` of ``points (k, 2)`` under the rigid motion of their body from
    ``pose_old (k, 3)`` to ``pose_new (k, 3)``."""
    r = points - pose_old[:, :2]
    return rotate(r, pose_new[:, 2] - pose_old[:, 2]) + pose_new[:, :2] - points


def clamp_to_sides(points, side, box) -> np.ndarray:
    """``points (k, 2)`` with those of ``side (k,)`` >= 0 put back on that box side (0 bottom,
    1 right, 2 top, 3 left) by their normal coordinate; ``-1``: left as they are."""
    xmin, xmax, ymin, ymax = box
    p = np.array(points, dtype=float)
    p[side == 0, 1] = ymin
    p[side == 1, 0] = xmax
    p[side == 2, 1] = ymax
    p[side == 3, 0] = xmin
    return p


def dragged_positions(points, triangles, kind, outline_row, outline_local, outline_body, contact_nodes,
                      contact_local, body_of, drag_mobility, assoc: DragAssociation, junction_nodes, junction_verts,
                      junction_bary, poses_old, poses_new, max_halvings: int,
                      harmonic: HarmonicDrag | None = None, *, wall_side=None, box=None) -> np.ndarray:
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
    harmonic : HarmonicDrag or None
        The harmonic extension (``drag_field="harmonic"``); ``None``: the ramp.
    wall_side : (c,) int or None
        Box side each contact node slides along (wall nodes of
        :mod:`fluidem.mesh.contact_outline`), ``-1`` for the others; with ``box``.
    box : (xmin, xmax, ymin, ymax) or None
    """
    rigid = points.copy()
    # 1. outline and contact nodes move rigidly with their body (Sec. 4.2)
    outline_nodes = np.flatnonzero(kind == OUTLINE)
    rows = outline_row[outline_nodes]
    rigid[outline_nodes] = world(outline_local[rows], outline_body[rows], poses_new)
    ci = contact_nodes
    if len(ci):
        rigid[ci] = world(contact_local, body_of[ci], poses_new)
        if wall_side is not None and (wall_side >= 0).any():
            # wall nodes slide along their box side with the body
            rigid[ci] = clamp_to_sides(rigid[ci], wall_side, box)
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
    junction_at = np.einsum("kj,kjd->kd", junction_bary, rigid[junction_verts]) if len(junction_nodes) else None
    if harmonic is not None:
        # the other free nodes: harmonic extension of the given displacements (module docstring)
        given = np.where(fixed[:, None], rigid - points, drag_disp)
        if junction_at is not None:
            given[junction_nodes] = junction_at - points[junction_nodes]
        drag_disp = harmonic.extend(given) * (drag_mobility != 0.0)
    dragged = rigid + np.where(fixed[:, None], 0.0, drag_disp)
    if junction_at is not None:
        # junction nodes keep their barycentric place between their three outline nodes
        dragged[junction_nodes] = junction_at
    # 3. a dragged free node must not invert an element that rigid motion alone keeps valid
    bad = signed_areas(dragged, triangles) <= 0
    if not bad.any():  # the common case: no rigid areas needed
        return dragged
    a_rigid = signed_areas(rigid, triangles)
    bad &= a_rigid > 0
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
