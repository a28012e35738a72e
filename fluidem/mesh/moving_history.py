"""Node trajectories of a :class:`~fluidem.mesh.moving.MovingMesh` and its ALE mesh velocity.

* :func:`carry_history`: after an update, the positions at t^n and t^{n−1} of the
  trajectories of the current nodes; through a re-triangulation the new nodes follow the old
  mesh motion (barycentric pull-back), the body nodes it created their body
  (:func:`fluidem.mesh.moving_images.rigid_history`);
* :func:`velocity_from_history`: the mesh velocity by BDF2 of those trajectories;
* :func:`velocity_from_last_step`: the first-order mesh velocity, nodes created by a
  re-triangulation taking the mean of their known neighbours.

Examples
--------
>>> import numpy as np
>>> x = np.array([[1.0, 0.0]])
>>> velocity_from_history(x, x - [0.5, 0.0], x - [1.0, 0.0], 0.5).tolist()   # uniform motion
[[1.0, 0.0]]
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .moving_images import periodic_copies, rigid_history
from .periodic import bends_seams

if TYPE_CHECKING:
    from .moving import MeshEvent, MovingMesh

__all__ = ["carry_history", "pull_back_moved", "velocity_from_history", "velocity_from_last_step"]


def carry_history(mesh: MovingMesh, ev: MeshEvent, x_n: np.ndarray, x_nm1: np.ndarray | None) -> None:
    """Set ``mesh._trajectory``: positions at t^n and t^{n−1} of the trajectories of the nodes after
    :meth:`~fluidem.mesh.moving.MovingMesh.update` (``ev``: what it did; ``ev.history`` is set).

    ``x_n`` (positions before the update) and ``x_nm1`` (their own history) belong to the
    nodes before the update.  Without re-triangulation the nodes are the same.  After one
    the new nodes y lie in the old connectivity at the positions reached this step
    (``ev.old_points``, covering the new domain); the old mesh motion is affine on each
    old element, so the trajectory of y is that of its barycentric combination of old
    nodes: x^n(y) = Σ λ_k x_k^n, x^{n−1}(y) = Σ λ_k x_k^{n−1}.  If the old mesh is not valid
    there (``"inverted"``) or did not move (``"regenerate"``) the nodes are at rest this
    step (Eulerian).
    """
    if not ev.retriangulated:
        if len(ev.repaired_nodes):
            x_n, x_nm1 = pull_back_moved(mesh.triangles, ev.repaired_from, mesh.points, ev.repaired_nodes, x_n, x_nm1)
        mesh._trajectory = (x_n, x_nm1)
        return
    if ev.reason in ("inverted", "regenerate") or ev.old_points is None:
        ev.history = "eulerian"
        mesh._trajectory = (mesh.points.copy(), mesh.points.copy())
        return
    from skfem import MeshTri

    from .transfer import locate_near

    old_p, old_t = np.asarray(ev.old_points, float), np.asarray(ev.old_triangles)
    if bends_seams(mesh):
        # the old mesh reached across the bent seams: new nodes by a seam are found in its copies
        old_p, old_t, x_n, x_nm1 = periodic_copies(mesh, old_p, old_t, x_n, x_nm1)
    old = MeshTri(old_p.T.copy(), old_t.T.copy())
    # a node that survived the re-triangulation moved little (relaxation): it is searched
    # first in the old elements around its old position
    hint = np.full(len(mesh.points), -1, dtype=np.int64)
    prev_uid = mesh._prev_uid
    if prev_uid is not None and len(prev_uid) == len(ev.old_points):
        order = np.argsort(prev_uid)
        pos = np.minimum(np.searchsorted(prev_uid[order], mesh.uid), len(order) - 1)
        match = prev_uid[order][pos] == mesh.uid
        hint[match] = order[pos[match]]
    cells, bary = locate_near(old, mesh.points.T, hint)
    tri = old.t[:, cells].T  # (n, 3), in the vertex order of the located cells

    def pull(x):
        return None if x is None else np.einsum("nk,nkd->nd", bary, x[tri])

    ev.history = "ale"
    mesh._trajectory = (pull(x_n), pull(x_nm1))
    if mesh.periodic:
        rigid_history(mesh)


def pull_back_moved(triangles, x_before, x_after, moved, x_n, x_nm1):
    """Trajectories after a few nodes ``moved`` (k,) jumped from ``x_before`` to ``x_after`` (n, 2)
    with the connectivity ``triangles`` (m, 3) unchanged (the repair, :mod:`fluidem.mesh.repair`):
    a moved node continues the mesh motion of the point it jumped to, x^n(y) = Σ λ_k x_k^n with
    λ its barycentric coordinates in the mesh before the jump (as :func:`carry_history` does
    through a re-triangulation), so the jump is a transfer, not mesh velocity.  Returns new
    ``(x_n, x_nm1)`` (the inputs are not changed; None stays None)."""
    from .transfer import elements_around, locate, submesh

    if x_n is None:
        return x_n, x_nm1
    sub, nodes = submesh(x_before, np.asarray(triangles)[elements_around(triangles, moved, 3)])
    cells, bary = locate(sub, np.asarray(x_after)[moved].T)
    tri = nodes[sub.t[:, cells].T]  # (k, 3) in the located cells' vertex order

    def pull(x):
        if x is None:
            return None
        x = x.copy()
        x[moved] = np.einsum("nk,nkd->nd", bary, x[tri])
        return x

    return pull(x_n), pull(x_nm1)


def velocity_from_history(points, x_n, x_nm1, dt: float) -> np.ndarray:
    """Mesh velocity ``(n, 2)`` at the current time of node trajectories through ``x_nm1``,
    ``x_n`` and ``points`` (each ``(n, 2)``; ``x_n`` None: zero; ``x_nm1`` None: BDF1) by BDF2,
    w = (3x^{n+1} − 4x^n + x^{n−1}) / (2 dt), constant ``dt``."""
    if x_n is None:
        return np.zeros_like(points)
    if x_nm1 is None:
        return (points - x_n) / dt
    return (3.0 * (points - x_n) - (x_n - x_nm1)) / (2.0 * dt)  # differences first: round-off


def velocity_from_last_step(points, uid, prev_points, prev_uid, topo, dt: float) -> np.ndarray:
    """Mesh velocity ``(n, 2)``: ``(points − prev_points) / dt`` per node (matched by ``uid``
    against ``prev_uid``) for the nodes that existed at the last step; a node created since
    gets the mean velocity of its mesh neighbours (edges of ``topo``) that did, spreading
    outwards until every node has one."""
    order = np.argsort(prev_uid)
    pos = np.minimum(np.searchsorted(prev_uid[order], uid), len(order) - 1)
    match = prev_uid[order][pos] == uid
    w = np.zeros_like(points)
    j = order[pos[match]]
    w[match] = (points[match] - prev_points[j]) / dt
    # nodes created by the re-triangulation: mean velocity of their known mesh
    # neighbours, spreading outwards until every node has one (a few passes over the
    # edges; Qhull-based interpolation of all nodes cost seconds at 100k nodes)
    known = match.copy()
    e0, e1 = topo.e0, topo.e1
    n = len(w)
    while not known.all():
        k0, k1 = known[e0], known[e1]
        cnt = np.bincount(e0, k1, n) + np.bincount(e1, k0, n)
        sx = np.bincount(e0, k1 * w[e1, 0], n) + np.bincount(e1, k0 * w[e0, 0], n)
        sy = np.bincount(e0, k1 * w[e1, 1], n) + np.bincount(e1, k0 * w[e0, 1], n)
        new = ~known & (cnt > 0)
        if not new.any():  # a component without any known node (cannot happen in a mesh with bodies)
            break
        w[new, 0] = sx[new] / cnt[new]
        w[new, 1] = sy[new] / cnt[new]
        known |= new
    return w
