"""Contacts of free bodies inside the fluid step: short-range repulsion and the DEM contact law,
sub-stepped with the fluid's force held.

The coupled step (:class:`fluidem.coupling.free_flow.FreeBodyFlow`) solves fluid and free
bodies together, the hydrodynamic force and the buoyant weight implicit.  Contacts are far
stiffer than that step can integrate, so they are sub-stepped (operator splitting, the usual
treatment in resolved fluid–DEM codes: Glowinski et al. 2001, §4; Wan & Turek 2006), but
their load is fed back into the same solve so that fluid and bodies agree on the velocities:

1. solve with a contact load ``F`` (first 0): body velocities ``V_c`` at t + Δt;
2. the DEM (:class:`fluidem.dem.DEM`, no gravity) integrates the free bodies over
   [t, t + Δt] from (Xⁿ, Vⁿ) in stable sub-steps (:meth:`DEM.advance`), with the non-contact
   acceleration of the solve held (``(V_c − Vⁿ)/Δt`` less ``F``'s share), the contact law of
   :mod:`fluidem.dem.contact` on overlaps and the short-range repulsion of
   :mod:`fluidem.dem.repulsion` below its range; its contacts' impulse / Δt is the new ``F``;
3. repeat from 1 — one more back-substitution with the same matrix, only body rows change —
   until ``F`` settles (:meth:`fluidem.coupling.free_bodies.FreeBodyStepper.step`).

The poses then advance with the final velocities by the step's BDF2 formula, as without
contacts, so a body resting on another (or on a wall) has zero velocity and feels a contact
load equal to its buoyant weight.  Nothing is sub-stepped while no pair of outlines (or outline
and wall) is within reach — the repulsion range plus twice the distance the bodies can travel
in a step — so a suspension of separated bodies pays one bounding-circle test per step.
Where contacts act the splitting is first order in time, and the repulsion needs
``Δt |v| ≪ ρ`` (approach speed v) to see a body coming.

The contact law acts on overlaps, which the repulsion prevents as long as its force scale
exceeds the loads pressing the bodies together; the mesh needs the bodies apart (it
re-triangulates a contact, :class:`fluidem.mesh.MovingMesh`), and the run's state checks stop
it on overlap.
"""

from __future__ import annotations

import time

import numpy as np

from ..dem import DEM, Body, ContactModel
from ..dem.repulsion import Repulsion

__all__ = ["FluidContacts", "repulsion_for"]


def repulsion_for(scene, free_areas: np.ndarray, free_densities: np.ndarray) -> Repulsion:
    """The scene's repulsion: ``contact.repulsion_*`` or their defaults (range ``mesh.h``, force
    the largest buoyant weight |ρ_s − ρ_f| A |g| of a free body)."""
    c = scene.contact
    rng = c.repulsion_range if c.repulsion_range is not None else scene.mesh.h
    if c.repulsion_force is not None:
        force = c.repulsion_force
    else:
        g = float(np.hypot(*scene.gravity))
        w = np.abs(free_densities - scene.fluid.density) * free_areas * g
        force = float(w.max()) if len(w) else 0.0
    return Repulsion(range=rng, force=force, epsilon=c.repulsion_epsilon)


