"""Granular benchmarks of the DEM: angle of repose of a poured heap, dry column collapse.

Material for both: random convex polygons (5–7 corners, sizes 0.8–1 cm, elongation
1–1.4), ρ = 10 kg/m², the same μ for grain–grain and grain–floor contacts, on a rough
floor of fixed grains.  γ = 1 (restitution 0.30 for flat faces; corner impacts stay
much livelier because the damping scales with the contact length): with γ = 0.3 the
grains kept bouncing and a poured heap spread to a few degrees.

Measured (seed 0, E = 2000 N/m, 1 s of settling; printed by the tests with ``-s``):

=====  ===================================  =====================
 μ     angle of repose (500 grains poured)  coordination number
=====  ===================================  =====================
 0.1   14.7°  (flanks 13.4°, 16.0°)         4.06
 0.3   19.5°  (flanks 18.3°, 20.6°)         3.79
 0.6   22.6°  (flanks 24.5°, 20.8°)         3.61
=====  ===================================  =====================
The heaps are at rest after 1.5 s (below); settled, their angles are 15.2°, 19.5° and 23.7°
(coordination 4.08, 3.79, 3.61), unchanged to 0.01° up to 5 s.  Before the contact forces of a
step saw the mid-step velocity (:mod:`fluidem.dem.system`, "Velocity") the 1 s figures were
12.7°, 22.2°, 28.2° (z = 4.01, 3.71, 3.41) of heaps that then crept (below).
E = 2000 N/m is soft on purpose (the number of steps grows as √E): E/(ρ g d) = 2000, so
the static overlap areas stay around 1 % of a grain's area (depth ~0.3 % of its size) at
the bottom of these ≤ 40-grain-high deposits, small enough for the overlap-area law.
One grain of the μ = 0.6 pour rolls off the end of the floor (x = −0.4 m) about 0.57 s after
the last batch and falls for ever (it stays one of the 500 free grains); the kinetic
energies below and in the tests are those of the grains above the floor (:func:`heap_kinetic_energy`).

Coming to rest (seed 0; the heap poured as :func:`pour_heap`, then settled in windows of 0.05 s
up to 5 s as :func:`settle_more` does, so the figures up to 2 s are those of the tests):
99th-percentile grain displacement per 0.05 s (D) / kinetic energy (J) at t s of settling after
the last batch, the fitted angle, and the fraction of the contacts at the Coulomb limit
(``sim.contacts.sliding``):

=====  ===============  ================  ================  ================  ====================  ===============
 μ     t = 1            1.5               2                 3                 angle at 1/2/3/5 s    Coulomb 1/2/5 s
=====  ===============  ================  ================  ================  ====================  ===============
 0.1   0.21 / 7.8e-6    6.7e-5 / 2.0e-10  1.0e-5 / 6.2e-10  8.9e-6 / 1.7e-10  14.7/15.2/15.2/15.2°  6.0/0.28/0.28 %
 0.3   7.6e-2 / 6.5e-7  4.8e-4 / 7.8e-9   2.8e-4 / 1.4e-9   6.4e-5 / 1.6e-11  19.5/19.5/19.5/19.5°  4.1/0.20/0 %
 0.6   0.24 / 2.3e-5    4.9e-4 / 5.9e-9   6.3e-4 / 9.6e-10  1.3e-4 / 3.9e-11  22.6/23.7/23.7/23.7°  2.8/0.11/0 %
=====  ===============  ================  ================  ================  ====================  ===============

Before the change (predictor velocity): 0.15 / 6.4e-6, 3.1e-3 / 5.8e-9, 1.6e-2 / 1.4e-8,
1.2e-3 / 1.1e-9 (μ = 0.1); 1.8e-2 / 2.2e-7, 9.6e-3 / 1.4e-7, 1.5e-2 / 1.3e-7, 1.6e-2 / 1.7e-7
(μ = 0.3); 0.12 / 3.5e-5, 0.21 / 5.1e-5, 0.18 / 2.9e-5, 0.13 / 2.8e-5 (μ = 0.6, angle
28.2/20.9/17.9/15.4°), with 35–50 % of the contacts at the Coulomb limit at 1 s.

Decay rates (1/s), expected from the contact law against measured:

=====  ===============================  ==============================  ================  =========================
 μ     expected, contacts stuck         expected, Coulomb-limit         measured arrest   measured
       (slowest mode; zero modes)       contacts free to slip           0.55 s → rest     1–3 s / 2–5 s (KE)
=====  ===============================  ==============================  ================  =========================
 0.1   2.2  (ω 108 rad/s); 1 zero mode  2.2  (3 of 1074 contacts slip)  6.1 (KE 12)       4.1 / 0.6  (4.0 / 1.0)
 0.3   0.51 (ω 50 rad/s); 4 zero modes  0.51 (2 of 994 contacts slip)   10  (KE 17)       1.9 / 0.8  (2.8 / 1.5)
 0.6   0.59 (ω 54 rad/s); 4 zero modes  0.59 (1 of 947 contacts slips)  9.7 (KE 10)       2.2 / 1.5  (5.2 / 3.2)
=====  ===============================  ==============================  ================  =========================

Expected (computed for these heaps, the pickled states after 2 s of settling): the contact network
linearised (normal spring E|S|/l and dashpot γ√(m_eff E)|S|/l, tangential spring κE and dashpot
γ√(m_eff κE) per contact, acting on the relative velocity at the overlap centroid, lever arms from
the centres; ``M ẍ + C ẋ + K x = 0`` on the x, y, θ of the 500 (μ = 0.6: 499) grains above the
floor, floor grains fixed; largest real part of the nonzero eigenvalues of the first-order
system).  The geometric stiffness (normals, lever arms and contact points turning with the poses
under the static forces) is neglected.  The same assembly for one square on the floor gives the
23.7 1/s of ``test_dem_rest.slowest_linear_decay(1)``.  The damping is stiffness proportional
(c/k = γ√(m_eff/E) ≈ 4e-4 s), so a mode of frequency ω decays at ≈ 2e-4 ω² 1/s.  The slowest modes, at
ω ≈ 108/50/54 rad/s, are not collective: they sit on one to a few grains held by two contacts
(participation ratio 1.6/4.6/2.3 grains).  Freeing the tangential spring and dashpot of the
0.1–0.3 % of contacts at the Coulomb limit changes nothing (rates equal to 1e-6, no new zero
mode).  The zero modes, in both variants, are the rocking of the grains held by a single contact
(1/3/4 of them) about their contact point, plus for μ = 0.3 one of two grains with two contacts:
the linear law has no restoring force for them (as for the rocking of a single block; the real law
restores it through the shift of the overlap centroid, i.e. the neglected geometric stiffness).
At 5 s the contacts are the same and the rates 2.2/0.51/0.58 1/s.  For comparison, the heaps
poured with the predictor velocity, linearised at 1 s, gave 1.7/1.9/0.12 1/s stuck and 20–78
mechanisms with the 35–50 % of contacts then sliding free to slip.

Measured: the rate of the arrest of the last surface avalanches (log-slope of the
99th-percentile move, of KE in brackets, from 0.55 s to the first window below 5e-3 D, at
1.30/1.10/1.20 s) is faster than any elastic prediction: it is friction stopping a flow, not a
mode ringing down.  (Measured on the same pour continued in 0.05 s windows from 0.5 s, 3 steps
shorter at 1 s than the tests' heap; from 1 s on its moves agree with those above to within
10 % and its angles to 0.01°.)  After it the three heaps are at rest and the residual motion
keeps decaying: fitted over 2–5 s, 0.6–1.5 1/s for the move (KE 1.6–2.1 times as fast, as for a
linear ringing-down), of the order of the slowest modes of these heaps' linearised networks
(2.2/0.51/0.59 1/s) but not equal to them: 0.28, 1.6 and 2.5 times those rates for μ = 0.1,
0.3, 0.6, so for μ = 0.1 slower than any mode of the stuck network; the flank angles no longer
change, and 0–0.3 % of the contacts remain at the Coulomb limit (3–6 % at 1 s, 29–79 % at 0.5 s
while the surface still flows).

The creep measured before was the integrator's, not that of Coulomb mechanisms: the forces of a
step saw the predictor velocity v_n + a_n dt, which feeds a_n back into a_{n+1} through the
dashpots, a period-2 oscillation that grows once c dt/m > 1, reached by the grains of a heap
through their rotational damping (:mod:`fluidem.dem.system`, "Velocity").  With it, 35–50 % of
the contacts sat at the Coulomb limit at 1 s (3–6 % now), μ = 0.3 kept rearranging (0.01–0.06 D
per 0.05 s, no decay up to 5 s) and μ = 0.6 crept as a whole (grains rolling, flank angle 28.2°
at 1 s, 15.4° at 5 s); the zero-frequency mechanisms of the linearised network were read as the
cause.  With the mid-step velocity the same contact law brings all three heaps to rest.
(Measured with scripts outside the suite; the tests below keep the 1.5–2 s figures.)
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fluidem.cases.collapse import D, E_SOFT, GAMMA, collapse, lube, rough_floor
from fluidem.cases.collapse import frozen as _frozen, grain as _grain
from fluidem.dem import ContactModel, DEM


def pour_heap(mu, n=500, batch=15, seed=0, settle=1.0, every=0.03):
    """Pour ``n`` grains in batches of ``batch`` onto a rough floor from a nozzle at x = 0
    kept 1.5 grain sizes above the heap top, then let the heap settle for ``settle`` seconds.

    Returns the simulation (grains first; the fixed floor grains follow them).
    """
    rng = np.random.default_rng(seed)
    model = ContactModel(E=E_SOFT, mu=mu, gamma=GAMMA)
    floor = rough_floor(rng)
    cols = 5
    sim = DEM(floor, walls=None, contact=model)
    poured = 0
    while poured < n:
        x, y = sim.positions[:, 0], sim.positions[:, 1]
        top = float(np.max(y[np.abs(x) < 3 * D]))
        k = min(batch, n - poured)
        new = [_grain(rng, ((c % cols - (cols - 1) / 2) * 1.1 * D + rng.uniform(-0.05, 0.05) * D,
                            top + 1.5 * D + (c // cols) * 1.1 * D)) for c in range(k)]
        sim.add_bodies(new)
        poured += k
        sim.run(sim.time + every, sim.dt_max)
    sim.run(sim.time + settle - 0.05, sim.dt_max)
    _frozen(sim)                    # the last 0.05 s: measure how much grains still move
    return sim


def repose_angle(sim):
    """Angle of the two outer flanks (degrees), averaged.

    Surface = the highest free grain in each one-grain-wide column on either side of the
    median x; on each side, a straight line is fitted through the surface points lying
    outward of the outermost point above 80 % of the heap height and above 20 % of it.
    """
    free = sim.free
    x, y = sim.positions[free, 0], sim.positions[free, 1]
    xc = float(np.median(x))
    hmax = y.max()
    angles = []
    for side in (-1, 1):
        sel = side * (x - xc) > 0
        xs, ys = side * (x[sel] - xc), y[sel]
        bins = np.floor(xs / D).astype(int)
        order = np.lexsort((-ys, bins))                  # per column, highest first
        first = np.r_[True, bins[order][1:] != bins[order][:-1]]
        px, py = xs[order][first], ys[order][first]
        x80 = px[py >= 0.8 * hmax].max()
        keep = (px > x80) & (py > 0.2 * hmax)
        slope = np.polyfit(px[keep], py[keep], 1)[0]
        angles.append(float(np.degrees(np.arctan(-slope))))
    return float(np.mean(angles)), angles


def heap_kinetic_energy(sim):
    """Kinetic energy (J) of the free grains above the floor (y > 0), leaving out a grain that
    rolled off the end of the floor and falls (one in the μ = 0.6 pour)."""
    on = sim.free & (sim.positions[:, 1] > 0)
    v = sim.velocities[on]
    return float(0.5 * (sim.mass[on] * (v * v).sum(axis=1)).sum()
                 + 0.5 * (sim.inertia[on] * sim.omegas[on] ** 2).sum())


_HEAPS: dict = {}


def heap(mu):
    """Poured heap for friction ``mu`` (1 s of settling), computed once per test session."""
    if mu not in _HEAPS:
        _HEAPS[mu] = pour_heap(mu)
    return _HEAPS[mu]


REPOSE_MUS = (0.1, 0.3, 0.6)


@pytest.mark.slow
@pytest.mark.parametrize("mu", REPOSE_MUS)
def test_poured_heap_is_a_symmetric_heap(mu):
    sim = heap(mu)
    ang, sides = repose_angle(sim)
    off = int((sim.positions[sim.free, 1] < 0).sum())
    print(f"\nmu={mu}: angle {ang:.1f} deg (flanks {sides[0]:.1f}, {sides[1]:.1f}), "
          f"KE/grain {heap_kinetic_energy(sim) / (500 - off):.2e} J, z = {sim.coordination_number():.2f}, "
          f"t = {sim.time:.2f} s, 99th percentile move in the last 0.05 s {sim.last_move / D:.1e} D, "
          f"{off} grain(s) off the floor")
    assert sim.free.sum() == 500
    assert abs(sides[0] - sides[1]) < 10.0                  # a heap, not a pile on one side


_SETTLED: dict = {}


def settle_more(mu, duration=1.0, window=0.05):
    """Continue a copy of the poured heap :func:`heap` (``mu``, 1 s of settling) for
    ``duration`` seconds in windows of ``window`` seconds; the cached heap is left as it is.

    Returns the simulation (cached per ``mu``, ``duration``, ``window``) and, per window, the
    time of settling at its end (s, from the last batch), the 99th-percentile grain displacement
    (in D) and :func:`heap_kinetic_energy` at its end (J).  About 45 s of CPU per heap and second.
    """
    key = (mu, duration, window)
    if key not in _SETTLED:
        sim = copy.deepcopy(heap(mu))
        times, moves, kes = [], [], []
        for k in range(int(round(duration / window))):
            _frozen(sim, window)
            times.append(1.0 + (k + 1) * window)
            moves.append(sim.last_move / D)
            kes.append(heap_kinetic_energy(sim))
        _SETTLED[key] = sim, np.array(times), np.array(moves), np.array(kes)
    return _SETTLED[key]


#: Measured over 1.5–2 s of settling: median over the 0.05 s windows of the 99th-percentile grain
#: displacement (D) and of the kinetic energy of the grains on the floor (J).
REST = ((0.1, 2.2e-5, 6.1e-10), (0.3, 2.3e-4, 2.1e-9), (0.6, 5.4e-4, 1.9e-9))


@pytest.mark.slow
@pytest.mark.parametrize("mu, move, ke", REST, ids=[str(r[0]) for r in REST])
def test_poured_heap_comes_to_rest(mu, move, ke):
    """The poured heaps come to rest: their last surface avalanches stop at 1.1–1.3 s of
    settling, and over 1.5–2 s the median over the 0.05 s windows of the 99th-percentile grain
    displacement is 2.2e-5, 2.3e-4 and 5.4e-4 D (μ = 0.1, 0.3, 0.6; windows 8e-6 … 1.2e-3 D), and
    that of the kinetic energy 6.1e-10, 2.1e-9 and 1.9e-9 J (module docstring, "Coming to rest").

    Before the forces saw the mid-step velocity the μ = 0.3 and 0.6 heaps crept (0.013 and
    0.245 D per 0.05 s over 1–1.5 s, no decay up to 5 s) and μ = 0.1 was at rest at 1.9e-3 D.
    The bounds are 2.5× the measured values.
    """
    sim, times, moves, kes = settle_more(mu)
    late = times > 1.5 + 1e-9
    print(f"\nmu={mu}, t = {sim.time:.2f} s: over 1.5-2 s of settling, median of the 99th-percentile move per "
          f"0.05 s {np.median(moves[late]):.2e} D (max {moves[late].max():.2e}; measured {move:.1e}), KE median "
          f"{np.median(kes[late]):.2e} J (measured {ke:.1e}); over 1-1.5 s {np.median(moves[~late]):.2e} D")
    assert np.median(moves[late]) < 2.5 * move
    assert np.median(kes[late]) < 2.5 * ke


@pytest.mark.slow
def test_angle_of_repose_grows_with_friction():
    """On the settled heaps (2 s): 15.2°, 19.5°, 23.7° for μ = 0.1, 0.3, 0.6 (14.7°, 19.5°, 22.6°
    at 1 s).  Before the change the order held only at 1 s: the μ = 0.6 heap crept to 15.4° by 5 s."""
    a = [repose_angle(settle_more(mu)[0])[0] for mu in REPOSE_MUS]
    a1 = [repose_angle(heap(mu))[0] for mu in REPOSE_MUS]
    print(f"\nangles of repose at 2 s {', '.join(f'{x:.2f}' for x in a)} deg "
          f"(at 1 s {', '.join(f'{x:.2f}' for x in a1)})")
    assert a[0] < a[1] < a[2]


#: Normalised runout (L∞ − L0)/L0 measured with :func:`fluidem.cases.collapse.collapse`
#: (μ = 0.5, seed 1; at least 10 grains across the smaller side) against Lube et al. (2005);
#: ``benchmarks/bench_dem_collapse.py`` writes ``benchmarks/results/column_collapse.md`` with the
#: same calls, so the tests reproduce its rows exactly.  Before the contact forces saw the mid-step
#: velocity (:mod:`fluidem.dem.system`, "Velocity") the runouts were 0.60 / 1.20 / 3.10 / 5.68 and
#: the deposits still moved 0.03–0.12 D per 0.05 s at the end; now they are at rest.
#:
#: =====  ===========  ======  =====  ========  ===============  ===================================
#: a      (L∞−L0)/L0   Lube    ratio  packing   last 0.05 s      grains, wall time on the shared machine
#: =====  ===========  ======  =====  ========  ===============  ===================================
#: 0.51   0.65         0.61    1.06   0.827     3.2e-5 D         376 (L0 = 20 grains), 3 min
#: 1.03   1.19         1.23    0.97   0.819     1.2e-5 D         189, 2 min
#: 1.95   3.10         2.34    1.33   0.838     5.8e-5 D         379, 3 min
#: 3.73   6.53         4.57    1.43   0.867     1.8e-4 D         749, 6 min
#: =====  ===========  ======  =====  ========  ===============  ===================================
#:
#: (packing: solid fraction of the settled column, :func:`fluidem.cases.collapse.packing_fraction`.)
#: Only a = 1 runs in the test suite (time budget): a = 2 and 4 miss the 20 % band with the
#: protocol of :func:`collapse` (the 2D polygons run out 33–43 % further than Lube's sand for
#: a ≳ 2), which the benchmark reports; a = 2 ran here as a non-strict expected failure, 2–8 min
#: of the suite that could not fail.
COLUMN_ASPECTS = (1.0,)


@pytest.mark.slow
@pytest.mark.parametrize("aspect", COLUMN_ASPECTS)
def test_column_collapse_runout_follows_lube(aspect):
    # at least 10 grains across the smaller side of the column
    a, runout, sim, t_flow = collapse(aspect, width_grains=int(round(max(10, 10 / aspect))))
    print(f"\na = {a:.2f}: (L_inf - L0)/L0 = {runout:.2f}, Lube {lube(a):.2f}, ratio "
          f"{runout / lube(a):.2f}, {sim.free.sum()} grains, flow time {t_flow:.2f} s, "
          f"99th-percentile move in the last 0.05 s {sim.last_move / D:.1e} D")
    assert runout == pytest.approx(lube(a), rel=0.2)
