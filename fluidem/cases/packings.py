"""Scenes of the moving-mesh hard cases: random packings of convex polygons and their motions.

The hard cases that the moving mesh (:class:`fluidem.mesh.MovingMesh`) must keep valid
(``tests/mesh/test_mesh_hard_cases.py``, ``benchmarks/bench_mesh.py``):

1. :func:`packing` + :class:`RandomMotion`: 200 convex polygons at area fraction 0.5 with
   gaps down to 1 % of the mean size, moving randomly;
2. :func:`sliding_pair`: two bars sliding past each other with a gap of ``h/10``;
3. :func:`crossing_body`: a hexagon crossing from the fine into the coarse region of a
   graded mesh and back;
4. :func:`collapsing_step`: a block of 200 squares shearing and settling (paper Fig. 6);
6. :func:`collective_motion`: a packing in the middle of a box moved as a whole (rigid
   rotation, uniform expansion and contraction, simple shear).

Case 5 is case 1 with the ``"regenerate"`` strategy.

Examples
--------
>>> from fluidem.cases.packings import RandomMotion, packing
>>> bodies, poses, box = packing(n=12, phi=0.3, seed=0)
>>> len(bodies), poses.shape
(12, (12, 3))
>>> motion = RandomMotion(bodies, poses, box, seed=1)
>>> motion.step().shape
(12, 3)
>>> motion.min_gap_now() >= 0.01
True
"""

from __future__ import annotations

import numpy as np
import shapely

from ..errors import InputError
from ..geometry import rectangle, regular_polygon

__all__ = ["random_convex", "world_polygons", "packing", "hexagon_packing", "RandomMotion", "sliding_pair",
           "crossing_body", "collapsing_step", "pore_ring", "COLLECTIVE_MOTIONS",
           "CollectiveMotion", "collective_motion"]


def random_convex(size: float, n_vertices: int, rng) -> np.ndarray:
    """Convex polygon ``(n_vertices, 2)`` of diameter ≈ ``size`` (vertices near an ellipse of
    axis ratio 1–1.6, randomly rotated), counter-clockwise, centroid at the origin.

    ``rng``: a :class:`numpy.random.Generator`.
    """
    t = np.sort(rng.uniform(0, 2 * np.pi, n_vertices))
    # keep angular gaps below π so the centroid is inside and no edge is degenerate
    t = 2 * np.pi * (np.arange(n_vertices) + 0.6 * (rng.random(n_vertices) - 0.5)) / n_vertices
    e = rng.uniform(1.0, 1.6)
    v = 0.5 * size * np.column_stack([np.cos(t), np.sin(t) / e])
    a = rng.uniform(0, 2 * np.pi)
    v = v @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T
    w = np.roll(v, -1, axis=0)
    c = v[:, 0] * w[:, 1] - w[:, 0] * v[:, 1]
    cen = ((v + w) * c[:, None]).sum(axis=0) / (3.0 * c.sum())
    return v - cen


def world_polygons(bodies, poses) -> np.ndarray:
    """Shapely polygons ``(n,)`` of ``bodies`` (outlines ``(n_i, 2)`` in body coordinates) at
    ``poses (n, 3)`` (x, y, angle)."""
    out = []
    for v, p in zip(bodies, poses):  # test set-up helper
        c, s = np.cos(p[2]), np.sin(p[2])
        out.append(shapely.Polygon(v @ np.array([[c, -s], [s, c]]).T + p[:2]))
    return np.array(out, dtype=object)


