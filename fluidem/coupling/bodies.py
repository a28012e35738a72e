"""Bodies (:class:`~fluidem.scene.BodySpec`) as motion providers for the simulation loop.

Both adapters expose ``step(dt)``, ``positions`` (n, 2), ``angles`` (n,), ``velocities``
(n, 2), ``omegas`` (n,), ``loads()`` and ``get_state``/``set_state`` for checkpoints.
"""

from __future__ import annotations

import copy

import numpy as np

__all__ = ["DEMBodies", "FlowBodies", "KinematicBodies", "LinearPath"]


class LinearPath:
    """Prescribed rigid motion with constant velocity: ``path(t) -> (position (2,), angle)``.

    Parameters
    ----------
    position : (2,) float
        Position at t = 0, length units.
    angle : float
        Angle at t = 0, rad.
    velocity : (2,) float
        Length units per time unit.
    omega : float
        Angular velocity, rad per time unit.

    Examples
    --------
    >>> p = LinearPath((0.0, 1.0), 0.0, (2.0, 0.0), 0.5)
    >>> pos, ang = p(0.5)
    >>> pos.tolist(), ang
    ([1.0, 1.0], 0.25)
    """

    def __init__(self, position, angle, velocity, omega):
        self.position = np.asarray(position, float)
        self.angle = float(angle)
        self.velocity = np.asarray(velocity, float)
        self.omega = float(omega)

    def __call__(self, t):
        return self.position + self.velocity * t, self.angle + self.omega * t


class KinematicBodies:
    """Bodies without contacts: free bodies fall under gravity, prescribed ones follow their path.

    Closed form, ``x = x₀ + v₀ t + g t²/2``, ``θ = θ₀ + ω t`` (g only for free bodies; fixed
    bodies have v₀ = 0, ω = 0).

    Parameters
    ----------
    bodies : list of fluidem.scene.BodySpec
        Initial poses (length, rad), velocities (length/time, rad/time) and motions.
    gravity : (2,) float
        Acceleration of gravity, length/time².

    Examples
    --------
    >>> from fluidem.scene import BodySpec
    >>> kin = KinematicBodies([BodySpec(radius=0.1, position=(0.0, 1.0))], gravity=(0.0, -10.0))
    >>> kin.step(0.1)
    >>> kin.positions.tolist()
    [[0.0, 0.95]]
    """

    def __init__(self, bodies, gravity):
        B = bodies
        n = len(B)
        self.x0 = np.array([b.position for b in B], float).reshape(n, 2)
        self.a0 = np.array([b.angle for b in B], float)
        self.v0 = np.array([b.velocity for b in B], float).reshape(n, 2)
        self.w0 = np.array([b.omega for b in B], float)
        fixed = np.array([b.motion == "fixed" for b in B], bool)
        self.v0[fixed] = 0.0
        self.w0[fixed] = 0.0
        self.g = np.where(np.array([b.motion == "free" for b in B])[:, None], np.asarray(gravity), 0.0)
        self.t = 0.0
        self.n = n

    def step(self, dt):
        self.t += dt

    @property
    def positions(self):
        t = self.t
        return self.x0 + self.v0 * t + 0.5 * self.g * t * t

    @property
    def angles(self):
        return self.a0 + self.w0 * self.t

    @property
    def velocities(self):
        return self.v0 + self.g * self.t

    @property
    def omegas(self):
        return self.w0.copy()

    def loads(self):
        """Forces (n, 2), torques (n,) and contact counts (n,) other than the fluid's: none here."""
        return np.zeros((self.n, 2)), np.zeros(self.n), np.zeros(self.n, int)

    def get_state(self):
        return {"t": self.t}

    def set_state(self, s):
        self.t = s["t"]


class FlowBodies(KinematicBodies):
    """Bodies in a fluid with free ones among them: the flow (:class:`fluidem.coupling.free_flow.FreeBodyFlow`)
    moves them; poses and velocities are read from it (``flow`` is set once the flow exists).
    Parameters as :class:`KinematicBodies`."""

    def __init__(self, bodies, gravity):
        super().__init__(bodies, gravity)
        self.flow = None

    @property
    def positions(self):
        return self.flow.poses[:, :2].copy()

    @property
    def angles(self):
        return self.flow.poses[:, 2].copy()

    @property
    def velocities(self):
        return self.flow.body_velocities[:, :2].copy()

    @property
    def omegas(self):
        return self.flow.body_velocities[:, 2].copy()

    def loads(self):
        """No loads besides the fluid's; contact counts (n,): the other bodies and walls within the
        short-range repulsion's range of each (:meth:`fluidem.coupling.contacts.FluidContacts.contact_counts`)."""
        F, T, cnt = super().loads()
        c = None if self.flow is None else self.flow.contacts
        return F, T, (cnt if c is None else c.contact_counts(self.flow.poses))


