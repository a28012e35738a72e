"""Checks of the bodies a :class:`~fluidem.mesh.moving.MovingMesh` is given.

* :func:`check_poses`: poses finite, of the right shape, every body inside the box: it may touch
  a wall or overlap it (the overlap is meshed as contact) by at most
  :func:`allowed_wall_overlap`, ``max(wall_overlap · h, wall_overlap_fraction · its extent
  across the side)`` (0.1 h, a quarter of its height); the error of a deeper overlap names the
  contact law's ``E``; periodic sides are no walls;
* :func:`check_widths`: every vertex of a body less than half a period from its origin.

Both raise :class:`~fluidem.errors.InputError` naming the body.

Examples
--------
>>> import numpy as np
>>> from fluidem.geometry import rectangle
>>> from fluidem.mesh import MovingMesh
>>> mm = MovingMesh((0, 2, 0, 1), [rectangle(0.4, 0.2)], [[0.6, 0.5, 0.0]], h=0.1)
>>> allowed_wall_overlap(mm, mm.body_poses).round(3).tolist()   # a quarter of the height, of the width
[[0.05, 0.1, 0.05, 0.1]]
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from .contact_outline import wall_depths
from .nodes import world
from .seam import period_of
from .triangulate import SIDE_NAMES

if TYPE_CHECKING:
    from .moving import MovingMesh

__all__ = ["check_poses", "check_widths", "allowed_wall_overlap"]


def check_poses(mesh: MovingMesh, poses) -> np.ndarray:
    """``poses`` as a float ``(n_real, 3)`` array (x, y, angle: length units, radians) of the real
    bodies of ``mesh``, checked (module docstring)."""
    try:
        p = np.asarray(poses, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"poses must be an (n_bodies, 3) array of numbers, got {poses!r}") from exc
    if mesh.n_real == 0 and p.size == 0:
        return np.zeros((0, 3))
    if p.shape != (mesh.n_real, 3) or not np.all(np.isfinite(p)):
        raise InputError(f"poses must be a finite ({mesh.n_real}, 3) array of x, y, angle; got shape {p.shape}")
    w = world(mesh._real_vcat, mesh._real_vbody, p)
    # a body may touch a wall or overlap it (the overlap is meshed as contact, the body with
    # the wall as one outline), as deep as allowed_wall_overlap; periodic sides are no walls
    depth = -wall_depths(w, mesh._real_vbody, mesh.n_real, mesh.box)  # (n_bodies, 4): > 0 outside
    depth[:, ~mesh._wall_sides] = -np.inf
    allowed = mesh.allowed_wall_overlap(p)
    bad = np.flatnonzero((depth > allowed).any(axis=1))
    if len(bad):
        b = int(bad[0])
        side = int(np.argmax(depth[b] - allowed[b]))
        if _outside(mesh, p[b]):
            raise InputError(
                f"body {b} ({mesh.body_names[b]}) at pose {p[b].tolist()} is not inside the domain "
                f"{tuple(float(c) for c in mesh.box)}: it lies outside")
        raise InputError(
            f"body {b} ({mesh.body_names[b]}) at pose {p[b].tolist()} is not inside the domain "
            f"{tuple(float(c) for c in mesh.box)}: it overlaps the {SIDE_NAMES[side]} wall by "
            f"{depth[b, side]:.3g}; expected an overlap of at most {allowed[b, side]:.3g} = max(wall_overlap · h, "
            f"wall_overlap_fraction · its extent across the wall) (the overlap is meshed as contact): a "
            f"resting overlap this deep means a contact law too soft for the load (raise [contact] E) or a "
            f"pose outside the box")
    return p


def _outside(mesh: MovingMesh, pose) -> bool:
    """The reference point of a body at ``pose`` lies outside the box (across a wall)."""
    xmin, xmax, ymin, ymax = mesh.box
    ax = mesh.__dict__.get("periodic", ())
    return not (("x" in ax or xmin <= pose[0] <= xmax) and ("y" in ax or ymin <= pose[1] <= ymax))


def check_widths(mesh: MovingMesh) -> None:
    """Every vertex of a body lies less than half the period from its origin: the arm of a
    point of a body across a periodic side is then the one to the nearest image of its
    origin (:func:`fluidem.geometry.minimum_image`)."""
    L = period_of(mesh.box, mesh.periodic)
    for c, Lc in enumerate(L):
        if not Lc or not mesh.n_real:
            continue
        r = np.zeros(mesh.n_real)
        np.maximum.at(r, mesh._real_vbody, np.linalg.norm(mesh._real_vcat, axis=1))
        b = int(np.argmax(r))
        if r[b] >= 0.5 * Lc:
            raise InputError(f"body {b} ({mesh.body_names[b]}) has a vertex {r[b]:.4g} from its origin, across "
                             f"periodic sides of period {Lc:.4g} in {'xy'[c]}: allowed: less than half the "
                             f"period, {0.5 * Lc:.4g} (the arms of its rigid motion go to its nearest image)")


def allowed_wall_overlap(mesh: MovingMesh, poses) -> np.ndarray:
    """Deepest overlap ``(n_real, 4)`` of each body of ``mesh`` at ``poses (n_real, 3)`` with each box
    side (bottom, right, top, left) that is meshed as contact, length units: ``max(wall_overlap · h,
    wall_overlap_fraction · e)``, ``e`` the body's extent across the side
    (:class:`~fluidem.mesh.params.MeshParams`)."""
    p = mesh.params
    w = world(mesh._real_vcat, mesh._real_vbody, poses)
    ext = np.zeros((mesh.n_real, 2))
    for axis in range(2):
        hi = np.full(mesh.n_real, -np.inf)
        lo = np.full(mesh.n_real, np.inf)
        np.maximum.at(hi, mesh._real_vbody, w[:, axis])
        np.minimum.at(lo, mesh._real_vbody, w[:, axis])
        ext[:, axis] = hi - lo
    across = ext[:, [1, 0, 1, 0]]  # bottom/top: the height, right/left: the width
    return np.maximum(p.wall_overlap * mesh.h, p.wall_overlap_fraction * across)
