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
    olw = outline_world
    n_ol = len(olw)
    ol_keep = np.ones(n_ol, dtype=bool)
    solids = list(polys)
    extra_pts, extra_body, seg_list, holes, pore_list = [], [], [], [], []
    clustered = np.zeros(n_bodies, dtype=bool)
    contacts = contact_pairs(polys, tree, min_gap) if n_bodies > 1 else np.zeros((0, 2), dtype=np.int64)
    merge = params.contact_merge * h
    spacing = params.contact_node_spacing * h
    if len(contacts):
        g = coo_matrix((np.ones(len(contacts)), (contacts[:, 0], contacts[:, 1])), shape=(n_bodies, n_bodies))
        _, lab = connected_components(g, directed=False)
        members_of = {}
        for k in np.unique(lab[np.concatenate([contacts[:, 0], contacts[:, 1]])]):
            members_of[k] = np.flatnonzero(lab == k)
        n_extra = 0
        tol = 1e-7 * h
        for k, mem in members_of.items():  # one per contact cluster (few)
            clustered[mem] = True
            r = 0.5 * min_gap
            closed = shapely.union_all(shapely.buffer(polys[mem], r, join_style="mitre",
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
                    pore_list.append(float(shapely.area(shapely.Polygon(ring))))
            in_mem = np.flatnonzero(np.isin(outlines.body, mem))
            pts_m = shapely.points(olw[in_mem])
            dring = np.column_stack([shapely.distance(rg, pts_m) for rg in rings])
            on = dring.min(axis=1) < max(tol, params.on_outline_factor * min_gap)
            ol_keep[in_mem[~on]] = False
            which = np.argmin(dring, axis=1)
            for ri, ring in enumerate(rings):
                rv = shapely.get_coordinates(ring)[:-1]
                # ring vertices closer than contact_merge · h to the previous kept one are dropped
                if len(rv) > 3:
                    step = np.linalg.norm(np.diff(rv, axis=0, append=rv[:1]), axis=1)
                    rv = rv[np.concatenate([[True], step[:-1] >= merge])]
                kept = in_mem[on & (which == ri)]
                if len(kept):
                    dk, _ = cKDTree(olw[kept]).query(rv)
                else:
                    dk = np.full(len(rv), np.inf)
                # ring vertices off the body outline nodes (contact points, bridge corners)
                # become contact nodes unless an outline node is within contact_node_spacing · h:
                # then the ring cuts straight across the contact notch, which lies in the
                # fluid (the union is concave there), so no element overlaps a body
                newp = rv[dk > spacing]
                # owner of a contact node: nearest member body
                if len(newp):
                    dmem = np.column_stack([shapely.distance(polys[m], shapely.points(newp)) for m in mem])
                    owner = mem[np.argmin(dmem, axis=1)]
                else:
                    owner = np.zeros(0, dtype=np.int64)
                # order the ring's nodes along it
                allp = np.vstack([olw[kept], newp])
                gid = np.concatenate([kept, n_ol + n_extra + np.arange(len(newp))])
                pos = shapely.line_locate_point(ring, shapely.points(allp))
                o = np.argsort(pos)
                ringn = gid[o]
                # outline nodes closer than contact_merge · h to their predecessor on the ring
                # (corners of two touching bodies) are merged into it
                if len(ringn) > 3:
                    rp = allp[o]
                    step = np.linalg.norm(rp - np.roll(rp, 1, axis=0), axis=1)
                    drop = (step < merge) & (ringn < n_ol)
                    drop[0] = False
                    ol_keep[ringn[drop]] = False
                    ringn = ringn[~drop]
                if len(ringn) >= 3:
                    seg_list.append(np.column_stack([ringn, np.roll(ringn, -1)]))
                extra_pts.append(newp)
                extra_body.append(owner)
                n_extra += len(newp)

    extra_pts = np.vstack(extra_pts) if extra_pts else np.zeros((0, 2))
    extra_body = np.concatenate(extra_body).astype(np.int64) if len(extra_pts) else np.zeros(0, dtype=np.int64)
    # outline segments of unclustered bodies
    free_ol = ~clustered[outlines.body]
    seg_plain = np.column_stack([np.flatnonzero(free_ol), outlines.next[free_ol]])
    hole_plain = (shapely.get_coordinates(shapely.point_on_surface(polys[~clustered]))
                  if n_bodies else np.zeros((0, 2)))
    hole_pts = (np.vstack([hole_plain] + [p[None] for p in holes]) if (len(hole_plain) or holes)
                else np.zeros((0, 2)))
    return ContactOutline(contacts=contacts, clustered=clustered, pore_areas=np.array(pore_list),
                          keep_outline=ol_keep, contact_points=extra_pts, contact_body=extra_body,
                          segments=np.vstack([seg_plain] + seg_list), holes=hole_pts, solids=solids)