def packing(n=200, phi=0.5, sizes=(0.5, 1.5), n_vertices=(3, 8), min_gap=0.01, seed=0):
    """Random non-overlapping convex polygons at area fraction ``phi`` in a square box.

    Bodies are placed biggest first at random positions/angles (batches of candidates tested
    with an STR tree), then compacted: each body is moved towards its nearest neighbour until
    the gap is ``min_gap`` (times a random factor 1–3) when that is free of other bodies.

    Parameters
    ----------
    n : int
        Number of bodies.
    phi : float
        Area fraction of the bodies in the box.
    sizes : (float, float)
        Range of the body diameters, length units (uniform).
    n_vertices : (int, int)
        Range of the vertex counts (inclusive).
    min_gap : float
        Smallest gap between bodies and to the walls, length units.
    seed : int
        Seed of :func:`numpy.random.default_rng`.

    Returns
    -------
    bodies : list of (n_i, 2) float
        Outlines in body coordinates (centroid at the origin).
    poses : (n, 3) float
        x, y, angle.
    box : (0, L, 0, L)
        The square box, ``L = sqrt(total body area / phi)``.

    Raises
    ------
    InputError
        No free place was found for a body (``phi`` too high).
    """
    rng = np.random.default_rng(seed)
    sz = np.sort(rng.uniform(*sizes, n))[::-1]
    bodies = [random_convex(s, int(rng.integers(n_vertices[0], n_vertices[1] + 1)), rng) for s in sz]
    area = sum(shapely.area(shapely.Polygon(b)) for b in bodies)
    L = float(np.sqrt(area / phi))
    box = (0.0, L, 0.0, L)
    placed, poses = [], []
    for v in bodies:
        r = np.linalg.norm(v, axis=1).max()
        for _ in range(200):
            k = 256
            xy = rng.uniform(r + min_gap, L - r - min_gap, (k, 2))
            ang = rng.uniform(0, 2 * np.pi, k)
            c, s = np.cos(ang), np.sin(ang)
            cand = np.stack([c[:, None] * v[None, :, 0] - s[:, None] * v[None, :, 1] + xy[:, :1],
                             s[:, None] * v[None, :, 0] + c[:, None] * v[None, :, 1] + xy[:, 1:]], axis=2)
            polys = shapely.polygons(cand)
            if placed:
                tree = shapely.STRtree(placed)
                ci, _ = tree.query(polys, predicate="dwithin", distance=min_gap)
                ok = np.ones(k, dtype=bool)
                ok[ci] = False
            else:
                ok = np.ones(k, dtype=bool)
            if ok.any():
                j = int(np.flatnonzero(ok)[0])
                placed.append(polys[j])
                poses.append([xy[j, 0], xy[j, 1], ang[j]])
                break
        else:
            raise InputError(f"phi = {phi!r}: expected a lower area fraction (no free place found for a body)")
    poses = np.array(poses)
    _compact(np.array(placed, dtype=object), poses, box, min_gap, rng)
    return bodies, poses, box


def _compact(placed, poses, box, min_gap, rng) -> None:
    """Move each body towards its nearest neighbour until the gap is ``min_gap`` times a random factor
    1–3 when that is free of other bodies and of the walls of ``box``: narrow gaps.  In place: ``placed``
    (n,) shapely polygons, ``poses (n, 3)``."""
    n = len(placed)
    x0, x1, y0, y1 = box
    for i in range(n):  # set-up helper over bodies
        tree = shapely.STRtree(placed)
        others = np.delete(np.arange(n), i)
        d = shapely.distance(placed[others], placed[i])
        j = others[np.argmin(d)]
        gap = d.min()
        target = min_gap * rng.uniform(1.0, 3.0)
        if gap <= target:
            continue
        dirn = poses[j, :2] - poses[i, :2]
        dirn /= np.linalg.norm(dirn)
        for frac in (1.0, 0.5, 0.25):
            shift = dirn * (gap - target) * frac
            moved = shapely.transform(placed[i], lambda p: p + shift)
            near = tree.query(moved, predicate="dwithin", distance=min_gap)
            near = near[near != i]
            xmin, ymin, xmax, ymax = shapely.bounds(moved)
            if len(near) == 0 and xmin > x0 + min_gap and ymin > y0 + min_gap and xmax < x1 - min_gap and \
                    ymax < y1 - min_gap:
                placed[i] = moved
                poses[i, :2] += shift
                break


