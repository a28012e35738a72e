"""Lubrication correction (fluidem.dem.lubrication): the squeeze-film law below the cut-off, integrated by
the DEM, against the exact solution of the approach it alone decelerates."""

import numpy as np
import pytest

from fluidem.dem import DEM, Body, ContactModel
from fluidem.dem.lubrication import SQUEEZE_FILM, Lubrication, equal_area_radius
from fluidem.geometry import regular_polygon

R, MU, G_C = 0.1, 0.01, 0.02  # disk radius, dynamic viscosity, cut-off
DISK = regular_polygon(R, 96)


def _approach_speed(g, g0, V0, m, a):
    """Exact approach speed at gap g of a body of mass m decelerated only by the correction, from V0 at g0.

    m dV/dt = −c(g) V with dg/dt = −V gives m dV = c(g) dg, so with c = K (g^(−3/2) − g_c^(−3/2)),
    K = 3√2π μ a^(3/2):  V(g) = V0 − (K/m) [2 (g^(−1/2) − g0^(−1/2)) − (g0 − g) g_c^(−3/2)]."""
    K = SQUEEZE_FILM * MU * a**1.5
    return V0 - (K / m) * (2.0 * (g**-0.5 - g0**-0.5) - (g0 - g) * G_C**-1.5)


def _dem(bodies, walls=None, min_gap=1e-5):
    lub = Lubrication(viscosity=MU, range=G_C, min_gap=min_gap)
    return DEM(bodies, walls=walls, gravity=(0.0, 0.0), contact=ContactModel(E=1e4, mu=0.0, gamma=0.0),
               lubrication=lub)


def _gap_to_floor(sim):
    return float(sim.world_vertices()[0, :, 1].min())


def _wall_approach_error(dt, V0=2.0, g0=0.019, duration=0.03):
    """Largest |V − V_exact| / V0 while V > 0.1 V0 and the smallest gap of a 96-gon released towards the floor."""
    body = Body.polygon(DISK, density=1.0, velocity=(0.0, -V0))
    body.position = np.array([0.5, g0 - DISK[:, 1].min()])
    sim = _dem([body], walls=(-np.inf, np.inf, 0.0, np.inf))
    assert _gap_to_floor(sim) == pytest.approx(g0, rel=1e-12)
    m, a = sim.mass[0], equal_area_radius(sim.area)[0]
    rows = []
    for _ in range(int(round(duration / dt))):
        sim.step(dt)
        rows.append((_gap_to_floor(sim), -sim.velocities[0, 1]))
    r = np.array(rows)
    moving = r[:, 1] > 0.1 * V0
    err = np.abs(r[moving, 1] - _approach_speed(r[moving, 0], g0, V0, m, a)).max() / V0
    assert np.abs(sim.velocities[0, 0]) < 1e-12 and abs(sim.omegas[0]) < 1e-9
    return err, r[:, 0].min()


def test_disk_approaching_a_wall_follows_the_exact_squeeze_film_deceleration():
    """A disk (96-gon, a = √(A/π)) released towards the floor at 2 from the gap 0.019 < g_c slows down as
    the exact solution of m dV/dg = c(g) says, and stops near g = 0.0033 without touching.  The damper
    sees the mid-step velocity (velocity Verlet, :meth:`fluidem.dem.DEM.step`), so the error is first
    order in Δt.  Measured: largest |V − V_exact| / V0 while V > 0.1 V0 1.17e-3 (Δt = 1e-5) and
    5.84e-4 (Δt = 5e-6), ratio 2.00; smallest gap 0.00327."""
    err, gap = _wall_approach_error(1e-5)
    err_half, _ = _wall_approach_error(5e-6)
    assert err < 2.5e-3, err                               # measured 1.17e-3
    assert 1.8 < err / err_half < 2.2, (err, err_half)     # first order: measured 2.00
    assert 0.0025 < gap < 0.004                            # stopped by the film, far from the floor


