"""Contacts of free bodies inside the fluid step: lubrication correction, short-range repulsion
and the DEM contact law, sub-stepped with the fluid's force held.

The coupled step (:class:`fluidem.coupling.free_flow.FreeBodyFlow`) solves fluid and free
bodies together, the hydrodynamic force and the buoyant weight implicit.  Contacts are far
stiffer than that step can integrate, so they are sub-stepped (operator splitting, the usual
treatment in resolved fluid–DEM codes: Glowinski et al. 2001, §4; Wan & Turek 2006), but
their load is fed back into the same solve so that fluid and bodies agree on the velocities:

1. solve with a contact load ``F`` (first 0): body velocities ``V_c`` at t + Δt;
2. the DEM (:class:`fluidem.dem.DEM`, no gravity) integrates the free bodies over
   [t, t + Δt] from (Xⁿ, Vⁿ) in stable sub-steps (:meth:`DEM.advance`), with the non-contact
   acceleration of the solve held (``(V_c − Vⁿ)/Δt`` less ``F``'s share), the contact law of
   :mod:`fluidem.dem.contact` on overlaps, the short-range repulsion of
   :mod:`fluidem.dem.repulsion` below its range and the lubrication correction of
   :mod:`fluidem.dem.lubrication` below its cut-off; its contacts' impulse / Δt is the new ``F``;
3. repeat from 1 — one more back-substitution with the same matrix, only body rows change —
   until ``F`` settles (:meth:`fluidem.coupling.free_bodies.FreeBodyStepper.step`).

The poses then advance with the final velocities by the step's BDF2 formula, as without
contacts, so a body resting on another (or on a wall) has zero velocity and feels a contact
load equal to its buoyant weight.  Nothing is sub-stepped while no pair of outlines (or outline
and wall) is within reach — the largest range of the two short-range models plus twice the
distance the bodies can travel in a step — so a suspension of separated bodies pays one
bounding-circle test per step.  Where contacts act the splitting is first order in time.

Which model acts where (``benchmarks/bench_narrow_gap.py``, ``benchmarks/results/narrow_gap.md``).
Quasi-statically the mesh resolves the squeeze film between close outlines down to gaps of a
fraction of h — Taylor–Hood and P3/P2 within a few per cent to h/4, then too weak; P2+bubble/P1dc
and MINI too strong (locking).  Dynamically the coupled step cannot follow the film once the gap
closes by more than itself in one step: two disks of the Uhlmann (2005) DKT meet at 5.6 cm/s, i.e.
5.6e-3 cm per step at dt = 1 ms, where the film stops them within a few 1e-3 cm, in one or two
steps, and the pair rebounds (measured with the resolved film alone, h = 0.02: three bounces,
separating to 0.047 cm, against a lasting kiss in both published computations).  The rebound is the
time step's: at dt/2 the first separation is 0.031 cm and the pair then kisses for good (from 11.7
t_ref); re-solving a step with the mesh at the poses the solve gave (those predicted from
2V − V_prev were off by 0.6 of the gap in the stopping step, by less than 3e-5 cm before it)
reduces it to 0.040 cm only.  So the default adds the whole
squeeze-film law below the cut-off h, less its value there, in the DEM sub-steps, which follow the
gap continuously: the pair then stops at a gap of 0.075 h and stays together from 9.5 to 15.5–15.8
t_ref (both references: 9.5 to 14).  The price is a double count where the film changes slowly: a quasi-static
approach meets 1.5–2.6 × the exact resistance (the table's "full law" column), so a body draining
onto a wall does so that much slower.  ``contact.lubrication_resolved_gap = δ_r`` (the element's
:data:`RESOLVED_FILM` times h) adds only the measured deficit instead: right quasi-statically for
Taylor–Hood and P3/P2 (within 1–12 % from h to h/50 at a ≥ 5 h), nothing for P2+bubble and MINI.
The repulsion stays as a backstop at ``0.01 h`` (:data:`BACKSTOP`), where a steady load that
drains the film eventually brings bodies.  Earlier versions put the repulsion at the range h: it
stopped approaching bodies before the film could, elastically, and the DKT pair rebounded.

The contact law acts on overlaps, which the repulsion prevents as long as its force scale
exceeds the loads pressing the bodies together (c/ε: 100 × the buoyant weight by default); the
mesh needs the bodies apart (it re-triangulates a contact, :class:`fluidem.mesh.MovingMesh`),
and the run's state checks stop it on overlap.
"""

from __future__ import annotations

import time

import numpy as np

from ..dem import DEM, Body, ContactModel
from ..dem.lubrication import Lubrication
from ..dem.periodic import image_shift
from ..dem.repulsion import Repulsion
from ..dem.system import critical_sub_step

