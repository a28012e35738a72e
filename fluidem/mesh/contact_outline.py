"""Contact-outline policy of the moving mesh: bodies closer than ``min_gap`` are meshed as one
closed outline ("closed union outline", module docstring of :mod:`fluidem.mesh.moving`).

For every cluster of bodies in contact (connected components of the pairs closer than
``min_gap``; touching or overlapping, as the DEM allows small overlaps) the fluid region
loses the morphological closing of the union of the cluster: a mitre buffer by
``min_gap/2`` out and back in, simplified at ``min_gap``.  So gaps narrower than ``min_gap``
are filled and no element thinner than ``min_gap`` is produced.  On the closed outline

* outline nodes of the cluster bodies within ``on_outline_factor · min_gap`` of it are kept,
  two closer than ``contact_merge · h`` along it are merged;
* its vertices farther than ``contact_node_spacing · h`` from every kept outline node (deep
  contact points, bridge corners) become *contact nodes*, owned by and moving with the
  nearest body;
* holes of the closed union are *pores*: fluid enclosed by a ring of touching bodies (meshed,
  and reported by area: a pore needs its own pressure reference).

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

__all__ = ["ContactOutline", "contact_pairs", "contact_outline"]


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


def contact_pairs(polys, tree, distance: float) -> np.ndarray:
    """Body pairs ``(k, 2)`` (``i < j``) closer than ``distance``; ``tree``: STR tree of ``polys``."""
    if len(polys) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    a, b = tree.query(polys, predicate="dwithin", distance=distance)
    sel = a < b
    return np.column_stack([a[sel], b[sel]])


def contact_outline(polys, tree, outline_world, outlines: BodyOutlines, h: float, min_gap: float,
                    params) -> ContactOutline:
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
    """
    n_bodies = len(polys)
    outline_world = outline_world
    n_outline = len(outline_world)
    keep_outline = np.ones(n_outline, dtype=bool)
    solids = list(polys)
    contact_points, contact_body, cluster_segments, holes, pores = [], [], [], [], []
    clustered = np.zeros(n_bodies, dtype=bool)
    contacts = contact_pairs(polys, tree, min_gap) if n_bodies > 1 else np.zeros((0, 2), dtype=np.int64)
    merge = params.contact_merge * h
    spacing = params.contact_node_spacing * h
    if len(contacts):
        g = coo_matrix((np.ones(len(contacts)), (contacts[:, 0], contacts[:, 1])), shape=(n_bodies, n_bodies))
        _, cluster_of = connected_components(g, directed=False)
        members_of = {}
        for k in np.unique(cluster_of[np.concatenate([contacts[:, 0], contacts[:, 1]])]):
            members_of[k] = np.flatnonzero(cluster_of == k)
        n_contacts = 0
        tol = 1e-7 * h
        for k, members in members_of.items():  # one per contact cluster (few)
            clustered[members] = True
            r = 0.5 * min_gap
            closed = shapely.union_all(shapely.buffer(polys[members], r, join_style="mitre",
                                                      mitre_limit=params.mitre_limit))
            closed = shapely.buffer(closed, -r, join_style="mitre", mitre_limit=params.mitre_limit)
            # features below the gap scale (bridge steps) are noise: drop them
            closed = shapely.simplify(closed, min_gap, preserve_topology=True)
            comps = list(getattr(closed, "geoms", [closed]))
            rings = []
            for comp in comps:
                solids.append(comp)
                holes.append(np.array(shapely.get_coordinates(shapely.point_on_surface(comp))[0]))
                rings.append(comp.exterior)
                for ring in comp.interiors:
                    rings.append(ring)
                    pores.append(float(shapely.area(shapely.Polygon(ring))))
            member_rows = np.flatnonzero(np.isin(outlines.body, members))
            member_points = shapely.points(outline_world[member_rows])
            dist_to_rings = np.column_stack([shapely.distance(rg, member_points) for rg in rings])
            on = dist_to_rings.min(axis=1) < max(tol, params.on_outline_factor * min_gap)
            keep_outline[member_rows[~on]] = False
            which = np.argmin(dist_to_rings, axis=1)
            for ri, ring in enumerate(rings):
                ring_vertices = shapely.get_coordinates(ring)[:-1]
                # ring vertices closer than contact_merge · h to the previous kept one are dropped
                if len(ring_vertices) > 3:
                    step = np.linalg.norm(np.diff(ring_vertices, axis=0, append=ring_vertices[:1]), axis=1)
                    ring_vertices = ring_vertices[np.concatenate([[True], step[:-1] >= merge])]
                kept = member_rows[on & (which == ri)]
                if len(kept):
                    dist_to_kept, _ = cKDTree(outline_world[kept]).query(ring_vertices)
                else:
                    dist_to_kept = np.full(len(ring_vertices), np.inf)
                # ring vertices off the body outline nodes (contact points, bridge corners)
                # become contact nodes unless an outline node is within contact_node_spacing · h:
                # then the ring cuts straight across the contact notch, which lies in the
                # fluid (the union is concave there), so no element overlaps a body
                new_contacts = ring_vertices[dist_to_kept > spacing]
                # owner of a contact node: nearest member body
                if len(new_contacts):
                    new_pts = shapely.points(new_contacts)
                    dist_to_members = np.column_stack([shapely.distance(polys[m], new_pts) for m in members])
                    owner = members[np.argmin(dist_to_members, axis=1)]
                else:
                    owner = np.zeros(0, dtype=np.int64)
                # order the ring's nodes along it
                ring_points = np.vstack([outline_world[kept], new_contacts])
                ring_ids = np.concatenate([kept, n_outline + n_contacts + np.arange(len(new_contacts))])
                pos = shapely.line_locate_point(ring, shapely.points(ring_points))
                o = np.argsort(pos)
                ring_nodes = ring_ids[o]
                # outline nodes closer than contact_merge · h to their predecessor on the ring
                # (corners of two touching bodies) are merged into it
                if len(ring_nodes) > 3:
                    rp = ring_points[o]
                    step = np.linalg.norm(rp - np.roll(rp, 1, axis=0), axis=1)
                    drop = (step < merge) & (ring_nodes < n_outline)
                    drop[0] = False
                    keep_outline[ring_nodes[drop]] = False
                    ring_nodes = ring_nodes[~drop]
                if len(ring_nodes) >= 3:
                    cluster_segments.append(np.column_stack([ring_nodes, np.roll(ring_nodes, -1)]))
                contact_points.append(new_contacts)
                contact_body.append(owner)
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
    return ContactOutline(contacts=contacts, clustered=clustered, pore_areas=np.array(pores),
                          keep_outline=keep_outline, contact_points=contact_points, contact_body=contact_body,
                          segments=np.vstack([plain_segments] + cluster_segments), holes=hole_pts, solids=solids)
