"""Contact-outline policy of the moving mesh: bodies closer than ``min_gap`` are meshed as one
closed outline ("closed union outline", module docstring of :mod:`fluidem.mesh.moving`).

For every cluster of bodies in contact (connected components of the pairs closer than
``min_gap``; touching or overlapping, as the DEM allows small overlaps) the fluid region
loses the morphological closing of the union of the cluster: a mitre buffer by
``min_gap/2`` out and back in, simplified at ``min_gap``.  So gaps narrower than ``min_gap``
are filled and no element thinner than ``min_gap`` is produced.  On the closed outline

* outline nodes of the cluster bodies within ``on_outline_factor · min_gap`` of it are kept
  unless they lie inside another body of the cluster (an overlap shallower than that
  tolerance), two closer than ``contact_merge · h`` along it are merged;
* its vertices farther than ``contact_node_spacing · h`` from every kept outline node (deep
  contact points, bridge corners) become *contact nodes*, owned by and moving with the
  nearest body;
* holes of the closed union are *pores*: fluid enclosed by a ring of touching bodies (meshed,
  and reported by area: a pore needs its own pressure reference); so is fluid cut off from
  the rest of the box by bodies in contact with a wall (all fluid regions but the largest).

Walls in contact: a box side closer than ``min_gap`` to a body of a cluster (touching, or
overlapping it up to :meth:`~fluidem.mesh.MovingMesh.allowed_wall_overlap`) is one more
member of that cluster.  It enters the union as a slab outside the box along that side, the closing fills the fluid
between body and wall narrower than ``min_gap``, and the result is clipped to the box.  The
clipped outline runs partly along the box sides: those parts are not fluid boundary (no
segment, the box nodes on them are dropped, :func:`covered_box_nodes`).  Where the outline
leaves a side, a *wall node* is placed: a contact node owned by the nearest body that slides
along its side with the body (``contact_wall``); body outline nodes within
``contact_merge · h`` of it are merged into it, and outline nodes only within ``min_gap`` of
the wall part are dropped.  A cluster that touches no wall is meshed exactly as before.

Examples
--------
>>> import numpy as np, shapely
>>> from fluidem.geometry import rectangle
>>> from fluidem.mesh.nodes import outline_nodes
>>> from fluidem.mesh.params import MeshParams
>>> from fluidem.mesh.contact_outline import contact_outline
>>> poses = np.array([[1.0, 1.0, 0.0], [1.4, 1.0, 0.0]])          # two touching squares
>>> sq = rectangle(0.4, 0.4)
>>> ol = outline_nodes([sq, sq], poses, lambda p: np.full(len(p), 0.1), 0.1)
>>> polys = shapely.polygons([sq + poses[0, :2], sq + poses[1, :2]])
>>> co = contact_outline(polys, shapely.STRtree(polys), ol.world(poses), ol, 0.1, 1e-4, MeshParams())
>>> co.contacts.tolist(), co.clustered.tolist(), len(co.holes)
([[0, 1]], [True, True], 1)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .nodes import BodyOutlines

__all__ = ["ContactOutline", "contact_pairs", "contact_outline", "wall_contacts", "wall_depths",
           "covered_box_nodes"]

#: box side names in the order of :func:`fluidem.mesh.nodes.classify_box`
_SIDES = ("bottom", "right", "top", "left")


@dataclass(frozen=True)
class ContactOutline:
    """The outlines to mesh around the bodies at one configuration.

    Node numbering of ``segments``: rows of the outline table (``0 .. n_outline − 1``), then
    the contact nodes (``n_outline + k``).

    Attributes
    ----------
    contacts : (k, 2) int
        Body pairs closer than ``min_gap``, ``contacts[:, 0] < contacts[:, 1]``.
    clustered : (n_bodies,) bool
        Bodies in a contact cluster.
    pore_areas : (p,) float
        Areas of the pores, length units².
    keep_outline : (n_outline,) bool
        Outline table rows that stay mesh nodes (all of unclustered bodies).
    contact_points : (m, 2) float
        Contact nodes, world coordinates.
    contact_body : (m,) int
        Body each contact node moves with.
    segments : (s, 2) int
        Outline segments (unclustered bodies first, then the closed cluster outlines).
    holes : (r, 2) float
        One point inside every body or closed cluster (Triangle's hole points).
    solids : list of shapely geometries
        The bodies and the closed cluster outlines (what the fluid region excludes).
    walls : (w, 2) int
        ``(body, side)`` pairs closer than ``min_gap`` (side 0 bottom, 1 right, 2 top, 3 left).
    contact_wall : (m,) int
        Side each contact node slides along (a wall node), ``-1`` for the others.
    wall_solids : list of shapely Polygons
        The closed outlines of the clusters in contact with a wall, clipped to the box: box
        nodes and box segments on them are no fluid boundary.
    wall_merge : float
        Box nodes closer than this to a wall node are dropped, length units.
    """

    contacts: np.ndarray
    clustered: np.ndarray
    pore_areas: np.ndarray
    keep_outline: np.ndarray
    contact_points: np.ndarray
    contact_body: np.ndarray
    segments: np.ndarray
    holes: np.ndarray
    solids: list
    walls: np.ndarray = None
    contact_wall: np.ndarray = None
    wall_solids: list = None
    wall_merge: float = 0.0

    def __post_init__(self):
        if self.walls is None:
            object.__setattr__(self, "walls", np.zeros((0, 2), dtype=np.int64))
        if self.contact_wall is None:
            object.__setattr__(self, "contact_wall", np.full(len(self.contact_points), -1, dtype=np.int64))
        if self.wall_solids is None:
            object.__setattr__(self, "wall_solids", [])


def wall_depths(vertices, vertex_body, n_bodies: int, box) -> np.ndarray:
    """Per body and box side the smallest signed distance of a vertex to that side, ``(n_bodies, 4)``
    (sides 0 bottom, 1 right, 2 top, 3 left; negative: the vertex lies outside the box by that much).

    ``vertices (k, 2)`` world coordinates, ``vertex_body (k,)`` their body.
    """
    xmin, xmax, ymin, ymax = box
    v = np.asarray(vertices, dtype=float)
    d = np.column_stack([v[:, 1] - ymin, xmax - v[:, 0], ymax - v[:, 1], v[:, 0] - xmin])
    out = np.full((n_bodies, 4), np.inf)
    for c in range(4):
        np.minimum.at(out[:, c], vertex_body, d[:, c])
    return out


def wall_contacts(vertices, vertex_body, n_bodies: int, box, min_gap: float) -> np.ndarray:
    """``(body, side)`` pairs ``(w, 2)`` closer than ``min_gap`` (:func:`wall_depths`).

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0.1, 0.0], [0.3, 0.0], [0.3, 0.2], [0.1, 0.2]])   # on the floor
    >>> wall_contacts(square, np.zeros(4, dtype=int), 1, (0.0, 1.0, 0.0, 1.0), 1e-4).tolist()
    [[0, 0]]
    """
    b, c = np.nonzero(wall_depths(vertices, vertex_body, n_bodies, box) < min_gap)
    return np.column_stack([b, c]).astype(np.int64)


def covered_box_nodes(points, contact: ContactOutline, tol: float, corner=None) -> np.ndarray:
    """Mask ``(k,)``: box nodes ``points (k, 2)`` that are no fluid boundary, on a closed wall
    cluster (within ``tol``) or, unless a box corner (``corner (k,)`` bool), closer than
    ``contact.wall_merge`` to a wall node."""
    out = np.zeros(len(points), dtype=bool)
    if not contact.wall_solids or not len(points):
        return out
    pts = shapely.points(points)
    for solid in contact.wall_solids:
        out |= shapely.distance(solid, pts) < tol
    wall_nodes = contact.contact_points[contact.contact_wall >= 0]
    if len(wall_nodes):
        d, _ = cKDTree(wall_nodes).query(points)
        near = d < contact.wall_merge
        if corner is not None:
            near &= ~np.asarray(corner, dtype=bool)
        out |= near
    return out


def _box_distance(points, box) -> np.ndarray:
    """Signed distance ``(k,)`` of ``points (k, 2)`` to the nearest box side (negative outside)."""
    xmin, xmax, ymin, ymax = box
    return np.min(np.column_stack([points[:, 1] - ymin, xmax - points[:, 0], ymax - points[:, 1],
                                   points[:, 0] - xmin]), axis=1)


def _snap_to_box(points, box, tol):
    """``points (k, 2)`` within ``tol`` of a box side put exactly on it, and that side ``(k,)``
    (-1 off the box; the first side of a corner)."""
    xmin, xmax, ymin, ymax = box
    p = np.array(points, dtype=float)
    d = np.column_stack([np.abs(p[:, 1] - ymin), np.abs(xmax - p[:, 0]), np.abs(ymax - p[:, 1]),
                         np.abs(p[:, 0] - xmin)])
    on = d < tol
    p[on[:, 0], 1] = ymin
    p[on[:, 1], 0] = xmax
    p[on[:, 2], 1] = ymax
    p[on[:, 3], 0] = xmin
    side = np.where(on.any(axis=1), np.argmax(on, axis=1), -1)
    return p, side


def _slabs(sides, box, thickness):
    """Rectangles outside the box along ``sides`` (the walls as members of a cluster)."""
    xmin, xmax, ymin, ymax = box
    t = thickness
    rect = {0: (xmin - t, ymin - t, xmax + t, ymin), 1: (xmax, ymin - t, xmax + t, ymax + t),
            2: (xmin - t, ymax, xmax + t, ymax + t), 3: (xmin - t, ymin - t, xmin, ymax + t)}
    return [shapely.box(*rect[int(c)]) for c in sides]


def contact_pairs(polys, tree, distance: float) -> np.ndarray:
    """Body pairs ``(k, 2)`` (``i < j``) closer than ``distance``; ``tree``: STR tree of ``polys``."""
    if len(polys) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    a, b = tree.query(polys, predicate="dwithin", distance=distance)
    sel = a < b
    return np.column_stack([a[sel], b[sel]])


def contact_outline(polys, tree, outline_world, outlines: BodyOutlines, h: float, min_gap: float,
                    params, box=None, wall_sides=None) -> ContactOutline:
    """The contact-outline policy (module docstring) at one configuration.

    Parameters
    ----------
    polys : (n_bodies,) shapely Polygons
        The bodies in world coordinates.
    tree : shapely.STRtree or None
        STR tree of ``polys`` (``None`` without bodies).
    outline_world : (n_outline, 2) float
        The outline table at the current poses.
    outlines : BodyOutlines
    h : float
        Target size near the bodies, length units.
    min_gap : float
        Contact distance, length units.
    params : MeshParams
        ``on_outline_factor``, ``contact_merge``, ``contact_node_spacing``, ``mitre_limit``.
    box : (xmin, xmax, ymin, ymax) or None
        The box: its sides closer than ``min_gap`` to a body join that body's cluster
        (``None``: walls are not looked at).
    wall_sides : (4,) bool or None
        Which sides (bottom, right, top, left) are walls; a periodic side is none (a body
        across it is clipped there, :mod:`fluidem.mesh.seam`).  ``None``: all four.
    """
    n_bodies = len(polys)
    n_outline = len(outline_world)
    keep_outline = np.ones(n_outline, dtype=bool)
    solids = list(polys)
    contact_points, contact_body, cluster_segments, holes, pores = [], [], [], [], []
    contact_wall, wall_solids = [], []
    clustered = np.zeros(n_bodies, dtype=bool)
    contacts = contact_pairs(polys, tree, min_gap) if n_bodies > 1 else np.zeros((0, 2), dtype=np.int64)
    walls = _wall_pairs(polys, box, min_gap, wall_sides)
    merge = params.contact_merge * h
    tol_box = 1e-7 * h
    n_contacts = 0
    for members in _clusters(contacts, walls, n_bodies):  # one per contact cluster (few)
        clustered[members] = True
        sides = np.unique(walls[np.isin(walls[:, 0], members), 1])
        comps = _closed_cluster(polys[members], sides, box, h, min_gap, params)
        if len(sides):
            wall_solids.extend(comps)
        rings = []
        for comp in comps:
            solids.append(comp)
            holes.append(np.array(shapely.get_coordinates(shapely.point_on_surface(comp))[0]))
            rings.append(comp.exterior)
            for ring in comp.interiors:
                rings.append(ring)
                pores.append(float(shapely.area(shapely.Polygon(ring))))
        ring_data = [_ring_parts(ring, sides, box, tol_box) for ring in rings]
        member_rows, on, which = _outline_rows_on_rings(ring_data, members, polys, outlines, outline_world,
                                                        h, min_gap, params)
        keep_outline[member_rows[~on]] = False
        for ri, (ring, ring_vertices, forced, wall_side, _) in enumerate(ring_data):
            seg, new_contacts, owner, new_wall = _ring_nodes(
                ring, ring_vertices, forced, wall_side, member_rows[on & (which == ri)], members, polys,
                outline_world, keep_outline, n_outline, n_outline + n_contacts, merge, params.contact_node_spacing * h,
                box, tol_box)
            if seg is not None:
                cluster_segments.append(seg)
            contact_points.append(new_contacts)
            contact_body.append(owner)
            contact_wall.append(new_wall)
            n_contacts += len(new_contacts)

    contact_points = np.vstack(contact_points) if contact_points else np.zeros((0, 2))
    contact_body = np.concatenate(contact_body).astype(np.int64) if len(contact_points) else np.zeros(0, dtype=np.int64)
    # outline segments of unclustered bodies
    unclustered_rows = ~clustered[outlines.body]
    plain_segments = np.column_stack([np.flatnonzero(unclustered_rows), outlines.next[unclustered_rows]])
    plain_holes = (shapely.get_coordinates(shapely.point_on_surface(polys[~clustered]))
                  if n_bodies else np.zeros((0, 2)))
    hole_pts = (np.vstack([plain_holes] + [p[None] for p in holes]) if (len(plain_holes) or holes)
                else np.zeros((0, 2)))
    contact_wall = (np.concatenate(contact_wall).astype(np.int64) if len(contact_points)
                    else np.zeros(0, dtype=np.int64))
    if wall_solids:
        pores.extend(_cut_off_pores(wall_solids, box, tol_box * h))
    return ContactOutline(contacts=contacts, clustered=clustered, pore_areas=np.array(pores),
                          keep_outline=keep_outline, contact_points=contact_points, contact_body=contact_body,
                          segments=np.vstack([plain_segments] + cluster_segments), holes=hole_pts, solids=solids,
                          walls=walls, contact_wall=contact_wall, wall_solids=wall_solids, wall_merge=merge)


def _wall_pairs(polys, box, min_gap: float, wall_sides) -> np.ndarray:
    """``(body, side)`` pairs ``(w, 2)`` of the bodies ``polys`` closer than ``min_gap`` to a wall of
    ``box`` (none without a box or bodies; ``wall_sides (4,)`` bool: the sides that are walls)."""
    walls = np.zeros((0, 2), dtype=np.int64)
    n_bodies = len(polys)
    if box is not None and n_bodies:
        coords, vertex_body = shapely.get_coordinates(shapely.get_exterior_ring(polys), return_index=True)
        walls = wall_contacts(coords, vertex_body, n_bodies, box, min_gap)
        if wall_sides is not None:
            walls = walls[np.asarray(wall_sides, dtype=bool)[walls[:, 1]]]
    return walls


def _clusters(contacts, walls, n_bodies: int) -> list:
    """The contact clusters: per connected component of the ``contacts (k, 2)`` graph that has a
    contact or a wall (``walls (w, 2)``) its member bodies ``(m,)``, in the order of the components."""
    if not (len(contacts) or len(walls)):
        return []
    g = coo_matrix((np.ones(len(contacts)), (contacts[:, 0], contacts[:, 1])), shape=(n_bodies, n_bodies))
    _, cluster_of = connected_components(g, directed=False)
    return [np.flatnonzero(cluster_of == k)
            for k in np.unique(cluster_of[np.concatenate([contacts[:, 0], contacts[:, 1], walls[:, 0]])])]


def _closed_cluster(member_polys, sides, box, h: float, min_gap: float, params) -> list:
    """The polygons of the morphological closing of a cluster's bodies ``member_polys`` and its
    walls ``sides`` (slabs outside the box): a mitre buffer by ``min_gap/2`` out and back in,
    simplified at ``min_gap``; with walls clipped to the box (vertices closer than ``min_gap`` to a
    side put on it first)."""
    tol_box = 1e-7 * h
    r = 0.5 * min_gap
    members_geom = (np.concatenate([member_polys, np.array(_slabs(sides, box, h), dtype=object)])
                    if len(sides) else member_polys)
    closed = shapely.union_all(shapely.buffer(members_geom, r, join_style="mitre", mitre_limit=params.mitre_limit))
    closed = shapely.buffer(closed, -r, join_style="mitre", mitre_limit=params.mitre_limit)
    # features below the gap scale (bridge steps) are noise: drop them
    closed = shapely.simplify(closed, min_gap, preserve_topology=True)
    if not len(sides):
        return list(getattr(closed, "geoms", [closed]))
    # the walls are outside the box: what the fluid loses is the part inside (vertices closer
    # than min_gap to a side put on it first: that gap is filled anyway, and the simplification
    # may have cut a chord of the wall slab across a shallow contact, a sliver along the wall)
    xmin, xmax, ymin, ymax = box
    closed = shapely.transform(closed, lambda q: _snap_to_box(q, box, max(tol_box, min_gap))[0])
    if not shapely.is_valid(closed):
        closed = shapely.make_valid(closed)
    closed = shapely.intersection(closed, shapely.box(xmin, ymin, xmax, ymax))
    return [c for c in shapely.get_parts(closed) if shapely.get_type_id(c) == 3 and shapely.area(c) > tol_box * h]


def _ring_parts(ring, sides, box, tol_box: float) -> tuple:
    """A ring of a closed cluster: ``(ring, vertices (n, 2), forced (n,), wall_side (n,), fluid)``, its
    vertices, which are wall nodes (vertices on the box with a fluid-facing edge) and their side
    (-1 for the others), and the part facing the fluid (the ring less its edges along the box sides
    ``sides``; vertices between two such edges are dropped)."""
    ring_vertices = shapely.get_coordinates(ring)[:-1]
    forced = np.zeros(len(ring_vertices), dtype=bool)
    wall_side = np.full(len(ring_vertices), -1, dtype=np.int64)
    fluid = ring
    if len(sides):
        ring_vertices, wall_side = _snap_to_box(ring_vertices, box, tol_box)
        on_box = wall_side >= 0
        nxt = np.roll(np.arange(len(ring_vertices)), -1)
        mid = 0.5 * (ring_vertices + ring_vertices[nxt])
        # edge i -> i + 1 along a box side: not fluid boundary
        wall_edge = on_box & on_box[nxt] & (np.abs(_box_distance(mid, box)) < tol_box)
        if wall_edge.any():
            ends = np.stack([ring_vertices[~wall_edge], ring_vertices[nxt[~wall_edge]]], axis=1)
            fluid = shapely.multilinestrings(shapely.linestrings(ends))
        # vertices on the box with a fluid-facing edge are wall nodes; the others go
        inner = on_box & wall_edge & np.roll(wall_edge, 1)
        forced = (on_box & ~inner)[~inner]
        ring_vertices, wall_side = ring_vertices[~inner], np.where(forced, wall_side[~inner], -1)
    return ring, ring_vertices, forced, wall_side, fluid


def _outline_rows_on_rings(ring_data, members, polys, outlines: BodyOutlines, outline_world, h: float,
                           min_gap: float, params) -> tuple:
    """The outline rows of the cluster ``members`` ``(r,)``, which of them lie on the fluid part of a
    ring (``(r,)`` bool) and outside the other member bodies, and the nearest ring of each ``(r,)``."""
    member_rows = np.flatnonzero(np.isin(outlines.body, members))
    member_points = shapely.points(outline_world[member_rows])
    dist_to_rings = np.column_stack([shapely.distance(rd[4], member_points) for rd in ring_data])
    on = dist_to_rings.min(axis=1) < max(1e-7 * h, params.on_outline_factor * min_gap)
    # an outline node inside another member body (an overlap shallower than the
    # tolerance above) is no node of the closed outline: kept, it would be a mesh node
    # inside that body (the ring cuts across the notch, or a contact node takes its place)
    member_body = outlines.body[member_rows]
    for m in members:  # one per body of the cluster (few)
        inside = (member_body != m) & shapely.contains_xy(polys[m], outline_world[member_rows])
        on &= ~inside
    return member_rows, on, np.argmin(dist_to_rings, axis=1)


def _ring_nodes(ring, ring_vertices, forced, wall_side, kept, members, polys, outline_world, keep_outline,
                n_outline: int, first_id: int, merge: float, spacing: float, box, tol_box: float) -> tuple:
    """The nodes of one ring: its contact nodes and its segments over the outline rows ``kept`` on it
    (``keep_outline`` loses the rows merged away).

    Returns ``(segments (s, 2) or None, contact points (c, 2), owners (c,), wall sides (c,))``;
    contact node ``i`` is numbered ``first_id + i`` in the segments.
    """
    ring_vertices, forced, wall_side = _merged_ring_vertices(ring_vertices, forced, wall_side, merge)
    if forced.any() and len(kept):
        # outline nodes next to a wall node are merged into it
        d_wall, _ = cKDTree(ring_vertices[forced]).query(outline_world[kept])
        keep_outline[kept[d_wall < merge]] = False
        kept = kept[d_wall >= merge]
    if len(kept):
        dist_to_kept, _ = cKDTree(outline_world[kept]).query(ring_vertices)
    else:
        dist_to_kept = np.full(len(ring_vertices), np.inf)
    # ring vertices off the body outline nodes (contact points, bridge corners)
    # become contact nodes unless an outline node is within contact_node_spacing · h:
    # then the ring cuts straight across the contact notch, which lies in the
    # fluid (the union is concave there), so no element overlaps a body
    new_sel = (dist_to_kept > spacing) | forced
    new_contacts = ring_vertices[new_sel]
    new_wall = wall_side[new_sel]
    # owner of a contact node: nearest member body
    if len(new_contacts):
        new_pts = shapely.points(new_contacts)
        dist_to_members = np.column_stack([shapely.distance(polys[m], new_pts) for m in members])
        owner = members[np.argmin(dist_to_members, axis=1)]
    else:
        owner = np.zeros(0, dtype=np.int64)
    # order the ring's nodes along it
    ring_points = np.vstack([outline_world[kept], new_contacts])
    ring_ids = np.concatenate([kept, first_id + np.arange(len(new_contacts))])
    ring_wall = np.concatenate([np.zeros(len(kept), dtype=bool), new_wall >= 0])
    pos = shapely.line_locate_point(ring, shapely.points(ring_points))
    o = np.argsort(pos)
    ring_nodes = ring_ids[o]
    ring_wall = ring_wall[o]
    rp = ring_points[o]
    rpos = pos[o]
    # outline nodes closer than contact_merge · h to their predecessor on the ring
    # (corners of two touching bodies) are merged into it
    if len(ring_nodes) > 3:
        step = np.linalg.norm(rp - np.roll(rp, 1, axis=0), axis=1)
        drop = (step < merge) & (ring_nodes < n_outline)
        drop[0] = False
        keep_outline[ring_nodes[drop]] = False
        ring_nodes, ring_wall, rpos = ring_nodes[~drop], ring_wall[~drop], rpos[~drop]
    seg = _ring_segments(ring, ring_nodes, ring_wall, rpos, box, tol_box) if len(ring_nodes) >= 3 else None
    return seg, new_contacts, owner, new_wall


def _merged_ring_vertices(ring_vertices, forced, wall_side, merge: float) -> tuple:
    """Ring vertices closer than ``merge`` to the previous kept one dropped (wall nodes ``forced``
    stay; other vertices that close to one go): ``(vertices, forced, wall_side)``."""
    if len(ring_vertices) > 3:
        step = np.linalg.norm(np.diff(ring_vertices, axis=0, append=ring_vertices[:1]), axis=1)
        sel = np.concatenate([[True], step[:-1] >= merge]) | forced
        if forced.any():
            d_wall, _ = cKDTree(ring_vertices[forced]).query(ring_vertices)
            sel &= forced | (d_wall >= merge)
        ring_vertices, forced, wall_side = ring_vertices[sel], forced[sel], wall_side[sel]
    return ring_vertices, forced, wall_side


def _ring_segments(ring, ring_nodes, ring_wall, rpos, box, tol_box: float) -> np.ndarray:
    """Segments ``(s, 2)`` between consecutive ``ring_nodes`` along the ring (at ``rpos``), less the
    stretches along a box side between two wall nodes (``ring_wall``): those are no fluid boundary."""
    seg = np.column_stack([ring_nodes, np.roll(ring_nodes, -1)])
    if ring_wall.any():
        # tested half-way along the ring, which may turn round a box corner
        length = shapely.length(ring)
        mid_pos = (0.5 * (rpos + np.roll(rpos, -1) + np.r_[np.zeros(len(rpos) - 1), length])) % length
        mid = shapely.get_coordinates(shapely.line_interpolate_point(ring, mid_pos))
        along = ring_wall & np.roll(ring_wall, -1) & (np.abs(_box_distance(mid, box)) < tol_box)
        seg = seg[~along]
    return seg


def _cut_off_pores(wall_solids, box, min_area: float) -> list:
    """Areas of the fluid regions cut off from the rest of the box by the closed wall clusters
    ``wall_solids`` (between the legs of an arch on the floor, between two bodies touching each
    other and the floor): all but the largest region, larger than ``min_area``."""
    xmin, xmax, ymin, ymax = box
    filled = shapely.union_all(shapely.polygons(shapely.get_exterior_ring(np.asarray(wall_solids, dtype=object))))
    parts = [q for q in shapely.get_parts(shapely.difference(shapely.box(xmin, ymin, xmax, ymax), filled))
             if shapely.get_type_id(q) == 3]
    areas = sorted((float(shapely.area(q)) for q in parts), reverse=True)
    return [a for a in areas[1:] if a > min_area]
