"""The periodic images a :class:`~fluidem.mesh.moving.MovingMesh` holds, and its seam nodes.

On a box with periodic sides a body near a seam is meshed as its periodic images, clipped at
the box (:mod:`fluidem.mesh.seam`, which has the geometry; this module keeps the moving mesh's
state of it):

* :func:`image_set`: the images to mesh at the body poses (every body once without periodic
  sides), from the bodies' extents (:func:`body_extent`);
* :func:`set_images`: make an image set the bodies the mesh holds (outline table, vertices,
  poses; bodies on a seam line held nudged off it), :func:`image_poses` their poses;
* between re-triangulations: :func:`place_seam_nodes` slides the seam nodes with the crossings
  of their segments, and :func:`needs_new_images` tells when a body reached into the box
  where the mesh holds no image of it (both re-triangulate);
* through a re-triangulation: :func:`rigid_history` gives the body nodes it created (an image
  entering the box, seam nodes) the rigid trajectories of their bodies.

The functions take the mesh (``mesh``) and read or set its attributes; they add none.

Examples
--------
>>> import numpy as np
>>> from fluidem.mesh.seam import PeriodicImages
>>> im = PeriodicImages(body=np.array([0, 0]), cell=np.array([[0, 0], [-1, 0]]), shift=np.array([[0.0, 0], [-2, 0]]))
>>> image_poses(np.array([[1.9, 0.5, 0.1]]), im).tolist()
[[1.9, 0.5, 0.1], [-0.10000000000000009, 0.5, 0.1]]
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .nodes import CORNER, FREE, JUNCTION, OUTLINE, SIDE, UID_OUTLINE, BodyOutlines, world
from .periodic import bends_seams
from .seam import SEAM_BAND, SEAM_CODE, PeriodicImages, period_of, periodic_images, seam_nudge, seam_positions

if TYPE_CHECKING:
    from .moving import MovingMesh

__all__ = ["body_extent", "image_set", "set_images", "image_outlines", "image_poses", "place_seam_nodes",
           "needs_new_images", "unbend_seams", "wrap_into_box", "periodic_copies", "rigid_history"]


def body_extent(mesh: MovingMesh, body_poses) -> np.ndarray:
    """Per real body ``(dx_min, dx_max, dy_min, dy_max)`` of its outline about its position at
    ``body_poses (n_real, 3)``, ``(n_real, 4)`` length units."""
    w = world(mesh._real_vcat, mesh._real_vbody, body_poses) - body_poses[mesh._real_vbody, :2]
    ext = np.zeros((mesh.n_real, 4))
    ext[:, [0, 2]], ext[:, [1, 3]] = np.inf, -np.inf
    for c in range(2):
        np.minimum.at(ext[:, 2 * c], mesh._real_vbody, w[:, c])
        np.maximum.at(ext[:, 2 * c + 1], mesh._real_vbody, w[:, c])
    return ext


def image_set(mesh: MovingMesh, body_poses, extent=None) -> PeriodicImages:
    """The periodic images to mesh at ``body_poses`` (:func:`fluidem.mesh.seam.periodic_images`;
    ``extent``: :func:`body_extent` at them, if the caller has it); without periodic sides every
    body once."""
    if not mesh.periodic or not mesh.n_real:
        n = mesh.n_real
        return PeriodicImages(body=np.arange(n), cell=np.zeros((n, 2), dtype=np.int64), shift=np.zeros((n, 2)))
    margin = (mesh.params.drag_reach + 1.0) * mesh.h
    ext = body_extent(mesh, body_poses) if extent is None else extent
    return periodic_images(body_poses, ext, mesh.box, mesh.periodic, margin)


def set_images(mesh: MovingMesh, images: PeriodicImages, nudge: bool = False) -> None:
    """Make ``images`` the bodies ``mesh`` holds: per image its outline, vertices and pose
    (``nudge``: bodies with an outline node on a periodic side line are held nudged off it,
    :func:`fluidem.mesh.seam.seam_nudge`)."""
    if nudge and mesh.periodic and mesh.n_real:
        ol = mesh._real_outlines
        pts = world(ol.local, ol.body, mesh.body_poses)
        shift = seam_nudge(pts, ol.body, mesh.n_real, mesh.box, mesh.periodic, SEAM_BAND * mesh.h)
        images = PeriodicImages(body=images.body, cell=images.cell, shift=images.shift + shift[images.body])
    mesh.images = images
    nb = len(images.body)
    mesh.n_bodies = nb
    mesh._verts_local = [mesh._body_verts[b] for b in images.body]
    mesh._nv = mesh._real_nv[images.body]
    mesh._vcat = np.vstack(mesh._verts_local) if nb else np.zeros((0, 2))
    mesh._vbody = np.repeat(np.arange(nb), mesh._nv)
    mesh.outlines = image_outlines(mesh._real_outlines, images, mesh.n_real)
    mesh.poses = image_poses(mesh.body_poses, images)


def image_outlines(outlines: BodyOutlines, images: PeriodicImages, n_real: int) -> BodyOutlines:
    """The outline table of ``images``: every image carries its body's rows of ``outlines`` (the
    real bodies' table, ``n_real`` bodies), with uids per (row, image cell); ``outlines`` itself
    when the images are the real bodies in order."""
    nb = len(images.body)
    if nb == n_real and np.array_equal(images.body, np.arange(nb)) and not images.cell.any():
        return outlines
    ol = outlines
    first = np.concatenate([[0], np.cumsum(np.bincount(ol.body, minlength=n_real))])
    counts = first[images.body + 1] - first[images.body]
    start = np.concatenate([[0], np.cumsum(counts)])[:-1]
    rows = np.concatenate([np.arange(first[b], first[b + 1]) for b in images.body]) if nb else \
        np.zeros(0, dtype=np.int64)
    img = np.repeat(np.arange(nb), counts)
    nxt = ol.next[rows] - np.repeat(first[images.body], counts) + np.repeat(start, counts)
    code = (images.cell[:, 0] + 512) * 1024 + (images.cell[:, 1] + 512)
    uid = UID_OUTLINE + rows + len(ol.body) * (np.repeat(code, counts) - (512 * 1024 + 512))
    return BodyOutlines(local=ol.local[rows], body=img, next=nxt, uid=uid)


def image_poses(body_poses, images: PeriodicImages) -> np.ndarray:
    """Poses ``(n_images, 3)`` of ``images`` for real ``body_poses (n, 3)`` (length units, radians)."""
    out = np.asarray(body_poses, dtype=float)[images.body].copy()
    out[:, :2] += images.shift
    return out


def place_seam_nodes(mesh: MovingMesh, xd, poses) -> bool:
    """Put the seam nodes of ``xd (n, 2)`` at the crossings of their segments at ``poses``
    (:func:`fluidem.mesh.seam.seam_positions`); ``True`` if a segment no longer crosses its
    side (its inner end left the box or its outer end came in): re-triangulate."""
    wall = mesh.__dict__.get("_contact_wall")
    if wall is None:
        return False
    sel = wall >= SEAM_CODE
    if not sel.any():
        return False
    idx = mesh._contact_idx[sel]
    p_in = world(mesh._contact_local[sel], mesh.body_of[idx], poses)
    p_out = world(mesh._seam_outer_local[sel], mesh._seam_outer_body[sel], poses)
    side = wall[sel] - SEAM_CODE
    xd[idx] = seam_positions(p_in, p_out, side, mesh.box, xd[idx])
    xmin, xmax, ymin, ymax = mesh.box
    level = np.select([side == 0, side == 1, side == 2, side == 3], [ymin, xmax, ymax, xmin])
    c = np.where((side == 1) | (side == 3), 0, 1)
    k = np.arange(len(side))
    outward = np.where((side == 1) | (side == 2), 1.0, -1.0)
    inner_in = outward * (level - p_in[k, c]) > 0.0
    outer_out = outward * (p_out[k, c] - level) > 0.0
    return bool(not (inner_in & outer_out).all())


def unbend_seams(mesh: MovingMesh) -> np.ndarray:
    """The candidate nodes ``(n, 2)`` of a re-triangulation with bent seams
    (:mod:`fluidem.mesh.seam`): the current nodes with the matched side nodes put back on their
    side lines (each pair keeps its place along the side) and the others beyond a periodic
    side put back in the box by the period (:func:`wrap_into_box`: they fill the place where
    the partner side bent in)."""
    p = np.array(mesh.points, dtype=float)
    pairs = mesh.__dict__.get("_side_pairs")
    if pairs is not None and len(pairs):
        xmin, xmax, ymin, ymax = mesh.box
        a, b = pairs[:, 0], pairs[:, 1]
        c = np.argmax(np.abs(p[b] - p[a]), axis=1)  # the pair's axis: its partners lie a period apart
        side = (mesh.kind[a] == SIDE) | (mesh.kind[a] == CORNER)
        p[a[side], c[side]] = np.where(c[side] == 0, xmin, ymin)
        p[b[side], c[side]] = np.where(c[side] == 0, xmax, ymax)
    return wrap_into_box(mesh, p, mesh.kind)


def wrap_into_box(mesh: MovingMesh, points, kind) -> np.ndarray:
    """``points (n, 2)`` of kinds ``kind (n,)`` with the free, junction and box nodes beyond a
    periodic side of ``mesh`` shifted back into the box by the period (a copy)."""
    L = period_of(mesh.box, mesh.periodic)
    xmin, xmax, ymin, ymax = mesh.box
    lo, hi = (xmin, ymin), (xmax, ymax)
    p = np.array(points, dtype=float)
    loose = (kind == FREE) | (kind == JUNCTION) | (kind == SIDE) | (kind == CORNER)
    for c in range(2):
        if L[c]:
            p[loose & (p[:, c] < lo[c]), c] += L[c]
            p[loose & (p[:, c] > hi[c]), c] -= L[c]
    return p


def periodic_copies(mesh: MovingMesh, points, triangles, *values):
    """A mesh ``points (n, 2)``, ``triangles (m, 3)`` of bent seams tiled with its copies shifted
    by one period across each periodic axis, and the nodal ``values`` (each ``(n, 2)`` positions
    or ``None``) shifted with them: a point the old mesh holds across a seam is found in a copy.
    The first ``n`` nodes and ``m`` triangles are the mesh itself."""
    L = period_of(mesh.box, mesh.periodic)
    shifts = [np.zeros(2)]
    for c in range(2):
        if L[c]:
            e = np.zeros(2)
            e[c] = L[c]
            shifts = shifts + [s + e for s in shifts] + [s - e for s in shifts]
    n = len(points)
    pts = np.vstack([points + s for s in shifts])
    tri = np.vstack([triangles + k * n for k in range(len(shifts))])
    out = [None if v is None else np.vstack([v + s for s in shifts]) for v in values]
    return (pts, tri, *out)


def needs_new_images(mesh: MovingMesh) -> bool:
    """A body reaches into the box through a periodic side where ``mesh`` holds no image of it."""
    ext = body_extent(mesh, mesh.body_poses)  # once per step: the image set and the test below
    need = image_set(mesh, mesh.body_poses, ext)
    p = image_poses(mesh.body_poses, need)
    xmin, xmax, ymin, ymax = mesh.box
    inside = ((p[:, 0] + ext[need.body, 1] > xmin) & (p[:, 0] + ext[need.body, 0] < xmax)
              & (p[:, 1] + ext[need.body, 3] > ymin) & (p[:, 1] + ext[need.body, 2] < ymax))
    return bool(np.setdiff1d(need.key()[inside], mesh.images.key()).size)


def rigid_history(mesh: MovingMesh) -> None:
    """Trajectories of the body nodes a re-triangulation created (nodes of an image entering
    the box, seam nodes): the rigid motion of their body (the crossing of their segment for
    seam nodes), not the old mesh's motion, which does not reach them (they lie beyond the
    old clipped outline).  Updates ``mesh._trajectory`` in place of those nodes."""
    hist = mesh.__dict__.get("_body_pose_history", (None, None))
    prev = mesh._prev_uid
    new = np.ones(len(mesh.uid), dtype=bool)
    if prev is not None and len(prev):
        new = ~np.isin(mesh.uid, prev)
    traj = list(mesh._trajectory)
    for level, body_poses in enumerate(hist):
        if body_poses is None or traj[level] is None:
            continue
        poses = image_poses(body_poses, mesh.images)
        x = traj[level]
        ol = np.flatnonzero(new & (mesh.kind == OUTLINE))
        if len(ol):
            rows = mesh.outline_row[ol]
            x[ol] = world(mesh.outlines.local[rows], mesh.outlines.body[rows], poses)
        ci = mesh._contact_idx
        sel = new[ci]
        if sel.any():
            wall = mesh._contact_wall[sel]
            idx = ci[sel]
            x[idx] = world(mesh._contact_local[sel], mesh.body_of[idx], poses)
            seam = wall >= SEAM_CODE
            if seam.any() and not bends_seams(mesh):  # bent: the seam nodes are fixed on their bodies
                p_out = world(mesh._seam_outer_local[sel][seam], mesh._seam_outer_body[sel][seam], poses)
                x[idx[seam]] = seam_positions(x[idx[seam]], p_out, wall[seam] - SEAM_CODE, mesh.box,
                                              mesh.points[idx[seam]])
    mesh._trajectory = tuple(traj)