class DEMBodies:
    """Bodies moved by :class:`fluidem.dem.DEM` (sub-steps of at most ``dt_max`` inside a step).

    Parameters
    ----------
    bodies : list of fluidem.scene.BodySpec
        Initial poses, velocities, densities and motions.
    outlines : list of (k, 2) float
        Every body's outline in body coordinates, length.
    domain : fluidem.scene.DomainSpec
        The box: walls where its sides are ``"wall"``, periods where they are ``"periodic"``.
    contact : fluidem.scene.ContactSpec
        The contact law (E, μ, γ).
    gravity : (2,) float
        Acceleration of gravity, length/time².
    t0 : float
        The DEM's start time.
    """

    def __init__(self, bodies, outlines, *, domain, contact, gravity, t0: float = 0.0):
        from ..dem import DEM, Body, ContactModel
        from .contacts import domain_period

        dem_bodies = []
        for b, v in zip(bodies, outlines):
            if b.motion == "prescribed":
                path = LinearPath(b.position, b.angle, b.velocity, b.omega)
                dem_bodies.append(Body.polygon(v, density=b.density, motion="prescribed", path=path))
            else:
                dem_bodies.append(Body.polygon(v, density=b.density, position=b.position, angle=b.angle,
                                               velocity=b.velocity, omega=b.omega, motion=b.motion))
        x0, x1, y0, y1 = domain.box
        sides = {s: domain.side(s).type for s in ("left", "right", "bottom", "top")}
        walls = (x0 if sides["left"] == "wall" else -np.inf, x1 if sides["right"] == "wall" else np.inf,
                 y0 if sides["bottom"] == "wall" else -np.inf, y1 if sides["top"] == "wall" else np.inf)
        c = contact
        self.dem = DEM(dem_bodies, walls=walls, gravity=gravity, contact=ContactModel(E=c.E, mu=c.mu, gamma=c.gamma),
                       t0=t0, period=domain_period(domain))
        self.n = len(dem_bodies)
        self.substeps = 0

    @classmethod
    def from_kinematic(cls, kinematic: KinematicBodies, bodies, outlines, *, domain, contact,
                       gravity) -> DEMBodies:
        """The DEM continuing the closed-form motion of ``kinematic`` at its time (a restart whose
        longer ``t_end`` switches contacts on): free bodies start from their current state,
        prescribed bodies keep their paths (the DEM's clock starts at that time).  The other
        parameters are those of :class:`DEMBodies` (``bodies`` at the start of the run; not changed)."""
        bodies = copy.deepcopy(bodies)
        pos, ang, vel, om = kinematic.positions, kinematic.angles, kinematic.velocities, kinematic.omegas
        for k, b in enumerate(bodies):  # once per restart
            if b.motion == "free":
                b.position, b.angle = tuple(pos[k]), float(ang[k])
                b.velocity, b.omega = tuple(vel[k]), float(om[k])
        return cls(bodies, outlines, domain=domain, contact=contact, gravity=gravity, t0=kinematic.t)

    def step(self, dt):
        self.substeps += self.dem.advance(dt)

    positions = property(lambda self: self.dem.positions.copy())
    angles = property(lambda self: self.dem.angles.copy())
    velocities = property(lambda self: self.dem.velocities.copy())
    omegas = property(lambda self: self.dem.omegas.copy())

    def loads(self):
        """Contact and external loads on the bodies: forces (n, 2), torques (n,), contact counts (n,)."""
        d = self.dem
        F = d.forces - d.mass[:, None] * d.gravity - d.external_force
        T = d.torques - d.external_torque
        C = d.contacts
        cnt = np.bincount(np.concatenate([C.i, C.j[C.j >= 0]]).astype(np.int64), minlength=self.n)
        return F, T, cnt

    def get_state(self):
        return {"dem": self.dem, "substeps": self.substeps}

    def set_state(self, s):
        self.dem = s["dem"]
        self.substeps = s["substeps"]
