"""Contacts of Stokes free bodies (fluidem.coupling.free_flow, the mobility problem with the
short-range repulsion linearly implicit in the poses): bodies come to rest where the repulsion
carries their buoyant weight, never overlapping."""

import numpy as np
import pytest
from scipy.optimize import brentq

from fluidem.cases.settling import settling_scene
from fluidem.geometry import regular_polygon
from fluidem.scene import Scene
from fluidem.simulation import Simulation

A = 0.1  # disk radius
H = 0.04  # mesh size; the repulsion acts below this gap (range = h, the contact model of earlier versions)


def _run(scene, body):
    sim = Simulation(scene)
    fl = sim.flow
    rows = []

    def record(*_):
        rows.append((fl.t, *fl.poses[body], *fl.body_velocities[body], fl.last_contact_iterations))

    sim.run(out_dir=None, progress=record)
    return sim, np.array(rows)


def test_repulsion_stiffness_is_the_derivative_of_its_force_along_the_normals():
    """The normal stiffness K of :meth:`FluidContacts.repulsion_linearised` against central
    differences of its force: a disk 0.002 off a wall and 0.01 from a second disk on the same
    line.  The entries along the normals are exact (measured 2.5e-11 relative, round-off of the
    differences); K neglects the turn of the normals, so the transverse entries differ (measured
    up to 20 % of the largest entry).  K is symmetric and negative semi-definite."""
    from fluidem.coupling.contacts import FluidContacts

    disk = regular_polygon(A, 32)
    sc = Scene.from_dict({
        "gravity": [0.0, -1.0], "fluid": {"model": "stokes", "viscosity": 0.01, "density": 1.0},
        "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
        "bodies": [{"name": "a", "shape": "polygon", "vertices": disk.tolist(), "position": [0.3, 0.5],
                    "density": 1.5},
                   {"name": "b", "shape": "polygon", "vertices": disk.tolist(), "position": [0.8, 0.5],
                    "density": 1.5}],
        "contact": {"E": 1e4, "mu": 0.0, "repulsion_range": H}, "mesh": {"h": H},
        "time": {"dt": 0.01, "t_end": 0.1}})
    c = FluidContacts(sc.bodies, np.array([0, 1]), [disk, disk], [None, None],
                      domain=sc.domain, fluid=sc.fluid, contact=sc.contact, gravity=sc.gravity, h=sc.mesh.h)
    P = np.array([[A + 0.002, 0.5, 0.0], [A + 0.002 + 2 * A + 0.01, 0.5, 0.0]])  # wall, then the pair
    F, K = c.repulsion_linearised(P)
    K = K.toarray()
    assert F[0, 0] > 0 and F[1, 0] > 0  # a off the wall (net of b's push), b away from a
    eps = 1e-7
    J = np.zeros((6, 6))
    for q in range(6):
        Pp, Pm = P.copy(), P.copy()
        Pp.flat[q] += eps
        Pm.flat[q] -= eps
        J[:, q] = (c.repulsion_linearised(Pp)[0] - c.repulsion_linearised(Pm)[0]).ravel() / (2 * eps)
    for r, s in ((0, 0), (0, 3), (3, 3)):  # x–x entries: the normals of the wall and of the pair
        assert K[r, s] == pytest.approx(J[r, s], rel=1e-10), (r, s, K[r, s], J[r, s])
    np.testing.assert_allclose(K, K.T, atol=1e-12 * np.abs(K).max())
    assert np.linalg.eigvalsh(K).max() <= 1e-9 * np.abs(K).max()


def test_stokes_disk_comes_to_rest_on_the_floor_at_the_repulsion_gap():
    """Stokes, a disk (ρ_s/ρ_f = 1.5) 0.1 above the floor: it drains the film, the repulsion
    (range h, ε = 1e-4) stops it at the gap ρ(1 − √(W ε / c)) = 0.0396 where it carries the buoyant
    weight W = c, and it stays there.  Measured (h = 0.04, dt = 0.05, to t = 3): smallest gap equal
    to the last, which is 8e-8 relative below the rest gap; last speed 5.6e-9 (1.1e-7 of the
    largest); one linearisation per step but for the three steps of arrival (2, 3, 4); lateral drift 1.6e-5."""
    sc = settling_scene(a=A, half_width=0.5, height=1.0, start=0.2, density=1.5, nu=0.01, g=1.0, h=H, segments=32,
                        dt=0.05, t_end=3.0)
    d = sc.to_dict()
    d["fluid"]["model"] = "stokes"
    d["contact"] = {"E": 1e4, "mu": 0.0, "repulsion_range": H, "repulsion_epsilon": 1e-4}
    scene = Scene.from_dict(d)
    assert "contacts of Stokes free bodies: the short-range repulsion (Glowinski et al. 2001) below 0.04" in \
        str(scene.plan())
    sim, r = _run(scene, 0)
    fl = sim.flow
    rest = fl.contacts.repulsion.rest_gap(-fl._weight[0, 1])
    assert rest == pytest.approx(0.99 * H, rel=1e-12)
    gap, vy, iters = r[:, 2] - A, r[:, 5], r[:, 7]
    assert gap.min() > 0.99 * rest
    assert gap[-1] == pytest.approx(rest, rel=2e-7)
    assert abs(vy[-1]) < 3e-7 * np.abs(vy).max()
    assert abs(r[-1, 1]) < 4e-5
    assert iters.max() <= 8 and np.median(iters[iters > 0]) == 1


def test_stokes_disk_settles_into_the_groove_of_two_fixed_disks():
    """Stokes, a free disk settling onto two fixed disks 0.28 apart (body–body repulsion, two
    contacts at once): it comes to rest on the centre line at the height where the two pair
    forces carry its buoyant weight — the root of F_y(y) = W of the repulsion alone (brentq,
    independent of the flow).  Measured (h = 0.04, dt = 0.05, to t = 4): height within 4.1e-9 of
    the root, never below it, lateral offset 5.7e-7, last vertical speed 7.1e-8 (1.9e-6 of the largest)."""
    disk = regular_polygon(A, 32).tolist()
    sc = Scene.from_dict({
        "gravity": [0.0, -1.0], "fluid": {"model": "stokes", "viscosity": 0.01, "density": 1.0},
        "domain": {"box": [0.0, 1.0, 0.0, 1.0]},
        "bodies": [{"name": "west", "shape": "polygon", "vertices": disk, "position": [0.36, 0.3], "motion": "fixed"},
                   {"name": "east", "shape": "polygon", "vertices": disk, "position": [0.64, 0.3],
                    "motion": "fixed"},
                   {"name": "free", "shape": "polygon", "vertices": disk, "position": [0.5, 0.55], "density": 1.5}],
        "contact": {"E": 1e4, "mu": 0.0, "repulsion_range": H}, "mesh": {"h": H}, "time": {"dt": 0.05, "t_end": 4.0}})
    sim, r = _run(sc, 2)
    fl = sim.flow
    W = -fl._weight[0, 1]
    P = fl.poses.copy()

    def lift(y):
        Q = P.copy()
        Q[2] = (0.5, y, P[2, 2])
        return fl.contacts.repulsion_linearised(Q)[0][0, 1] - W

    y_rest = brentq(lift, 0.48, 0.55, xtol=1e-14)  # the one root above the touching height 0.47
    assert r[-1, 2] == pytest.approx(y_rest, abs=1e-8)
    assert abs(r[-1, 1] - 0.5) < 1.5e-6
    assert abs(r[-1, 5]) < 5e-6 * np.abs(r[:, 5]).max()
    assert r[:, 2].min() > y_rest - 1e-8  # no overshoot into the fixed disks
