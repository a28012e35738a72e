"""Which bodies can meet before ``t_end``: contact pairs and collisions of prescribed bodies.

Contacts are off when no two bodies (one of them movable), or a movable body and a wall,
can meet before ``t_end`` at the speeds the scene allows: prescribed speed plus |ω| r for
prescribed bodies, |v₀| t + |g| t²/2 for free bodies in a dry scene (until the first
contact only gravity acts), zero for fixed bodies (:func:`contact_candidates`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import names

if TYPE_CHECKING:  # pragma: no cover
    from ..scene import Scene

__all__ = ["contact_candidates", "prescribed_collisions"]


def _sweep(scene: Scene):
    """Motion of each body before any contact: (p0 (n, 2), v (n, 2), acc (n, 2), bounded (n,) bool).

    Until its first contact a body in a dry scene moves exactly as ``p0 + v t + acc t²/2``
    (``acc`` = gravity for free bodies, 0 otherwise); a free body in a fluid is unbounded.
    """
    B = scene.bodies
    n = len(B)
    p0 = np.array([b.position for b in B], float).reshape(n, 2)
    motion = np.array([b.motion for b in B])
    v = np.array([b.velocity for b in B], float).reshape(n, 2)
    v[motion == "fixed"] = 0.0
    acc = np.zeros((n, 2))
    acc[motion == "free"] = scene.gravity
    bounded = ~((motion == "free") & (scene.fluid is not None))
    return p0, v, acc, bounded


def _swept_boxes(p0, v, acc, T):
    """Axis-aligned boxes (lo, hi), each (n, 2), of the centre paths p0 + v t + acc t²/2 for t in [0, T]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(acc != 0, -v / np.where(acc != 0, acc, 1.0), 0.0)
    ts = [np.zeros_like(v), np.full_like(v, T), np.clip(tv, 0.0, T)]  # ends and the parabola's vertex
    pts = np.stack([p0 + v * t + 0.5 * acc * t * t for t in ts])
    return pts.min(axis=0), pts.max(axis=0)


def _min_distance_linear(dp, dv, T):
    """Smallest |dp + dv t| over t in [0, T], rows of (m, 2) arrays."""
    vv = (dv * dv).sum(axis=1)
    t = np.where(vv > 0, -(dp * dv).sum(axis=1) / np.where(vv > 0, vv, 1.0), 0.0)
    t = np.clip(t, 0.0, T)[:, None]
    return np.linalg.norm(dp + dv * t, axis=1)


def contact_candidates(scene: Scene) -> tuple[int, int]:
    """(body–body, body–wall) pairs that may touch before ``t_end``.

    Only free bodies feel contact forces, so every pair counted has a free body.  Walls: the
    swept box of a body's centre path, grown by its bounding radius, reaches a solid side.
    Bodies: their grown swept boxes overlap and, when
    both have the same acceleration (two free bodies under gravity, or two prescribed or
    fixed bodies), their relative motion is linear and its closest approach is exact.
    """
    n = len(scene.bodies)
    if n == 0:
        return 0, 0
    T = scene.time.t_end
    p0, v, acc, bounded = _sweep(scene)
    r = np.array([b.bounding_radius for b in scene.bodies])
    moving = np.array([b.motion == "free" for b in scene.bodies])
    lo, hi = _swept_boxes(p0, v, acc, T)
    lo, hi = lo - r[:, None], hi + r[:, None]
    lo[~bounded], hi[~bounded] = -np.inf, np.inf
    x0, x1, y0, y1 = scene.domain.box
    solid = {k: scene.domain.side(k).type in ("wall", "moving-wall") or (scene.fluid is None and
             scene.domain.side(k).type != "outflow") for k in names.choices("side")}
    hit = {"left": lo[:, 0] <= x0, "right": hi[:, 0] >= x1, "bottom": lo[:, 1] <= y0, "top": hi[:, 1] >= y1}
    n_wall = int(sum((hit[k] & moving).sum() for k in names.choices("side") if solid[k]))
    if not bounded.all():  # free bodies in a fluid: every pair with a free body
        nm = int(moving.sum())
        return int(nm * (nm - 1) // 2 + nm * (n - nm)), n_wall
    n_body = 0
    step = max(1, 1_000_000 // n)
    for a in range(0, n, step):  # brute force in row blocks of ~1e6 pairs
        sl = slice(a, min(a + step, n))
        ii = np.arange(a, min(a + step, n))[:, None]
        jj = np.arange(n)[None, :]
        ok = (jj > ii) & (moving[sl, None] | moving[None, :])
        ok &= (lo[sl, None, 0] <= hi[None, :, 0]) & (lo[None, :, 0] <= hi[sl, None, 0])
        ok &= (lo[sl, None, 1] <= hi[None, :, 1]) & (lo[None, :, 1] <= hi[sl, None, 1])
        i, j = np.nonzero(ok)
        i = i + a
        same = np.all(acc[i] == acc[j], axis=1)
        d = _min_distance_linear(p0[j] - p0[i], v[j] - v[i], T)
        n_body += int((~same | (d < r[i] + r[j])).sum())
    return n_body, n_wall


def prescribed_collisions(scene: Scene) -> list:
    """Descriptions of prescribed bodies that reach a side or another non-free body before ``t_end``."""
    B = scene.bodies
    idx = [k for k, b in enumerate(B) if b.motion == "prescribed" and any(b.velocity)]
    if not idx:
        return []
    T = scene.time.t_end
    p0, v, acc, _ = _sweep(scene)
    r = np.array([b.bounding_radius for b in B])
    lo, hi = _swept_boxes(p0, v, acc, T)
    lo, hi = lo - r[:, None], hi + r[:, None]
    x0, x1, y0, y1 = scene.domain.box
    out = []
    for k in idx:  # prescribed bodies: a handful
        reach = [s for s, hit in (("left", lo[k, 0] <= x0), ("right", hi[k, 0] >= x1), ("bottom", lo[k, 1] <= y0),
                                  ("top", hi[k, 1] >= y1)) if hit]
        periodic = [s for s in reach if scene.domain.side(s).type == "periodic"]
        walls = [s for s in reach if scene.domain.side(s).type != "periodic"]
        if periodic:
            out.append(f"{B[k].name} across the periodic side {periodic[0]!r} (meshed as its images on both "
                       "sides; a re-triangulation whenever an outline node passes it)")
        if walls:
            out.append(f"{B[k].name} to a side of the box")
        others = [j for j, b in enumerate(B) if j != k and b.motion != "free"]
        if others:
            o = np.array(others)
            d = _min_distance_linear(p0[o] - p0[k], v[o] - v[k], T)
            out += [f"{B[k].name} onto {B[j].name}" for j in o[d < r[o] + r[k]] if j > k or B[j].motion == "fixed"]
    return out