def test_two_disks_meeting_head_on_keep_their_momentum_and_follow_the_reduced_law():
    """Two equal disks approaching at ±1: the pair's law is the wall's with the reduced radius a/2 and
    the reduced mass m/2; the forces are equal and opposite, so the momentum stays zero to round-off.
    Measured (Δt = 1e-5, first order as for the wall): relative-speed error 1.29e-3 of the initial one,
    momentum 0 to 3.4e-18."""
    g0, V0 = 0.019, 1.0
    x0 = DISK[:, 0].max() + 0.5 * g0  # the facing vertices g0 apart
    left = Body.polygon(DISK, density=1.0, position=(-x0, 0.0), velocity=(V0, 0.0))
    right = Body.polygon(DISK, density=1.0, position=(x0, 0.0), velocity=(-V0, 0.0))
    sim = _dem([left, right])

    def gap():
        W = sim.world_vertices()
        return float(W[1, :, 0].min() - W[0, :, 0].max())

    assert gap() == pytest.approx(g0, rel=1e-9)
    m, a = sim.mass[0], equal_area_radius(sim.area)[0]
    rows = []
    for _ in range(3000):
        sim.step(1e-5)
        v = sim.velocities
        rows.append((gap(), v[0, 0] - v[1, 0], abs(sim.mass @ v[:, 0]) + abs(sim.mass @ v[:, 1])))
    r = np.array(rows)
    moving = r[:, 1] > 0.1 * 2 * V0
    err = np.abs(r[moving, 1] - _approach_speed(r[moving, 0], g0, 2 * V0, m / 2, a / 2)).max() / (2 * V0)
    assert err < 3e-3, err  # measured 1.29e-3
    assert r[:, 2].max() < 1e-14 * sim.mass[0] * V0


def test_outside_the_range_and_sliding_along_a_wall_nothing_acts():
    """Above the cut-off there is no correction; a disk sliding parallel to the floor inside the range
    (no normal approach) feels none either: both keep their velocity exactly."""
    lo = Body.polygon(DISK, density=1.0, velocity=(3.0, 0.0))
    lo.position = np.array([0.5, 0.005 - DISK[:, 1].min()])
    hi = Body.polygon(DISK, density=1.0, velocity=(0.0, -1.0))
    hi.position = np.array([2.0, 0.2 + G_C + 0.01 - DISK[:, 1].min()])
    sim = _dem([lo, hi], walls=(-np.inf, np.inf, 0.0, np.inf))
    for _ in range(20):
        sim.step(1e-4)
    assert sim.lubrication_pairs == 1
    np.testing.assert_array_equal(sim.velocities, [[3.0, 0.0], [0.0, -1.0]])


def test_the_implicit_damper_never_reverses_the_approach_at_any_sub_step():
    """With a regularisation gap (1e-9) so small that nothing bounds c(g), k = cΔt/m reaches 8–10 per
    sub-step at Δt = dt_max, where an explicit damper (v ← (1 − k) v) reverses and grows for k > 2.  Backward
    Euler divides the speed by 1 + k with k at the step's end: measured ratios v_{n+1}(1 + k)/v_n = 1 to
    2e-16, k = 7.97, 10.0, 10.2, ...; the speed falls to round-off (< 1e-12 from the 13th sub-step) and never
    changes sign.  Released at gap 0.001 at speed 1."""
    body = Body.polygon(DISK, density=1.0, velocity=(0.0, -1.0))
    body.position = np.array([0.5, 0.001 - DISK[:, 1].min()])
    sim = _dem([body], walls=(-np.inf, np.inf, 0.0, np.inf), min_gap=1e-9)
    dt = sim.dt_max
    v, k = [1.0], []
    for _ in range(200):
        sim.step(dt)
        v.append(-sim.velocities[0, 1])
        c = sim.lubrication.coefficient(np.array([_gap_to_floor(sim)]), equal_area_radius(sim.area))[0]
        k.append(c * dt / sim.mass[0])
    v, k = np.array(v), np.array(k)
    assert (v >= -1e-12).all() and (np.diff(v) <= 1e-15).all()
    assert k[0] > 2.0                                      # an explicit damper would reverse: measured 7.97
    ratio = v[1:6] * (1.0 + k[:5]) / v[:5]
    np.testing.assert_allclose(ratio, 1.0, rtol=1e-12)     # backward Euler; measured 1 to 2e-16
    assert np.abs(v[13:]).max() < 1e-12                    # stopped; measured 3.1e-13 at the 13th


