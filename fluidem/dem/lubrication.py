"""Lubrication correction between bodies closer than the mesh resolves (bodies in a fluid).

Two no-slip bodies approaching each other squeeze the fluid out of the gap between them; in 2D
the film's resistance grows as ``g^(-3/2)`` with the gap ``g``, so it decelerates the bodies
long before they touch (Hillairet 2007: never, in finite time).  A mesh of size h resolves that
film quasi-statically down to a fraction of h, how far depends on the element pair
(``benchmarks/bench_narrow_gap.py``, ``benchmarks/results/narrow_gap.md``), but a fluid step of
the usual size cannot follow it in time once the gap closes by more than itself in one step.
This module adds the film force in the DEM sub-steps, which follow the gap continuously: the
whole law below a cut-off (the default of :mod:`fluidem.coupling.contacts`), or only the part the
mesh misses quasi-statically.

Law.  A cylinder of radius a approaching a plane wall at speed V through fluid of dynamic
viscosity μ, gap δ ≪ a (Reynolds' lubrication equation for the gap δ + x²/2a; the δ → 0 limit
of the bipolar solution, Jeffrey & Onishi 1981; REFERENCES.md "Free bodies in Stokes flow")::

    F⊥ = 3√2 π μ V (a/δ)^(3/2) = μ V L(δ),   L(δ) = 3√2 π (a/δ)^(3/2)     (Jeffrey & Onishi 1981)

Two cylinders of radii aᵢ, aⱼ have the gap δ + x²/2a* with the reduced radius
``a* = aᵢ aⱼ / (aᵢ + aⱼ)``, so the same law holds with a*.

Resolved part.  The measured resolved force of an element pair that under-resolves the film
follows the same law at a wider gap, ``L(√(δ² + δ_r²))``, with a *resolved-film length*
``δ_r`` of a few hundredths of h (Taylor–Hood on a fresh mesh: with the deficit added the force is
within a few per cent of the exact one from δ = h down to δ = h/50, where the resolved one alone
falls to half of it; on a dragged mesh the film is resolved less well, 0.7 of the exact force at
h/10).  The correction is the whole law (``δ_r`` None) or that deficit, continued to zero at the
cut-off ``g_c``::

    F = −c(g) Vₙ n,   c(g) = μ [D(g_e) − D(g_c)]₊,   D(g) = L(g) − L(√(g² + δ_r²)),   g_e = max(g, g_min)

with ``Vₙ`` the normal relative velocity of the two outlines at the point of closest approach
(negative while approaching) and ``n`` the unit vector from the other body (or the wall) towards
this one.  It is equal and opposite on a pair, so it keeps momentum, and it only dissipates
(``−c Vₙ² ≤ 0``).  With ``δ_r``, ``D`` falls as ``δ_r² g^(−7/2)`` for g ≫ δ_r, so the cut-off only
spares work; ``δ_r = 0`` (an element pair whose resolved film is at least the exact one, such as
P2+bubble/P1dc on the meshes measured) means no correction.  Below ``g_min`` the coefficient
stays at its value there (default the repulsion's range: below it the short-range repulsion of
:mod:`fluidem.dem.repulsion` holds bodies apart that a steady load drains towards each other).

Polygons.  Each body's radius is that of the disk of equal area, ``a = √(A/π)``: exact for the
regular many-sided polygons that stand for disks (to O(1/n²) for an n-gon); for angular bodies
an approximation (a face approaching a parallel face resists more, ∝ g⁻³).  The tangential
lubrication force (∝ (a/δ)^(1/2), Jeffrey & Onishi 1981) is weak and not modelled.

Sub-steps.  The DEM applies the correction implicitly at the end of each sub-step (backward Euler on
``M dV/dt = −C V``, :func:`implicit_damping`; :meth:`fluidem.dem.DEM.step`): the damping matrix
``C = Σ c G Gᵀ`` of all pairs, with the generalised normals ``G = (n, r × n)`` of both ends, so a film
acting off the centre line damps the turn as well.  It is stable at any ``c Δt / m``, first order in Δt
(measured: 9.0e-4 of the approach speed at Δt = 1e-5 in ``tests/dem/test_lubrication.py``, halving with
Δt), and the film's force does not depend on the sub-step.  Earlier versions integrated it explicitly,
capped at ``m*/Δt`` with the translational reduced mass: the turn's share ``c r² Δt / I`` came on top,
and a packed pile of polygons reached ``cΔt(1/m* + r²/I) > 2`` and blew up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validate
from .repulsion import _shift, approach_geometry, pair_gaps, wall_approaches

__all__ = ["Lubrication", "equal_area_radius", "generalised_normals", "implicit_damping", "lubrication_pairs"]

#: 3√2 π: the prefactor of the 2D squeeze-film force, F/(μV) = 3√2 π (a/δ)^(3/2).
SQUEEZE_FILM = 3.0 * np.sqrt(2.0) * np.pi


@dataclass(frozen=True)
class Lubrication:
    """Parameters of the lubrication correction (module docstring).

    Parameters
    ----------
    viscosity : float
        Dynamic viscosity μ = ρ_f ν of the fluid (per unit depth: mass/time), > 0.
    range : float
        Cut-off gap g_c, length, > 0: no correction at or above it.
    min_gap : float
        Regularisation gap g_min, length, 0 < g_min < g_c: the coefficient stays at its value
        there for smaller gaps and overlaps.
    resolved_gap : float or None
        Resolved-film length δ_r of the mesh, length, ≥ 0 (0: no correction); ``None`` the full
        law, ``D = L``, for a film the mesh does not resolve at all (as in the analytic tests).

    Examples
    --------
    With ``resolved_gap=None`` the correction at a gap of 0.001 from a wall (disk radius 0.1,
    cut-off 0.02) is the squeeze-film law 3√2π μ (a/g)^(3/2) less its value at the cut-off; a
    resolved-film length of 0.0005 leaves about a sixth of it:

    >>> full = Lubrication(viscosity=0.01, range=0.02, min_gap=1e-4)
    >>> c = float(full.coefficient(np.array([1e-3]), np.array([0.1]))[0])
    >>> round(c, 4), round(float(SQUEEZE_FILM * 0.01 * ((0.1 / 1e-3) ** 1.5 - (0.1 / 0.02) ** 1.5)), 4)
    (131.7963, 131.7963)
    >>> part = Lubrication(viscosity=0.01, range=0.02, min_gap=1e-4, resolved_gap=5e-4)
    >>> round(float(part.coefficient(np.array([1e-3]), np.array([0.1]))[0]) / c, 3)
    0.156
    >>> float(full.coefficient(np.array([0.02, 0.05]), np.array([0.1, 0.1])).max())
    0.0
    """

    viscosity: float
    range: float
    min_gap: float
    resolved_gap: float | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "viscosity", validate.positive("Lubrication(viscosity=...)", self.viscosity))
        set_(self, "range", validate.positive("Lubrication(range=...)", self.range))
        set_(self, "min_gap", validate.positive("Lubrication(min_gap=...)", self.min_gap))
        if self.min_gap >= self.range:
            raise validate.fail("Lubrication(min_gap=...)", self.min_gap,
                                f"a gap below the cut-off range = {self.range:g}")
        if self.resolved_gap is not None:
            set_(self, "resolved_gap", validate.nonnegative("Lubrication(resolved_gap=...)", self.resolved_gap))

    @property
    def active(self) -> bool:
        """Whether the correction can be non-zero (``resolved_gap`` is not 0)."""
        return self.resolved_gap is None or self.resolved_gap > 0

    def _deficit(self, g):
        """D(g)/a*^(3/2): the part of the law the mesh misses, per unit viscosity."""
        law = g ** -1.5
        if self.resolved_gap is None:
            return law
        return law - (g * g + self.resolved_gap**2) ** -0.75

    def coefficient(self, gap: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Damping coefficient c(g) (force per normal speed; per unit depth: mass/time).

        Parameters
        ----------
        gap : (P,) float
            Gaps between the outlines (negative: overlap), length.
        radius : (P,) float
            Reduced radii a* of the pairs (a body's own radius against a wall), length.
        """
        gap = np.asarray(gap, float)
        g = np.maximum(gap, self.min_gap)
        d = np.maximum(self._deficit(g) - self._deficit(self.range), 0.0)
        c = SQUEEZE_FILM * self.viscosity * np.asarray(radius, float) ** 1.5 * d
        return np.where(gap < self.range, c, 0.0)