def hexagon_packing(nx: int = 4, ny: int = 4, phi: float = 0.7, size: float = 1.0, spread: float = 0.1,
                    min_gap: float = 0.01, seed: int = 0):
    """Hexagons on a triangular lattice at area fraction ``phi`` (up to about 0.75), with narrow gaps.

    Random placement (:func:`packing`) jams near φ ≈ 0.55; denser packings are built on a lattice.
    ``nx × ny`` regular hexagons (pointed top, so that their flat sides face the six lattice
    neighbours), of flat-to-flat width ``size`` times a random factor ``1 − spread … 1``, sit on a
    triangular lattice (odd rows shifted by half a spacing) whose spacing is found by bisection so
    that the bodies cover ``phi`` of the box (a margin of half the gap to the walls); then they are
    compacted towards their nearest neighbours as in :func:`packing`, down to gaps of ``min_gap``.

    Parameters
    ----------
    nx, ny : int
        Bodies per row, rows.
    phi : float
        Area fraction.
    size : float
        Largest flat-to-flat width, length.
    spread : float
        Relative spread of the widths, in [0, 1).
    min_gap : float
        Smallest gap, length.
    seed : int

    Returns
    -------
    bodies, poses, box
        As :func:`packing` (``box`` a rectangle).

    Raises
    ------
    InputError
        ``phi`` above what the lattice reaches with gaps ≥ ``min_gap``, or ``spread`` outside [0, 1).

    Examples
    --------
    >>> bodies, poses, box = hexagon_packing(4, 4, phi=0.7, seed=0)
    >>> area = sum(float(shapely.area(shapely.Polygon(b))) for b in bodies)
    >>> round(area / ((box[1] - box[0]) * (box[3] - box[2])), 6)
    0.7
    """
    if not 0.0 <= spread < 1.0:
        raise InputError(f"spread = {spread!r}: expected a number in [0, 1)")
    rng = np.random.default_rng(seed)
    n = nx * ny
    w = size * rng.uniform(1.0 - spread, 1.0, n)  # flat-to-flat widths
    R = w / np.sqrt(3.0)  # circumradii
    bodies = [regular_polygon(r, 6, phase=np.pi / 6) for r in R]
    area = float(sum(shapely.area(shapely.Polygon(b)) for b in bodies))
    Rm = float(R.max())

    def layout(d):
        g = d - np.sqrt(3.0) * Rm  # the narrowest lattice gap
        i, j = np.meshgrid(np.arange(nx), np.arange(ny))
        x = g / 2 + np.sqrt(3.0) * Rm / 2 + (i + 0.5 * (j % 2)) * d
        y = g / 2 + Rm + j * d * np.sqrt(3.0) / 2
        box = (0.0, float(x.max() + np.sqrt(3.0) * Rm / 2 + g / 2), 0.0, float(y.max() + Rm + g / 2))
        return np.column_stack([x.ravel(), y.ravel(), np.zeros(n)]), box

    def fraction(d):
        _, b = layout(d)
        return area / ((b[1] - b[0]) * (b[3] - b[2]))

    lo, hi = np.sqrt(3.0) * Rm + 2 * min_gap, 4.0 * Rm
    if fraction(lo) < phi:
        raise InputError(f"phi = {phi!r}: expected at most {fraction(lo):.3g} for {nx} x {ny} hexagons with gaps "
                         f">= {min_gap:g}")
    for _ in range(60):  # bisection on the spacing: the fraction falls as it grows
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fraction(mid) > phi else (lo, mid)
    poses, box = layout(0.5 * (lo + hi))
    placed = np.array([shapely.Polygon(b + p[:2]) for b, p in zip(bodies, poses)], dtype=object)
    _compact(placed, poses, box, min_gap, rng)
    return bodies, poses, box


class RandomMotion:
    """Random small rigid motions keeping every gap ≥ ``min_gap`` and bodies inside the box.

    Each step every body gets a Gaussian translation (std ``sigma_x``) and rotation (std
    ``sigma_a`` rad); moves that would bring two bodies (or a body and a wall) closer than
    ``min_gap`` are undone for the bodies involved (repeated until none is left).
    """

    def __init__(self, bodies, poses, box, sigma_x=0.002, sigma_a=0.004, min_gap=0.01, seed=1):
        self.bodies = bodies
        self.poses = np.array(poses, dtype=float)
        self.box = box
        self.sigma_x, self.sigma_a, self.min_gap = sigma_x, sigma_a, min_gap
        self.rng = np.random.default_rng(seed)
        self._nv = np.array([len(b) for b in bodies])
        self._vc = np.vstack(bodies)
        self._vb = np.repeat(np.arange(len(bodies)), self._nv)

    def polygons(self, poses) -> np.ndarray:
        """Shapely polygons ``(n,)`` of the bodies at ``poses (n, 3)``."""
        c, s = np.cos(poses[self._vb, 2]), np.sin(poses[self._vb, 2])
        x = c * self._vc[:, 0] - s * self._vc[:, 1] + poses[self._vb, 0]
        y = s * self._vc[:, 0] + c * self._vc[:, 1] + poses[self._vb, 1]
        return shapely.polygons(shapely.linearrings(np.column_stack([x, y]), indices=self._vb))

    def step(self) -> np.ndarray:
        """Advance one step; returns a copy of the new poses ``(n, 3)``."""
        n = len(self.poses)
        trial = self.poses.copy()
        trial[:, :2] += self.rng.normal(0, self.sigma_x, (n, 2))
        trial[:, 2] += self.rng.normal(0, self.sigma_a, n)
        for _ in range(20):
            polys = self.polygons(trial)
            a, b = shapely.STRtree(polys).query(polys, predicate="dwithin", distance=self.min_gap)
            bad = np.zeros(n, dtype=bool)
            sel = a != b
            bad[a[sel]] = True
            xmin, ymin, xmax, ymax = shapely.bounds(polys).T
            g = self.min_gap
            bad |= ((xmin < self.box[0] + g) | (ymin < self.box[2] + g) | (xmax > self.box[1] - g)
                    | (ymax > self.box[3] - g))
            moved = np.any(trial != self.poses, axis=1)
            bad &= moved
            if not bad.any():
                break
            trial[bad] = self.poses[bad]
        self.poses = trial
        return trial.copy()

    def min_gap_now(self) -> float:
        """Smallest gap between two bodies now (pairs closer than 1 length unit), length units."""
        polys = self.polygons(self.poses)
        a, b = shapely.STRtree(polys).query(polys, predicate="dwithin", distance=1.0)
        sel = a < b
        return float(shapely.distance(polys[a[sel]], polys[b[sel]]).min())


