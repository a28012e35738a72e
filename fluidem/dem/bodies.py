"""Rigid convex polygons for the DEM: shape, mass properties and initial state.

A :class:`Body` holds its outline in *body coordinates* with the centre of mass at the
origin, the mass and the moment of inertia about the centre of mass (uniform areal
density, 2D: mass per unit area), and its initial pose and velocity.  The time-dependent
state lives in the :class:`fluidem.dem.DEM` arrays, not here, so that the step works on
arrays of bodies.

Mass properties come from :mod:`fluidem.geometry` (shoelace area and centroid, polygon
polar moment ``J``); the inertia about the centroid is ``ρ (J_0 − A |c|²)`` (parallel
axis theorem).

Units: one consistent system of the user's choice (see :mod:`fluidem.dem`, "Units"):
lengths in length units, areal density in mass/length² (kg/m² in SI), mass in mass units,
inertia in mass·length², angles in radians.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from fluidem import geometry as geo
from fluidem import names, validate

__all__ = ["Body", "MOTIONS", "random_convex_vertices"]

#: The kinds of motion a body may have.
MOTIONS = names.choices("motion")  # ("free", "fixed", "prescribed")


def _key(name: str, param: str, call: str = "Body") -> str:
    """Where a value was given: ``Body(density=...)``, or ``Body(name='grain', density=...)``."""
    return f"{call}({param}=...)" if name == "body" else f"{call}(name={name!r}, {param}=...)"


def _pair(key: str, value) -> np.ndarray:
    """A pair of finite numbers as a float (2,) array (numpy arrays of any shape with 2 entries pass)."""
    if isinstance(value, np.ndarray):
        value = value.reshape(-1)
    return np.array(validate.pair(key, value))


def _real(key: str, value) -> float:
    """A finite number (numpy 0-d arrays pass)."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    return validate.number(key, value)


def _box(key: str, box) -> tuple[float, float, float, float]:
    """``(xmin, xmax, ymin, ymax)`` with ``xmin < xmax`` and ``ymin < ymax`` (sides may be ±inf)."""
    try:
        w = np.asarray(box, float).reshape(-1)
    except (TypeError, ValueError):
        raise validate.fail(key, box, "(xmin, xmax, ymin, ymax) with xmin < xmax and ymin < ymax") from None
    if w.shape != (4,) or np.any(np.isnan(w)) or not (w[0] < w[1] and w[2] < w[3]):
        raise validate.fail(key, box, "(xmin, xmax, ymin, ymax) with xmin < xmax and ymin < ymax")
    return tuple(float(x) for x in w)


def random_convex_vertices(size: float, n_vertices: int = 6, elongation: float = 1.0,
                           jitter: float = 0.5, rng=None) -> np.ndarray:
    """Random convex polygon of diameter about ``size``, CCW, shape ``(n_vertices, 2)``.

    Vertices sit on an ellipse with axes ``size/2`` and ``size/(2·elongation)`` at angles
    ``2πk/n`` shifted by a uniform random fraction ``jitter`` of the angular spacing, and
    the whole shape is turned by a random angle.  Points on an ellipse in angular order
    always form a convex polygon.

    Parameters
    ----------
    size : float
        Diameter of the circumscribing ellipse along its long axis (length, e.g. m).
    n_vertices : int
        Number of corners, ≥ 3.
    elongation : float
        Aspect ratio of the ellipse (≥ 1).
    jitter : float
        Angular perturbation as a fraction of ``2π/n`` (0 gives a regular, stretched shape).
    rng : numpy.random.Generator or int or None
        Random source.
    """
    size = validate.positive("random_convex_vertices(size=...)", size)
    n = validate.integer("random_convex_vertices(n_vertices=...)", n_vertices, lo=3)
    elongation = validate.number("random_convex_vertices(elongation=...)", elongation, "a finite number >= 1",
                                 lo=1.0)
    jitter = validate.fraction("random_convex_vertices(jitter=...)", jitter, hi_open=True)
    rng = np.random.default_rng(rng)
    t = 2.0 * np.pi * (np.arange(n) + jitter * (rng.random(n) - 0.5)) / n
    v = 0.5 * size * np.column_stack([np.cos(t), np.sin(t) / elongation])
    return v @ geo.rotation_matrix(rng.uniform(0, 2 * np.pi)).T


