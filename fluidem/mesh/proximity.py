"""Distances between many points and a few hundred polygons, vectorised over points.

The moving mesh asks, at every re-triangulation, which bodies lie within a few ``h`` of
~10⁵ nodes (cut-out, drag association, narrow gaps).  :class:`PolygonTable` answers with
plain array arithmetic:

- the polygons' edges are stored slot-major, ``(max_vertices, n_polygons)`` per
  coordinate, so a distance is a loop over the few vertex *slots*, each a vectorised pass
  over all queried points (short polygons pad with a zero-length edge at their first
  vertex, which changes neither the distance nor the crossing count);
- candidate (point, polygon) pairs come from a uniform grid of cells about half a polygon
  wide: a point meets the polygons whose bounding box, grown by its radius, covers its
  cell, and then the exact bounding-box test.

Point–segment distance: the foot of the perpendicular, clamped to the segment (e.g.
Ericson, *Real-Time Collision Detection*, 2005, Sec. 5.1.2); inside test: even–odd
crossing number of a horizontal ray (ibid., Sec. 5.4.1).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["PolygonTable"]


class PolygonTable:
    """Edges of simple polygons, arranged for vectorised point queries.

    Parameters
    ----------
    vertices : (sum n_i, 2) float
        Vertices of all polygons, one polygon after the other, length units.
    counts : (n_polygons,) int
        Vertices of each polygon (≥ 3).

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> tab = PolygonTable(square, [4])
    >>> tab.distance(np.array([[2.0, 0.5], [0.5, 0.5]]), np.array([0, 0]))
    array([1. , 0.5])
    >>> tab.distance(np.array([[2.0, 0.5], [0.5, 0.5]]), np.array([0, 0]), solid=True)
    array([1., 0.])
    """

    def __init__(self, vertices, counts):
        v = np.asarray(vertices, dtype=float)
        n = np.asarray(counts, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 2 or n.ndim != 1 or int(n.sum()) != len(v) or (n < 3).any():
            raise InputError(
                f"vertices must be (sum counts, 2) with counts >= 3, got vertices {v.shape}, counts {n.tolist()}"
            )
        self.n_polygons = len(n)
        self.counts = n
        first = np.concatenate([[0], np.cumsum(n)[:-1]])
        m = int(n.max()) if len(n) else 0
        j = np.arange(m)[:, None]
        real = j < n[None, :]
        ia = first[None, :] + np.where(real, j, 0)
        ib = first[None, :] + np.where(real, (j + 1) % np.maximum(n[None, :], 1), 0)
        ax, ay = v[ia, 0], v[ia, 1]
        self._ax, self._ay = ax, ay
        self._dx, self._dy = v[ib, 0] - ax, v[ib, 1] - ay
        len2 = self._dx**2 + self._dy**2
        self._inv_len2 = np.where(len2 > 0, 1.0 / np.where(len2 > 0, len2, 1.0), 0.0)
        if len(n):
            self.bounds = np.column_stack([
                np.minimum.reduceat(v[:, 0], first), np.minimum.reduceat(v[:, 1], first),
                np.maximum.reduceat(v[:, 0], first), np.maximum.reduceat(v[:, 1], first),
            ])
        else:
            self.bounds = np.zeros((0, 4))

    def distance(self, points, polygon, solid: bool = False) -> np.ndarray:
        """Distance from each point to one polygon each.

        Parameters
        ----------
        points : (k, 2) float
        polygon : (k,) int
            Index of the polygon for each point.
        solid : bool
            Distance to the filled polygon (0 inside), as ``shapely.distance``; else to its
            outline.

        Returns
        -------
        (k,) float, length units.
        """
        p = np.asarray(points, dtype=float)
        poly = np.asarray(polygon, dtype=np.int64)
        k = len(p)
        n_slots = self._ax.shape[0]
        px, py = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
        # with polygons of very different vertex counts (disks among triangles), sort the
        # pairs by count so that slot j only visits pairs whose polygon has more than j
        # vertices; else every pair pays for the largest polygon's padding
        cnt = self.counts[poly]
        order = None
        active = np.full(n_slots, k)
        if k and n_slots > 1.5 * cnt.mean():
            order = np.argsort(-cnt, kind="stable")
            poly, px, py = poly[order], px[order], py[order]
            active = k - np.cumsum(np.bincount(cnt, minlength=n_slots + 1))[:n_slots]
        best = np.full(k, np.inf)
        rx_all, ry_all, dx_all, dy_all, tt_all, tmp_all = np.empty((6, k))
        odd = np.zeros(k, dtype=bool) if solid else None
        for j in range(n_slots):  # vertex slots (≤ the largest polygon's count)
            a = int(active[j])
            rx, ry, dx, dy, tt, tmp = rx_all[:a], ry_all[:a], dx_all[:a], dy_all[:a], tt_all[:a], tmp_all[:a]
            pa, xa, ya = poly[:a], px[:a], py[:a]
            self._ax[j].take(pa, out=tt)
            np.subtract(xa, tt, out=rx)
            self._ay[j].take(pa, out=tt)
            np.subtract(ya, tt, out=ry)
            self._dx[j].take(pa, out=dx)
            self._dy[j].take(pa, out=dy)
            if solid:
                # the edge crosses the horizontal line through p right of p (even–odd rule)
                ay_above = ry < 0.0
                by_above = tmp
                np.subtract(dy, ry, out=by_above)
                cross = ay_above != (by_above > 0.0)
                # x of the crossing relative to p: a_x − p_x + (p_y − a_y)·dx/dy
                with np.errstate(divide="ignore", invalid="ignore"):
                    xc = (ry * dx) / dy - rx
                odd[:a] ^= cross & (xc > 0.0)
            # foot of the perpendicular, clamped to the edge (Ericson 2005, Sec. 5.1.2)
            np.multiply(rx, dx, out=tt)
            np.multiply(ry, dy, out=tmp)
            tt += tmp
            self._inv_len2[j].take(pa, out=tmp)
            tt *= tmp
            np.clip(tt, 0.0, 1.0, out=tt)
            dx *= tt
            dy *= tt
            rx -= dx
            ry -= dy
            rx *= rx
            ry *= ry
            rx += ry
            np.minimum(best[:a], rx, out=best[:a])
        np.sqrt(best, out=best)
        if solid:
            best[odd] = 0.0
        if order is not None:
            out = np.empty(k)
            out[order] = best
            return out
        return best

    def candidate_pairs(self, points, radius) -> tuple[np.ndarray, np.ndarray]:
        """(point, polygon) pairs whose polygon's bounding box, grown by ``radius``, covers the point.

        Parameters
        ----------
        points : (k, 2) float
        radius : float or (k,) float
            Search radius per point, length units (≥ 0).

        Returns
        -------
        point_idx, polygon_idx : (n_pairs,) int
            Sorted by point.
        """
        p = np.asarray(points, dtype=float)
        k = len(p)
        r = np.broadcast_to(np.asarray(radius, dtype=float), (k,))
        empty = np.zeros(0, dtype=np.int64)
        if not k or not self.n_polygons:
            return empty, empty
        rmax = float(r.max())
        lo = self.bounds[:, :2] - rmax
        hi = self.bounds[:, 2:] + rmax
        # cells about half a grown polygon wide, at most ~16 per polygon over the covered area
        ext = hi.max(axis=0) - lo.min(axis=0)
        cell = max(0.5 * float(np.median((hi - lo).max(axis=1))),
                   float(np.sqrt(ext[0] * ext[1] / (16.0 * self.n_polygons))), 1e-300)
        origin = lo.min(axis=0)
        i0 = np.floor((lo - origin) / cell).astype(np.int64)
        i1 = np.floor((hi - origin) / cell).astype(np.int64)
        nx, ny = int(i1[:, 0].max()) + 1, int(i1[:, 1].max()) + 1
        # (cell, polygon) table, grouped by cell
        w = i1 - i0 + 1
        cnt = w[:, 0] * w[:, 1]
        poly = np.repeat(np.arange(self.n_polygons), cnt)
        loc = np.arange(len(poly)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        cid = (i0[poly, 0] + loc % w[poly, 0]) * ny + i0[poly, 1] + loc // w[poly, 0]
        cell_poly = poly[np.argsort(cid, kind="stable")]
        start = np.zeros(nx * ny + 1, dtype=np.int64)
        np.cumsum(np.bincount(cid, minlength=nx * ny), out=start[1:])
        # the points' cells
        q = np.floor((p - origin) / cell).astype(np.int64)
        inside = (q[:, 0] >= 0) & (q[:, 0] < nx) & (q[:, 1] >= 0) & (q[:, 1] < ny)
        c = np.where(inside, q[:, 0] * ny + q[:, 1], 0)
        s = start[c]
        n = np.where(inside, start[c + 1] - s, 0)
        pi = np.repeat(np.arange(k), n)
        off = np.arange(len(pi)) - np.repeat(np.cumsum(n) - n, n)
        bi = cell_poly[s[pi] + off]
        # exact test against the box grown by the point's own radius
        rr = r[pi]
        x, y = p[pi, 0], p[pi, 1]
        b = self.bounds
        ok = (x >= b[bi, 0] - rr) & (x <= b[bi, 2] + rr) & (y >= b[bi, 1] - rr) & (y <= b[bi, 3] + rr)
        return pi[ok], bi[ok]

    def pairs_within(self, points, radius, solid: bool = False):
        """All (point, polygon) pairs closer than ``radius``, with their distances.

        Parameters
        ----------
        points : (k, 2) float
        radius : float or (k,) float
            Search radius per point, length units.
        solid : bool
            Measure to the filled polygons (points inside are at distance 0).

        Returns
        -------
        point_idx, polygon_idx : (n_pairs,) int
            Sorted by point.
        distance : (n_pairs,) float
        """
        p = np.asarray(points, dtype=float)
        r = np.broadcast_to(np.asarray(radius, dtype=float), (len(p),))
        pi, bi = self.candidate_pairs(p, r)
        d = self.distance(p[pi], bi, solid=solid)
        ok = d < r[pi]
        return pi[ok], bi[ok], d[ok]
