"""Checks of a run's state after every step: a bad state stops the run before it is recorded.

:class:`StateCheck` is built once per run from the scene and called after each step (DEM
alone, fixed-mesh flow, moving-mesh flow).  It raises :class:`StateError` naming the body
(or the place in the fluid), the quantity and the likely cause when

* a body's position, angle, velocity or angular velocity is not finite;
* a body reaches through a wall (its outline beyond the wall), or overlaps another body,
  by more than :data:`MAX_OVERLAP` of its size (the diameter of the disk of its area; the
  overlap depth with another body estimated as overlap area / chord length) — a contact too
  soft for the load or a time step too large;
* the flow velocity is not finite, or exceeds :data:`MAX_SPEEDUP` times the largest speed
  the scene imposes (inflow, moving walls, prescribed bodies, body-force scale) — a
  diverging time integration;
* the mesh nodes are not finite.

Every check is a few vectorised reductions over arrays the step produced anyway.

Examples
--------
>>> import numpy as np
>>> from fluidem.state_checks import StateCheck, StateError
>>> check = StateCheck(["disk"], sizes=np.array([0.1]), speed=1.0, cause_dem="contact.E = 1 is too soft")
>>> try:
...     check.bodies(np.array([[np.nan, 0.0]]), np.zeros(1), np.zeros((1, 2)), np.zeros(1), t=0.5)
... except StateError as err:
...     print(err)  # doctest: +ELLIPSIS
body 'disk': position is not finite ([nan, 0]) at t = 0.5; likely cause: contact.E = 1 is too soft...
"""

from __future__ import annotations

import numpy as np

from .errors import FluidemError

__all__ = ["StateError", "StateCheck", "MAX_OVERLAP", "MAX_SPEEDUP", "scene_speed", "body_sizes"]

#: largest overlap depth allowed, as a fraction of a body's size (diameter of the disk of its area)
MAX_OVERLAP = 0.5
#: largest flow speed allowed, as a multiple of the largest speed the scene imposes
MAX_SPEEDUP = 1000.0


class StateError(FluidemError, RuntimeError):
    """The state after a step is not finite or not physical; the step is not recorded.

    Attributes
    ----------
    body : str or None
        Name of the body concerned (``None`` for the fluid).
    quantity : str
    """

    def __init__(self, message: str, body: str | None = None, quantity: str = ""):
        super().__init__(message)
        self.body = body
        self.quantity = quantity


def scene_speed(scene) -> float:
    """Largest speed a scene imposes, length/time: inflow, moving walls, prescribed bodies, body force.

    A body force ``f`` over the box size ``L`` counts as ``max(|f| L² / ν, sqrt(|f| L))``
    (viscous and inertial scales); gravity on free bodies as ``sqrt(|g| L)``.
    """
    x0, x1, y0, y1 = scene.domain.box
    L = max(x1 - x0, y1 - y0)
    u = [0.0]
    for s in ("bottom", "right", "top", "left"):
        side = scene.domain.side(s)
        u.append(float(np.hypot(*side.velocity)))
        if side.type == "inflow":
            prof = scene.domain.profile_of(s) or {}
            u.append(abs(float(prof.get("umax", 0.0))))
    for b in scene.bodies:
        u.append(float(np.hypot(*b.velocity)) + abs(b.omega) * b.bounding_radius)
    if scene.fluid is not None:
        f = float(np.hypot(*scene.fluid.body_force))
        u += [f * L * L / scene.fluid.viscosity, np.sqrt(f * L)]
    if any(b.motion == "free" for b in scene.bodies):
        u.append(np.sqrt(float(np.hypot(*scene.gravity)) * L))
    return max(u)


def body_sizes(scene) -> np.ndarray:
    """(n,) diameter of the disk of each body's initial outline area, length."""
    outlines = scene.world_outlines()
    if not outlines:
        return np.zeros(0)
    a = np.array([0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
                  for p in outlines])  # once per run
    return 2.0 * np.sqrt(a / np.pi)


def _fmt(v) -> str:
    return "[" + ", ".join(f"{x:.6g}" for x in np.atleast_1d(v)) + "]" if np.ndim(v) else f"{v:.6g}"