__all__ = ["BACKSTOP", "FluidContacts", "RESOLVED_FILM", "domain_period", "lubrication_for", "repulsion_for"]


#: Resolved-film length δ_r / h of each element pair, for ``contact.lubrication_resolved_gap``:
#: the resolved force on a disk approaching a wall follows the squeeze-film law at the gap
#: √(δ² + δ_r²) (:mod:`fluidem.dem.lubrication`).  Measured by ``benchmarks/bench_narrow_gap.py``
#: (``benchmarks/results/narrow_gap.md``; disk radius a = 5–10 h, gaps δ = h … h/50):
#: Taylor–Hood 0.021–0.036, P3/P2 0.010–0.030.  P2+bubble/P1dc and MINI resist at least as much
#: as the exact solution on those meshes (P2+bubble up to 1.6×, MINI up to 5.3×: locking): 0.
RESOLVED_FILM = {"th": 0.025, "p3": 0.015, "p2b": 0.0, "mini": 0.0}

#: The repulsion's default range as a fraction of the mesh size: a backstop below the gaps whose
#: film the mesh resolves (down to h/50 in the measurement above).
BACKSTOP = 0.01


def repulsion_for(contact, free_areas: np.ndarray, free_densities: np.ndarray, *, h: float, fluid_density: float,
                  gravity) -> Repulsion:
    """The repulsion of ``contact``: ``contact.repulsion_*`` or their defaults (range ``0.01 h``,
    ε = 1e-4 · h/range, force the largest buoyant weight |ρ_s − ρ_f| A |g| of a free body).

    Parameters
    ----------
    contact : fluidem.scene.ContactSpec
    free_areas, free_densities : (n_free,) float
        Area (length²) and density (mass/length³) of each free body.
    h : float
        The mesh size, length.
    fluid_density : float
        ρ_f, mass/length³.
    gravity : (2,) float
        Acceleration of gravity, length/time².
    """
    c = contact
    rng = c.repulsion_range if c.repulsion_range is not None else BACKSTOP * h
    eps = c.repulsion_epsilon if c.repulsion_epsilon is not None else 1e-4 * h / rng
    if c.repulsion_force is not None:
        force = c.repulsion_force
    else:
        g = float(np.hypot(*gravity))
        w = np.abs(free_densities - fluid_density) * free_areas * g
        force = float(w.max()) if len(w) else 0.0
    return Repulsion(range=rng, force=force, epsilon=eps)


def domain_period(domain) -> tuple:
    """The periods ``(L_x, L_y)`` of the box of ``domain`` (a :class:`~fluidem.scene.DomainSpec`) for
    :class:`fluidem.dem.DEM` (``period=...``), length: the box's width where ``left``/``right`` are
    ``"periodic"``, its height where ``bottom``/``top`` are, None on the other axes."""
    from .boundary import period_of_domain

    return tuple(None if L is None else float(L) for L in period_of_domain(domain))


def _pairs_within(pos: np.ndarray, r: float, period: np.ndarray):
    """Index pairs (P, 2) of centres ``pos`` (N, 2) closer than ``r`` (length), across the periodic
    sides between nearest images (cKDTree with ``boxsize`` on copies wrapped into [0, L))."""
    from scipy.spatial import cKDTree

    from ..dem.periodic import wrap

    if period.any():
        return cKDTree(wrap(pos, period), boxsize=period).query_pairs(r, output_type="ndarray")
    return cKDTree(pos).query_pairs(r, output_type="ndarray")


def lubrication_for(contact, fluid, h: float) -> Lubrication | None:
    """The lubrication correction of ``contact`` (a :class:`~fluidem.scene.ContactSpec` or None;
    ``contact.lubrication*``; μ = ρ_f ν of ``fluid``, a :class:`~fluidem.scene.FluidSpec` or None;
    cut-off the mesh size ``h`` (length), the full law below it unless ``lubrication_resolved_gap``
    is set, regularised at the repulsion's range), or None where it is off, cannot act (δ_r = 0)
    or the flow has no inertia (Stokes free bodies feel only the repulsion)."""
    c = contact
    if c is None or not c.lubrication or fluid is None or fluid.model == "stokes":
        return None
    rng = c.lubrication_range if c.lubrication_range is not None else h
    dr = c.lubrication_resolved_gap
    if dr == 0.0:
        return None
    backstop = c.repulsion_range if c.repulsion_range is not None else BACKSTOP * h
    return Lubrication(viscosity=fluid.density * fluid.viscosity, range=rng,
                       min_gap=min(backstop, 0.5 * rng), resolved_gap=dr)