def equal_area_radius(area: np.ndarray) -> np.ndarray:
    """Radius √(A/π) of the disk with each body's area (length); ``area`` (N,) length²."""
    return np.sqrt(np.asarray(area, float) / np.pi)


def lubrication_pairs(model: Lubrication, W: np.ndarray, pos: np.ndarray, i: np.ndarray, j: np.ndarray,
                      overlapping: np.ndarray, radius: np.ndarray, walls=None, movable: np.ndarray | None = None,
                      gaps=None, period: np.ndarray | None = None):
    """The pairs and body–wall pairs within the cut-off and their damping coefficients (module docstring).

    Parameters
    ----------
    model : Lubrication
    W : (N, K, 2) float
        Padded world outlines, length.
    pos : (N, 2) float
        Centres of mass, length.
    i, j : (P,) int
        Candidate pairs.
    overlapping : (P,) bool
        Pairs that overlap (the coefficient at ``min_gap``, along the centre line).
    radius : (N,) float
        Each body's lubrication radius (:func:`equal_area_radius`), length.
    walls, movable
        As in :func:`fluidem.dem.repulsion.repulsion_forces`.
    gaps : tuple or None
        ``pair_gaps(W, i, j, ...)`` already computed with a reach ≥ ``model.range`` (and the
        periodic shifts).
    period : (2,) float or None
        Periods of a periodic box (0 for a non-periodic axis), length: every pair sees the
        nearest image of its second body (:mod:`fluidem.dem.periodic`).

    Returns
    -------
    a, b : (M,) int
        The two bodies; ``b = -1`` for a wall.
    c : (M,) float
        Damping coefficient c(g), force per normal speed (uncapped).
    point : (M, 2) float
        Where the film acts, length (in a periodic box at ``a``: see :func:`implicit_damping`).
    normal : (M, 2) float
        Unit vector from ``b`` (or the wall) towards ``a``.
    """
    rows = []
    rho = model.range
    if len(i):
        shift = _shift(pos, i, j, period)
        p, q, d = gaps if gaps is not None else pair_gaps(W, i, j, shift=shift)
        gap = d.min(axis=1)
        near = (gap < rho) | overlapping
        if near.any():
            ii, jj, ov = i[near], j[near], overlapping[near]
            line = pos[ii] - pos[jj] - (0.0 if shift is None else shift[near])
            point, normal = approach_geometry(p[near], q[near], d[near], rho, line, ov)
            a_star = radius[ii] * radius[jj] / (radius[ii] + radius[jj])
            c = model.coefficient(np.where(ov, -np.inf, gap[near]), a_star)
            rows.append((ii, jj, c, point, normal))
    if walls is not None:
        for k, gap, point, normal in wall_approaches(W, walls, rho, movable):
            rows.append((k, np.full(len(k), -1), model.coefficient(gap, radius[k]), point, normal))
    if not rows:
        return (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2)))
    return tuple(np.concatenate(col) for col in zip(*rows))


