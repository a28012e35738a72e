"""The DEM driver: arrays of bodies, one Gear step, contacts, energies.

A dry granular scene is a :class:`DEM` and nothing else: it builds no mesh and no fluid
solver.  The fluid coupling enters through :attr:`DEM.external_force` and
:attr:`DEM.external_torque` (set before a step; they stay until changed) and through
:meth:`DEM.advance`, which sub-steps a fluid step with stable DEM steps.

Time step.  The bound is ``dt_max = 0.1 π √(m_min / E)`` (Matuttis & Chen 2014, ch. 7;
``m_min`` the lightest free body): :meth:`DEM.step` raises an
:class:`~fluidem.errors.InputError` (a ``ValueError``) naming that body above it,
:meth:`DEM.advance` sub-steps below it.

Velocity.  With the default 2nd-order scheme (velocity Verlet, :mod:`fluidem.dem.integrate`) the
forces of a step see the positions at ``t + Δt`` and the mid-step velocity ``v_n + a_n Δt/2``, the one
that moved the bodies over the step (as LAMMPS's granular and lubrication pair styles do): the
tangential spring grows by the real relative displacement, and a dashpot ``c`` on a mass ``m``
multiplies the velocity by ``1 − cΔt/m`` per step, stable for ``cΔt/m < 2``; it is first order in Δt
for the dissipative forces.  The predictor's ``v_n + a_n Δt`` (second order) feeds ``a_n`` back into
``a_{n+1}`` through the dashpots: a period-2 oscillation that grows once ``cΔt/m > 1``, which the grains
of a heap reach through their rotational damping (Σ c r² Δt / I up to 1.3), so that heaps crept.

Units: one consistent system of the user's choice, quantities of a slab of unit depth (see
:mod:`fluidem.dem`, "Units"); dimensions below, SI as the example.

Length: the module passes 600 lines because :class:`DEM` alone has about 660: the bodies'
state and its stepping are one concept, which splitting the class would cut in two.
"""

from __future__ import annotations

import time

import numpy as np

from .. import geometry as geo
from .. import validate
from ..cost import CostSplit
from ..errors import InputError
from .bodies import Body, _box, _pair
from .broad_phase import grid_pairs
from .contact import Contacts, ContactModel, contact_forces
from .integrate import GEAR_ORDERS, Gear
from .lubrication import Lubrication, equal_area_radius, implicit_damping, lubrication_pairs
from .overlaps import polygon_overlaps, wall_overlaps
from .periodic import as_period, check_pair_reach, image_shift
from .repulsion import Repulsion, pair_gaps, repulsion_forces, repulsion_pairs

__all__ = ["DEM", "StepCost", "COST_PARTS", "COST_COUNTS", "critical_sub_step", "stable_sub_step"]


#: Deprecated alias of :class:`fluidem.cost.CostSplit`, the one cost-split type (kept for one version).
StepCost = CostSplit

#: The parts of a DEM step, in the order :attr:`DEM.cost` lists them.
COST_PARTS = ("broad", "narrow", "forces", "integrate")
#: The counters of :attr:`DEM.cost`.
COST_COUNTS = ("steps", "contacts", "rebuilds")


def _new_cost() -> CostSplit:
    return CostSplit(dict.fromkeys(COST_PARTS, 0.0), dict.fromkeys(COST_COUNTS, 0))


def _pad_vertices(bodies) -> tuple[np.ndarray, np.ndarray]:
    nv = np.array([len(b.vertices) for b in bodies], dtype=np.int64)
    # width a multiple of 8: the narrow phase reduces boolean rows 8 at a time
    K = 8 * int(np.ceil((nv.max() if len(nv) else 3) / 8))
    V = np.zeros((len(bodies), K, 2))
    for k, b in enumerate(bodies):
        V[k, : nv[k]] = b.vertices
        V[k, nv[k]:] = b.vertices[0]
    return V, nv



def critical_sub_step(mass, stiffness):
    """The explicit sub-step ``0.1 π √(m / k)`` that resolves a spring of ``stiffness`` k
    (force/length) on a body of ``mass`` m (Matuttis & Chen 2014, ch. 7), time units; scalars or arrays.

    Examples
    --------
    >>> round(float(critical_sub_step(0.01, 1e4)), 7)
    0.0003142
    """
    with np.errstate(all="ignore"):  # an absurd stiffness: 0, which the plan refuses
        return 0.1 * np.pi * np.sqrt(np.asarray(mass, dtype=float) / stiffness)


def stable_sub_step(mass: float, E: float, repulsion=None) -> tuple[float, str]:
    """The DEM's largest stable sub-step ``0.1 π √(m / k)`` (Matuttis & Chen 2014, ch. 7) and what sets it.

    ``m`` the lightest free body's mass, ``k`` the stiffer of the contact law's ``E`` and the
    repulsion's stiffness at contact 2c/(ερ) (:attr:`fluidem.dem.repulsion.Repulsion.max_stiffness`).
    Returns ``(dt_max, set_by)``, ``set_by`` naming that stiffness and the parameters that set it.

    Examples
    --------
    >>> dt, by = stable_sub_step(0.01, 1e4)
    >>> round(dt, 7), by
    (0.0003142, 'contact.E = 1e+04 force/length')
    """
    k, by = E, f"contact.E = {E:.3g} force/length"
    if repulsion is not None and repulsion.max_stiffness > k:
        k = repulsion.max_stiffness
        by = (f"the repulsion's stiffness at contact 2c/(ερ) = {k:.3g} force/length (contact.repulsion_epsilon, "
              "repulsion_force, repulsion_range)")
    return float(critical_sub_step(mass, k)), by