# ---------------------------------------------------------------- the other hard cases
def sliding_pair(h):
    """Case 2: two 1 × 0.3 bars, gap ``h/10``, that slide past each other in opposite directions.

    Returns ``bodies``, ``poses (2, 3)``, ``box`` and ``poses_at(k, n)``: the poses after
    step ``k`` of ``n`` (each bar moves by 2 length units in ``n`` steps).
    """
    bodies = [rectangle(1.0, 0.3), rectangle(1.0, 0.3)]
    poses = np.array([[1.0, 1.0, 0.0], [3.0, 1.3 + h / 10, 0.0]])
    box = (0.0, 4.0, 0.0, 2.3)

    def poses_at(k, n):
        p = poses.copy()
        p[0, 0] += 2.0 * k / n
        p[1, 0] -= 2.0 * k / n
        return p

    return bodies, poses, box, poses_at


def crossing_body():
    """Case 3: a hexagon that crosses from the fine region (x < 5) of a graded mesh to x = 7 and back.

    Returns ``bodies``, ``poses (1, 3)``, ``box``, the ``grading`` dict of
    :class:`fluidem.mesh.MovingMesh` and ``poses_at(k, n)``: the pose after step ``k`` of ``n``.
    """
    bodies = [regular_polygon(0.5, 6)]
    box = (0.0, 14.0, 0.0, 8.0)
    grading = {"region": (0.0, 5.0, 0.0, 8.0), "growth": 1.25, "h_max": 1.0}

    def poses_at(k, n):
        s = k / n
        x = 2.5 + 4.5 * (1 - abs(1 - 2 * s))
        return np.array([[x, 4.0, 0.5 * s]])

    return bodies, poses_at(0, 1), box, grading, poses_at


def collapsing_step():
    """Case 4: a 10 × 20 block of squares (side 0.5, gaps 0.05) sliding down and to the side (paper Fig. 6).

    Rows shear to the right and the block spreads and settles by 8 % in height, so that no two
    squares overlap: a prescribed stand-in for the granular collapse.  Returns ``bodies``,
    ``poses (200, 3)``, ``box``, the ``grading`` dict and ``poses_at(k, n)``.
    """
    X, Y = np.meshgrid(1.0 + 0.55 * np.arange(10), 0.5 + 0.55 * np.arange(20))
    base = np.column_stack([X.ravel(), Y.ravel()])
    bodies = [rectangle(0.5, 0.5)] * len(base)
    box = (0.0, 30.0, 0.0, 14.0)
    grading = {"region": (0.0, 7.0, 0.0, 12.0), "growth": 1.2, "h_max": 1.0}

    def poses_at(k, n):
        s = 0.5 - 0.5 * np.cos(np.pi * k / n)
        x = base[:, 0] + 0.5 * (base[:, 0] - 1.0) * s + 0.9 * (base[:, 1] - 0.5) * s
        y = 0.5 + (base[:, 1] - 0.5) * (1 - 0.08 * s)
        return np.column_stack([x, y, np.zeros(len(x))])

    return bodies, poses_at(0, 1), box, grading, poses_at