class Body:
    """A rigid convex polygon with uniform areal density.

    Build bodies with :meth:`polygon`, :meth:`disk`, :meth:`rectangle` or
    :meth:`random_convex`; the constructor takes the same arguments as :meth:`polygon`.

    Attributes
    ----------
    vertices : (n, 2) float
        Outline in body coordinates (length), counter-clockwise, centre of mass at the origin.
    area : float
        Polygon area, length² (m² in SI).
    density : float
        Areal density, mass/length² (kg/m²).
    mass : float
        ``density · area``, mass (kg).
    inertia : float
        Moment of inertia about the centre of mass, mass·length² (kg·m²).
    radius : float
        Bounding radius: largest distance of a vertex from the centre of mass, length.
    position : (2,) float
        Initial position of the centre of mass, length.
    angle : float
        Initial orientation, rad (world = rotate(angle) · body + position).
    velocity : (2,) float
        Initial velocity of the centre of mass, length/time (m/s).
    omega : float
        Initial angular velocity, rad/time (counter-clockwise positive).
    motion : {"free", "fixed", "prescribed"}
        ``free`` bodies obey Newton's laws; ``fixed`` ones never move; ``prescribed`` ones
        follow ``path``.
    path : callable or None
        For prescribed motion, ``path(t) -> (position (2,), angle)``, with ``t`` in time units.
    """

    def __init__(self, vertices, density: float = 1.0, position=(0.0, 0.0), angle: float = 0.0,
                 velocity=(0.0, 0.0), omega: float = 0.0, motion="free",
                 path: Callable | None = None, name: str = "body"):
        v = geo.validate_polygon(vertices, name=name, require_convex=True)
        rho = validate.positive(_key(name, "density"), density)
        if callable(motion):
            path, motion = motion, "prescribed"
        motion = names.lookup("motion", motion, where=_key(name, "motion"))
        if motion == "prescribed" and not callable(path):
            raise validate.fail(_key(name, "path"), path, "a callable path(t) -> (position, angle) for "
                                "motion 'prescribed'")
        area = geo.polygon_area(v)
        c = geo.polygon_centroid(v)
        j0 = geo.polygon_polar_moment(v)
        self.vertices = v - c
        self.area = area
        self.density = rho
        self.mass = rho * area
        self.inertia = rho * (j0 - area * float(c @ c))
        self.radius = float(np.sqrt((self.vertices**2).sum(axis=1)).max())
        self.position = _pair(_key(name, "position"), position)
        self.angle = _real(_key(name, "angle"), angle)
        self.velocity = _pair(_key(name, "velocity"), velocity)
        self.omega = _real(_key(name, "omega"), omega)
        self.motion = motion
        self.path = path
        self.name = name
        if motion == "prescribed":
            p, a = self.pose_at(0.0)
            self.position, self.angle = p, a

    # ---- constructors -----------------------------------------------------------------
    @classmethod
    def polygon(cls, vertices, density: float = 1.0, position=(0.0, 0.0), angle: float = 0.0,
                velocity=(0.0, 0.0), omega: float = 0.0, motion="free",
                path: Callable | None = None) -> "Body":
        """Convex polygon body.

        Parameters
        ----------
        vertices : (n, 2) array_like
            Counter-clockwise outline (length).  It is shifted so that its centroid is the
            origin of body coordinates; ``position`` then places that centroid.
        density : float
            Areal density, mass/length² (kg/m² in SI), > 0.
        position : (2,) array_like
            Centre of mass, length.
        angle : float
            Orientation, rad.
        velocity : (2,) array_like
            Length/time (m/s).
        omega : float
            Rad/time (rad/s).
        motion : {"free", "fixed", "prescribed"} or callable
            A callable is taken as ``path`` with ``motion="prescribed"``.
        path : callable, optional
            ``path(t) -> (position, angle)`` for prescribed motion.

        Raises
        ------
        fluidem.errors.InputError
            (a ``ValueError``) Clockwise, self-intersecting or non-convex outline; density
            ≤ 0; an unknown motion; a non-finite position, angle or velocity.
        """
        return cls(vertices, density=density, position=position, angle=angle,
                   velocity=velocity, omega=omega, motion=motion, path=path)

    @classmethod
    def disk(cls, radius: float, segments: int = 16, density: float = 1.0, **kwargs) -> "Body":
        """Regular ``segments``-gon inscribed in a circle of ``radius`` (length); other keywords as :meth:`polygon`."""
        return cls(geo.regular_polygon(radius, segments), density=density, **kwargs)

    @classmethod
    def rectangle(cls, width: float, height: float, density: float = 1.0, **kwargs) -> "Body":
        """Rectangle ``width`` × ``height`` (length) centred on its centre of mass; keywords as :meth:`polygon`."""
        return cls(geo.rectangle(width, height), density=density, **kwargs)

    @classmethod
    def random_convex(cls, size: float, n_vertices: int = 6, elongation: float = 1.0,
                      jitter: float = 0.5, rng=None, density: float = 1.0, **kwargs) -> "Body":
        """Random convex polygon, see :func:`random_convex_vertices`; keywords as :meth:`polygon`."""
        v = random_convex_vertices(size, n_vertices, elongation, jitter, rng)
        return cls(v, density=density, **kwargs)

    @classmethod
    def random_packing(cls, n: int, box, sizes=(1.0, 1.0), n_vertices=(5, 8),
                       elongation=(1.0, 1.5), spacing: float = 1.05, rng=None,
                       density: float = 1.0) -> list["Body"]:
        """``n`` random convex polygons placed on a loose square lattice inside ``box``.

        Sizes are uniform in ``sizes`` (length); corners uniform integers in ``n_vertices``;
        elongation uniform in ``elongation``.  Lattice spacing is ``spacing`` × the largest
        size, filled row by row from the bottom left of ``box = (xmin, xmax, ymin, ymax)``,
        so bodies never overlap at start.

        Raises
        ------
        fluidem.errors.InputError
            (a ``ValueError``) When ``n`` bodies do not fit in ``box``, or a bad argument.
        """
        n = validate.integer("Body.random_packing(n=...)", n, lo=1)
        xmin, xmax, ymin, ymax = _box("Body.random_packing(box=...)", box)
        lo, hi = (validate.positive("Body.random_packing(sizes=...)", s) for s in validate.pair(
            "Body.random_packing(sizes=...)", tuple(sizes)))
        spacing = validate.positive("Body.random_packing(spacing=...)", spacing)
        rng = np.random.default_rng(rng)
        dmax = max(lo, hi)
        h = spacing * dmax
        nx = int(np.floor((xmax - xmin) / h))
        ny = int(np.floor((ymax - ymin) / h))
        if nx * ny < n:
            raise validate.fail("Body.random_packing(n=...)", n, f"at most {max(nx, 0) * max(ny, 0)}: the "
                                f"bodies of size up to {dmax:g} on a lattice of spacing {h:g} fit in box {box}")
        out = []
        for k in range(n):
            iy, ix = divmod(k, nx)
            p = (xmin + (ix + 0.5) * h, ymin + (iy + 0.5) * h)
            size = rng.uniform(*sizes)
            nv = int(rng.integers(n_vertices[0], n_vertices[1] + 1))
            el = rng.uniform(*elongation)
            out.append(cls.random_convex(size, nv, el, rng=rng, density=density, position=p))
        return out

    # ---- prescribed motion ------------------------------------------------------------
    def pose_at(self, t: float) -> tuple[np.ndarray, float]:
        """Position (2,) (length) and angle (rad) of a prescribed body at time ``t`` (time units)."""
        p, a = self.path(t)
        return _pair(f"{self.name}.path({t!r})[0]", p), _real(f"{self.name}.path({t!r})[1]", a)

    def world_vertices(self, position=None, angle=None) -> np.ndarray:
        """Outline in world coordinates (length), shape ``(n, 2)``, at the given or initial pose."""
        return geo.transform(self.vertices, self.position if position is None else position,
                             self.angle if angle is None else angle)

    def __repr__(self) -> str:
        return (f"Body({len(self.vertices)}-gon, mass={self.mass:.4g}, inertia={self.inertia:.4g}, "
                f"position={self.position.tolist()}, motion={self.motion!r})")
