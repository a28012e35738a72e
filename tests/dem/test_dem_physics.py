"""DEM against physics: energy conservation, restitution, static equilibrium, friction.

Units SI, 2D: areal density in kg/m², E in N/m.  Squares of side 1 cm, ρ = 10 kg/m²
(m = 1 g).  E = 1e6 N/m for collisions (overlap ≤ 0.1 % of the side at 0.1 m/s),
E = 1e5 N/m for resting blocks (overlap 2e-5 of the side under their weight).
"""

import numpy as np
import pytest

from fluidem.dem import Body, ContactModel, DEM

H = 0.01        # side, m
RHO = 10.0      # kg/m²
G = 9.81


def _head_on(gamma, frac, shape="square", v0=0.1, E=1e6, order=2):
    """Two equal bodies approaching along x at ±v0.

    Returns the coefficient of restitution (separation over approach speed), the largest
    relative deviation of kinetic + elastic energy during the collision and the relative
    change of kinetic energy over it.
    """
    if shape == "square":
        def mk(x, v):
            return Body.rectangle(H, H, density=RHO, position=(x, 0.0), velocity=(v, 0.0))
        gap = 0.5 * H + 1e-5
    else:   # hexagons meeting corner to corner
        def mk(x, v):
            return Body.disk(0.5 * H, 6, density=RHO, position=(x, 0.0), velocity=(v, 0.0))
        gap = 0.5 * H + 1e-5
    sim = DEM([mk(-gap, v0), mk(gap, -v0)], gravity=(0, 0),
              contact=ContactModel(E=E, mu=0.0, gamma=gamma), order=order)
    e0 = sim.kinetic_energy()
    dt = frac * sim.dt_max
    touched, dev = False, 0.0
    for _ in range(200000):
        sim.step(dt)
        dev = max(dev, abs(sim.kinetic_energy() + sim.elastic_energy() - e0) / e0)
        if len(sim.contacts):
            touched = True
        elif touched:
            break
    e = (sim.velocities[1, 0] - sim.velocities[0, 0]) / (2 * v0)
    return e, dev, abs(sim.kinetic_energy() - e0) / e0


def test_undamped_head_on_collision_conserves_energy():
    """Flat faces, no damping, no friction, dt = dt_max/40: kinetic + elastic energy is
    constant to 1e-4 during the collision and the kinetic energy is recovered after it."""
    e, dev, after = _head_on(0.0, 0.025)
    assert dev <= 1e-4
    assert after <= 1e-4
    assert e == pytest.approx(1.0, abs=1e-4)


def test_energy_error_is_second_order_in_dt():
    """Velocity-Verlet-equivalent Gear(2): halving dt divides the energy deviation by ~4."""
    _, d1, _ = _head_on(0.0, 0.1)
    _, d2, _ = _head_on(0.0, 0.05)
    assert 3.2 < d1 / d2 < 4.8


def test_corner_to_corner_collision_conserves_energy():
    """Hexagons corner to corner (overlap ∝ δ²) at dt = dt_max/10."""
    e, dev, after = _head_on(0.0, 0.1, shape="hexagon")
    assert dev <= 1e-4 and after <= 1e-4


#: Coefficient of restitution of two 1 cm squares meeting face to face at 0.2 m/s,
#: E = 1e6 N/m, ρ = 10 kg/m², no friction, dt = dt_max/20 (measured; the third digit
#: moves by ~1e-3 between dt_max/10 and dt_max/20).
RESTITUTION_TABLE = {0.0: 1.0, 0.025: 0.96188, 0.05: 0.92577, 0.1: 0.85907, 0.2: 0.74462,
                     0.3: 0.65061, 0.5: 0.50719, 1.0: 0.29953}


def test_restitution_is_smooth_decreasing_function_of_gamma():
    gammas = sorted(RESTITUTION_TABLE)
    e = np.array([_head_on(g, 0.05)[0] for g in gammas])
    np.testing.assert_allclose(e, [RESTITUTION_TABLE[g] for g in gammas], atol=2e-3)
    assert np.all(np.diff(e) < 0)
    # flat contact: stiffness E|S|/l and damping γ√(m_eff E)|S|/l with |S| = l give the
    # damping ratio ζ = γ/2; the linear spring-dashpot e = exp(−πζ/√(1−ζ²)) holds while
    # the no-attraction cap is negligible (small γ)
    for g, ei in zip(gammas, e):
        if 0 < g <= 0.1:
            z = g / 2
            assert ei == pytest.approx(np.exp(-np.pi * z / np.sqrt(1 - z * z)), rel=0.01)