def pore_ring(n: int = 6, radius: float = 0.5, center=(1.25, 1.25)):
    """``n`` touching 0.52 × 0.2 bars on a circle of ``radius`` around ``center``, enclosing a fluid pore.

    Returns ``(bodies, poses)``: outlines ``(4, 2)`` in body coordinates and poses ``(n, 3)``
    (x, y, angle), each bar tangent to the circle; in a 2.5 × 2.5 box at ``h = 0.05`` the
    moving mesh merges them into one closed outline with one pore.
    """
    a = 2 * np.pi * np.arange(n) / n
    poses = np.column_stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a), a + np.pi / 2])
    return [rectangle(0.52, 0.2) for _ in range(n)], poses


# ---------------------------------------------------------------- case 6: collective motion
#: the motions of :func:`collective_motion` (the first three keep every gap open)
COLLECTIVE_MOTIONS = ("rotation", "breathing", "shear", "turn-and-breathe")


class CollectiveMotion:
    """Case 6: a packing moved as a whole about the centre ``c`` of its box, one period of a sine.

    With ``s(k) = sin(2π k / n_steps)`` the body centres ``x0`` and angles ``θ0`` become, after
    step ``k``,

    * ``"rotation"``: a rigid rotation by ``α(k) = amplitude · s(k)`` rad about ``c``:
      ``x = c + R(α)(x0 − c)``, ``θ = θ0 + α``;
    * ``"breathing"``: uniform expansion and contraction of the centre positions (shapes are
      rigid), ``x = c + (1 + amplitude · s(k))(x0 − c)``, ``θ = θ0``; the gaps between bodies
      shrink at the strongest contraction, so the packing is built with gaps large enough
      that none closes (:attr:`min_gap_seen`);
    * ``"shear"``: simple shear of the centre positions, ``x = x0 + γ(k)(y0 − c_y)``,
      ``γ(k) = amplitude · s(k)``, each body turning with the mean rotation of the flow,
      ``θ = θ0 − γ(k)/2``;
    * ``"turn-and-breathe"``: both the rotation and the scaling, ``amplitude = (α0, s0)``
      (rad, relative): ``x = c + (1 + s0 s(k)) R(α0 s(k))(x0 − c)``, ``θ = θ0 + α0 s(k)``; with
      the narrow gaps of a dense packing the contraction brings bodies into contact.

    Attributes
    ----------
    bodies, poses0, box, center, kind, amplitude, n_steps
        The set-up (``poses0 (n, 3)``: x, y, angle at ``k = 0``).
    rim_step : float
        Largest displacement of a body vertex in one step over the period, length units.
    min_gap_seen : float
        Smallest gap between two bodies or a body and the box over the period (sampled at
        every step), length units.
    """

    def __init__(self, bodies, poses0, box, kind, amplitude, n_steps):
        if kind not in COLLECTIVE_MOTIONS:
            raise InputError(f"motion kind = {kind!r}: expected one of {COLLECTIVE_MOTIONS}")
        self.bodies, self.poses0, self.box = bodies, np.asarray(poses0, dtype=float), box
        self.center = np.array([0.5 * (box[0] + box[1]), 0.5 * (box[2] + box[3])])
        amplitude = tuple(float(a) for a in amplitude) if kind == "turn-and-breathe" else float(amplitude)
        self.kind, self.amplitude, self.n_steps = kind, amplitude, int(n_steps)
        self._nv = np.array([len(b) for b in bodies])
        self._vc = np.vstack(bodies)
        self._vb = np.repeat(np.arange(len(bodies)), self._nv)
        seq = [self.poses_at(k) for k in range(self.n_steps + 1)]
        verts = np.array([self._world(p) for p in seq])
        self.rim_step = float(np.linalg.norm(np.diff(verts, axis=0), axis=2).max())
        self.min_gap_seen = min(self._min_gap(p) for p in seq)

    def poses_at(self, k) -> np.ndarray:
        """Poses ``(n, 3)`` after step ``k`` (``k = 0``: the initial packing)."""
        s = np.sin(2 * np.pi * k / self.n_steps)
        r = self.poses0[:, :2] - self.center
        p = self.poses0.copy()
        if self.kind in ("rotation", "turn-and-breathe"):
            a0, s0 = self.amplitude if self.kind == "turn-and-breathe" else (self.amplitude, 0.0)
            a = a0 * s
            c, sn = np.cos(a), np.sin(a)
            p[:, :2] = self.center + (1.0 + s0 * s) * (r @ np.array([[c, -sn], [sn, c]]).T)
            p[:, 2] += a
        elif self.kind == "breathing":
            p[:, :2] = self.center + (1.0 + self.amplitude * s) * r
        else:
            g = self.amplitude * s
            p[:, 0] += g * r[:, 1]
            p[:, 2] -= 0.5 * g
        return p

    def sequence(self) -> list:
        """Poses after steps ``1 … n_steps``, a list of ``(n, 3)`` arrays."""
        return [self.poses_at(k) for k in range(1, self.n_steps + 1)]

    def _world(self, poses):
        c, s = np.cos(poses[self._vb, 2]), np.sin(poses[self._vb, 2])
        x = c * self._vc[:, 0] - s * self._vc[:, 1] + poses[self._vb, 0]
        y = s * self._vc[:, 0] + c * self._vc[:, 1] + poses[self._vb, 1]
        return np.column_stack([x, y])

    def _min_gap(self, poses) -> float:
        w = self._world(poses)
        polys = shapely.polygons(shapely.linearrings(w, indices=self._vb))
        a, b = shapely.STRtree(polys).query(polys, predicate="dwithin", distance=1.0)
        sel = a < b
        gap = shapely.distance(polys[a[sel]], polys[b[sel]]).min() if sel.any() else np.inf
        xmin, xmax, ymin, ymax = self.box
        wall = min(w[:, 0].min() - xmin, xmax - w[:, 0].max(), w[:, 1].min() - ymin, ymax - w[:, 1].max())
        return float(min(gap, wall))


