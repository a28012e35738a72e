"""Polygon contact: the contact law (:class:`ContactModel`), the contacts of one step
(:class:`Contacts`) and their forces (:func:`contact_forces`).

Everything here works on arrays of pairs; there is no Python loop over bodies or
contacts.  The pairs come from the broad phase (:mod:`fluidem.dem.broad_phase`) and their
overlap geometry from the narrow phase (:mod:`fluidem.dem.overlaps`); this module holds the
contact law, the contacts of a step and the forces, and re-exports both phases' functions.

Force law (Matuttis & Chen 2014, ch. 7; REFERENCES.md "Polygonal DEM")
    * normal elastic force ``F_el = E A / l`` with ``1/l = (r_i + r_j) / (4 r_i r_j)``,
      ``r`` the distances from the centres of mass to the overlap centroid (a domain wall
      has ``r_j → ∞``: ``l = 4 r_i``, the limit a large fixed polygon tends to);
    * direction: normal to the segment ``S`` joining the two intersection points of the
      outlines; point of action: the overlap centroid;
    * damping ``F_d = γ √(m_eff E) (dA/dt) / l``, with ``dA/dt = |S| v_n`` (the overlap
      grows by the contact line times the normal approach speed, exact to first order, so
      no history of ``A`` is needed); ``F_n = max(F_el + F_d, 0)`` never attracts;
    * tangential: Cundall & Strack (1979) incremental spring ``ξ += v_t dt``,
      ``F_t = −k_t ξ − γ √(m_eff k_t) v_t`` with ``k_t = κ E`` (κ = 2/7 by default),
      capped at ``μ F_n`` (Coulomb); when capped the spring is reset to
      ``ξ = −F_t / k_t`` (sliding).  ``ξ`` is kept per contact between steps and dropped
      when the contact opens.

Elastic energy of a contact: the work done on it by the elastic normal force since it
closed, ``∫ F_el dδ = ∫ (F_el/|S|) dA`` (``dA = |S| dδ`` for a mean penetration ``δ``),
integrated by the trapezoidal rule over the steps, plus the tangential spring energy
``k_t ξ² / 2``.  (The closed form ``E A²/(2 l |S|)`` is exact only for a flat contact at
fixed ``l``; for a corner pressed into a face it is 25 % low.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fluidem import validate

from .broad_phase import grid_pairs
from .overlaps import WALL_IDS, clip_convex, polygon_overlaps, wall_overlaps

__all__ = ["ContactModel", "Contacts", "WALL_IDS", "grid_pairs", "clip_convex",
           "polygon_overlaps", "wall_overlaps", "contact_forces"]


@dataclass(frozen=True)
class ContactModel:
    """Material parameters of the polygon contact law.

    Parameters
    ----------
    E : float
        2D "Young's modulus" of the overlap law ``F = E A / l``, force/length (> 0; N/m
        in SI, dyn/cm in CGS): a 3D modulus times the unit depth of the 2D bodies.
    mu : float
        Coulomb friction coefficient (≥ 0).
    gamma : float
        Normal damping coefficient (≥ 0, dimensionless); the damping ratio of a contact is
        about ``(γ/2) √(|S|/l)``.
    gamma_t : float or None
        Tangential damping coefficient (dimensionless, ≥ 0); ``None`` uses ``gamma``.
    kt_ratio : float
        Tangential stiffness ``k_t = kt_ratio · E`` (force/length); 2/7 after Matuttis & Chen.

    Raises
    ------
    fluidem.errors.InputError
        (a ``ValueError``) A parameter out of range, named with its value.
    """

    E: float = 1e7
    mu: float = 0.23
    gamma: float = 0.025
    gamma_t: float | None = None
    kt_ratio: float = 2.0 / 7.0

    def __post_init__(self):
        set_ = object.__setattr__  # frozen: store the checked values once
        set_(self, "E", validate.positive("ContactModel(E=...)", self.E))
        set_(self, "mu", validate.nonnegative("ContactModel(mu=...)", self.mu))
        set_(self, "gamma", validate.nonnegative("ContactModel(gamma=...)", self.gamma))
        if self.gamma_t is not None:
            set_(self, "gamma_t", validate.nonnegative("ContactModel(gamma_t=...)", self.gamma_t))
        set_(self, "kt_ratio", validate.positive("ContactModel(kt_ratio=...)", self.kt_ratio))

    @property
    def kt(self) -> float:
        """Tangential spring stiffness ``kt_ratio · E``, force/length (N/m in SI)."""
        return self.kt_ratio * self.E

    @property
    def gt(self) -> float:
        """Tangential damping coefficient in use (``gamma_t``, or ``gamma`` when that is None)."""
        return self.gamma if self.gamma_t is None else self.gamma_t


@dataclass
class Contacts:
    """Contacts of one step, one entry per touching pair.

    Attributes
    ----------
    i : (n,) int
        First body (always a body index).
    j : (n,) int
        Second body index, or a wall id < 0 (see :data:`WALL_IDS`).
    point : (n, 2) float
        Point of action (overlap centroid), length.
    normal : (n, 2) float
        Unit normal pointing from ``j`` towards ``i``.
    normal_force : (n, 2) float
        Normal force on ``i`` (``j`` feels the opposite), force (N in SI).
    tangential_force : (n, 2) float
        Tangential (friction) force on ``i``, force.
    area : (n,) float
        Overlap area, length².
    length : (n,) float
        Characteristic length ``l``, length.
    chord : (n,) float
        Distance ``|S|`` between the two intersection points, length.
    xi : (n,) float
        Tangential spring elongation, length.
    sliding : (n,) bool
        True where the Coulomb cap is active.
    work : (n,) float
        Work done so far by the elastic normal force of the contact, force·length (J in
        SI): the stored normal
        elastic energy (trapezoidal rule of ``∫ (F_el/|S|) dA``, ``dA = |S| dδ``).
    shift : (n, 2) float
        In a periodic box, the shift of body ``j`` to its image nearest ``i``
        (:mod:`fluidem.dem.periodic`), length; ``point`` lies at ``i``, so ``point − (x_j + shift)``
        is the arm of ``j``'s force.  Zero for walls and outside periodic boxes.
    """

    i: np.ndarray
    j: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    area: np.ndarray
    length: np.ndarray
    chord: np.ndarray
    xi: np.ndarray
    sliding: np.ndarray
    work: np.ndarray
    key: np.ndarray = field(repr=False, default=None)
    shift: np.ndarray = field(repr=False, default=None)

    def __post_init__(self):
        if self.shift is None:
            self.shift = np.zeros((len(self.i), 2))

    def __len__(self) -> int:
        return len(self.i)

    @classmethod
    def empty(cls) -> "Contacts":
        z = np.zeros(0)
        z2 = np.zeros((0, 2))
        zi = np.zeros(0, dtype=np.int64)
        return cls(zi, zi, z2, z2, z2, z2, z, z, z, z, np.zeros(0, bool), z, zi, z2)

    def select(self, mask) -> "Contacts":
        return Contacts(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))

    @staticmethod
    def concat(parts) -> "Contacts":
        parts = list(parts)
        return Contacts(*(np.concatenate([getattr(p, f) for p in parts])
                          for f in Contacts.__dataclass_fields__))


def pair_key(i, j):
    """Integer key of a pair for the tangential history (j may be a wall id ≥ −8)."""
    return (np.asarray(i, np.int64) << 32) | (np.asarray(j, np.int64) + 8)


# ---------------------------------------------------------------------------------------
# force law
# ---------------------------------------------------------------------------------------
def _perp(v):
    return np.column_stack([-v[:, 1], v[:, 0]])


def contact_forces(ov: dict, pos, vel, omega, mass, free, model: ContactModel, dt: float,
                   history: dict) -> Contacts:
    """Forces of the overlap law for pairs (body–body, or body–wall when ``ov['j'] < 0``).

    Parameters
    ----------
    ov : dict
        Output of :func:`polygon_overlaps` or :func:`wall_overlaps` (with ``shift``, the
        periodic image of ``j`` is taken).
    pos, vel : (N, 2) float
        Positions (length) and velocities (length/time) of the bodies.
    omega : (N,) float
        Angular velocities, rad/time.
    mass : (N,) float
        Masses (mass units).
    free : (N,) bool
        Free bodies (the others count as infinitely heavy in ``m_eff``).
    model : ContactModel
    dt : float
        Step for the tangential spring increment, time units (0 for a force evaluation without
        advancing the spring).
    history : dict
        The contacts of the previous step: ``key`` (sorted), ``xi``, ``area``, ``g``
        (``F_el/|S|``) and ``work``, each (H,).

    Returns
    -------
    Contacts
    """
    i, j = ov["i"], ov["j"]
    wall = j < 0
    jb = np.where(wall, i, j)  # harmless index for walls
    shift = ov["shift"] if "shift" in ov else np.zeros((len(i), 2))
    pj = pos[jb] + shift  # j's centre, at its image nearest i
    c = ov["centroid"]
    ri_v = c - pos[i]
    rj_v = c - pj
    ri = np.sqrt((ri_v**2).sum(axis=1))
    rj = np.sqrt((rj_v**2).sum(axis=1))
    # characteristic length, Matuttis & Chen: 1/l = (r_i + r_j)/(4 r_i r_j); wall: r_j → ∞
    with np.errstate(invalid="ignore", divide="ignore"):
        length = np.where(wall, 4.0 * ri, 4.0 * ri * rj / (ri + rj))
    S = ov["p2"] - ov["p1"]
    chord = np.sqrt((S**2).sum(axis=1))
    # normal: perpendicular to the chord, oriented from j towards i
    with np.errstate(invalid="ignore", divide="ignore"):
        n = _perp(S) / chord[:, None]
    dji = pos[i] - pj
    bad = ~np.isfinite(n).all(axis=1) | (ov["ncross"] < 2)
    if np.any(bad):  # degenerate chord: fall back to the line of centres
        dn = np.sqrt((dji**2).sum(axis=1))[:, None]
        n[bad] = dji[bad] / np.where(dn[bad] > 0, dn[bad], 1.0)
        chord = np.where(bad, np.sqrt(ov["area"]), chord)
    if "normal" in ov:
        n = np.where(wall[:, None], ov["normal"], n)
    flip = np.einsum("ij,ij->i", n, dji) < 0
    n = np.where((flip & ~wall)[:, None], -n, n)
    t = _perp(n)
    # relative velocity of i with respect to j at the contact point
    vi = vel[i] + omega[i][:, None] * _perp(ri_v)
    vj = np.where(wall[:, None], 0.0, vel[jb] + omega[jb][:, None] * _perp(rj_v))
    vr = vi - vj
    vn = -np.einsum("ij,ij->i", vr, n)          # approach speed (> 0 when closing)
    vt = np.einsum("ij,ij->i", vr, t)
    mi, mj = mass[i], mass[jb]
    fi, fj = free[i], free[jb] & ~wall
    meff = np.where(fi & fj, mi * mj / (mi + mj), np.where(fi, mi, mj))
    A = ov["area"]
    E = model.E
    f_el = E * A / length
    f_d = model.gamma * np.sqrt(meff * E) * chord * vn / length
    fn = np.maximum(f_el + f_d, 0.0)
    # Cundall–Strack tangential spring with history
    key = pair_key(i, j)
    xi = np.zeros(len(i))
    A0 = np.zeros(len(i))
    g0 = np.zeros(len(i))
    W0 = np.zeros(len(i))
    hk = history["key"]
    if len(hk):
        p = np.minimum(np.searchsorted(hk, key), len(hk) - 1)
        hit = hk[p] == key
        ph = p[hit]
        xi[hit] = history["xi"][ph]
        A0[hit] = history["area"][ph]
        g0[hit] = history["g"][ph]
        W0[hit] = history["work"][ph]
    # stored normal elastic energy: W += ½ (g_old + g_new)(A_new − A_old), g = F_el/|S|
    g = f_el / chord
    work = W0 + 0.5 * (g0 + g) * (A - A0)
    xi = xi + vt * dt
    kt = model.kt
    ft = -kt * xi - model.gt * np.sqrt(meff * kt) * vt
    cap = model.mu * fn
    sliding = np.abs(ft) > cap
    ft = np.where(sliding, np.sign(ft) * cap, ft)
    xi = np.where(sliding, -ft / kt, xi)
    return Contacts(i=i, j=j, point=c, normal=n, normal_force=fn[:, None] * n,
                    tangential_force=ft[:, None] * t, area=A, length=length, chord=chord,
                    xi=xi, sliding=sliding, work=work, key=key, shift=shift)