def generalised_normals(pos: np.ndarray, body: np.ndarray, point: np.ndarray, normal: np.ndarray,
                        shift=0.0) -> np.ndarray:
    """(M, 3) generalised normal ``(n, r × n)`` of each pair's end on ``body``, ``r = point − (x_body + shift)``
    (``shift`` (M, 2): the periodic image of ``body`` the pair sees, length; 0 for none).

    The rate of the gap of a pair is ``−(g_aᵀ V_a − g_bᵀ V_b)`` for the velocities ``V = (U_x, U_y, ω)`` of its
    two bodies, and a normal force ``f n`` on ``a`` (``−f n`` on ``b``) is the generalised load ``f g_a``
    (``−f g_b``): force and torque about the centre of mass.
    """
    r = point - pos[body] - shift
    return np.column_stack([normal, r[:, 0] * normal[:, 1] - r[:, 1] * normal[:, 0]])


def implicit_damping(pairs, pos: np.ndarray, velocity: np.ndarray, mass: np.ndarray, inertia: np.ndarray,
                     free: np.ndarray, dt: float, period: np.ndarray | None = None) -> np.ndarray:
    """Velocities after the film's damping over ``dt`` by backward Euler, (N, 3).

    The damping force of all pairs is ``F = −C V``, ``C = Σ c G Gᵀ`` with ``G`` the pair's generalised
    normals (:func:`generalised_normals`, ``+g_a`` at ``a`` and ``−g_b`` at ``b``); backward Euler on
    ``M dV/dt = −C V`` solves

        (M_ff + Δt C_ff) V_f = M_ff V*_f − Δt C_fk V_k                       (implicit Euler)

    for the free bodies ``f``, the others' velocities ``V_k`` given (prescribed, fixed, walls).  It is
    stable at any ``c Δt / m``, dissipates (``Vᵀ C V ≥ 0``), keeps the momentum of a pair of free bodies and
    never reverses an approach of one body to a wall (``V ← V/(1 + cΔt/m)``), where the explicit damper
    needs ``cΔt/m* < 2`` with the generalised reduced mass of the pair, rotation included.

    Parameters
    ----------
    pairs : tuple
        ``(a, b, c, point, normal)`` of :func:`lubrication_pairs`.
    pos : (N, 2) float
        Centres of mass, length.
    velocity : (N, 3) float
        ``V*`` before the damping (U_x, U_y, ω).
    mass, inertia : (N,) float
        Masses and moments of inertia of the bodies.
    free : (N,) bool
    dt : float
        Time.
    period : (2,) float or None
        Periods of a periodic box (0 for a non-periodic axis), length: the arm of ``b`` is taken
        about its image nearest ``a`` (:mod:`fluidem.dem.periodic`), where ``point`` lies.
    """
    a, b, c, point, normal = pairs
    V = np.array(velocity, float)
    act = c > 0
    if not act.any() or dt <= 0:
        return V
    a, b, c, point, normal = a[act], b[act], c[act], point[act], normal[act]
    wall = b < 0
    bb = np.where(wall, a, b)
    ga = generalised_normals(pos, a, point, normal)
    s = _shift(pos, a, bb, period)
    gb = np.where(wall[:, None], 0.0, -generalised_normals(pos, bb, point, normal, 0.0 if s is None else s))
    # the bodies the film touches, numbered compactly: unknowns of the free ones, given the others
    body, slot = np.unique(np.concatenate([a, bb]), return_inverse=True)
    sa, sb = slot[: len(a)], slot[len(a):]
    isfree = free[body]
    if not isfree.any():
        return V
    # the system in the free bodies' unknowns only: ``fs`` numbers them 0 … n_f − 1 (−1: given)
    fs = np.cumsum(isfree) - 1
    fs[~isfree] = -1
    nf = int(isfree.sum())
    v = V[body]
    m3 = np.column_stack([mass[body], mass[body], inertia[body]])[isfree]
    rhs = m3 * v[isfree]  # (n_f, 3): M_ff V*_f …
    dof3 = np.arange(3)
    rows, cols, vals = [], [], []
    ends = ((fs[sa], sa, ga), (fs[sb], sb, gb))
    for f1, _, g1 in ends:
        cg1 = c[:, None] * g1
        for f2, s2, g2 in ends:
            ff = (f1 >= 0) & (f2 >= 0)
            blk = cg1[ff, :, None] * g2[ff, None, :]  # c g₁ g₂ᵀ (P, 3, 3)
            rows.append((3 * f1[ff, None, None] + dof3[None, :, None]).repeat(3, axis=2).ravel())
            cols.append((3 * f2[ff, None, None] + dof3[None, None, :]).repeat(3, axis=1).ravel())
            vals.append(blk.ravel())
            fk = (f1 >= 0) & (f2 < 0)  # … − Δt C_fk V_k
            if fk.any():
                np.add.at(rhs, f1[fk], -dt * cg1[fk] * (g2[fk] * v[s2[fk]]).sum(axis=1)[:, None])
    rows, cols, vals = np.concatenate(rows), np.concatenate(cols), dt * np.concatenate(vals)
    diag = np.arange(3 * nf)
    rows, cols = np.concatenate([rows, diag]), np.concatenate([cols, diag])
    vals = np.concatenate([vals, m3.ravel()])
    if nf <= 64:  # a few clusters: dense is cheaper than building a sparse matrix
        A = np.zeros((3 * nf, 3 * nf))
        np.add.at(A, (rows, cols), vals)
        vf = np.linalg.solve(A, rhs.ravel())
    else:
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        A = sp.csc_matrix((vals, (rows, cols)), shape=(3 * nf, 3 * nf))  # duplicates summed
        vf = spla.spsolve(A, rhs.ravel())
    v[isfree] = vf.reshape(nf, 3)
    V[body] = v
    return V