def collective_motion(kind: str, h: float = 0.08, n: int = 120, phi: float = 0.3, sizes=(0.3, 0.6),
                      min_gap: float = 0.06, box_size: float = 10.0, n_steps: int = 300, amplitude=None,
                      seed: int = 0) -> CollectiveMotion:
    """Case 6: a :func:`packing` of ``n`` bodies placed in the middle of a ``box_size`` square,
    moved as a whole (:class:`CollectiveMotion`).

    Parameters
    ----------
    kind : {"rotation", "breathing", "shear", "turn-and-breathe"}
    h : float
        Mesh size the motion is scaled to: by default the rim bodies move at most ``h/8`` per
        step (rotation), the centre positions scale by ±5 % (breathing, rim step ≈ h/16)
        and the shear amplitude is 0.1 (rim step ≈ h/11); ``"turn-and-breathe"``: 0.25 rad
        and 5 % (rim step ≈ h/4).
    n, phi, sizes, min_gap, seed
        The packing (:func:`packing`; its own box, side ``sqrt(area/phi)``, is centred in
        the big one).  ``min_gap = 0.06`` keeps every gap ≥ 0.02 (``h/4``) at the
        strongest contraction and shear.
    box_size : float
        Side of the box, length units.
    n_steps : int
        Steps of one period.
    amplitude : float, (float, float) or None
        Rotation angle (rad), relative scaling or shear, (angle, scaling) for
        ``"turn-and-breathe"``; ``None``: the defaults above.

    Raises
    ------
    InputError
        ``kind`` unknown, or the packing does not fit in the box.
    """
    if kind not in COLLECTIVE_MOTIONS:
        raise InputError(f"motion kind = {kind!r}: expected one of {COLLECTIVE_MOTIONS}")
    bodies, poses, inner = packing(n=n, phi=phi, sizes=sizes, min_gap=min_gap, seed=seed)
    if inner[1] >= box_size:
        raise InputError(f"box_size = {box_size!r}: expected more than the packing's side {inner[1]:.3g}")
    poses = poses.copy()
    poses[:, :2] += 0.5 * (box_size - inner[1])
    box = (0.0, float(box_size), 0.0, float(box_size))
    if amplitude is None:
        if kind == "rotation":
            c = np.array([0.5 * box_size] * 2)
            r_max = max(float(np.linalg.norm(p[:2] - c) + np.linalg.norm(b, axis=1).max())
                        for b, p in zip(bodies, poses))  # set-up helper over bodies
            amplitude = (h / 8) * n_steps / (2 * np.pi * r_max)
        else:
            amplitude = {"breathing": 0.05, "shear": 0.1, "turn-and-breathe": (0.25, 0.05)}[kind]
    return CollectiveMotion(bodies, poses, box, kind, amplitude, n_steps)
