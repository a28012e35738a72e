"""One rigid body of a scene: :class:`BodySpec`, its shape, place and motion.

Units: none built in; every value is in the one consistent system the user picks (see
:mod:`fluidem.scene`).  Every user-typed name goes through :mod:`fluidem.names` and is
stored canonically; every bad value raises :class:`fluidem.errors.SceneError` (a
``ValueError``) in the one format of :mod:`fluidem.validate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import geometry as geo
from .. import names
from ..errors import SceneError
from ..validate import fail, integer, number, pair, positive

__all__ = ["BodySpec", "MAX_SEGMENTS"]

#: most outline vertices of a disk or ellipse (``segments``): a disk of radius r in a mesh of size h
#: needs about 2πr/h, so 100000 is a mesh of more than 1e9 triangles, far beyond one machine
MAX_SEGMENTS = 100_000


@dataclass
class BodySpec:
    """One rigid body.

    Parameters
    ----------
    shape : {"disk", "polygon", "rectangle", "ellipse"}
        ``disk``: ``radius``, ``segments``; ``polygon``: ``vertices`` (n, 2) in body
        coordinates (shifted so that their area centroid is the origin), counter-clockwise,
        convex; ``rectangle``: ``width``, ``height``; ``ellipse``: semi-axes ``a``, ``b``,
        ``segments``.  Every size is a length.
    position : (2,) float
        Centre of mass, length.
    angle : float
        Orientation, rad.
    density : float
        Areal density, mass/length² (as the fluid's ``density``).
    motion : {"free", "fixed", "prescribed"}
        ``prescribed`` bodies move with constant ``velocity`` (2,) and ``omega`` (rad/time).
    velocity, omega
        Initial (free) or prescribed (prescribed) velocity (2,), length/time, and angular
        velocity, rad/time.
    name : str
        Boundary name of its outline on the mesh; default ``body<i>``.
    """

    shape: str = "disk"
    radius: float | None = None
    segments: int | None = None
    vertices: list | None = None
    width: float | None = None
    height: float | None = None
    a: float | None = None
    b: float | None = None
    position: tuple = (0.0, 0.0)
    angle: float = 0.0
    density: float = 1.0
    motion: str = "free"
    velocity: tuple = (0.0, 0.0)
    omega: float = 0.0
    name: str | None = None

    KEYS = ("shape", "radius", "segments", "vertices", "width", "height", "a", "b", "position", "angle",
            "density", "motion", "velocity", "omega", "name")
    SHAPE_KEYS = {"disk": ("radius",), "polygon": ("vertices",), "rectangle": ("width", "height"),
                  "ellipse": ("a", "b")}

    def validate(self, where):
        """Check and convert every value (``where``: ``"bodies[i]"``); ``SceneError`` names the first bad one."""
        self.shape = names.lookup("shape", self.shape, f"{where}.shape", SceneError)
        for k in self.SHAPE_KEYS[self.shape]:
            if getattr(self, k) is None:
                raise SceneError(f"{where}: shape = {self.shape!r} needs {k} "
                                 f"(a {self.shape} takes {', '.join(self.SHAPE_KEYS[self.shape])})")
        for k in ("radius", "width", "height", "a", "b"):
            if getattr(self, k) is not None:
                if k not in self.SHAPE_KEYS[self.shape]:
                    raise fail(f"{where}.{k}", getattr(self, k),
                               f"no {k} for shape {self.shape!r} (it takes {', '.join(self.SHAPE_KEYS[self.shape])})",
                               SceneError)
                setattr(self, k, positive(f"{where}.{k}", getattr(self, k), error=SceneError))
        if self.segments is not None:
            self.segments = integer(f"{where}.segments", self.segments, lo=3, hi=MAX_SEGMENTS, error=SceneError)
        if self.shape == "polygon":
            try:
                v = geo.validate_polygon(self.vertices, f"{where}.vertices", require_convex=True)
            except ValueError as exc:
                raise SceneError(f"{where}.vertices = {self.vertices!r}: {exc}; expected a counter-clockwise "
                                 f"convex polygon [[x0, y0], [x1, y1], ...] with at least 3 vertices") from None
            self.vertices = v - geo.polygon_centroid(v)
        self.position = pair(f"{where}.position", self.position, error=SceneError)
        self.angle = number(f"{where}.angle", self.angle, error=SceneError)
        self.density = positive(f"{where}.density", self.density, error=SceneError)
        self.motion = names.lookup("motion", self.motion, f"{where}.motion", SceneError)
        self.velocity = pair(f"{where}.velocity", self.velocity, error=SceneError)
        self.omega = number(f"{where}.omega", self.omega, error=SceneError)
        if self.motion == "fixed" and (any(self.velocity) or self.omega):
            raise fail(f"{where}.velocity/omega", (list(self.velocity), self.omega),
                       "zero for a fixed body (use motion = 'prescribed' to move it)", SceneError)

    def local_vertices(self, segments_default: int = 32) -> np.ndarray:
        """Outline in body coordinates, (n, 2), centroid at the origin."""
        n = self.segments or segments_default
        if self.shape == "disk":
            return geo.regular_polygon(self.radius, n)
        if self.shape == "rectangle":
            return geo.rectangle(self.width, self.height)
        if self.shape == "ellipse":
            return geo.ellipse_polygon(self.a, self.b, n)
        return np.asarray(self.vertices, dtype=float)

    def world_vertices(self, segments_default: int = 32, position=None, angle=None) -> np.ndarray:
        return geo.transform(self.local_vertices(segments_default), self.position if position is None else position,
                             self.angle if angle is None else angle)

    @property
    def bounding_radius(self) -> float:
        if self.shape == "disk":
            return self.radius
        if self.shape == "rectangle":
            return 0.5 * math.hypot(self.width, self.height)
        if self.shape == "ellipse":
            return max(self.a, self.b)
        return float(np.sqrt((np.asarray(self.vertices) ** 2).sum(axis=1)).max())

    @property
    def moves(self) -> bool:
        """Whether the body can move at all (free, or prescribed with a non-zero velocity)."""
        return self.motion == "free" or (self.motion == "prescribed" and (any(self.velocity) or self.omega != 0))

    @property
    def outline_moves(self) -> bool:
        """Whether the region it covers changes: a disk spinning about its centre does not."""
        if self.motion == "fixed":
            return False
        if self.motion == "prescribed":
            return any(self.velocity) or (self.omega != 0 and self.shape != "disk")
        return True

