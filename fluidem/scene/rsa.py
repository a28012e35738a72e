"""Random sequential addition (RSA; Feder 1980, Hinrichsen, Feder & Jøssang 1986): the placement
loop of :func:`fluidem.scene.fill.fill`.

Bodies are placed one at a time, each at the first of a stream of uniformly random candidate
poses (vectorised batches) that keeps at least the gap from every body placed before and from
the sides; along a periodic axis a body may sit anywhere and every gap is measured to the
nearest periodic image.  A body that finds no place in ``attempts`` candidates ends the fill
with :class:`FillJammed`.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .shapes import bounding_factor, inradius, shape_outline

__all__ = ["FillJammed", "place"]

_REBUILD = 128  # placed bodies checked directly before the k-d tree is rebuilt


class FillJammed(InputError):
    """No place found for a body in ``attempts`` candidates: the fill is jammed.

    Attributes
    ----------
    placed : int
        Bodies placed before the jam.
    fraction : float
        Area fraction they cover.
    """

    def __init__(self, message, placed: int, fraction: float):
        super().__init__(message)
        self.placed = placed
        self.fraction = fraction


class _Placement:
    """The bodies placed so far and the gap test of a candidate against them.

    Neighbours come from a k-d tree over the placed centres (rebuilt every :data:`_REBUILD`
    bodies; the latest are checked directly); pairs whose bounding and inscribed circles do not
    decide are measured exactly with shapely.  Along an axis of ``period`` every displacement is
    taken to its nearest periodic image (the minimum-image convention).
    """

    def __init__(self, m, box, period, g, R_max):
        from scipy.spatial import cKDTree

        self._kdtree = cKDTree
        x0, x1, y0, y1 = box
        self.P = np.empty((m, 2))             # centres
        self.Rb = np.empty(m)                 # bounding radii
        self.Ri = np.empty(m)                 # inscribed radii
        self.buf = np.empty(m)                # disk radius (the core is its centre), 0 for polygons
        self.cores = np.empty(m, dtype=object)
        self.g, self.R_max = g, R_max
        self.tree, self.n_tree = None, 0
        self.origin = np.array([x0, y0])
        self.L = np.array([period[0] or 0.0, period[1] or 0.0])
        self.wrap = self.L > 0.0
        # the k-d trees' box: the period along a periodic axis, far beyond the region along another
        self.boxsize = (np.where(self.wrap, self.L, 4.0 * (max(x1 - x0, y1 - y0) + R_max + g))
                        if self.wrap.any() else None)

    def nearest_image(self, d):
        """Displacements ``d`` (..., 2) to their nearest periodic image."""
        if self.boxsize is None:
            return d
        return d - self.L * np.round(d / np.where(self.wrap, self.L, 1.0))

    def kd_tree(self, points):
        if self.boxsize is None:
            return self._kdtree(points)
        return self._kdtree(points - self.origin, boxsize=self.boxsize)

    def clashes(self, i, xy, rx, ry, disk, bad):
        """Mark in ``bad`` the candidate centres ``xy`` (k, 2) of body ``i`` (rotated outlines
        ``rx``, ``ry`` (k, n) unless a disk) closer than ``g`` to a placed body."""
        import shapely

        P, Rb, Ri, g = self.P, self.Rb, self.Ri, self.g
        ci, cj, cd = [], [], []
        if self.tree is not None:
            sdm = self.kd_tree(xy).sparse_distance_matrix(self.tree, Rb[i] + self.R_max + g, output_type="ndarray")
            ci.append(sdm["i"]), cj.append(sdm["j"]), cd.append(sdm["v"])
        n_tree = self.n_tree
        if i > n_tree:
            d = np.hypot(*np.moveaxis(self.nearest_image(xy[:, None, :] - P[None, n_tree:i, :]), -1, 0))
            a, b = np.nonzero(d < Rb[i] + Rb[None, n_tree:i] + g)
            ci.append(a), cj.append(b + n_tree), cd.append(d[a, b])
        if not ci:
            return
        pi, pj, pd = (np.concatenate(t) for t in (ci, cj, cd))
        clear = pd >= Rb[i] + Rb[pj] + g
        pi, pj, pd = pi[~clear], pj[~clear], pd[~clear]
        near = pd < Ri[i] + Ri[pj] + g
        bad[pi[near]] = True
        keep = ~near & ~bad[pi]
        pi, pj = pi[keep], pj[keep]
        if len(pi):  # exact outline distances of the pairs in between
            q = P[pj] - self.nearest_image(P[pj] - xy[pi])  # the candidate's image next to body pj
            if disk:
                geo = shapely.points(q)
            else:
                geo = shapely.polygons(np.stack([rx[pi] + q[:, :1], ry[pi] + q[:, 1:]], axis=2))
            dist = shapely.distance(geo, self.cores[pj]) - self.buf[i] - self.buf[pj]
            bad[pi[(dist < g) | (dist <= 0.0)]] = True  # 0: they meet (or overlap)

    def add(self, i, p, core):
        """Body ``i`` placed at ``p`` with the shapely ``core`` (its centre for a disk)."""
        self.P[i], self.cores[i] = p, core
        if i + 1 - self.n_tree > _REBUILD:
            self.tree, self.n_tree = self.kd_tree(self.P[:i + 1]), i + 1


def _candidates(k, r, v, box, gaps, wrap, rng):
    """A batch of ``k`` random poses of a body (equal-area radius ``r``; outline ``v``, None for
    a disk) inside ``box`` with its side gaps (anywhere along an axis with ``wrap``): angles (k,),
    rotated outlines ``rx``, ``ry`` (k, n) or None, centres (k, 2) and a mask of poses that do
    not fit."""
    x0, x1, y0, y1 = box
    ang = rng.uniform(0.0, 2.0 * math.pi, k)
    if v is None:
        rx = ry = None
        lo = hi = np.full((k, 2), r)
    else:
        c, s = np.cos(ang), np.sin(ang)
        rx = c[:, None] * v[None, :, 0] - s[:, None] * v[None, :, 1]
        ry = s[:, None] * v[None, :, 0] + c[:, None] * v[None, :, 1]
        lo = -np.column_stack([rx.min(axis=1), ry.min(axis=1)])
        hi = np.column_stack([rx.max(axis=1), ry.max(axis=1)])
    xlo, xhi = x0 + gaps["x"] + lo[:, 0], x1 - gaps["x"] - hi[:, 0]
    ylo, yhi = y0 + gaps["y"] + lo[:, 1], y1 - gaps["y"] - hi[:, 1]
    if wrap[0]:
        xlo, xhi = np.full(k, x0), np.full(k, x1)
    if wrap[1]:
        ylo, yhi = np.full(k, y0), np.full(k, y1)
    u = rng.random((k, 2))
    xy = np.column_stack([xlo + u[:, 0] * (xhi - xlo), ylo + u[:, 1] * (yhi - ylo)])
    upper = np.array([x1, y1])
    xy = np.where(wrap & (xy >= upper), np.array([x0, y0]), xy)  # u * L rounded up to the period
    return ang, rx, ry, xy, (xhi < xlo) | (yhi < ylo)


def _jammed(i, m, frac, attempts, n_asked, area_fraction, asked_fraction, lab) -> FillJammed:
    """The one-line error of a fill that found no place for body ``i`` (of ``m``)."""
    if n_asked is not None and area_fraction is None:
        what = (f"{lab['n']} = {n_asked}: only {i} bodies fit (area fraction {frac:.4f}) before random "
                f"sequential addition jammed ({attempts} attempts for the next one); allowed here: "
                f"{lab['n']} up to about {i}, or a larger region, smaller radius or smaller "
                f"{lab['min_gap']}")
    else:
        asked = area_fraction if area_fraction is not None else asked_fraction
        what = (f"{lab['area_fraction']} = {asked:g}: random sequential addition jammed at area "
                f"fraction {frac:.4f} ({i} of {m} bodies placed, {attempts} attempts for the next one); "
                f"allowed here: up to about {math.floor(100 * frac) / 100:.2f} (RSA jams near 0.547 "
                f"for equal disks without gap; a smaller {lab['min_gap']} or a wider radius range "
                "reaches more)")
    return FillJammed(what, placed=i, fraction=frac)


def _body_entry(kind, r, v, segments, p, angle) -> dict:
    """The body dict of :attr:`Packing.bodies` for a body placed at ``p`` turned by ``angle``."""
    if kind == "disk":
        body = {"shape": "disk", "radius": float(r)}
        if segments is not None:
            body["segments"] = segments
    elif kind in ("rectangle", "square"):
        body = {"shape": "rectangle", "width": float(2 * v[1, 0]), "height": float(2 * v[2, 1])}
    else:
        body = {"shape": "polygon", "vertices": v.tolist()}
    body["position"] = (float(p[0]), float(p[1]))
    body["angle"] = angle
    return body


def place(kinds, radii, aspect, segments, box, gaps, period, g, attempts, rng, area_fraction, n_asked, lab):
    """Random sequential addition of the bodies ``kinds``/``radii`` (largest first) in ``box``;
    along an axis of ``period`` (length or None) anywhere, gaps to the nearest image."""
    import shapely

    from ..geometry import polygon_area

    x0, x1, y0, y1 = box
    A = (x1 - x0) * (y1 - y0)
    m = len(kinds)
    bodies, areas = [], np.empty(m)
    R_all = np.array([radii[i] * bounding_factor(kinds[i], aspect) for i in range(m)])
    placed = _Placement(m, box, period, g, float(R_all.max()))
    batch = 16
    outlines = {}
    for i, (kind, r) in enumerate(zip(kinds, radii)):
        disk = kind == "disk"
        if disk:
            v = None
            placed.Rb[i], placed.Ri[i], placed.buf[i] = r, r, r
            areas[i] = (math.pi * r * r if segments is None
                        else 0.5 * segments * r * r * math.sin(2.0 * math.pi / segments))
        else:
            key = (kind, float(r))
            v = outlines.get(key)
            if v is None:
                v = outlines[key] = shape_outline(kind, r, aspect)
            placed.Rb[i], placed.Ri[i], placed.buf[i] = R_all[i], inradius(v), 0.0
            areas[i] = float(polygon_area(v))
        tried = 0
        while True:
            k = batch
            ang, rx, ry, xy, bad = _candidates(k, r, v, box, gaps, placed.wrap, rng)
            placed.clashes(i, xy, rx, ry, disk, bad)
            ok = np.flatnonzero(~bad)
            if len(ok):
                j = int(ok[0])
                tried += j + 1
                batch = max(16, batch // 2) if j < k // 4 else batch
                break
            tried += k
            batch = min(2048, 2 * batch)
            if tried >= attempts:
                raise _jammed(i, m, float(areas[:i].sum() / A), attempts, n_asked, area_fraction,
                              float(areas.sum() / A), lab)
        p = xy[j]
        placed.add(i, p, shapely.points(p) if disk else shapely.polygons(np.column_stack([rx[j] + p[0],
                                                                                         ry[j] + p[1]])))
        bodies.append(_body_entry(kind, r, v, segments, p, float(ang[j])))
    return bodies, areas
