"""Short-range repulsion (fluidem.dem.repulsion, Glowinski et al. 2001 eq. 4.1) on its own and in the DEM."""

import numpy as np
import pytest

from fluidem.dem import DEM, Body, ContactModel
from fluidem.dem.repulsion import Repulsion, repulsion_forces
from fluidem.geometry import regular_polygon, rigid_transform

R, RHO = 0.1, 0.02


def _outlines(verts, poses):
    V = np.stack(verts)
    return rigid_transform(V, np.asarray(poses, float))


def test_two_disks_feel_the_formula_equal_and_opposite_along_the_centre_line():
    """Two 64-gons (a vertex facing the other's vertex along x) at gap g: F = (c/ε)((ρ−g)/ρ)² on
    each, opposite, along the centre line, no torque, for gaps in and out of range."""
    rep = Repulsion(range=RHO, force=2.0, epsilon=1e-3)
    v = regular_polygon(R, 64)
    for g in (0.0005, 0.01, 0.0199, 0.021):
        poses = [(0.0, 0.0, 0.0), (2 * R + g, 0.0, 0.0)]
        W = _outlines([v, v], poses)
        F, T, n = repulsion_forces(rep, W, W.mean(axis=1), np.array([0]), np.array([1]), np.array([False]))
        expected = 2.0 / 1e-3 * max((RHO - g) / RHO, 0.0) ** 2
        assert F[0, 0] == pytest.approx(-expected, rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(F[1], -F[0], atol=1e-12)
        assert abs(F[0, 1]) < 1e-9 * max(expected, 1) and np.abs(T).max() < 1e-9 * max(expected, 1)
        assert n == (1 if g < RHO else 0)


def test_square_face_on_a_wall_gets_no_torque_and_a_tilted_one_does():
    """A square parallel to the floor at gap g: the two bottom vertices share the load, no torque;
    tilted, the lower corner carries it and the torque turns the square back (restoring)."""
    rep = Repulsion(range=RHO, force=1.0, epsilon=1e-4)
    sq = np.array([[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]])
    walls = (-np.inf, np.inf, 0.0, np.inf)
    W = _outlines([sq], [(0.0, 0.1 + 0.01, 0.0)])
    F, T, _ = repulsion_forces(rep, W, np.array([[0.0, 0.11]]), np.zeros(0, int), np.zeros(0, int),
                               np.zeros(0, bool), walls)
    assert F[0, 1] == pytest.approx(1e4 * 0.25, rel=1e-12) and abs(T[0]) < 1e-12
    ang = 0.02  # counter-clockwise: the right bottom corner goes up, the left one down
    W = _outlines([sq], [(0.0, 0.115, ang)])
    F, T, _ = repulsion_forces(rep, W, np.array([[0.0, 0.115]]), np.zeros(0, int), np.zeros(0, int),
                               np.zeros(0, bool), walls)
    assert F[0, 1] > 0 and T[0] < 0


def test_a_face_beside_a_body_with_more_vertices_gets_no_torque_from_the_padding():
    """A square's bottom face at gap 0.01 above a wider block, and above the floor, in a batch padded to a
    64-gon's 64 rows (as the DEM's outlines are): no torque about its centre, as alone.  Before, the 60
    padding rows repeated the bottom-left vertex, which then weighed 61 times in the force's point: the
    torque was −0.968 of force × half-width against the block and on the floor alike."""
    rep = Repulsion(range=RHO, force=1.0, epsilon=1e-4)
    sq = np.array([[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]])
    wide = np.array([[-0.5, -0.1], [0.5, -0.1], [0.5, 0.1], [-0.5, 0.1]])
    padded = [np.vstack([v, np.repeat(v[:1], 60, axis=0)]) for v in (sq, wide)]
    pos = np.array([[0.0, 0.11], [5.0, 5.0], [0.0, -0.1]])
    W = _outlines([padded[0], regular_polygon(R, 64), padded[1]], np.column_stack([pos, np.zeros(3)]))
    F, T, _ = repulsion_forces(rep, W, pos, np.array([0]), np.array([2]), np.array([False]))
    assert F[0, 1] == pytest.approx(1e4 * 0.25, rel=1e-12) and F[2, 1] == -F[0, 1]
    assert abs(T[0]) < 1e-12 and abs(T[2]) < 1e-12
    F, T, _ = repulsion_forces(rep, W[:1], pos[:1], np.zeros(0, int), np.zeros(0, int), np.zeros(0, bool),
                               (-np.inf, np.inf, 0.0, np.inf))
    assert F[0, 1] == pytest.approx(1e4 * 0.25, rel=1e-12) and abs(T[0]) < 1e-12


def test_dem_dt_max_takes_the_repulsion_stiffness():
    """dt_max = 0.1 π √(m / max(E, 2c/(ερ)))."""
    b = Body.polygon(regular_polygon(R, 32), density=1.0, position=(0.0, 0.5))
    rep = Repulsion(range=RHO, force=10.0, epsilon=1e-4)
    sim = DEM([b], walls=(-1, 1, 0, 2), contact=ContactModel(E=1e3), repulsion=rep)
    assert sim.dt_max == pytest.approx(0.1 * np.pi * np.sqrt(b.mass / (2 * 10.0 / (1e-4 * RHO))), rel=1e-12)


def test_a_disk_bounces_off_the_floor_without_losing_energy_and_never_touches_it():
    """The repulsion is conservative: a 64-gon dropped from y = 0.5 under gravity returns to its
    height (measured 5.5e-6 relative) and its lowest gap is where the potential c ρ s³/(3ε) took
    the drop's energy (measured gap 0.01642 against 0.01642 from the potential)."""
    b = Body.polygon(regular_polygon(R, 64), density=1.0, position=(0.0, 0.5))
    W = b.mass * 9.81
    rep = Repulsion(range=RHO, force=W, epsilon=1e-4)
    sim = DEM([b], walls=(-1, 1, 0, 2), gravity=(0, -9.81), contact=ContactModel(E=1e5), repulsion=rep)
    dt = sim.dt_max
    ys = []
    for _ in range(int(0.7 / dt)):
        sim.step(dt)
        ys.append(sim.positions[0, 1])
    ys = np.array(ys)
    k = int(np.argmin(ys))
    gap_min = ys[k] - R  # the lowest vertex of the 64-gon points straight down
    drop = 0.5 - R - gap_min
    s = (RHO - gap_min) / RHO
    assert W * RHO * s**3 / (3 * 1e-4) == pytest.approx(W * drop, rel=3e-4)  # measured 1.1e-4
    assert gap_min > 0.8 * RHO
    assert ys[k:].max() == pytest.approx(0.5, rel=1.5e-5)  # measured 5.5e-6


def test_resting_gap_balances_the_load():
    """rest_gap: (c/ε) s² = load at g = ρ(1 − s)."""
    rep = Repulsion(range=0.03, force=3.0, epsilon=1e-4)
    g = rep.rest_gap(1.5)
    assert rep.magnitude(np.array([g]))[0] == pytest.approx(1.5, rel=1e-12)


@pytest.mark.parametrize("kw, msg", [({"range": 0.0, "force": 1.0}, "range"), ({"range": 1.0, "force": -1.0}, "force"),
                                     ({"range": 1.0, "force": 1.0, "epsilon": 0.0}, "epsilon")])
def test_bad_parameters_are_named(kw, msg):
    with pytest.raises(ValueError, match=msg):
        Repulsion(**kw)
