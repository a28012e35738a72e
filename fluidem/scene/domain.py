"""The box of a scene and what each of its sides is: :class:`DomainSpec` and :class:`SideSpec`.

Units: none built in; every value is in the one consistent system the user picks (see
:mod:`fluidem.scene`).  Every user-typed name goes through :mod:`fluidem.names` and is
stored canonically; every bad value raises :class:`fluidem.errors.SceneError` (a
``ValueError``) in the one format of :mod:`fluidem.validate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import names
from ..errors import SceneError
from ..validate import check_keys, fail, nonnegative, number, pair

__all__ = ["DomainSpec", "SideSpec", "MAX_COORDINATE"]

#: largest |coordinate| of the box, and 1 / the shortest side (lengths to the fourth power stay in double range)
MAX_COORDINATE = 1e50


@dataclass
class SideSpec:
    """One side of the box.

    Parameters
    ----------
    type : {"wall", "inflow", "outflow", "periodic", "moving-wall"}
        ``names.meaning("side type", type)`` says what each is.  ``"periodic"`` sides come in
        pairs (``left`` with ``right``, ``bottom`` with ``top``): the mesh has matching nodes
        on both and the fluid DOFs there are identified (:mod:`fluidem.mesh.periodic`,
        :mod:`fluidem.fluid.periodic`); ``fluid.body_force`` (a mean pressure gradient G is
        ``body_force = −G / density``) or moving walls drive the flow.  Bodies must be narrower
        than the period and must not overlap a periodic side (on a moving mesh: stay at least
        ``mesh.h`` away from it).
    velocity : (2,) float
        Wall velocity of a ``"moving-wall"`` side, length/time (zero on every other type).
    profile : dict or None
        Inflow profile of this side; ``None``: the domain's ``inflow_profile``.
    """

    type: str = "wall"
    velocity: tuple = (0.0, 0.0)
    profile: dict | None = None

    KEYS = ("type", "velocity", "profile")


@dataclass
class DomainSpec:
    """The box ``(xmin, xmax, ymin, ymax)`` (length) and what each side is.

    Sides are named and ordered as ``names.choices("side")``: bottom (y = ymin), right
    (x = xmax), top (y = ymax), left (x = xmin).

    ``inflow_profile`` is ``{type = "parabolic" | "uniform", umax = U, ramp = T}``: the
    inflow speed normal to an inflow side (parabolic: ``4 U s (L − s) / L²`` along the
    side, ``U`` in length/time), raised smoothly from 0 over ``ramp`` time units (``0``: at once).
    """

    box: tuple = (0.0, 1.0, 0.0, 1.0)
    bottom: SideSpec = field(default_factory=SideSpec)
    right: SideSpec = field(default_factory=SideSpec)
    top: SideSpec = field(default_factory=SideSpec)
    left: SideSpec = field(default_factory=SideSpec)
    inflow_profile: dict | None = None

    KEYS = ("box",) + names.choices("side") + ("inflow_profile",)
    #: keys of an inflow profile table (``inflow_profile`` or a side's ``profile``)
    PROFILE_KEYS = ("type", "umax", "ramp")

    def side(self, name) -> SideSpec:
        """The :class:`SideSpec` of side ``name`` (a name of ``names.choices("side")``)."""
        return getattr(self, names.lookup("side", name, "side", SceneError))

    def profile_of(self, name) -> dict:
        """The inflow profile of side ``name``: its own, else the domain's ``inflow_profile``."""
        s = self.side(name)
        return s.profile if s.profile is not None else self.inflow_profile

    def validate(self, where="domain"):
        """Check the box, every side and the profiles; ``SceneError`` names the first bad value."""
        b = self.box
        if (not isinstance(b, (list, tuple, np.ndarray)) or len(b) != 4
                or not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                           and math.isfinite(float(v)) for v in b)
                or not (b[1] > b[0] and b[3] > b[2])):
            raise fail(f"{where}.box", b, "[xmin, xmax, ymin, ymax], finite, with xmax > xmin and ymax > ymin",
                       SceneError)
        if max(abs(float(v)) for v in b) > MAX_COORDINATE or min(b[1] - b[0], b[3] - b[2]) < 1.0 / MAX_COORDINATE:
            raise fail(f"{where}.box", list(b), f"coordinates of magnitude at most {MAX_COORDINATE:g} and sides at "
                       f"least {1.0 / MAX_COORDINATE:g} long (squares and fourth powers of lengths must stay finite "
                       "and nonzero in double precision; pick a unit that fits)", SceneError)
        self.box = tuple(float(v) for v in b)
        for s in names.choices("side"):
            side = getattr(self, s)
            if isinstance(side, str):
                side = SideSpec(side)
            elif isinstance(side, dict):
                check_keys(side, SideSpec.KEYS, f"{where}.{s}", error=SceneError)
                side = SideSpec(**side)
            if not isinstance(side, SideSpec):
                raise fail(f"{where}.{s}", side, "a side type string or a table {type = ..., velocity = ...}",
                           SceneError)
            side.type = names.lookup("side type", side.type,
                                     f"{where}.{s}" if isinstance(getattr(self, s), str) else f"{where}.{s}.type",
                                     SceneError)
            side.velocity = pair(f"{where}.{s}.velocity", side.velocity, error=SceneError)
            if side.type != "moving-wall" and any(side.velocity):
                raise fail(f"{where}.{s}.velocity", list(side.velocity),
                           f"no velocity on a {side.type!r} side (only a 'moving-wall' moves)", SceneError)
            if side.profile is not None:
                side.profile = self._check_profile(f"{where}.{s}.profile", side.profile)
            setattr(self, s, side)
        if self.inflow_profile is not None:
            self.inflow_profile = self._check_profile(f"{where}.inflow_profile", self.inflow_profile)
        for s in names.choices("side"):
            if getattr(self, s).type == "inflow" and self.profile_of(s) is None:
                raise SceneError(f"{where}.{s} = 'inflow' has no profile: add {where}.inflow_profile = "
                                 f"{{ type = 'parabolic', umax = ... }} (allowed types: "
                                 f"{', '.join(names.choices('profile'))})")
        for a, b_ in (("left", "right"), ("bottom", "top")):
            pa, pb = getattr(self, a).type == "periodic", getattr(self, b_).type == "periodic"
            if pa != pb:
                one, other = (a, b_) if pa else (b_, a)
                raise SceneError(f"{where}.{one} = 'periodic' but {where}.{other} = {getattr(self, other).type!r}: "
                                 f"periodic sides come in pairs; allowed: both {a} and {b_} 'periodic' or neither")

    @staticmethod
    def _check_profile(key, prof):
        if not isinstance(prof, dict):
            raise fail(key, prof, "a table { type = 'parabolic' | 'uniform', umax = ..., ramp = ... }", SceneError)
        check_keys(prof, DomainSpec.PROFILE_KEYS, key, error=SceneError)
        out = {"type": names.lookup("profile", prof.get("type", "parabolic"), f"{key}.type", SceneError)}
        if "umax" not in prof:
            raise SceneError(f"{key} has no umax: the inflow speed is required (a finite number, length/time)")
        out["umax"] = number(f"{key}.umax", prof["umax"], error=SceneError)
        out["ramp"] = nonnegative(f"{key}.ramp", prof.get("ramp", 0.0), error=SceneError)
        return out