class DEM:
    """Polygonal discrete element simulation.

    Parameters
    ----------
    bodies : sequence of Body
        The particles (free, fixed or prescribed).
    walls : (xmin, xmax, ymin, ymax) or None
        Domain sides acting as rigid walls with the same contact law (length); a side may
        be ``±inf`` to leave it open.  Sides along a periodic axis never act.
    gravity : (2,) float
        Length/time² (m/s² in SI: the default ``(0, -9.81)``; give ``(0, -981)`` in CGS).
    contact : ContactModel
        Material parameters.
    order : int
        Gear predictor order (2 or 5 are the usual choices; 2 is the default).
    skin : float or None
        Verlet-list skin, length; ``None`` takes 0.2 × the largest bounding radius.
    overlap_tolerance : float
        Largest overlap allowed at start, as a fraction of the smaller body's area.
    t0 : float
        Initial time, time units.
    repulsion : Repulsion or None
        A short-range repulsion between outlines closer than its range (bodies in a fluid,
        :mod:`fluidem.dem.repulsion`); its stiffness enters :attr:`dt_max`.
    lubrication : Lubrication or None
        The lubrication correction between outlines closer than its range (bodies in a fluid,
        :mod:`fluidem.dem.lubrication`): a normal damping, applied implicitly after each
        step, so it never shortens :attr:`dt_max`.
    period : (L_x, L_y) or None
        Periods of a periodic box, length: an entry for each axis, a positive period or None
        where the axis is not periodic (``(1.0, None)``: the left and right sides are one).
        Positions stay unwrapped (a body that crossed the right side has ``x > xmax``); every pair
        (contacts, repulsion, lubrication, gaps) sees the nearest periodic image of its partner
        (minimum-image convention, :mod:`fluidem.dem.periodic`), and walls act only on the
        non-periodic sides: along a periodic axis ``walls`` must be ``±inf`` or span exactly one
        period.  Every pair of bodies must satisfy ``r_i + r_j + near_range < L/2`` (bounding
        radii): bodies narrower than half the period.

    Attributes
    ----------
    positions : (N, 2) float
        Centres of mass, length (m in SI).
    angles : (N,) float
        Rad.
    velocities : (N, 2) float
        Length/time (m/s).
    omegas : (N,) float
        Rad/time (rad/s).
    mass, inertia : (N,) float
        Masses (mass units, kg) and moments of inertia about the centres of mass
        (mass·length², kg·m²).
    forces : (N, 2) float
        Total force on each body in the last step (contacts + gravity + external), force
        (N).
    torques : (N,) float
        Total torque about each centre of mass in the last step, force·length (N·m).
    contacts : Contacts
        Contacts of the last step.
    external_force : (N, 2) float
        User forces (e.g. from a fluid), force; kept until changed.
    external_torque : (N,) float
        User torques, force·length.
    time : float
        Time units (s).
    cost : fluidem.cost.CostSplit
        Wall seconds per part of the steps so far (``broad``, ``narrow``, ``forces``,
        ``integrate``; read as ``sim.cost.broad``) and counters ``steps``, ``contacts``
        (contacts evaluated, summed over steps) and ``rebuilds`` (Verlet-list rebuilds);
        :meth:`cost_per_step` divides them, :meth:`reset_cost` starts afresh.

    Raises
    ------
    fluidem.errors.InputError
        (a ``ValueError``) A bad argument (named with its value), bodies overlapping each
        other or a wall beyond ``overlap_tolerance`` (naming the bodies and the overlap), a
        ``period`` that does not match ``walls`` or bodies wider than half of it.

    Examples
    --------
    >>> from fluidem.dem import Body, ContactModel, DEM
    >>> b = Body.rectangle(0.02, 0.01, density=100.0, position=(0.0, 0.00499))
    >>> sim = DEM([b], walls=(-1, 1, 0, 1), contact=ContactModel(E=1e5, mu=0.5, gamma=0.3))
    >>> sim.run(0.05, 0.5 * sim.dt_max)
    >>> bool(abs(sim.forces[0, 1]) < 1e-3 * b.mass * 9.81)    # at rest on the floor
    True
    """

    def __init__(self, bodies, walls=None, gravity=(0.0, -9.81), contact: ContactModel | None = None,
                 order: int = 2, skin: float | None = None, overlap_tolerance: float = 0.01,
                 t0: float = 0.0, repulsion: Repulsion | None = None, lubrication: Lubrication | None = None,
                 period=None):
        bodies = _check_bodies("DEM(bodies=...)", bodies)
        if not bodies:
            raise validate.fail("DEM(bodies=...)", bodies, "at least one fluidem.dem.Body")
        self.model = contact if contact is not None else ContactModel()
        if not isinstance(self.model, ContactModel):
            raise validate.fail("DEM(contact=...)", _Shown(contact), "a fluidem.dem.ContactModel")
        self.gravity = _pair("DEM(gravity=...)", gravity)
        self._L = as_period("DEM(period=...)", period)
        self.walls = walls
        self.order = int(validate.choice("DEM(order=...)", order, GEAR_ORDERS))
        self.overlap_tolerance = validate.nonnegative("DEM(overlap_tolerance=...)", overlap_tolerance)
        self.time = validate.number("DEM(t0=...)", t0)
        self._skin_arg = None if skin is None else validate.nonnegative("DEM(skin=...)", skin)
        if repulsion is not None and not isinstance(repulsion, Repulsion):
            raise validate.fail("DEM(repulsion=...)", _Shown(repulsion), "None or a fluidem.dem.repulsion.Repulsion")
        self.repulsion = repulsion
        self.repulsion_pairs = 0  # pairs and body-wall pairs within the repulsion range in the last step
        if lubrication is not None and not isinstance(lubrication, Lubrication):
            raise validate.fail("DEM(lubrication=...)", _Shown(lubrication),
                                "None or a fluidem.dem.lubrication.Lubrication")
        self.lubrication = lubrication
        self.lubrication_pairs = 0  # likewise within the lubrication range
        #: the smallest gap between outlines (or outline and wall) within :attr:`near_range` met by the
        #: steps since it was last set to ``inf`` (length; ``-inf`` after an overlap)
        self.closest_gap_seen = np.inf
        self._lub = (np.zeros(0, np.int64),) * 2 + (np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2)))
        self.cost = _new_cost()
        #: the bodies a grouped :meth:`advance` moves now (bool (N,)); None: every body
        self._active = None
        self.bodies: list[Body] = []
        self._setup(bodies, key="DEM(period=...)")
        self._check_overlaps(np.arange(len(self.bodies)))
        self._initial_forces()
        self._fresh = True      # again at the first step, with the external forces set by then

    def __setstate__(self, state: dict) -> None:
        """Restore from a checkpoint; one written before periodic boxes gets none (``period`` None)."""
        self.__dict__.update(state)
        if "_L" not in state:
            self._L = np.zeros(2)
            self._wall_box = self._walls
        C = self.__dict__.get("contacts")
        if C is not None and getattr(C, "shift", None) is None:
            C.shift = np.zeros((len(C.i), 2))

    # ---- set-up ------------------------------------------------------------------------
    def _setup(self, bodies, state=None, key="DEM(period=...)"):
        B = list(bodies)
        check_pair_reach(key, self._L, [b.radius for b in B], self.near_range)
        self.bodies = B
        self.n = len(B)
        self._V, self._nv = _pad_vertices(B)
        self.mass = np.array([b.mass for b in B])
        self.inertia = np.array([b.inertia for b in B])
        self.area = np.array([b.area for b in B])
        self.radii = np.array([b.radius for b in B])
        self.motion = np.array([b.motion for b in B])
        self.free = self.motion == "free"
        self.movable = self.motion != "fixed"
        self._prescribed = np.flatnonzero(self.motion == "prescribed")
        if state is None:
            x = np.array([[*b.position, b.angle] for b in B])
            v = np.array([[*b.velocity, b.omega] for b in B])
            self.external_force = np.zeros((self.n, 2))
            self.external_torque = np.zeros(self.n)
        else:
            x, v, a, fe, te = state
        self._mask = np.repeat(self.free[:, None], 3, axis=1)
        if state is None:
            v = np.where((self.motion == "fixed")[:, None], 0.0, v)
            self.gear = Gear(x, v, np.zeros_like(x), self.order)
        else:
            self.gear = Gear(x, v, a, self.order)
            self.external_force, self.external_torque = fe, te
        fr = self.radii[self.movable]
        rmax = float(fr.max()) if len(fr) else float(self.radii.max())
        self.skin = 0.2 * rmax if self._skin_arg is None else float(self._skin_arg)
        self.lubrication_radius = equal_area_radius(self.area)
        if self.near_range > 0:  # the Verlet list must hold the pairs within the ranges
            self.skin = max(self.skin, 4.0 * self.near_range)
        self._cell = 2.0 * rmax + self.skin
        self._nbr = None
        self._nbr_ref = None
        self._hist = _empty_history()
        self.contacts = Contacts.empty()
        self.forces = np.zeros((self.n, 2))
        self.torques = np.zeros(self.n)
        self._dt_max = self._compute_dt_max()
        self._fresh = True

    def _compute_dt_max(self) -> float:
        if not self.free.any():
            self._lightest = None
            self.dt_max_set_by = "no free body"
            return np.inf
        k = int(np.flatnonzero(self.free)[np.argmin(self.mass[self.free])])
        self._lightest = k
        dt, by = stable_sub_step(self.mass[k], self.model.E, self.repulsion)
        self.dt_max_set_by = f"{by} with the lightest free body {k} (mass {self.mass[k]:.3g}), 0.1π√(m/k) = {dt:.3g}"
        return dt

    @property
    def walls(self):
        """Domain sides ``(xmin, xmax, ymin, ymax)`` in length units (``±inf`` for an open side) or None.

        May be changed between steps, e.g. to open a gate.
        """
        return self._walls

    @walls.setter
    def walls(self, walls):
        box = None if walls is None else _box("DEM(walls=...)", walls)
        w = box
        if w is not None and self._L.any():
            for c in np.flatnonzero(self._L > 0):
                lo, hi = w[2 * c], w[2 * c + 1]
                if (np.isfinite(lo) or np.isfinite(hi)) and not abs((hi - lo) - self._L[c]) <= 1e-9 * self._L[c]:
                    raise InputError(
                        f"DEM(walls=...) = {walls!r}: along the periodic {'xy'[c]} axis the box sides span "
                        f"{hi - lo:.6g}, not the period {self._L[c]:.6g} of DEM(period=...); expected sides "
                        f"{'xy'[c]}max − {'xy'[c]}min = {self._L[c]:.6g} or ±inf")
            # the sides along a periodic axis never act
            w = tuple(-np.inf if self._L[k // 2] > 0 and k % 2 == 0 else
                      np.inf if self._L[k // 2] > 0 else w[k] for k in range(4))
            w = None if not np.isfinite(w).any() else w
        self._walls = box
        self._wall_box = w  # the sides that act

    @property
    def period(self):
        """Periods ``(L_x, L_y)`` of a periodic box, length, None for a non-periodic axis (the
        constructor's ``period``; :mod:`fluidem.dem.periodic`)."""
        return tuple(float(v) if v > 0 else None for v in self._L)

    def image_shift(self, i, j, poses=None) -> np.ndarray:
        """(P, 2) shifts bringing bodies ``j`` (P,) to their periodic images nearest bodies ``i`` (P,),
        length (zero outside a periodic box; :func:`fluidem.dem.periodic.image_shift`).

        ``poses`` (N, 2 or 3), default the current ones: ``x_j + shift − x_i`` is the pair's
        displacement, and the arm of ``j``'s force acting at ``point`` (at ``i``) is
        ``point − (x_j + shift)``.
        """
        x = self.gear.X[0] if poses is None else np.asarray(poses, float)
        i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
        return image_shift(x[j, :2] - x[i, :2], self._L)

    @property
    def near_range(self) -> float:
        """The largest range of the short-range models (repulsion, lubrication), 0 for none; length."""
        return max([m.range for m in (self.repulsion, self.lubrication) if m is not None], default=0.0)

    @property
    def dt_max(self) -> float:
        """Largest stable step ``0.1 π √(m_min/E)``, time units (Matuttis & Chen 2014, ch. 7)."""
        return self._dt_max

    # ---- cost ----------------------------------------------------------------------------
    def reset_cost(self) -> None:
        """Start a fresh :attr:`cost` (all parts and counters zero)."""
        self.cost = _new_cost()

    def cost_per_step(self) -> dict:
        """Seconds per step of each part and in total, seconds per contact, contacts per step.

        :meth:`fluidem.cost.CostSplit.per_step` of :attr:`cost` plus ``"per_contact"``
        (total seconds over the contacts evaluated) and ``"contacts_per_step"``.
        """
        c = self.cost
        steps = max(int(c.counts.get("steps", 0)), 1)
        contacts = int(c.counts.get("contacts", 0))
        out = dict.fromkeys(COST_PARTS, 0.0)
        out.update(c.per_step(steps))
        out["per_contact"] = c.total / max(contacts, 1)
        out["contacts_per_step"] = contacts / steps
        return out

    # ---- state views ---------------------------------------------------------------------
    @property
    def positions(self) -> np.ndarray:
        """(N, 2) float, length."""
        return self.gear.X[0][:, :2]

    @property
    def angles(self) -> np.ndarray:
        """(N,) float, rad."""
        return self.gear.X[0][:, 2]

    @property
    def velocities(self) -> np.ndarray:
        """(N, 2) float, length/time."""
        return self.gear.X[1][:, :2]

    @property
    def omegas(self) -> np.ndarray:
        """(N,) float, rad/time."""
        return self.gear.X[1][:, 2]

    def world_vertices(self, x=None) -> np.ndarray:
        """World outlines, (N, K, 2) padded by repeating each body's first vertex, length.

        ``x`` : (N, 3) poses ``(x, y, angle)``, default the current ones.
        """
        return geo.rigid_transform(self._V, self.gear.X[0] if x is None else x)

    def outlines(self) -> list[np.ndarray]:
        """World outline of each body as a list of (n_k, 2) arrays, length."""
        W = self.world_vertices()
        return [W[k, : self._nv[k]] for k in range(self.n)]

    # ---- contacts ----------------------------------------------------------------------
    def _neighbours(self, pos, extra: float = 0.0):
        """Pairs whose bounding circles come closer than ``extra`` (length)."""
        t0 = time.perf_counter()
        rebuild = self._nbr is None
        if not rebuild:
            disp = pos - self._nbr_ref
            rebuild = float((disp * disp).sum(axis=1).max()) > (0.5 * self.skin) ** 2
        if rebuild:
            self._nbr = grid_pairs(pos, self.radii, self._cell, self.movable, self.skin, self._L)
            self._nbr_ref = pos.copy()
            self.cost.count("rebuilds")
        i, j = self._nbr
        d = pos[j] - pos[i]
        d = d + image_shift(d, self._L)
        reach = self.radii[i] + self.radii[j] + extra
        keep = (d * d).sum(axis=1) < reach * reach
        if self._active is not None:  # a group's pairs: among its bodies, or with a fixed body
            act = self._active
            present = act | ~self.movable
            keep &= present[i] & present[j] & (act[i] | act[j])
        self.cost.add("broad", time.perf_counter() - t0)
        return i[keep], j[keep]

    @property
    def _moving(self) -> np.ndarray:
        """The bodies that move now (bool (N,)): the movable ones, of the group a grouped :meth:`advance` moves."""
        return self.movable if self._active is None else self.movable & self._active

    def _others(self, key: np.ndarray) -> np.ndarray:
        """Contacts (by :func:`~fluidem.dem.contact.pair_key`) of no body of the group moved now (bool)."""
        i = key >> 32
        j = (key & 0xFFFFFFFF) - 8
        act = self._active
        return ~act[i] & ~(act[np.maximum(j, 0)] & (j >= 0))

    def _overlaps(self, x, W=None):
        pos = x[:, :2]
        i, j = self._neighbours(pos)
        t0 = time.perf_counter()
        W = self.world_vertices(x) if W is None else W
        ovs = []
        if len(i):
            ovs.append(polygon_overlaps(W, self._nv, pos, i, j, image_shift(pos[j] - pos[i], self._L)))
        if self._wall_box is not None:
            mv = np.flatnonzero(self._moving)
            lo, hi = np.zeros((self.n, 2)), np.zeros((self.n, 2))
            lo[mv], hi[mv] = W[mv].min(axis=1), W[mv].max(axis=1)
            ow = wall_overlaps(W, self._nv, pos, lo, hi, self._wall_box, mv)
            if ow is not None:
                ovs.append(ow)
        self.cost.add("narrow", time.perf_counter() - t0)
        return ovs

    def _check_overlaps(self, which):
        ovs = self._overlaps(self.gear.X[0])
        which = set(np.asarray(which).tolist())
        for ov in ovs:
            i, j, A = ov["i"], ov["j"], ov["area"]
            ref = np.where(j >= 0, np.minimum(self.area[i], self.area[np.maximum(j, 0)]), self.area[i])
            bad = np.flatnonzero(A > self.overlap_tolerance * ref)
            for k in bad:
                if int(i[k]) in which or int(j[k]) in which:
                    other = f"body {int(j[k])}" if j[k] >= 0 else f"wall {int(j[k])} ({_wall_name(j[k])})"
                    raise InputError(
                        f"body {int(i[k])} and {other} overlap at start by {A[k]:.4g} (length²) = "
                        f"{A[k] / ref[k]:.3g} of the body area; allowed: overlap_tolerance = "
                        f"{self.overlap_tolerance:g}")

    def _evaluate(self, x, v, dt):
        """Contacts and total forces/torques at state (x, v); advances spring history by dt.

        The lubrication is not among the forces: its pairs are kept for :meth:`_damp`.
        """
        W = self.world_vertices(x)
        ovs = self._overlaps(x, W)
        t0 = time.perf_counter()
        pos = x[:, :2]
        parts = [contact_forces(ov, pos, v[:, :2], v[:, 2], self.mass, self.free, self.model, dt,
                                self._hist) for ov in ovs]
        C = Contacts.concat(parts) if parts else Contacts.empty()
        n = self.n
        F = C.normal_force + C.tangential_force
        rel = C.point - pos[C.i]
        T = rel[:, 0] * F[:, 1] - rel[:, 1] * F[:, 0]
        body = C.j >= 0
        jb = C.j[body]
        relj = C.point[body] - (pos[jb] + C.shift[body])  # the arm about j's image at the contact
        Fj = -F[body]
        Tj = relj[:, 0] * Fj[:, 1] - relj[:, 1] * Fj[:, 0]
        idx = np.concatenate([C.i, jb])
        fx = np.bincount(idx, np.concatenate([F[:, 0], Fj[:, 0]]), minlength=n)
        fy = np.bincount(idx, np.concatenate([F[:, 1], Fj[:, 1]]), minlength=n)
        tq = np.bincount(idx, np.concatenate([T, Tj]), minlength=n)
        forces = np.column_stack([fx, fy]) + self.mass[:, None] * self.gravity + self.external_force
        torques = tq + self.external_torque
        if self.near_range > 0:  # repulsion and lubrication below their ranges
            ri, rj = self._neighbours(pos, self.near_range)
            touching = np.zeros(len(ri), bool)
            if len(ri) and len(C):  # overlapping pairs act along their centre line
                n = self.n
                body = C.j >= 0
                touching = np.isin(ri * n + rj, np.minimum(C.i, C.j)[body] * n + np.maximum(C.i, C.j)[body])
            active = self.lubrication is not None or self.repulsion.force > 0  # a zero force scale measures nothing
            shift = image_shift(pos[rj] - pos[ri], self._L)
            gaps = pair_gaps(W, ri, rj, pos, self.radii, self.near_range, shift) if len(ri) and active else None
            self.closest_gap_seen = min(self.closest_gap_seen, self._closest_gap(W, gaps))
            if self.repulsion is not None:
                Fr, Tr, self.repulsion_pairs = repulsion_forces(self.repulsion, W, pos, ri, rj, touching,
                                                                self._wall_box, self._moving, self.radii, gaps=gaps,
                                                                period=self._L)
                forces = forces + Fr
                torques = torques + Tr
            if self.lubrication is not None:  # applied implicitly after the step (:meth:`_damp`)
                self._lub = lubrication_pairs(self.lubrication, W, pos, ri, rj, touching, self.lubrication_radius,
                                              self._wall_box, self._moving, gaps=gaps, period=self._L)
                self.lubrication_pairs = len(self._lub[0])
        hist = {"key": C.key, "xi": C.xi, "area": C.area, "g": self.model.E * C.area / (C.length * C.chord),
                "work": C.work}
        found = len(C)
        if self._active is not None:  # a group: the other bodies' contacts, springs and forces stay
            kept = self._others(self._hist["key"])
            hist = {k: np.concatenate([self._hist[k][kept], v]) for k, v in hist.items()}
            old = self.contacts
            C = Contacts.concat([old.select(self._others(old.key)), C])
            forces = np.where(self._active[:, None], forces, self.forces)
            torques = np.where(self._active, torques, self.torques)
        order = np.argsort(hist["key"], kind="stable")
        self._hist = {k: v[order] for k, v in hist.items()}
        self.contacts = C
        self.forces = forces
        self.torques = torques
        self.cost.add("forces", time.perf_counter() - t0)
        self.cost.count("contacts", found)
        self._found = found
        if found:
            self.closest_gap_seen = -np.inf
        return forces, torques

    def _fresh_rows(self):
        """The bodies moved now whose accelerations are still to be evaluated (bool (N,)), or None."""
        rows = np.broadcast_to(np.asarray(self._fresh, bool), (self.n,))
        if self._active is not None:
            rows = rows & self._active
        return rows if rows.any() else None

    def _initial_forces(self, rows=None):
        # accelerations at the current state; no spring increment, no lubrication (implicit, :meth:`_damp`)
        x = self.gear.X[0]
        if len(self._prescribed):
            self._apply_prescribed(self.time, x, self.gear.X[1])
        F, T = self._evaluate(x, self.gear.X[1], 0.0)
        self.cost.count("contacts", -self._found)
        a = np.where(self._mask, self._acc(F, T), 0.0)
        if rows is None:
            self._fresh = False
            self.gear.set(a=a)
        else:  # a group's bodies (a grouped :meth:`advance`)
            left = np.broadcast_to(np.asarray(self._fresh, bool), (self.n,)) & ~rows
            self._fresh = left if left.any() else False
            self.gear.set(a=a, mask=np.repeat(rows[:, None], 3, axis=1))

    def _acc(self, F, T):
        return np.column_stack([F / self.mass[:, None], T / self.inertia])

    def _apply_prescribed(self, t, x, v):
        # central differences; h balances truncation (h²) against round-off (eps/h)
        h = 1e-2 * (self.dt_max if np.isfinite(self.dt_max) else 1e-3)
        moving = self._prescribed if self._active is None else self._prescribed[self._active[self._prescribed]]
        for k in moving:  # one call per prescribed body (user callables)
            b = self.bodies[k]
            p, a = b.pose_at(t)
            pp, ap = b.pose_at(t + h)
            pm, am = b.pose_at(t - h)
            x[k] = (*p, a)
            v[k] = (*((pp - pm) / (2 * h)), (ap - am) / (2 * h))

    # ---- stepping ------------------------------------------------------------------------
    def step(self, dt: float) -> None:
        """Advance by one Gear predictor–corrector step of ``dt`` (time units).

        Raises
        ------
        fluidem.errors.InputError
            (a ``ValueError``) ``dt`` not positive, or above :attr:`dt_max` (naming the
            lightest body).
        """
        dt = validate.positive("DEM.step(dt=...)", dt)
        if dt > self._dt_max * (1 + 1e-12):
            k = self._lightest
            raise InputError(
                f"DEM.step(dt=...) = {dt:.4g}: exceeds the stability bound dt_max = 0.1π√(m/E) = "
                f"{self._dt_max:.4g} set by body {k} (mass {self.mass[k]:.4g}, E = {self.model.E:.4g}); "
                f"expected dt <= {self._dt_max:.4g}, or DEM.advance() to sub-step")
        self._step(dt)

    def _step(self, dt: float) -> None:
        """:meth:`step` without the check of ``dt`` (the caller vouches for its stability)."""
        rows = self._fresh_rows()
        if rows is not None:
            # accelerations at t0 with the external forces the caller may have set since
            # construction (the predictor uses them)
            self._initial_forces(None if self._active is None else rows)
        t0 = time.perf_counter()
        mask = self._mask if self._active is None else self._mask & self._active[:, None]
        x, v = self.gear.predict(dt, mask)
        x, v = x.copy(), v.copy()
        if len(self._prescribed):
            self._apply_prescribed(self.time + dt, x, v)
        # the velocity the forces see: for the 2nd-order scheme (velocity Verlet) the mid-step
        # velocity v_n + a_n dt/2, which moved the bodies over the step (module docstring, "Velocity")
        v_forces = np.where(self._mask, 0.5 * (v + self.gear.X[1]), v) if self.order == 2 else v
        self.cost.add("integrate", time.perf_counter() - t0)
        F, T = self._evaluate(x, v_forces, dt)
        t0 = time.perf_counter()
        self.gear.correct(self._acc(F, T))
        if len(self._prescribed):
            m = np.zeros((self.n, 3), bool)
            m[self._prescribed] = True
            if self._active is not None:
                m &= self._active[:, None]
            self.gear.set(x=x, v=v, a=np.zeros_like(x), mask=m)
        if self.lubrication is not None:
            self._damp(dt)
        self.time += dt
        self.cost.add("integrate", time.perf_counter() - t0)
        self.cost.count("steps")

    def _damp(self, dt: float) -> None:
        """The lubrication of the step, implicitly (backward Euler, :func:`fluidem.dem.lubrication.implicit_damping`):
        the film's damping acts on the velocities the step ends with, so no ``cΔt/m`` bound applies and the
        film's force does not depend on the sub-step.  Its force joins :attr:`forces` and :attr:`torques`."""
        pairs = self._lub
        if not len(pairs[0]):
            return
        x = self.gear.X[0]
        v0 = self.gear.X[1]
        v1 = implicit_damping(pairs, x[:, :2], v0, self.mass, self.inertia, self.free, dt, self._L)
        moved = np.repeat(self._moving[:, None] & self.free[:, None], 3, axis=1) & (v1 != v0)
        if not moved.any():
            return
        dv = np.where(moved, v1 - v0, 0.0)
        self.gear.set(v=v1, mask=moved)
        self.forces = self.forces + self.mass[:, None] * dv[:, :2] / dt
        self.torques = self.torques + self.inertia * dv[:, 2] / dt

    def run(self, t_end: float, dt: float, callback=None, every: int = 1) -> None:
        """Step with ``dt`` until ``time ≥ t_end − dt/2``; ``callback(sim)`` after every ``every`` steps."""
        t_end = validate.number("DEM.run(t_end=...)", t_end)
        dt = validate.positive("DEM.run(dt=...)", dt)
        every = validate.integer("DEM.run(every=...)", every, lo=1)
        if callback is not None and not callable(callback):
            raise validate.fail("DEM.run(callback=...)", _Shown(callback), "None or a callable callback(sim)")
        n = int(np.round((t_end - self.time) / dt))
        for k in range(max(n, 0)):
            self.step(dt)
            if callback is not None and (k + 1) % every == 0:
                callback(self)

    def advance(self, duration: float, dt: float | None = None, *, n: int | None = None, bodies=None) -> int:
        """Advance by ``duration`` (time units) in equal sub-steps no larger than ``dt`` (default :attr:`dt_max`).

        ``n`` instead takes exactly ``n`` equal sub-steps, also longer than :attr:`dt_max`: for a caller
        that knows the stiffness in play is lower than the bound assumes (no overlap can form, the
        repulsion far from contact: :meth:`fluidem.coupling.contacts.FluidContacts.sub_steps`).

        ``bodies`` (int indices) moves only those bodies, with the forces among them, with fixed bodies
        and with the walls; every other body stays where it is and keeps its contacts' springs, and
        :attr:`time` is left unchanged.  For a caller that has split the bodies into groups none of
        which can come within :attr:`near_range` of another during ``duration``
        (:meth:`fluidem.coupling.contacts.FluidContacts.sub_step_groups`): each group then takes the
        sub-steps its own stiffness needs, and after every group the caller sets :attr:`time`.

        Returns the number of sub-steps taken.
        """
        duration = validate.positive("DEM.advance(duration=...)", duration)
        if n is not None:
            n = validate.integer("DEM.advance(n=...)", n, lo=1)
        else:
            h = self._dt_max if dt is None else min(validate.positive("DEM.advance(dt=...)", dt), self._dt_max)
            n = max(int(np.ceil(duration / h - 1e-9)), 1)
        if bodies is None:
            for _ in range(n):
                self._step(duration / n)
            return n
        active = np.zeros(self.n, bool)
        active[self._indices("DEM.advance(bodies=...)", bodies)] = True
        t0 = self.time
        self._active = active
        try:
            for _ in range(n):
                self._step(duration / n)
        finally:
            self._active = None
            self.time = t0
        return n

    def _indices(self, key: str, bodies) -> np.ndarray:
        idx = np.asarray(bodies)
        if idx.ndim != 1 or (idx.size and (idx.dtype.kind not in "iu" or idx.min() < 0 or idx.max() >= self.n)):
            raise validate.fail(key, _Shown(bodies), f"a sequence of body indices in [0, {self.n})")
        return idx.astype(np.int64)

    def _closest_gap(self, W, gaps) -> float:
        """Smallest gap of the pairs measured (``gaps`` of :func:`pair_gaps`, or None) and of the movable
        bodies to the walls, length (``inf`` for none)."""
        g = float(gaps[2].min()) if gaps is not None and gaps[2].size else np.inf
        if self._wall_box is not None:
            Wm = W[self._moving]
            if len(Wm):
                x0, x1, y0, y1 = self._wall_box
                lo, hi = Wm.min(axis=(0, 1)), Wm.max(axis=(0, 1))
                g = min(g, lo[0] - x0, x1 - hi[0], lo[1] - y0, y1 - hi[1])
        return g

    def repulsion_geometry(self, poses: np.ndarray):
        """The short-range repulsion's pairs within range at ``poses`` (N, 3), walls included.

        No contact detection and no change of state: overlapping pairs are measured like the
        others (a fluid run stops on overlap).  Returns ``(a, b, gap, point, direction)`` of
        :func:`fluidem.dem.repulsion.repulsion_pairs` (``b = -1`` for a wall), empty without a
        repulsion.  In a periodic box ``point`` lies at ``a``: the arm of ``b`` is
        ``point − (x_b + image_shift(a, b))`` (:meth:`image_shift`).
        """
        x = np.asarray(poses, float).reshape(self.n, 3)
        if self.repulsion is None or self.repulsion.force == 0.0:
            return repulsion_pairs(Repulsion(1.0, 0.0), np.zeros((0, 1, 2)), np.zeros((0, 2)), np.zeros(0, int),
                                   np.zeros(0, int), np.zeros(0, bool))
        W = self.world_vertices(x)
        pos = x[:, :2]
        ri, rj = self._neighbours(pos, self.repulsion.range)
        return repulsion_pairs(self.repulsion, W, pos, ri, rj, np.zeros(len(ri), bool), self._wall_box, self.movable,
                               self.radii, period=self._L)

    def set_motion(self, poses: np.ndarray, velocities: np.ndarray, time: float | None = None, bodies=None) -> None:
        """Replace every body's pose and velocity (e.g. to sub-step a fluid step from its state).

        Accelerations are evaluated afresh at the next step from the forces at the new state
        (contacts, gravity, :attr:`external_force`); the tangential spring history of the
        contacts is kept.

        Parameters
        ----------
        poses : (N, 3) float
            x, y (length), angle (rad).
        velocities : (N, 3) float
            U_x, U_y (length/time), ω (rad/time).
        time : float or None
            The new :attr:`time`; None keeps it.
        bodies : int indices or None
            Replace only these bodies' rows (e.g. to take a group of a grouped :meth:`advance` again).
        """
        x = np.array(poses, float).reshape(self.n, 3)
        v = np.where((self.motion == "fixed")[:, None], 0.0, np.array(velocities, float).reshape(self.n, 3))
        if time is not None:
            self.time = validate.number("DEM.set_motion(time=...)", time)
        if bodies is None:
            self.gear = Gear(x, v, np.zeros_like(x), self.order)
            self._fresh = True
            return
        rows = np.zeros(self.n, bool)
        rows[self._indices("DEM.set_motion(bodies=...)", bodies)] = True
        self.gear.set(x=x, v=v, a=np.zeros_like(x), mask=np.repeat(rows[:, None], 3, axis=1))
        self._fresh = np.broadcast_to(np.asarray(self._fresh, bool), (self.n,)) | rows

    @property
    def spring_history(self) -> dict:
        """The contacts' tangential spring state (arrays keyed by contact), for checkpoints."""
        return self._hist

    @spring_history.setter
    def spring_history(self, h: dict) -> None:
        self._hist = {k: np.asarray(v) for k, v in h.items()}

    # ---- adding bodies ---------------------------------------------------------------------
    def add_bodies(self, bodies) -> np.ndarray:
        """Append bodies (e.g. for pouring); returns their indices.

        Raises :class:`~fluidem.errors.InputError` (a ``ValueError``) if a new body overlaps another
        beyond ``overlap_tolerance``.
        """
        new = _check_bodies("DEM.add_bodies(bodies=...)", bodies)
        n0 = self.n
        X = self.gear.X
        xn = np.array([[*b.position, b.angle] for b in new])
        vn = np.array([[*b.velocity, b.omega] for b in new])
        an = np.array([[*(self.gravity if b.motion == "free" else (0, 0)), 0.0] for b in new])
        x = np.concatenate([X[0], xn])
        v = np.concatenate([X[1], vn])
        a = np.concatenate([X[2], an])
        fe = np.concatenate([self.external_force, np.zeros((len(new), 2))])
        te = np.concatenate([self.external_torque, np.zeros(len(new))])
        hist = self._hist
        cost = self.cost
        self._setup(self.bodies + new, state=(x, v, a, fe, te), key="DEM.add_bodies(bodies=...)")
        # keep the higher Gear derivatives of the old bodies
        for k in range(3, self.gear.q):
            self.gear.X[k][:n0] = X[k]
        self._hist = hist
        self.cost = cost
        idx = np.arange(n0, self.n)
        self._check_overlaps(idx)
        return idx

    # ---- diagnostics -------------------------------------------------------------------
    def kinetic_energy(self) -> float:
        """Translational plus rotational kinetic energy of all bodies, force·length (J in SI)."""
        v = self.velocities
        return float(0.5 * (self.mass * (v * v).sum(axis=1)).sum()
                     + 0.5 * (self.inertia * self.omegas**2).sum())

    def elastic_energy(self) -> float:
        """Energy stored in the contacts of the last step, force·length (J in SI).

        Work stored by the elastic normal forces plus ``Σ k_t ξ² / 2`` of the tangential
        springs (see :mod:`fluidem.dem.contact`).  Evaluated at the predicted positions,
        which for the default 2nd-order Gear scheme are the final positions of the step.
        """
        C = self.contacts
        if len(C) == 0:
            return 0.0
        return float(C.work.sum() + 0.5 * self.model.kt * (C.xi**2).sum())

    def potential_energy(self) -> float:
        """Gravitational potential energy ``−Σ m g·x`` of the free bodies, force·length (J in SI)."""
        return float(-(self.mass[self.free] * (self.positions[self.free] @ self.gravity)).sum())

    def coordination_number(self) -> float:
        """Mean number of contacts (with bodies or walls) per free body that has at least one."""
        C = self.contacts
        if len(C) == 0:
            return 0.0
        idx = np.concatenate([C.i, C.j[C.j >= 0]])
        z = np.bincount(idx, minlength=self.n)[self.free]
        touching = z > 0
        return float(z[touching].mean()) if touching.any() else 0.0


class _Shown:
    """A value shown in an error message by its type (``<list object>``), not its full repr."""

    def __init__(self, value):
        self.value = value

    def __repr__(self) -> str:
        return f"<{type(self.value).__name__} object>"


def _check_bodies(key: str, bodies) -> list:
    """``bodies`` as a list of :class:`Body`, or an :class:`InputError` naming the first other item."""
    try:
        out = list(bodies)
    except TypeError:
        raise validate.fail(key, _Shown(bodies), "a sequence of fluidem.dem.Body") from None
    for k, b in enumerate(out):
        if not isinstance(b, Body):
            raise validate.fail(f"{key}[{k}]", _Shown(b), "a fluidem.dem.Body")
    return out


def _empty_history() -> dict:
    z = np.zeros(0)
    return {"key": np.zeros(0, np.int64), "xi": z, "area": z, "g": z, "work": z}


def _wall_name(j) -> str:
    from .overlaps import WALL_IDS
    return {v: k for k, v in WALL_IDS.items()}.get(int(j), "?")
