"""Velocity conditions of a domain and its bodies: box sides (walls, moving walls, inflow) and rigid bodies."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["inflow_value", "velocity_bcs", "periodic_axes_of"]


def periodic_axes_of(domain) -> tuple:
    """Periodic axes of the box of ``domain`` (a :class:`~fluidem.scene.DomainSpec`): ``"x"`` if
    ``left``/``right`` are periodic, ``"y"`` if ``bottom``/``top`` are (:mod:`fluidem.mesh.periodic`)."""
    from ..mesh.periodic import axes_of_sides

    return axes_of_sides({s: domain.side(s).type for s in ("left", "right", "bottom", "top")})


def period_of_domain(domain) -> tuple:
    """``(L_x or None, L_y or None)``: the periods of the periodic axes of ``domain`` (a
    :class:`~fluidem.scene.DomainSpec`), length units."""
    from ..mesh.seam import period_of

    return period_of(domain.box, periodic_axes_of(domain))


def inflow_value(side: str, box, profile: dict):
    """Velocity ``(x, y, t) -> (2, n)`` of an inflow side, normal to it, pointing into the box.

    Parameters
    ----------
    side : {"left", "right", "bottom", "top"}
    box : (x0, x1, y0, y1) float
        Length units.
    profile : dict
        ``type`` (``"parabolic"``: 4 s (L − s) / L², or uniform), ``umax`` (length/time) and
        ``ramp`` (time of the smooth start (1 − cos(π t / ramp)) / 2; 0: none).

    Examples
    --------
    >>> f = inflow_value("left", (0.0, 2.0, 0.0, 1.0), {"type": "parabolic", "umax": 1.5, "ramp": 0.0})
    >>> f(np.array([0.0]), np.array([0.5]), 0.0).ravel().tolist()
    [1.5, 0.0]
    """
    x0, x1, y0, y1 = box
    kind, U, ramp = profile["type"], profile["umax"], profile["ramp"]
    normal = {"left": (1.0, 0.0), "right": (-1.0, 0.0), "bottom": (0.0, 1.0), "top": (0.0, -1.0)}[side]

    def value(x, y, t):
        s, L = ((y - y0), y1 - y0) if side in ("left", "right") else ((x - x0), x1 - x0)
        shape = 4.0 * s * (L - s) / L**2 if kind == "parabolic" else np.ones_like(s)
        f = 1.0 if ramp <= 0 or t >= ramp else 0.5 * (1.0 - math.cos(math.pi * t / ramp))
        speed = U * f * shape
        return np.array([normal[0] * speed, normal[1] * speed])

    return value


def velocity_bcs(domain, bodies, centers):
    """Velocity conditions of the box sides and the bodies (rigid motion about ``centers`` (n, 2)).

    Parameters
    ----------
    domain : fluidem.scene.DomainSpec
        The box and its sides.
    bodies : list of fluidem.scene.BodySpec
        The bodies (name, motion, velocity in length/time, ω in rad/time), in the order of ``centers``.
    centers : (n, 2) float
        The centre of each body's rigid motion, length units.

    Returns
    -------
    list of fluidem.fluid.space.VelocityBC
        The sides first (in the order left, right, bottom, top; outflow and periodic sides get
        none), then one per body, so a body's condition wins on DOFs it shares with a side.
    """
    from ..fluid.space import RigidMotion, VelocityBC

    bcs = []
    period = period_of_domain(domain)
    for s in ("left", "right", "bottom", "top"):
        side = domain.side(s)
        if side.type == "wall":
            bcs.append(VelocityBC(s, (0.0, 0.0)))
        elif side.type == "moving-wall":
            bcs.append(VelocityBC(s, side.velocity))
        elif side.type == "inflow":
            bcs.append(VelocityBC(s, inflow_value(s, domain.box, domain.profile_of(s))))
    for b, c in zip(bodies, centers):
        if b.motion == "fixed":
            bcs.append(VelocityBC(b.name, (0.0, 0.0)))
        else:
            bcs.append(VelocityBC(b.name, RigidMotion(b.velocity, b.omega, tuple(map(float, c)), period)))
    return bcs


def viscous_form_of(bodies) -> str:
    """``"stress"`` when one of ``bodies`` (list of :class:`~fluidem.scene.BodySpec`) may rotate (free,
    or prescribed with ω ≠ 0): the torque on it needs the true viscous traction
    (:mod:`fluidem.fluid.forms`); ``"laplacian"`` otherwise."""
    return "stress" if any(b.motion == "free" or (b.motion == "prescribed" and b.omega) for b in bodies) \
        else "laplacian"