def _resting_block(gamma=0.5, mu=0.5, tilt=0.0, E=1e5, width=2 * H, height=H):
    """Block on the floor; gravity tilted by ``tilt`` (rad) stands for an incline."""
    b = Body.rectangle(width, height, density=RHO, position=(0.0, 0.5 * height))
    g = (G * np.sin(tilt), -G * np.cos(tilt))
    return DEM([b], walls=(-np.inf, np.inf, 0.0, np.inf), gravity=g,
               contact=ContactModel(E=E, mu=mu, gamma=gamma))


def test_block_on_floor_reaches_static_equilibrium():
    """Net force → 0 (to 1e-8 of the weight), overlap × E / l balances the weight."""
    sim = _resting_block()
    w = sim.mass[0] * G
    sim.run(6000 * sim.dt_max, sim.dt_max)
    assert np.abs(sim.forces[0]).max() <= 1e-8 * w
    assert abs(sim.torques[0]) <= 1e-8 * w * H
    c = sim.contacts
    assert len(c) == 1 and c.j[0] == -3
    # F = E A / l with l = 4 r (wall), r = distance centre → overlap centroid
    assert sim.model.E * c.area[0] / c.length[0] == pytest.approx(w, rel=1e-10)
    assert c.length[0] == pytest.approx(4 * (sim.positions[0, 1] - c.point[0, 1]), rel=1e-12)


@pytest.mark.slow
def test_static_block_does_not_drift_over_1e5_steps():
    sim = _resting_block()
    w = sim.mass[0] * G
    dt = sim.dt_max
    sim.run(6000 * dt, dt)
    a0, x0, th0 = sim.contacts.area[0], sim.positions[0].copy(), sim.angles[0]
    for _ in range(100_000):
        sim.step(dt)
    assert sim.contacts.area[0] == pytest.approx(a0, rel=1e-10)
    assert np.abs(sim.positions[0] - x0).max() <= 1e-12
    assert abs(sim.angles[0] - th0) <= 1e-12
    assert np.abs(sim.forces[0]).max() <= 1e-8 * w


@pytest.mark.parametrize("alpha_deg", [10.0, 20.0])
def test_block_sticks_below_friction_angle(alpha_deg):
    """Inclined plane done by tilting gravity by α with the floor horizontal.
    μ = 0.4: friction angle tan⁻¹ 0.4 = 21.8°; below it the block stops and stays."""
    sim = _resting_block(mu=0.4, tilt=np.radians(alpha_deg))
    dt = sim.dt_max
    sim.run(3000 * dt, dt)
    x0 = sim.positions[0, 0]
    sim.run(sim.time + 5000 * dt, dt)
    assert abs(sim.positions[0, 0] - x0) < 1e-9          # no creep
    assert abs(sim.velocities[0, 0]) < 1e-7
    assert not sim.contacts.sliding[0]
    w = sim.mass[0] * G
    ft = sim.contacts.tangential_force[0, 0]
    assert ft == pytest.approx(-w * np.sin(np.radians(alpha_deg)), rel=1e-6)


@pytest.mark.parametrize("alpha_deg", [25.0, 35.0])
def test_block_slides_above_friction_angle_with_analytic_acceleration(alpha_deg):
    """Above tan⁻¹ μ: a = g (sin α − μ cos α), measured from the velocity slope, within 1 %."""
    mu = 0.4
    al = np.radians(alpha_deg)
    sim = _resting_block(mu=mu, tilt=al)
    dt = sim.dt_max
    sim.run(1000 * dt, dt)                              # normal transient decays
    t, v = [], []
    for _ in range(2000):
        sim.step(dt)
        t.append(sim.time)
        v.append(sim.velocities[0, 0])
    a = np.polyfit(t, v, 1)[0]
    assert sim.contacts.sliding[0]
    assert a == pytest.approx(G * (np.sin(al) - mu * np.cos(al)), rel=0.01)
