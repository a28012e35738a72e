"""Random packings of polygons in a box: a suspension's bodies without scripting.

:func:`fill` places ``n`` bodies, or as many as cover an ``area_fraction`` of the region, at
random positions and angles by *random sequential addition* (RSA; Feder 1980, Hinrichsen,
Feder & Jøssang 1986): bodies are drawn first (shape and size), then placed one at a time,
largest first, each at the first of a stream of uniformly random candidate poses that keeps
at least ``min_gap`` from every body placed before and ``side_gap`` from the sides.  A body
that finds no place in ``attempts`` candidates ends the fill with :class:`FillJammed`.
:meth:`Packing.to_csv` writes the bodies as the CSV body table of a scene's
``[bodies_table]`` (:func:`fluidem.scene.files.read_bodies_table` reads it back), and
``fluidem fill`` does both from the command line (``docs/suspensions.md``).

Sizes
-----
``radius`` is the *equal-area* radius: every body of radius r has the area π r² whatever its
shape (a rectangle of aspect ratio α is r √(π/α) by α r √(π/α), a regular n-gon has the
circumradius r √(2π / (n sin(2π/n)))), so the area fraction and, at one density, the mass
distribution do not depend on the mix of shapes.  Radii are uniform in ``radius =
(r_min, r_max)``.  A disk is a circle (the curved outline of a fluid scene); with
``segments`` it is the regular polygon inscribed in that circle that a scene builds from it
(and the area counted is that polygon's).

The gap test
------------
Two bodies with centres d apart are clear when d ≥ R_i + R_j + g (bounding radii R) and
too close when d < ρ_i + ρ_j + g (the radii ρ of the largest disks about their centres that
they contain); only the pairs in between have their exact outline distance measured (shapely,
vectorised: polygon–polygon, and centre–polygon minus the radius for a disk).  Candidates
come in vectorised batches; neighbours from a k-d tree over the placed centres (rebuilt
every 128 bodies, the latest checked directly), so 1000 bodies take a fraction of a second.

Reachable fractions
-------------------
RSA jams: for equal disks without gap the fraction tends to 0.547 (Hinrichsen et al. 1986)
only as the attempts grow without bound, and the layer next to a wall is sparser.  Measured
with this function (default ``attempts``, seeds 0 and 1, the unit box, ``docs/suspensions.md``):

=========================================  =============  ===============================
bodies                                     no gap         default gap (0.1 × mean radius)
=========================================  =============  ===============================
equal disks, r = 0.01 (1650 bodies)        0.517–0.519    0.470–0.473
disks, r = 0.01–0.02                       0.553–0.558
disks, rectangles, triangles, hexagons,    0.470–0.473    0.423–0.430
r = 0.01
the same, r = 0.025–0.04 (box 2 × 2)                      0.39–0.41
=========================================  =============  ===============================

A gap g acts as bodies of radius r + g/2 packed touching: the default gap scales the reachable
fraction by about (1 + 0.05)⁻² = 0.91, as measured.  A jammed fill raises :class:`FillJammed`
(an :class:`~fluidem.errors.InputError`) naming the fraction it reached.

Examples
--------
>>> from fluidem.scene.fill import fill
>>> p = fill((0.0, 1.0, 0.0, 1.0), area_fraction=0.3, shapes=("disk", "hexagon"),
...          radius=(0.03, 0.05), seed=1)
>>> len(p), round(p.area_fraction, 2)
(57, 0.3)
>>> p.bodies[0]["shape"], sorted(p.bodies[0])
('polygon', ['angle', 'position', 'shape', 'vertices'])
>>> fill((0.0, 1.0, 0.0, 1.0), area_fraction=1.2, radius=0.05)
Traceback (most recent call last):
...
fluidem.errors.InputError: area_fraction = 1.2: expected a number in (0, 1)
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..validate import fail, integer, nonnegative, number, positive
from .rsa import FillJammed, place
from .shapes import SHAPES, bounding_factor, check_shape, disk_area_factor, shape_outline

__all__ = ["fill", "Packing", "FillJammed", "SHAPES", "shape_outline", "DEFAULT_ATTEMPTS", "MAX_BODIES"]

#: candidate poses tried for one body before the fill is declared jammed
DEFAULT_ATTEMPTS = 20000
#: most bodies one fill places (a region of 10^5 bodies is not a scene the solver can mesh)
MAX_BODIES = 100000
#: the default gap between outlines, times the mean radius
DEFAULT_GAP_FACTOR = 0.1


@dataclass
class Packing:
    """The bodies of a :func:`fill`, ready for a scene.

    Attributes
    ----------
    region : (4,) float
        ``(xmin, xmax, ymin, ymax)``, length.
    bodies : list of dict
        One per body, keyed as :class:`fluidem.scene.BodySpec` fields: ``shape`` (``"disk"``,
        ``"rectangle"`` or ``"polygon"``), its size (``radius`` [``segments``] / ``width``,
        ``height`` / ``vertices`` in body coordinates, centroid at the origin), ``position``
        (centroid, length) and ``angle`` (rad).  ``Scene.from_dict({"bodies": ...})`` takes them.
    kinds : list of str
        The :data:`SHAPES` name each body was drawn as (``"hexagon"``, ``"7-gon"``).
    radii : (n,) float
        Equal-area radius of each body, length.
    areas : (n,) float
        Area of each outline as the scene builds it, length².
    area_fraction : float
        ``areas.sum()`` over the region's area.
    min_gap, side_gap : float
        The gaps kept between outlines and from the sides, length.
    seed : int
    """

    region: tuple
    bodies: list
    kinds: list
    radii: np.ndarray
    areas: np.ndarray
    min_gap: float
    side_gap: float
    seed: int
    area_fraction: float = field(init=False)

    def __post_init__(self):
        x0, x1, y0, y1 = self.region
        self.area_fraction = float(self.areas.sum() / ((x1 - x0) * (y1 - y0)))

    def __len__(self) -> int:
        return len(self.bodies)

    def counts(self) -> dict:
        """Shape name -> number of bodies, in the order of first appearance."""
        out: dict = {}
        for k in self.kinds:
            out[k] = out.get(k, 0) + 1
        return out

    def __str__(self) -> str:
        x0, x1, y0, y1 = self.region
        mix = ", ".join(f"{v} {k}" for k, v in self.counts().items())
        return (f"{len(self)} bodies ({mix}) at area fraction {self.area_fraction:.4f} in [{x0:g}, {x1:g}] x "
                f"[{y0:g}, {y1:g}], radius {self.radii.min():.4g}..{self.radii.max():.4g}, gaps >= {self.min_gap:.4g} "
                f"(sides {self.side_gap:.4g}), seed {self.seed}")

    def to_csv(self, path, density: float | None = None, overwrite: bool = False) -> Path:
        """Write the bodies as a CSV body table (the columns of :data:`fluidem.scene.files.TABLE_COLUMNS`).

        Parameters
        ----------
        path : path
            The CSV file; name it in a scene as ``[bodies_table] file = "..."``.
        density : float, optional
            Areal density of every body, mass/length² (a ``density`` column); default none (the
            ``[bodies_table]`` density, or the body default 1, applies).
        overwrite : bool
            Replace an existing file (refused otherwise).

        Returns
        -------
        pathlib.Path
        """
        path = Path(path)
        if path.exists() and not overwrite:
            raise InputError(f"{str(path)!r} exists already; expected a new file name (or overwrite)")
        if density is not None:
            density = positive("density", density)
        cols = ["shape", "radius", "segments", "width", "height", "vertices", "x", "y", "angle"]
        if density is not None:
            cols.append("density")

        def num(v):
            return f"{float(v):.12g}"

        with open(path, "w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(cols)
            for b in self.bodies:
                row = dict.fromkeys(cols, "")
                row["shape"] = b["shape"]
                for k in ("radius", "width", "height"):
                    if k in b:
                        row[k] = num(b[k])
                if "segments" in b:
                    row["segments"] = str(b["segments"])
                if "vertices" in b:
                    row["vertices"] = "; ".join(f"{num(x)} {num(y)}" for x, y in b["vertices"])
                row["x"], row["y"] = num(b["position"][0]), num(b["position"][1])
                row["angle"] = num(b["angle"])
                if density is not None:
                    row["density"] = num(density)
                w.writerow([row[c] for c in cols])
        return path


# ---------------------------------------------------------------------------------------
# the fill
# ---------------------------------------------------------------------------------------
def fill(region, *, n=None, area_fraction=None, shapes=("disk",), radius=None, aspect=2.0, seed=0,
         min_gap=None, side_gap=None, periodic=(), segments=None, attempts=DEFAULT_ATTEMPTS,
         labels=None) -> Packing:
    """Place random non-overlapping bodies in a box by random sequential addition.

    Parameters
    ----------
    region : (xmin, xmax, ymin, ymax)
        The box to fill, length (a scene's ``domain.box``, or a part of it).
    n : int, optional
        Number of bodies.
    area_fraction : float, optional
        Fraction of the region's area the bodies cover, in (0, 1): bodies are drawn until their
        areas add up to it (to within half the largest body's area).  Give ``n`` or
        ``area_fraction``; both with no ``radius`` make ``n`` equal bodies of the radius that
        covers that fraction; all three must agree (the expected fraction of ``n`` bodies
        within 5 %).
    shapes : str, sequence of str, or dict
        Shape names (:data:`SHAPES` or ``"<N>-gon"``) drawn with equal probability, or a dict
        name -> relative weight.
    radius : float or (float, float)
        Equal-area radius (the body's area is π r²), or the range it is drawn from uniformly,
        length.
    aspect : float
        Width / height of the rectangles, > 0.
    seed : int
        Seed of :func:`numpy.random.default_rng`: the same arguments and seed give the same bodies.
    min_gap : float, optional
        Smallest distance between two outlines, length; default 0.1 × the mean radius: a film
        of fluid between every two bodies at the start (a fluid scene refuses touching bodies)
        that costs about 10 % of the reachable fraction (a gap g acts as bodies of radius
        r + g/2 packed touching).
    side_gap : float, optional
        Smallest distance from an outline to a side of the region, length; default ``min_gap``.
    periodic : sequence of {"x", "y"}
        Axes along which the region is periodic.  Bodies are placed anywhere along such an axis,
        across its sides too (a body across the side is the same body on both sides; every gap is
        measured to the nearest periodic image), and ``side_gap`` applies only to the other sides.
        A fluid scene meshes a body across a periodic side on the moving mesh (free or moving
        bodies).  A body's bounding diameter must stay below half the period (the nearest-image
        rule of :class:`fluidem.dem.DEM`).
    segments : int, optional
        Outline vertices of every disk (a ``segments`` column; default: the scene's choice, a
        curved circle in a fluid scene, 32 vertices in a dry one).
    attempts : int
        Candidate poses tried for one body before the fill is declared jammed.
    labels : dict, optional
        How error messages name the arguments (argument name -> label; the command line
        passes its option names).

    Returns
    -------
    Packing

    Raises
    ------
    fluidem.errors.InputError
        A bad argument (one line naming it and what is allowed).
    FillJammed
        (an ``InputError``) No place found for a body: the message names the fraction reached.
    """
    lab = {k: k for k in ("region", "n", "area_fraction", "shapes", "radius", "aspect", "seed", "min_gap",
                          "side_gap", "periodic", "segments", "attempts")}
    lab.update(labels or {})
    x0, x1, y0, y1 = _region(region, lab["region"])
    Lx, Ly = x1 - x0, y1 - y0
    A = Lx * Ly
    if n is None and area_fraction is None:
        raise InputError(f"no amount: give {lab['n']} (the number of bodies) or {lab['area_fraction']} (the area "
                         "fraction they cover)")
    if n is not None:
        n = integer(lab["n"], n, lo=1, hi=MAX_BODIES)
    if area_fraction is not None:
        area_fraction = number(lab["area_fraction"], area_fraction, "a number in (0, 1)", lo=0.0, lo_open=True,
                               hi=1.0, hi_open=True)
    weights = _shapes(shapes, lab["shapes"])
    aspect = positive(lab["aspect"], aspect)
    seed = integer(lab["seed"], seed, lo=0)
    attempts = integer(lab["attempts"], attempts, lo=1)
    if segments is not None:
        segments = integer(lab["segments"], segments, lo=3, hi=100000)
    axes = _axes(periodic, lab["periodic"])
    if radius is None:
        if n is None or area_fraction is None:
            raise InputError(f"no size: give {lab['radius']} (the equal-area radius, or a range r_min r_max), or both "
                             f"{lab['n']} and {lab['area_fraction']}")
        r_lo = r_hi = math.sqrt(area_fraction * A / (n * math.pi * disk_area_factor(weights, segments)))
    else:
        r_lo, r_hi = _radius(radius, lab["radius"])
    r_mean = 0.5 * (r_lo + r_hi)
    min_gap = DEFAULT_GAP_FACTOR * r_mean if min_gap is None else nonnegative(lab["min_gap"], min_gap)
    side_gap = min_gap if side_gap is None else nonnegative(lab["side_gap"], side_gap)
    gaps = {"x": side_gap, "y": side_gap}
    period = (Lx if "x" in axes else None, Ly if "y" in axes else None)

    # the largest bounding radius must fit with its side gaps (or in half a period)
    R_factor = max(bounding_factor(s, aspect) for s in weights)
    room = min(0.5 * Lx if period[0] else Lx - 2 * gaps["x"], 0.5 * Ly if period[1] else Ly - 2 * gaps["y"])
    if 2.0 * R_factor * r_hi > room:
        big = max(weights, key=lambda s: bounding_factor(s, aspect))
        if radius is None:
            raise InputError(f"{lab['n']} = {n}, {lab['area_fraction']} = {area_fraction:g}: equal bodies of radius "
                             f"{r_hi:.4g} (a {big}'s bounding diameter {2 * R_factor * r_hi:.4g}) do not fit in the "
                             f"room {room:.4g} the region {Lx:.4g} x {Ly:.4g} leaves inside its side gaps (half the "
                             f"period along a periodic axis); expected "
                             f"more bodies or a smaller fraction")
        raise fail(lab["radius"], radius if radius is not None else r_hi,
                   f"a radius up to {0.5 * room / R_factor:.4g}: a {big} of radius {r_hi:.4g} has a bounding "
                   f"diameter {2 * R_factor * r_hi:.4g}, more than the room {room:.4g} the region "
                   f"{Lx:.4g} x {Ly:.4g} leaves inside its side gaps (half the period along a periodic axis)")

    rng = np.random.default_rng(seed)
    kind_names, radii = _draw_sizes(rng, weights, n, area_fraction, radius, r_lo, r_hi, segments, A, lab)
    order = np.argsort(-radii * np.array([bounding_factor(s, aspect) for s in kind_names]), kind="stable")
    placed = place([kind_names[i] for i in order], radii[order], aspect, segments, (x0, x1, y0, y1), gaps,
                    period, min_gap, attempts, rng, area_fraction, n, lab)
    bodies, areas = placed
    return Packing(region=(x0, x1, y0, y1), bodies=bodies, kinds=[kind_names[i] for i in order],
                   radii=radii[order].copy(), areas=areas, min_gap=min_gap, side_gap=side_gap, seed=seed)


def _draw_sizes(rng, weights, n, area_fraction, radius, r_lo, r_hi, segments, A, lab):
    """The shapes (names) and equal-area radii of the bodies to place: ``n`` of them, or as many as
    cover ``area_fraction`` of the area ``A`` (to within half the last body's area)."""
    names, probs = list(weights), np.array(list(weights.values()))
    disk_factor = disk_area_factor({"disk": 1.0}, segments)
    if n is not None:
        radii = rng.uniform(r_lo, r_hi, n)
        kinds = rng.choice(len(names), size=n, p=probs)
        if area_fraction is not None and radius is not None:
            expected = n * math.pi * (r_lo ** 2 + r_lo * r_hi + r_hi ** 2) / 3.0 * disk_area_factor(weights, segments)
            if abs(expected / (area_fraction * A) - 1.0) > 0.05:
                raise InputError(f"{lab['n']} = {n}, {lab['area_fraction']} = {area_fraction:g} and {lab['radius']} = "
                                 f"{_show(radius)} disagree: {n} bodies of that radius cover about "
                                 f"{expected / A:.4g} of the region; expected two of them, or all three within 5 %")
    else:
        target = area_fraction * A
        per = math.pi * r_lo ** 2 * min(disk_factor, 1.0)
        n_max = int(min(MAX_BODIES, math.ceil(target / per) + 1))
        radii = rng.uniform(r_lo, r_hi, n_max)
        kinds = rng.choice(len(names), size=n_max, p=probs)
        a = math.pi * radii ** 2 * np.where(np.array(names)[kinds] == "disk", disk_factor, 1.0)
        cum = np.cumsum(a)
        if cum[-1] < target - 0.5 * a[-1]:
            raise InputError(f"{lab['area_fraction']} = {area_fraction:g} with {lab['radius']} = {_show(radius)}: more "
                             f"than {MAX_BODIES} bodies; expected a larger radius or a smaller region or fraction")
        k = int(np.argmin(np.abs(np.concatenate([[0.0], cum]) - target)))
        k = max(k, 1)
        radii, kinds = radii[:k], kinds[:k]
    return [names[i] for i in kinds], radii


def _show(radius) -> str:
    return repr(radius) if not isinstance(radius, (list, tuple)) else " ".join(f"{float(r):g}" for r in radius)


def _region(region, key):
    try:
        x0, x1, y0, y1 = (float(v) for v in region)
        ok = all(math.isfinite(v) for v in (x0, x1, y0, y1)) and x1 > x0 and y1 > y0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise fail(key, region, "four finite numbers xmin, xmax, ymin, ymax with xmin < xmax and ymin < ymax")
    return x0, x1, y0, y1


def _radius(radius, key):
    if isinstance(radius, (list, tuple, np.ndarray)):
        if len(radius) == 1:
            radius = radius[0]
        elif len(radius) != 2:
            raise fail(key, radius, "one radius or a range r_min, r_max (length)")
    if isinstance(radius, (list, tuple, np.ndarray)):
        lo = positive(key, radius[0])
        hi = positive(key, radius[1])
        if hi < lo:
            raise fail(key, [float(r) for r in radius], "a range r_min, r_max with r_min <= r_max")
        return lo, hi
    r = positive(key, radius)
    return r, r


def _shapes(shapes, key) -> dict:
    """Shape name -> probability."""
    if isinstance(shapes, str):
        shapes = [shapes]
    if isinstance(shapes, dict):
        items = list(shapes.items())
    else:
        try:
            items = [(s, 1.0) for s in shapes]
        except TypeError:
            raise fail(key, shapes, "a shape name, a list of them or a dict name -> weight") from None
    if not items:
        raise fail(key, shapes, "at least one shape")
    out: dict = {}
    for s, w in items:
        s = check_shape(s, key)
        out[s] = out.get(s, 0.0) + positive(f"{key} weight of {s!r}", w)
    total = sum(out.values())
    return {s: w / total for s, w in out.items()}


def _axes(periodic, key) -> tuple:
    try:
        axes = tuple(dict.fromkeys(list(periodic)))
    except TypeError:
        raise fail(key, periodic, "axes 'x' and/or 'y'") from None
    for a in axes:
        if a not in ("x", "y"):
            raise fail(key, periodic, "axes 'x' and/or 'y'")
    return axes