class FluidContacts:
    """Contacts and repulsion of free bodies in a fluid, applied after each coupled solve.

    Parameters
    ----------
    scene : fluidem.scene.Scene
        A fluid scene with a ``[contact]`` table.
    free : (n_free,) int
        Indices of the free bodies.
    vertices : list of (k, 2) float
        Every body's outline in body coordinates, length.

    Attributes
    ----------
    repulsion : Repulsion
    dem : fluidem.dem.DEM
        The bodies (free ones free, the others as prescribed or fixed), walls from the box,
        no gravity.
    substeps : int
        DEM sub-steps taken so far; ``dem_calls`` the sub-stepped passes over a fluid step.
    """

    def __init__(self, scene, free, vertices, path):
        B = scene.bodies
        self.free = np.asarray(free, np.int64)
        rho_f = scene.fluid.density
        bodies = []
        for k, b in enumerate(B):
            if b.motion == "prescribed":
                bodies.append(Body.polygon(vertices[k], density=b.density, motion="prescribed", path=path[k]))
            else:  # free bodies: translational mass with the added mass ρ_f A (see mean_load)
                bodies.append(Body.polygon(vertices[k], density=b.density + (rho_f if b.motion == "free" else 0.0),
                                           position=b.position, angle=b.angle,
                                           velocity=b.velocity if b.motion == "free" else (0.0, 0.0),
                                           omega=b.omega if b.motion == "free" else 0.0, motion=b.motion))
        dens = np.array([B[k].density for k in self.free])
        areas = np.array([bodies[k].area for k in self.free])
        self.repulsion = repulsion_for(scene, areas, dens)
        x0, x1, y0, y1 = scene.domain.box
        solid = {s: scene.domain.side(s).type in ("wall", "moving-wall") for s in ("left", "right", "bottom", "top")}
        walls = (x0 if solid["left"] else -np.inf, x1 if solid["right"] else np.inf,
                 y0 if solid["bottom"] else -np.inf, y1 if solid["top"] else np.inf)
        c = scene.contact
        self.dem = DEM(bodies, walls=walls, gravity=(0.0, 0.0), contact=ContactModel(E=c.E, mu=c.mu, gamma=c.gamma),
                       repulsion=self.repulsion)
        self.radii = np.array([b.radius for b in bodies])
        self.walls = walls
        # no rotational added mass: the free bodies' moments of inertia are their own, ρ_s J
        self.dem.inertia[self.free] *= dens / (dens + rho_f)
        self.substeps = 0
        self.dem_calls = 0
        self.seconds = 0.0  # wall time in the DEM

    def within_reach(self, poses: np.ndarray, travel: float) -> bool:
        """Whether any outline may come within the repulsion range of another or of a wall
        during a step in which no body moves more than ``travel`` (length): bounding circles."""
        reach = self.repulsion.range + 2.0 * travel
        p, r, f = poses[:, :2], self.radii, self.free
        x0, x1, y0, y1 = self.walls
        pf, rf = p[f], r[f] + reach
        if ((pf[:, 0] - rf <= x0) | (pf[:, 0] + rf >= x1) | (pf[:, 1] - rf <= y0) | (pf[:, 1] + rf >= y1)).any():
            return True
        if len(p) < 2:
            return False
        from scipy.spatial import cKDTree

        tree = cKDTree(p)
        pairs = tree.query_pairs(2.0 * float(r.max()) + reach, output_type="ndarray")
        if not len(pairs):
            return False
        i, j = pairs[:, 0], pairs[:, 1]
        isfree = np.zeros(len(p), bool)
        isfree[f] = True
        d = np.linalg.norm(p[i] - p[j], axis=1)
        return bool(((isfree[i] | isfree[j]) & (d < r[i] + r[j] + reach)).any())

    def load_function(self, t: float, dt: float, poses: np.ndarray, velocities: np.ndarray):
        """The contact load of the step [t, t + dt] as a function of the solve's body velocities.

        Parameters
        ----------
        t, dt : float
            Step start and length, time.
        poses, velocities : (n_bodies, 3) float
            All bodies at t (x, y, angle; U_x, U_y, ω).

        Returns
        -------
        callable or None
            ``load(V_c, F) -> (n_free, 3)`` (see :meth:`mean_load`), or None when no outline
            can come within reach of another or of a wall during the step (nothing to do).
        """
        f = self.free
        travel = 2.0 * dt * float(np.abs(velocities[f, :2]).max()) if len(f) else 0.0
        if not self.within_reach(poses, travel):
            return None
        return lambda V_c, F: self.mean_load(t, dt, poses, velocities, V_c, F)

    def mean_load(self, t, dt, poses, velocities, V_c, F):
        """Mean contact force and torque on the free bodies over [t, t + dt], (n_free, 3).

        The DEM integrates the free bodies from (Xⁿ, Vⁿ) with the non-contact acceleration
        the solve implies held, ``a = (V_c − Vⁿ)/Δt − F/m_s``, ``F`` the contact load that
        solve already contained, and returns its contacts' impulse / Δt.  ``m_s`` is the body
        mass plus the added mass of a circular cylinder in unbounded fluid, ρ_f A (translation;
        no rotational added mass): it makes the fixed-point iteration of
        :meth:`fluidem.coupling.free_bodies.FreeBodyStepper.step` converge fast where the true
        added mass is close to it, and does not change its fixed point.
        """
        t_start = time.perf_counter()
        f = self.free
        d = self.dem
        V0 = velocities[f]
        m = np.column_stack([d.mass[f], d.mass[f], d.inertia[f]])
        a = (V_c - V0) / dt - F / m
        d.set_motion(poses, velocities, time=t)
        d.external_force = np.zeros((d.n, 2))
        d.external_torque = np.zeros(d.n)
        d.external_force[f] = m[:, :2] * a[:, :2]
        d.external_torque[f] = m[:, 2] * a[:, 2]
        self.substeps += d.advance(dt)
        self.dem_calls += 1
        V_end = np.column_stack([d.velocities, d.omegas])[f]
        self.seconds += time.perf_counter() - t_start
        return m * (V_end - V0 - dt * a) / dt

    def get_state(self) -> dict:
        return {"springs": self.dem.spring_history, "substeps": self.substeps, "dem_calls": self.dem_calls}

    def set_state(self, s: dict) -> None:
        self.dem.spring_history = s["springs"]
        self.substeps, self.dem_calls = s["substeps"], s["dem_calls"]