#: The fixed work of a DEM sub-step of a group of bodies (:meth:`FluidContacts.sub_step_groups`) in body
#: sub-steps: a group of m bodies at n sub-steps joins a stiffer one at n₀ when m (n₀ − n) is below this
#: times n.  Measured: a sub-step of a group of two bodies costs 2.2 ms, each further body 0.02–0.05 ms
#: (1 000 and 100 settling polygons, one core of the machine of ``benchmarks/results/dense_groups.md``).
GROUP_OVERHEAD = 50


class FluidContacts:
    """Contacts and repulsion of free bodies in a fluid, applied after each coupled solve.

    Parameters
    ----------
    bodies : list of fluidem.scene.BodySpec
        Every body of the flow (motion, density, initial pose and velocity).
    free : (n_free,) int
        Indices of the free bodies.
    vertices : list of (k, 2) float
        Every body's outline in body coordinates, length.
    path : list
        Every body's path ``t -> (position (2,), angle)``
        (:class:`~fluidem.coupling.bodies.LinearPath`; used for the prescribed bodies).
    domain : fluidem.scene.DomainSpec
        The box: walls where its sides are solid, periods where they are periodic.
    fluid : fluidem.scene.FluidSpec
    contact : fluidem.scene.ContactSpec
    gravity : (2,) float
        Acceleration of gravity, length/time² (the repulsion's default force scale).
    h : float
        The mesh size, length (the default ranges).

    Attributes
    ----------
    repulsion : Repulsion
    dem : fluidem.dem.DEM
        The bodies (free ones free, the others as prescribed or fixed), walls from the box,
        periodic where its sides are (:func:`domain_period`; positions unwrapped, pairs between
        nearest images), no gravity.
    substeps : int
        DEM sub-steps taken so far; ``dem_calls`` the sub-stepped passes over a fluid step.
    """

    def __init__(self, bodies, free, vertices, path, *, domain, fluid, contact, gravity, h: float):
        self.free = np.asarray(free, np.int64)
        rho_f = fluid.density
        dem_bodies = []
        for k, b in enumerate(bodies):
            if b.motion == "prescribed":
                dem_bodies.append(Body.polygon(vertices[k], density=b.density, motion="prescribed", path=path[k]))
            else:  # free bodies: translational mass with the added mass ρ_f A (see mean_load)
                dem_bodies.append(Body.polygon(vertices[k], density=b.density + (rho_f if b.motion == "free" else 0.0),
                                               position=b.position, angle=b.angle,
                                               velocity=b.velocity if b.motion == "free" else (0.0, 0.0),
                                               omega=b.omega if b.motion == "free" else 0.0, motion=b.motion))
        dens = np.array([bodies[k].density for k in self.free])
        areas = np.array([dem_bodies[k].area for k in self.free])
        self.repulsion = repulsion_for(contact, areas, dens, h=h, fluid_density=rho_f, gravity=gravity)
        self.lubrication = lubrication_for(contact, fluid, h)
        x0, x1, y0, y1 = domain.box
        solid = {s: domain.side(s).type in ("wall", "moving-wall") for s in ("left", "right", "bottom", "top")}
        walls = (x0 if solid["left"] else -np.inf, x1 if solid["right"] else np.inf,
                 y0 if solid["bottom"] else -np.inf, y1 if solid["top"] else np.inf)
        c = contact
        self.dem = DEM(dem_bodies, walls=walls, gravity=(0.0, 0.0),
                       contact=ContactModel(E=c.E, mu=c.mu, gamma=c.gamma), repulsion=self.repulsion,
                       lubrication=self.lubrication, period=domain_period(domain))
        self._L = self.dem._L  # (2,) periods, 0 on a non-periodic axis
        self.radii = np.array([b.radius for b in dem_bodies])
        self.walls = walls
        # no rotational added mass: the free bodies' moments of inertia are their own, ρ_s J
        self.dem.inertia[self.free] *= dens / (dens + rho_f)
        self.substeps = 0
        self.dem_calls = 0
        self.redone = 0  # passes redone at the DEM's bound (sub_steps)
        #: sub-steps summed over the bodies that took them (sub_step_groups): the DEM's work
        self.body_substeps = 0
        #: (N,) the closest gap each body's group met in the last pass of the last step (length; ``inf``
        #: none), from which the first pass of the next step takes its sub-steps; None after a step
        #: without contacts
        self.seen_last_step = None
        #: below this gap a stiff force acts: the repulsion's range (0 without a repulsion: overlaps only)
        self._stiff_range = self.repulsion.range if self.repulsion.force > 0 else 0.0
        self.last_set_by = ""  # what set the sub-steps of the last pass (sub_steps), for --verbose
        self.seconds = 0.0  # wall time in the DEM

    def within_reach(self, poses: np.ndarray, travel: float) -> bool:
        """Whether any outline may come within the repulsion range of another or of a wall
        during a step in which no body moves more than ``travel`` (length): bounding circles."""
        reach = self.dem.near_range + 2.0 * travel
        p, r, f = poses[:, :2], self.radii, self.free
        x0, x1, y0, y1 = self.walls
        pf, rf = p[f], r[f] + reach
        if ((pf[:, 0] - rf <= x0) | (pf[:, 0] + rf >= x1) | (pf[:, 1] - rf <= y0) | (pf[:, 1] + rf >= y1)).any():
            return True
        if len(p) < 2:
            return False
        pairs = _pairs_within(p, 2.0 * float(r.max()) + reach, self._L)
        if not len(pairs):
            return False
        i, j = pairs[:, 0], pairs[:, 1]
        isfree = np.zeros(len(p), bool)
        isfree[f] = True
        d = p[j] - p[i]
        d = np.linalg.norm(d + image_shift(d, self._L), axis=1)
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
            self.seen_last_step = None  # nothing within reach: the next step starts afresh
            return None
        # the step's passes: the closest gap each body's group met in the last one (sub_steps), at first
        # that of the last pass of the step before, from whose end this step starts
        memo = {} if self.seen_last_step is None else {"gap": self.seen_last_step}
        return lambda V_c, F: self.mean_load(t, dt, poses, velocities, V_c, F, memo=memo)

    def mean_load(self, t, dt, poses, velocities, V_c, F, memo: dict | None = None):
        """Mean contact force and torque on the free bodies over [t, t + dt], (n_free, 3).

        The DEM integrates the free bodies from (Xⁿ, Vⁿ) with the non-contact acceleration
        the solve implies held, ``a = (V_c − Vⁿ)/Δt − F/m_s``, ``F`` the contact load that
        solve already contained, and returns its contacts' impulse / Δt.  ``m_s`` is the body
        mass plus the added mass of a circular cylinder in unbounded fluid, ρ_f A (translation;
        no rotational added mass): it makes the fixed-point iteration of
        :meth:`fluidem.coupling.free_bodies.FreeBodyStepper.step` converge fast where the true
        added mass is close to it, and does not change its fixed point.

        The bodies move in groups that cannot reach each other during the pass, each at its own sub-steps
        (:meth:`sub_step_groups`, :meth:`fluidem.dem.DEM.advance` with ``bodies``); a group that meets a
        stiffer force than its sub-steps assumed is taken again (:meth:`sub_steps`).

        ``memo`` (a dict shared by the passes of one step, :meth:`load_function`) keeps the closest gap
        each body's group met in the last pass, from which the next pass takes its sub-steps
        (:meth:`sub_steps`, ``seen``).
        """
        t_start = time.perf_counter()
        f = self.free
        d = self.dem
        V0 = velocities[f]
        m = np.column_stack([d.mass[f], d.mass[f], d.inertia[f]])
        a = (V_c - V0) / dt - F / m
        n_max = max(int(np.ceil(dt / d.dt_max - 1e-9)), 1)
        seen = memo.get("gap") if memo is not None else None
        groups = self.sub_step_groups(dt, poses, velocities, V_c, seen=seen)
        d.set_motion(poses, velocities, time=t)
        d.external_force = np.zeros((d.n, 2))
        d.external_torque = np.zeros(d.n)
        d.external_force[f] = m[:, :2] * a[:, :2]
        d.external_torque[f] = m[:, 2] * a[:, 2]
        seen = np.full(d.n, np.inf)
        whole = len(groups) == 1
        largest, by_largest = 0, ""
        redone = 0
        for bodies, n, floor, by in groups:
            springs = d.spring_history
            taken = 0
            while True:
                d.closest_gap_seen = np.inf
                d.advance(dt, n=n, bodies=None if whole else bodies)
                self.body_substeps += n * len(bodies)
                taken += n
                # stiffer than assumed only inside the repulsion's range (or on an overlap, -inf)
                met = d.closest_gap_seen
                if n >= n_max or met >= min(floor, self._stiff_range):
                    break
                # a gap closed below the floor the sub-steps assumed: the group again, at the repulsion's
                # stiffness at half the gap met (no overlap), else at the DEM's own bound
                self.redone += 1
                redone += 1
                d.spring_history = springs
                d.set_motion(poses, velocities, time=t, bodies=None if whole else bodies)
                n_k, floor = self._repulsion_sub_steps(dt, 0.5 * met) if met > 0 else (n_max, -np.inf)
                if n_k < n_max and n_k > n:
                    n, by = n_k, f"the repulsion's stiffness at half the gap {met:.3g} met: a pass redone"
                else:
                    n, floor, by = n_max, -np.inf, "the DEM's bound: a pass redone"
            seen[bodies] = met
            if taken > largest:
                largest, by_largest = taken, by
        d.time = t + dt
        d.closest_gap_seen = float(seen.min())
        self.substeps += largest  # those of the group that took the most, its redone passes included
        self.dem_calls += 1 + redone
        self.last_set_by = by_largest
        if memo is not None:
            memo["gap"] = seen
            self.seen_last_step = seen
        V_end = np.column_stack([d.velocities, d.omegas])[f]
        self.seconds += time.perf_counter() - t_start
        return m * (V_end - V0 - dt * a) / dt

    def _repulsion_sub_steps(self, dt: float, gap: float) -> tuple[int, float]:
        """Sub-steps of ``dt`` stable with the repulsion's stiffness at ``gap`` (length) for the lightest free
        body (:func:`fluidem.dem.system.critical_sub_step`), and that gap (the floor they assume)."""
        d = self.dem
        m = float(d.mass[d.free].min())
        k = float(self.repulsion.stiffness(np.array([gap]))[0])
        return (int(np.ceil(dt / float(critical_sub_step(m, k)) - 1e-9)) if k > 0 else 1), gap

    def sub_steps(self, dt: float, poses: np.ndarray, velocities: np.ndarray, V_c: np.ndarray,
                  seen: float | None = None):
        """Sub-steps of a pass over [t, t + dt] from the stiffness in play, the gap floor it assumes and why.

        The explicit sub-step must resolve only the stiff forces that can act during the pass.  Every
        outline moves at most ``s_k = |U_k| + |ω_k| R_k`` (the larger of the step's start and the solve's
        end velocities; ``R_k`` its bounding radius), so the gap of a pair can close by at most
        ``1.5 Δt (s_i + s_j)`` (50 % margin), that to a wall by ``1.5 Δt s_k``; the closest gap over the
        pass stays above the *floor*, the least of ``gap − closing`` over the pairs (``s_i + s_j`` with the
        relative translation ``|U_i − U_j|`` instead of the sum of the speeds, and the speed normal to a
        wall, so that a pile moving as a whole closes nothing):

        * below 0 the contact law ``E`` and the repulsion at contact can act: the DEM's own bound
          :attr:`fluidem.dem.DEM.dt_max` (Matuttis & Chen 2014, ch. 7);
        * inside the repulsion's range its stiffness there, 2c s_r/(ερ) with s_r = (ρ − floor)/ρ
          (:meth:`fluidem.dem.repulsion.Repulsion.stiffness`), sets 0.1π√(m/k);
        * above it nothing stiff acts (the lubrication is implicit, :func:`fluidem.dem.lubrication.implicit_damping`).

        ``seen``, the closest gap (length) an earlier pass of the same step met (the same start, only the
        solve's end velocities ``V_c`` differ), replaces a floor at or below 0 by half that gap when it is
        positive: bodies resting on each other or sliding in a pile close by the bound above more than their
        gap, and would take the DEM's bound in every pass although the repulsion keeps them apart (in
        ``column-collapse-fluid`` every pass did, 24 sub-steps).  The first pass of a step takes the gap
        the last pass of the step before met (:meth:`load_function`; it ended where this step starts): in a
        settling pile of 100 polygons the first pass of every step took the DEM's bound, 119 of the step's
        160–190 sub-steps.  Only the first step with contacts takes the bound.

        To follow the film and the onset of the repulsion, no sub-step closes the gap of a pair by more
        than a quarter of the larger of its gap and ρ.  :meth:`mean_load` checks the floor against the
        closest gap the pass met and redoes a pass that met a stiffer force than assumed (a gap below both
        the floor and ρ): at the repulsion's stiffness at half the gap it met, and, should that pass break
        its floor too, or after an overlap, at the DEM's own bound.

        Returns
        -------
        n : int
            Sub-steps, at least 1 and at most ``ceil(dt / dt_max)``.
        floor : float
            The gap floor (length).
        set_by : str
            What sets ``n``.
        """
        entries = self._reach(dt, poses, velocities, V_c)
        if entries is None:
            return 1, -np.inf, "no gap within the short-range models' reach"
        g, cl, _, _ = entries
        req = self._requirements(dt, g, cl, np.zeros(1, np.int64), np.array([np.inf if seen is None else seen], float))
        return int(req["n"][0]), float(req["floor"][0]), self._set_by(req, 0)

    def sub_step_groups(self, dt: float, poses: np.ndarray, velocities: np.ndarray, V_c: np.ndarray,
                        seen: np.ndarray | None = None) -> list:
        """The bodies split into groups that cannot reach each other during a pass, each with its own sub-steps.

        The pairs and walls within the short-range models' reach over the pass (as in :meth:`sub_steps`: the
        gap less the most it can close, ``1.5 Δt`` times the relative speed, below :attr:`DEM.near_range
        <fluidem.dem.DEM.near_range>`) join their bodies; each connected component takes the sub-steps of
        :meth:`sub_steps` over its own pairs and walls, and the bodies within reach of nothing take one
        (no stiff force acts on them; the held acceleration integrates exactly).  So the one pair of a
        thousand bodies inside the repulsion's range sets the sub-steps of its cluster, not of every body.
        Clusters of the same sub-steps form one group (they cannot reach each other either), and a group
        joins the next stiffer one where its bodies' extra sub-steps cost less than its own sub-steps'
        fixed work (:data:`GROUP_OVERHEAD`): a few bodies do not take their own tens of sub-steps beside a
        pile that takes a hundred.  A group's floor is the least of its clusters' (none for the bodies near
        nothing: ``inf``).

        ``seen`` (N,) the closest gap each body's group met in an earlier pass of the step (``inf``: none).

        Returns
        -------
        list of (bodies, n, floor, set_by)
            ``bodies`` (k,) int, their sub-steps, gap floor and what sets them (:meth:`sub_steps`), the
            stiffest group first.
        """
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        N = len(poses)
        entries = self._reach(dt, poses, velocities, V_c)
        if entries is None:
            return [(np.arange(N), 1, -np.inf, "no gap within the short-range models' reach")]
        g, cl, a, b = entries
        pair = b >= 0
        graph = coo_matrix((np.ones(int(pair.sum())), (a[pair], b[pair])), shape=(N, N))
        _, label = connected_components(graph, directed=False)
        reached = np.zeros(N, bool)
        reached[a] = True
        reached[b[pair]] = True
        order = np.argsort(label[a], kind="stable")  # the entries by component
        comp = label[a][order]
        starts = np.concatenate([[0], np.flatnonzero(np.diff(comp)) + 1])
        comps = comp[starts]
        if seen is None:
            seen_c = np.full(len(comps), np.inf)
        else:  # the closest gap a body of each component met
            seen_c = np.full(label.max() + 1, np.inf)
            np.minimum.at(seen_c, label, np.asarray(seen, float))
            seen_c = seen_c[comps]
        req = self._requirements(dt, g[order], cl[order], starts, seen_c)
        n_c = req["n"]
        size = np.bincount(label)[comps]
        in_comp = np.full(label.max() + 1, -1)
        in_comp[comps] = np.arange(len(comps))
        body_run = in_comp[label]  # each body's run (-1: within reach of nothing)
        levels = []
        for n in np.unique(n_c)[::-1]:  # one level a number of sub-steps (a few), the stiffest first
            runs = np.flatnonzero(n_c == n)
            r = runs[np.argmin(req["floor"][runs])]
            words = f"{self._set_by(req, r)}; {len(runs)} cluster{'s' if len(runs) > 1 else ''} of at most " \
                    f"{int(size[runs].max())} bodies"
            levels.append((np.flatnonzero(np.isin(body_run, runs)), int(n), float(req["floor"][runs].min()), words))
        alone = np.flatnonzero(~reached)
        if len(alone):  # nothing to check against: no floor
            levels.append((alone, 1, np.inf, "no gap within the short-range models' reach"))
        groups = []
        for bodies, n, floor, words in levels:
            if groups and len(bodies) * (groups[-1][1] - n) < GROUP_OVERHEAD * n:
                # cheaper at the stiffer level's sub-steps than on its own (a group's sub-step has a fixed cost)
                b0, n0, f0, w0 = groups[-1]
                groups[-1] = (np.union1d(b0, bodies), n0, min(f0, floor), w0)
            else:
                groups.append((bodies, n, floor, words))
        return groups

    def _reach(self, dt: float, poses: np.ndarray, velocities: np.ndarray, V_c: np.ndarray):
        """The pairs and walls within the short-range models' reach over a pass (:meth:`sub_steps`): their gaps
        and the most they can close (length), their bodies ``a`` and ``b`` (``-1`` for a wall); None for none."""
        from ..dem.repulsion import pair_gaps

        d = self.dem
        x = np.asarray(poses, float)
        V1 = np.array(velocities, float)
        V1[self.free] = V_c
        V0 = np.where((d.motion == "fixed")[:, None], 0.0, np.asarray(velocities, float))
        V1 = np.where((d.motion == "fixed")[:, None], 0.0, V1)
        turn = np.maximum(np.abs(V0[:, 2]), np.abs(V1[:, 2])) * self.radii  # fastest outline point's turn
        speed = np.maximum(np.hypot(V0[:, 0], V0[:, 1]), np.hypot(V1[:, 0], V1[:, 1])) + turn
        near = d.near_range
        W = d.world_vertices(x)
        gaps, closing, ends = [], [], []
        pos = x[:, :2]
        if len(x) > 1:
            reach = near + 3.0 * dt * float(speed.max())
            pairs = _pairs_within(pos, 2.0 * float(self.radii.max()) + reach, self._L)
            if len(pairs):
                i, j = pairs[:, 0], pairs[:, 1]
                rel = np.maximum(np.hypot(*(V0[i, :2] - V0[j, :2]).T), np.hypot(*(V1[i, :2] - V1[j, :2]).T))
                cl = 1.5 * dt * (rel + turn[i] + turn[j])
                shift = image_shift(pos[j] - pos[i], self._L)  # j's image nearest i
                keep = (np.linalg.norm(pos[j] + shift - pos[i], axis=1) < self.radii[i] + self.radii[j] + near + cl) & \
                    (d.movable[i] | d.movable[j])
                i, j, cl, shift = i[keep], j[keep], cl[keep], shift[keep]
                if len(i):
                    g = pair_gaps(W, i, j, pos, self.radii, near + float(cl.max()), shift)[2].min(axis=1)
                    gaps.append(g)
                    closing.append(cl)
                    ends.append(np.column_stack([i, j]))
        x0, x1, y0, y1 = self.walls
        mv = np.flatnonzero(d.movable)
        lo, hi = W[mv].min(axis=1), W[mv].max(axis=1)
        for gw, axis in ((lo[:, 0] - x0, 0), (x1 - hi[:, 0], 0), (lo[:, 1] - y0, 1), (y1 - hi[:, 1], 1)):
            ok = np.isfinite(gw)
            normal_speed = np.maximum(np.abs(V0[mv, axis]), np.abs(V1[mv, axis])) + turn[mv]
            gaps.append(gw[ok])
            closing.append(1.5 * dt * normal_speed[ok])
            ends.append(np.column_stack([mv[ok], np.full(int(ok.sum()), -1)]))
        g = np.concatenate(gaps) if gaps else np.zeros(0)
        cl = np.concatenate(closing) if closing else np.zeros(0)
        e = np.concatenate(ends) if ends else np.zeros((0, 2), np.int64)
        within = g < near + cl
        if not within.any():
            return None
        return g[within], cl[within], e[within, 0], e[within, 1]

    def _requirements(self, dt: float, g: np.ndarray, cl: np.ndarray, starts: np.ndarray, seen: np.ndarray) -> dict:
        """The sub-steps of :meth:`sub_steps` for each run of entries beginning at ``starts`` (a component of
        :meth:`sub_step_groups`, or all of them): the gaps ``g`` that can close by ``cl`` in a pass, ``seen``
        (one a run) the closest gap an earlier pass of the step met (``inf``: none).

        Returns arrays, one entry a run: ``n`` (int), ``floor`` (length; ``-inf`` at the DEM's bound) and what
        :meth:`_set_by` needs to say why.
        """
        d = self.dem
        n_max = max(int(np.ceil(dt / d.dt_max - 1e-9)), 1)
        rng = self.repulsion.range if self.repulsion.force > 0 else 0.0
        floor = np.minimum.reduceat(g - cl, starts)
        n = np.maximum(np.maximum.reduceat(np.ceil(cl / (0.25 * np.maximum(g, max(rng, 1e-300))) - 1e-9), starts),
                       1).astype(np.int64)
        from_seen = (floor <= 0.0) & (seen > 0.0) & np.isfinite(seen) & (rng > 0.0)
        closing = (floor <= 0.0) & ~from_seen  # an overlap may form: the contact law acts
        floor = np.where(from_seen, 0.5 * seen, floor)
        k = np.where(closing | (floor >= rng), 0.0, self.repulsion.stiffness(floor))
        m = float(d.mass[d.free].min())
        n_rep = np.ones(len(n), np.int64)
        if (k > 0).any():
            n_rep[k > 0] = np.ceil(dt / critical_sub_step(m, k[k > 0]) - 1e-9)
        by_repulsion = n_rep > n
        n = np.maximum(n, n_rep)
        capped = closing | (n >= n_max)
        return {"n": np.where(capped, n_max, n), "floor": np.where(capped, -np.inf, floor), "closing": closing,
                "capped": capped, "by_repulsion": by_repulsion, "from_seen": from_seen, "seen": seen,
                "stiffness": k}

    @staticmethod
    def _set_by(req: dict, r: int) -> str:
        """What sets the sub-steps of run ``r`` of :meth:`_requirements`, in words."""
        if req["closing"][r]:
            return "a gap that may close in the pass: the DEM's bound"
        if req["capped"][r]:
            return "the DEM's bound"
        origin = f" (half the closest gap {req['seen'][r]:.3g} of the step's last pass)" if req["from_seen"][r] else ""
        if req["by_repulsion"][r]:
            return (f"the repulsion's stiffness at the gap floor {req['floor'][r]:.3g}{origin}: "
                    f"{req['stiffness'][r]:.3g} force/length, softer with a larger contact.repulsion_epsilon "
                    "or repulsion_range")
        return f"the gaps' change: a quarter of a gap per sub-step{origin}"

    def repulsion_linearised(self, poses: np.ndarray):
        """The repulsion on the free bodies at ``poses`` and its derivative in their poses.

        Each pair within range pushes with f(g) along its unit normal n at its point of action
        c; a pose change dX of a body changes the gap by aᵀ dX with a = (n, (c − X) × n) for the
        body pushed along +n and −a for the other.  The derivative keeps only this normal
        stiffness, K = −Σ_pairs f′(g) a aᵀ (symmetric, negative semi-definite; the turn of n is
        neglected), which is what a linearly implicit step needs to be stable.

        Parameters
        ----------
        poses : (n_bodies, 3) float
            x, y (length), angle (rad) of every body.

        Returns
        -------
        F : (n_free, 3) float
            Force (x, y) and torque on the free bodies, force, force·length.
        K : (3 n_free, 3 n_free) scipy.sparse.csr_matrix
            dF/dX of the free bodies' poses, force/length (force per rad in the angle columns).
        """
        import scipy.sparse as sp

        x = np.asarray(poses, float)
        a, b, gap, point, n = self.dem.repulsion_geometry(x)
        nf = len(self.free)
        slot = np.full(len(x), -1)
        slot[self.free] = np.arange(nf)
        rep = self.repulsion
        f = rep.magnitude(gap)
        k = rep.stiffness(gap)

        def gen(body, shift=0.0):  # generalised normal (P, 3) of each pair's end on ``body`` (at its image + shift)
            r = point - x[np.maximum(body, 0), :2] - shift
            return np.column_stack([n, r[:, 0] * n[:, 1] - r[:, 1] * n[:, 0]])

        sb = self.dem.image_shift(a, np.where(b >= 0, b, a), x)  # b's image nearest a, where ``point`` lies

        ends = [(slot[a], gen(a)), (np.where(b >= 0, slot[np.maximum(b, 0)], -1), -gen(b, sb))]
        F = np.zeros((nf, 3))
        for s_, g in ends:
            on = s_ >= 0
            np.add.at(F, s_[on], f[on, None] * g[on])
        rows, cols, vals = [], [], []
        for s1, g1 in ends:
            for s2, g2 in ends:
                on = (s1 >= 0) & (s2 >= 0)
                blk = -k[on, None, None] * g1[on, :, None] * g2[on, None, :]  # (P, 3, 3)
                rows.append((3 * s1[on, None, None] + np.arange(3)[None, :, None]).repeat(3, axis=2).ravel())
                cols.append((3 * s2[on, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1).ravel())
                vals.append(blk.ravel())
        K = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * nf, 3 * nf))
        return F, K

    def contact_counts(self, poses: np.ndarray) -> np.ndarray:
        """(n_bodies,) int: how many bodies and walls are within the repulsion's range of each body at
        ``poses`` (n_bodies, 3), overlaps included: the contacts through which a contact force acts.  A
        body resting on another in a fluid sits inside that range (at ``ρ (1 − √ε)`` under a load equal
        to the repulsion's force scale), not on an overlap."""
        a, b, *_ = self.dem.repulsion_geometry(poses)
        cnt = np.bincount(a, minlength=len(poses))
        return cnt + np.bincount(b[b >= 0], minlength=len(poses))

    def get_state(self) -> dict:
        return {"springs": self.dem.spring_history, "substeps": self.substeps, "dem_calls": self.dem_calls,
                "redone": self.redone, "body_substeps": self.body_substeps,
                "seen_last_step": self.seen_last_step}

    def set_state(self, s: dict) -> None:
        self.dem.spring_history = s["springs"]
        self.substeps, self.dem_calls = s["substeps"], s["dem_calls"]
        self.redone = s.get("redone", 0)  # checkpoints written before it was counted
        self.body_substeps = s.get("body_substeps", 0)
        seen = s.get("seen_last_step")  # checkpoints written before it was kept: the bound at the first pass
        self.seen_last_step = None if seen is None else np.asarray(seen, float)
