"""Contacts inside the fluid step (fluidem.coupling.contacts): repulsion below the mesh resolution, the DEM
contact law, sub-stepped with the fluid's force held and fed back into the coupled solve."""

import numpy as np
import pytest

from fluidem.cases.settling import settling_scene
from fluidem.scene import Scene
from fluidem.simulation import Simulation

A = 0.1  # disk radius


def _floor_scene(h=0.04, dt=0.04, t_end=4.0, start=0.25, contact=True, **kw):
    sc = settling_scene(a=A, half_width=0.5, height=1.0, start=start, density=1.5, nu=0.01, g=1.0, h=h,
                        segments=32, dt=dt, t_end=t_end)
    d = sc.to_dict()
    if contact:
        d["contact"] = {"E": 1e4, "mu": 0.0, "gamma": 0.3, **kw}
    return Scene.from_dict(d)


def _run(scene):
    sim = Simulation(scene)
    fl = sim.flow
    rows = []

    def record(k, n, t, cost):
        k0 = fl.free[0]
        rows.append((fl.t, fl.poses[k0, 0], fl.poses[k0, 1] - A, fl.body_velocities[k0, 1],
                     fl.coupled.last_contact_iterations))

    sim.run(out_dir=None, progress=record)
    return sim, np.array(rows)


def test_contacts_out_of_reach_change_nothing_bit_for_bit():
    """A [contact] table whose bodies stay out of reach gives exactly the run without one."""
    _, with_c = _run(_floor_scene(t_end=0.2, start=0.6))
    _, without = _run(_floor_scene(t_end=0.2, start=0.6, contact=False))
    np.testing.assert_array_equal(with_c[:, :4], without[:, :4])


@pytest.mark.slow
def test_disk_settling_on_the_floor_comes_to_rest_at_the_repulsion_gap():
    """Case A's end in miniature (ρ_s/ρ_f = 1.5, Re ≈ 1.8, h = 0.04, dt = 0.04): the disk approaches the
    floor through the lubrication film, the repulsion (range mesh.h = 0.04, ε = 1e-4, force scale the
    buoyant weight W) stops it at g = ρ(1 − √ε) where it carries W — never touching — and it comes to
    rest there.  Measured to t = 5: smallest gap 0.03914 = 0.979 ρ (first contact at t ≈ 2), last gap
    0.039600 against the rest gap 0.0396, last speed 1e-4 of the largest, lateral drift 3.3e-5 (the
    fluid alone holds the disk sideways, friction is 0), contact loads converged in 3-5 extra solves
    per contact step (the cap of 8 reached once, at the first contact)."""
    sim, r = _run(_floor_scene(h=0.04, dt=0.04, t_end=5.0, start=0.2))
    fl = sim.flow
    rep = fl.contacts.repulsion
    rest = rep.rest_gap(-fl._weight[0, 1])
    assert rest == pytest.approx(0.99 * 0.04, rel=1e-12)
    gap, v, iters = r[:, 2], r[:, 3], r[:, 4]
    assert gap.min() > 0.95 * rep.range
    assert gap[-1] == pytest.approx(rest, rel=1e-3)
    assert abs(v[-1]) < 1e-3 * np.abs(v).max()
    assert np.abs(r[:, 1]).max() < 1e-4
    active = iters[iters > 0]
    assert np.median(active) <= 5 and (active >= fl.coupled.contact_iterations).sum() <= 2