def test_the_implicit_damper_of_a_pile_solves_backward_euler_keeps_momentum_and_dissipates():
    """Two hundred bodies on a jittered lattice, film pairs between neighbours (c from 0.1 to 1000), a floor
    under the bottom row and every tenth body prescribed: above 64 free bodies the damper solves the sparse
    system in the free unknowns.  Against (M + Δt C) V = M V* assembled here densely from the pairs'
    generalised normals (the prescribed bodies' velocities given): measured to 6.1e-16 of the largest speed.
    Without floor and prescribed bodies the total momentum is kept (measured 1.9e-17 of Σ m|U|) and the kinetic
    energy falls (measured to 0.69 of its value)."""
    from scipy.spatial import cKDTree

    from fluidem.dem.lubrication import generalised_normals, implicit_damping

    rng = np.random.default_rng(7)
    n = 200
    pos = np.array([[k % 15, k // 15] for k in range(n)], float) + 0.05 * rng.standard_normal((n, 2))
    pairs = cKDTree(pos).query_pairs(1.2, output_type="ndarray")
    a, b = pairs[:, 0], pairs[:, 1]
    c = 10 ** rng.uniform(-1, 3, len(a))
    point = 0.5 * (pos[a] + pos[b]) + 0.01 * rng.standard_normal((len(a), 2))
    normal = (pos[a] - pos[b]) / np.linalg.norm(pos[a] - pos[b], axis=1)[:, None]
    mass, inertia = rng.uniform(1, 2, n), rng.uniform(0.1, 0.2, n)
    V0 = rng.standard_normal((n, 3))
    dt = 1e-2

    # all free, no walls: momentum kept, energy dissipated
    V = implicit_damping((a, b, c, point, normal), pos, V0, mass, inertia, np.ones(n, bool), dt)
    P0, P1 = (mass[:, None] * V0[:, :2]).sum(axis=0), (mass[:, None] * V[:, :2]).sum(axis=0)
    assert np.abs(P1 - P0).max() < 5e-17 * (mass * np.hypot(*V0[:, :2].T)).sum()  # measured 1.9e-17

    def energy(W):
        return float((mass * (W[:, :2] ** 2).sum(axis=1) + inertia * W[:, 2] ** 2).sum())

    assert energy(V) < 0.75 * energy(V0)                                                 # measured 0.69

    # a floor under the bottom row and prescribed bodies: the dense backward-Euler system built here
    floor = np.flatnonzero(pos[:, 1] < 0.5)
    A = np.concatenate([a, floor])
    B = np.concatenate([b, -np.ones(len(floor), int)])
    C = np.concatenate([c, 10 ** rng.uniform(-1, 3, len(floor))])
    pt = np.concatenate([point, pos[floor] - [0.0, 0.45]])
    nr = np.concatenate([normal, np.tile([0.0, 1.0], (len(floor), 1))])
    free = np.ones(n, bool)
    free[::10] = False
    V = implicit_damping((A, B, C, pt, nr), pos, V0, mass, inertia, free, dt)
    ga = generalised_normals(pos, A, pt, nr)
    gb = np.where((B >= 0)[:, None], -generalised_normals(pos, np.maximum(B, 0), pt, nr), 0.0)
    K = np.zeros((3 * n, 3 * n))
    for p in range(len(A)):  # C = Σ c g gᵀ with g = (+g_a at a, −g_b at b), one pair at a time
        g = np.zeros(3 * n)
        g[3 * A[p]:3 * A[p] + 3] += ga[p]
        if B[p] >= 0:
            g[3 * B[p]:3 * B[p] + 3] += gb[p]
        K += C[p] * np.outer(g, g)
    fd = np.flatnonzero(np.repeat(free, 3))
    kd = np.flatnonzero(~np.repeat(free, 3))
    M = np.column_stack([mass, mass, inertia]).ravel()
    lhs = np.diag(M[fd]) + dt * K[np.ix_(fd, fd)]
    rhs = M[fd] * V0.ravel()[fd] - dt * K[np.ix_(fd, kd)] @ V0.ravel()[kd]
    expected = V0.ravel().copy()
    expected[fd] = np.linalg.solve(lhs, rhs)
    assert np.abs(V.ravel() - expected).max() < 2e-15 * np.abs(V0).max()  # measured 6.1e-16


def test_lubrication_checks_its_parameters():
    with pytest.raises(ValueError, match="min_gap"):
        Lubrication(viscosity=MU, range=0.01, min_gap=0.01)
    with pytest.raises(ValueError, match="viscosity"):
        Lubrication(viscosity=0.0, range=0.01, min_gap=0.001)
    with pytest.raises(ValueError, match="lubrication"):
        DEM([Body.polygon(DISK)], lubrication=0.1)
