"""Broad phase of polygon contact: the candidate pairs whose bounding circles overlap
(:func:`grid_pairs`), vectorised, no Python loop over bodies.

A uniform cell grid (cell side = largest bounding diameter of the movable bodies),
bodies binned by centre, pairs formed with the half stencil of 5 neighbour cells by
``np.repeat``/``searchsorted`` and kept when their bounding circles (plus a skin)
overlap.  The list is a Verlet list: it is rebuilt only after some body moved more
than half the skin.  Bodies larger than a cell (big fixed obstacles) are tested
against all bodies directly.  Cost ~N.
"""

from __future__ import annotations

import numpy as np

from .periodic import image_shift

__all__ = ["grid_pairs"]


def grid_pairs(centers: np.ndarray, radii: np.ndarray, cell: float, movable: np.ndarray,
               skin: float = 0.0, period: np.ndarray | None = None):
    """Candidate pairs whose bounding circles (grown by ``skin``) overlap.

    Parameters
    ----------
    centers : (N, 2) float
        Centres of mass, length.
    radii : (N,) float
        Bounding radii, length.
    cell : float
        Cell side, ≥ twice the largest radius of the binned bodies plus ``skin``, length.
    movable : (N,) bool
        Pairs of two non-movable bodies are skipped.
    skin : float
        Extra distance, length.
    period : (2,) float or None
        Periods of a periodic box along x and y (0 for a non-periodic axis), length: pairs are
        found across the periodic sides and measured between nearest images
        (:mod:`fluidem.dem.periodic`); the centres may be unwrapped.

    Returns
    -------
    i, j : (P,) int
        Pairs with ``i < j``.
    """
    n = len(centers)
    if n < 2:
        z = np.zeros(0, np.int64)
        return z, z
    L = np.zeros(2) if period is None else np.asarray(period, float)
    periodic = L > 0
    large = 2.0 * radii + skin > cell
    small = np.flatnonzero(~large)
    ii_all, jj_all = [], []
    if len(small) > 1:
        c = centers[small]
        ij = np.floor((c - c.min(axis=0)) / cell).astype(np.int64) + 1
        m = np.zeros(2, np.int64)  # cells along a periodic axis (its indices wrap), 0 on the others
        for a in np.flatnonzero(periodic):
            m[a] = max(int(np.floor(L[a] / cell)), 1)  # cells of side L/m >= cell
            ij[:, a] = np.floor(np.mod(c[:, a], L[a]) / (L[a] / m[a])).astype(np.int64) % m[a]
        nx = int(m[0]) if periodic[0] else int(ij[:, 0].max()) + 2
        key = ij[:, 1] * nx + ij[:, 0]
        order = np.argsort(key, kind="stable")
        skey = key[order]
        uniq, start, counts = np.unique(skey, return_index=True, return_counts=True)
        ar = np.arange(len(small))
        for off, (ox, oy) in zip((0, 1, nx - 1, nx, nx + 1), ((0, 0), (1, 0), (-1, 1), (0, 1), (1, 1))):
            if periodic.any():  # wrapped neighbour cells (a cell may then be met twice: pairs made unique below)
                cx, cy = ij[:, 0] + ox, ij[:, 1] + oy
                if periodic[0]:
                    cx = cx % m[0]
                if periodic[1]:
                    cy = cy % m[1]
                nk = cy * nx + cx
            else:
                nk = key + off
            pos = np.searchsorted(uniq, nk)
            pos = np.minimum(pos, len(uniq) - 1)
            found = uniq[pos] == nk
            cnt = np.where(found, counts[pos], 0)
            tot = int(cnt.sum())
            if tot == 0:
                continue
            a = np.repeat(ar, cnt)
            first = np.repeat(start[pos] - (np.cumsum(cnt) - cnt), cnt)
            b = order[first + np.arange(tot)]
            if off == 0 or periodic.any():
                keep = a < b if off == 0 else a != b
                a, b = a[keep], b[keep]
            ii_all.append(small[a])
            jj_all.append(small[b])
    big = np.flatnonzero(large)
    if len(big):
        a = np.repeat(big, n)
        b = np.tile(np.arange(n), len(big))
        keep = (a != b) & ~(large[b] & (b < a))  # large-large pairs once
        ii_all.append(a[keep])
        jj_all.append(b[keep])
    if not ii_all:
        z = np.zeros(0, np.int64)
        return z, z
    i = np.concatenate(ii_all)
    j = np.concatenate(jj_all)
    i, j = np.minimum(i, j), np.maximum(i, j)
    if periodic.any():  # a pair may have been met through more than one (wrapped) cell
        ij = np.unique(i * n + j)
        i, j = ij // n, ij % n
    d = centers[j] - centers[i]
    d = d + image_shift(d, L)
    reach = radii[i] + radii[j] + skin
    keep = ((d * d).sum(axis=1) < reach * reach) & (movable[i] | movable[j])
    return i[keep], j[keep]
