"""Free, fixed and prescribed bodies, external forces, Gear orders."""

import numpy as np
import pytest

from fluidem.dem import Body, ContactModel, DEM, Gear

RHO = 10.0
G = 9.81


def test_external_force_and_torque_give_exact_uniform_acceleration():
    """Constant force F and torque T, no contacts: x = F t²/(2m), θ = T t²/(2I) exactly
    (the 2nd-order Gear scheme integrates constant accelerations without error)."""
    b = Body.random_convex(0.01, 6, rng=2, density=RHO)
    sim = DEM([b], gravity=(0.0, 0.0))
    F, T = np.array([1e-3, -2e-3]), 3e-6
    sim.external_force[0] = F
    sim.external_torque[0] = T
    dt = sim.dt_max
    n = 500
    for _ in range(n):
        sim.step(dt)
    t = n * dt
    np.testing.assert_allclose(sim.positions[0], F * t**2 / (2 * b.mass), rtol=1e-9)
    assert sim.angles[0] == pytest.approx(T * t**2 / (2 * b.inertia), rel=1e-9)
    np.testing.assert_allclose(sim.forces[0], F, rtol=1e-14)
    assert sim.torques[0] == pytest.approx(T, rel=1e-14)


@pytest.mark.parametrize("order", [2, 3, 4, 5])
def test_gear_orders_integrate_a_harmonic_oscillator(order):
    """x'' = −x over one period: error shrinks with the order of the scheme."""
    dt = 2 * np.pi / 200
    g = Gear(np.array([1.0]), np.array([0.0]), np.array([-1.0]), order=order)
    for _ in range(200):
        x, v = g.predict(dt)
        g.correct(-x)
    err = abs(g.x[0] - 1.0) + abs(g.v[0])
    assert err < {2: 2e-3, 3: 2e-3, 4: 2e-3, 5: 2e-3}[order]


def test_block_resting_on_fixed_polygon():
    """A fixed polygon acts as a wall with the same law (E A / l balances the weight)."""
    floor = Body.rectangle(1.0, 0.1, density=RHO, position=(0.0, -0.05), motion="fixed")
    block = Body.rectangle(0.02, 0.01, density=RHO, position=(0.0, 0.005))
    sim = DEM([floor, block], contact=ContactModel(E=1e5, mu=0.5, gamma=0.5))
    sim.run(6000 * sim.dt_max, sim.dt_max)
    w = block.mass * G
    assert np.abs(sim.forces[1]).max() <= 1e-8 * w
    np.testing.assert_allclose(sim.positions[0], [0.0, -0.05], atol=0)   # never moves
    c = sim.contacts
    assert len(c) == 1
    assert sim.model.E * c.area[0] / c.length[0] == pytest.approx(w, rel=1e-10)
    # the floor feels the reaction: its total force is its weight plus the block's
    np.testing.assert_allclose(sim.forces[0], [0.0, -(floor.mass + block.mass) * G], rtol=1e-8,
                               atol=1e-12 * block.mass * G)


def test_prescribed_paddle_follows_its_path_and_pushes():
    v = 0.05
    paddle = Body.rectangle(0.01, 0.04, density=RHO, motion=lambda t: ((-0.02 + v * t, 0.02), 0.0))
    block = Body.rectangle(0.01, 0.01, density=RHO, position=(0.0, 0.005))
    sim = DEM([paddle, block], walls=(-1, 1, 0, 1), contact=ContactModel(E=1e4, mu=0.0, gamma=0.5))
    sim.run(0.3, sim.dt_max)
    np.testing.assert_allclose(sim.positions[0], [-0.02 + v * sim.time, 0.02], atol=1e-12)
    np.testing.assert_allclose(sim.velocities[0], [v, 0.0], atol=1e-9)
    # frictionless floor: hit by an unstoppable paddle the block leaves faster than it,
    # at (1 + e) v with 0 < e < 1
    assert v < sim.velocities[1, 0] < 2 * v
    assert sim.positions[1, 0] - 0.005 > sim.positions[0, 0] + 0.005


def test_add_bodies_and_contact_output_shapes():
    model = ContactModel(E=1e4, mu=0.5, gamma=0.5)
    sim = DEM([Body.rectangle(0.01, 0.01, density=RHO, position=(0, 0.005))], walls=(-1, 1, 0, 1),
              contact=model)
    idx = sim.add_bodies([Body.rectangle(0.01, 0.01, density=RHO, position=(0, 0.0151))])
    assert list(idx) == [1]
    sim.run(0.1, sim.dt_max)
    c = sim.contacts
    assert sim.positions.shape == (2, 2) and sim.angles.shape == (2,)
    assert c.point.shape == (len(c), 2) and c.normal_force.shape == (len(c), 2)
    assert sorted(c.j.tolist()) == [-3, 1] and sorted(c.i.tolist()) == [0, 0]
    np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0)
    assert sim.coordination_number() == pytest.approx(1.5)   # (2 + 1) / 2 bodies
    assert sim.elastic_energy() > 0
    # the floor carries both blocks
    floor = c.j == -3
    assert c.normal_force[floor, 1].sum() == pytest.approx(2 * sim.mass[0] * G, rel=1e-3)
    with pytest.raises(ValueError, match="body 2 overlap"):
        sim.add_bodies([Body.rectangle(0.01, 0.01, density=RHO, position=sim.positions[1])])


def test_docstring_examples_run():
    import doctest

    import fluidem.dem.system as mod
    assert doctest.testmod(mod).failed == 0


def test_cost_is_the_one_cost_split_type():
    from fluidem.cost import CostSplit
    from fluidem.dem import StepCost

    assert StepCost is CostSplit  # deprecated alias, kept for one version
    bodies = [Body.rectangle(0.02, 0.01, density=RHO, position=(0.03 * k, 0.00499)) for k in range(3)]
    sim = DEM(bodies, walls=(-1, 1, 0, 1), contact=ContactModel(E=1e5, mu=0.5, gamma=0.3))
    for _ in range(20):
        sim.step(sim.dt_max)
    c = sim.cost
    assert isinstance(c, CostSplit)
    assert list(c.parts) == ["broad", "narrow", "forces", "integrate"]
    assert (c.steps, c.rebuilds) == (20, 1) and c.contacts > 0  # they touch the floor
    assert c.total == pytest.approx(c.broad + c.narrow + c.forces + c.integrate) and c.total > 0
    p = sim.cost_per_step()
    assert p["total"] == pytest.approx(c.total / 20)
    assert p["per_contact"] == pytest.approx(c.total / c.contacts)
    assert p["contacts_per_step"] == pytest.approx(c.contacts / 20)
    sim.reset_cost()
    assert sim.cost.total == 0.0 and sim.cost.steps == 0
    sim.step(sim.dt_max)
    assert sim.cost.steps == 1 and sim.cost_per_step()["contacts_per_step"] == sim.cost.contacts