class StateCheck:
    """The per-step checks of one run (see the module docstring).

    Parameters
    ----------
    names : list of str
        Body names, in body order.
    sizes : (n,) float
        Body sizes (:func:`body_sizes`), length.
    speed : float
        Largest imposed speed (:func:`scene_speed`), length/time; 0 disables the speed bound.
    cause_dem, cause_flow : str
        The likely cause to name for a bad body state and for a bad flow.
    """

    def __init__(self, names, sizes, speed: float, cause_dem: str = "", cause_flow: str = ""):
        self.names = list(names)
        self.sizes = np.asarray(sizes, float)
        self.speed = float(speed)
        self.cause_dem = cause_dem or "too large a dt"
        self.cause_flow = cause_flow or "too large a dt"

    @classmethod
    def for_scene(cls, scene) -> StateCheck:
        dt = scene.time.dt
        c = scene.contact
        cause = f"too soft a contact for the load (contact.E = {c.E:g}: raise it) or too large a dt = {dt:g}" \
            if c is not None and c.enabled else f"too large a dt = {dt:g}"
        flow = f"too large a dt = {dt:g} for the flow"
        if scene.fluid is not None and scene.fluid.model == "navier-stokes" and scene.fluid.convection == "explicit":
            flow += " (explicit convection needs a Courant number below 1)"
        return cls([b.name for b in scene.bodies], body_sizes(scene), scene_speed(scene), cause, flow)

    # -- bodies ------------------------------------------------------------------------------
    def bodies(self, pos, ang, vel, omega, t: float) -> None:
        """Raise :class:`StateError` for the first body whose state is not finite."""
        for q, a in (("position", pos), ("angle", ang), ("velocity", vel), ("angular velocity", omega)):
            a = np.asarray(a, float)
            ok = np.isfinite(a).reshape(len(a), -1).all(axis=1) if a.size else np.ones(0, bool)
            if not ok.all():
                k = int(np.flatnonzero(~ok)[0])
                raise StateError(f"body {self.names[k]!r}: {q} is not finite ({_fmt(a[k])}) at t = {t:.6g}; "
                                 f"likely cause: {self.cause_dem}", self.names[k], q)

    def walls(self, vertices, walls, t: float) -> None:
        """Raise :class:`StateError` when a body reaches through a wall deeper than :data:`MAX_OVERLAP` of its size.

        ``vertices``: (n, K, 2) world outlines (padded by repetition), length; ``walls``:
        ``(xmin, xmax, ymin, ymax)``, infinite for an open side.
        """
        if walls is None or not len(vertices):
            return
        V = np.asarray(vertices, float)
        lo, hi = V.min(axis=1), V.max(axis=1)
        x0, x1, y0, y1 = walls
        with np.errstate(invalid="ignore"):
            depth = np.stack([x0 - lo[:, 0], hi[:, 0] - x1, y0 - lo[:, 1], hi[:, 1] - y1], axis=1).max(axis=1)
        frac = depth / self.sizes
        bad = frac > MAX_OVERLAP
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise StateError(f"body {self.names[k]!r}: overlap with a wall is {frac[k]:.0%} of its size "
                             f"({depth[k]:.3g} of {self.sizes[k]:.3g}; allowed {MAX_OVERLAP:.0%}) at t = {t:.6g}; "
                             f"likely cause: {self.cause_dem}", self.names[k], "overlap")

    def overlaps(self, contacts, t: float) -> None:
        """Raise :class:`StateError` when a contact overlap is deeper than :data:`MAX_OVERLAP` of a body's size.

        ``contacts``: a :class:`fluidem.dem.contact.Contacts` (``i``, ``j``, ``area``, ``chord``)
        of the last force evaluation.
        """
        if contacts is None or not len(contacts.i):
            return
        area = np.asarray(contacts.area, float)
        depth = area / np.maximum(np.asarray(contacts.chord, float), np.sqrt(np.maximum(area, 0.0)) + 1e-300)
        i, j = np.asarray(contacts.i), np.asarray(contacts.j)
        frac_i = depth / self.sizes[i]
        jj = np.where(j >= 0, j, i)
        frac_j = np.where(j >= 0, depth / self.sizes[jj], 0.0)
        frac = np.maximum(frac_i, frac_j)
        bad = ~np.isfinite(frac) | (frac > MAX_OVERLAP)
        if bad.any():
            c = int(np.flatnonzero(bad)[0])
            k = int(i[c]) if frac_i[c] >= frac_j[c] or not np.isfinite(frac_j[c]) else int(j[c])
            other = f"body {self.names[int(j[c])]!r}" if j[c] >= 0 else "a wall"
            other = other if k == int(i[c]) else f"body {self.names[int(i[c])]!r}"
            raise StateError(f"body {self.names[k]!r}: overlap with {other} is {frac[c]:.0%} of its size "
                             f"({depth[c]:.3g} of {self.sizes[k]:.3g}; allowed {MAX_OVERLAP:.0%}) at t = {t:.6g}; "
                             f"likely cause: {self.cause_dem}", self.names[k], "overlap")

    # -- fluid ---------------------------------------------------------------------------------
    def flow(self, u_x, u_y, points, t: float, x=None) -> None:
        """Raise :class:`StateError` for a non-finite or runaway flow velocity.

        ``u_x``, ``u_y``: (n,) nodal velocity components; ``points``: (2, n_nodes) mesh nodes;
        ``x``: all flow DOFs (velocity and pressure), checked for finiteness.
        """
        if x is not None and not np.isfinite(x).all():
            raise StateError(f"the flow solution (velocity or pressure) is not finite at {(~np.isfinite(x)).sum()} "
                             f"DOFs at t = {t:.6g}; likely cause: {self.cause_flow}", None, "flow")
        p = np.asarray(points)
        if not np.isfinite(p).all():
            raise StateError(f"the mesh nodes are not finite at t = {t:.6g}; likely cause: {self.cause_flow}",
                             None, "mesh")
        speed = np.hypot(u_x, u_y)
        finite = np.isfinite(speed)
        if not finite.all():
            raise StateError(f"the flow velocity is not finite at {(~finite).sum()} nodes at t = {t:.6g}; likely "
                             f"cause: {self.cause_flow}", None, "velocity")
        smax = float(speed.max(initial=0.0))
        if self.speed > 0 and smax > MAX_SPEEDUP * self.speed:
            raise StateError(f"the flow velocity reached {smax:.3g}, more than {MAX_SPEEDUP:g} times the largest "
                             f"speed the scene imposes ({self.speed:.3g}), at t = {t:.6g}: the time integration "
                             f"diverges; likely cause: {self.cause_flow}", None, "velocity")
