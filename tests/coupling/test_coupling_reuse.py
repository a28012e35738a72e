"""The moving-mesh reuse: a moved FlowProblem equals a new one, one rigid-mode operator gives the
loads of body_loads, vectorised boundary values equal the per-condition ones, and the forces of the
moving-mesh flow with reuse equal those of a full rebuild every step."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from fluidem.fluid.forces import RigidModes, body_loads
from fluidem.fluid.problem import FlowProblem
from fluidem.fluid.space import FlowSpace, RigidMotion, VelocityBC
from fluidem.geometry import rectangle
from fluidem.mesh.triangulate import Obstacle, to_skfem, triangulate_box
from fluidem.scene import Scene
from fluidem.simulation import Simulation


def _turned(w, h, centre, angle):
    c, s = np.cos(angle), np.sin(angle)
    return rectangle(w, h) @ np.array([[c, s], [-s, c]]) + centre


@pytest.fixture(scope="module")
def two_plates():
    obs = [Obstacle(_turned(0.3, 0.1, (0.8, 0.5), 0.3), "a"), Obstacle(_turned(0.2, 0.2, (2.0, 0.4), -0.2), "b")]
    return to_skfem(triangulate_box((0.0, 3.0, 0.0, 1.0), obs, 0.1))


def _moved(mesh, amp=0.01):
    """The same triangles with interior nodes displaced (boundary nodes stay on the box)."""
    p = mesh.p.copy()
    inner = (p[0] > 1e-9) & (p[0] < 3 - 1e-9) & (p[1] > 1e-9) & (p[1] < 1 - 1e-9)
    p[:, inner] += amp * np.sin(3.0 * p[:, inner][::-1])
    return dataclasses.replace(mesh, doflocs=p)


def _bcs(ca, cb):
    return [VelocityBC(("bottom", "top", "left"), (0.0, 0.0)),
            VelocityBC("a", RigidMotion((1.0, 0.2), 0.7, ca)), VelocityBC("b", RigidMotion((-0.3, 0.0), -1.1, cb))]


@pytest.mark.parametrize("element", ["th", "p2b", "mini", "p3"])
def test_moved_problem_equals_a_new_one(two_plates, element):
    pr = FlowProblem(FlowSpace(two_plates, element), 0.01, _bcs((0.8, 0.5), (2.0, 0.4)), body_force=(0.3, -1.0),
                     moving=True)
    for step in (1, 2):  # twice: the second refill reuses every structure
        m = _moved(two_plates, 0.01 * step)
        bcs = _bcs((0.8 + 0.01 * step, 0.5), (2.0, 0.4 - 0.01 * step))
        pr.update_geometry(m, bcs)
        ref = FlowProblem(FlowSpace(m, element), 0.01, bcs, body_force=(0.3, -1.0))
        for name in ("A", "M", "B"):
            a, b = getattr(pr, name), getattr(ref, name)
            assert abs(a - b).max() < 1e-13 * abs(b).max(), name
        np.testing.assert_allclose(pr._f, ref._f, atol=1e-15)
        d1, v1 = pr.dirichlet_values(0.3)
        d2, v2 = ref.dirichlet_values(0.3)
        assert np.array_equal(d1, d2) and np.array_equal(pr.free, ref.free)
        np.testing.assert_allclose(v1, v2, rtol=0, atol=1e-15)
        K1, K2 = pr.condensed_matrix(pr.A_data + pr.M_data), ref.condensed_matrix(ref.A_data + ref.M_data)
        assert abs(K1 - K2).max() < 1e-13 * abs(K2).max()
    with pytest.raises(ValueError, match="same boundaries"):
        pr.update_geometry(m, _bcs((0, 0), (0, 0))[:2])


def test_a_re_triangulated_mesh_is_refused(two_plates):
    other = to_skfem(triangulate_box((0.0, 3.0, 0.0, 1.0), [], 0.1))
    pr = FlowProblem(FlowSpace(two_plates, "th"), 0.01, _bcs((0.8, 0.5), (2.0, 0.4)))
    with pytest.raises(ValueError, match="same triangles"):
        pr.update_geometry(other)


def _loop_dirichlet(pr, t):
    """The per-condition evaluation the vectorised one replaces (later conditions win)."""
    x = np.zeros(pr.space.n_u)
    for bc in pr.bcs:
        for name in bc.names:
            for c in bc.components:
                d = pr.space.velocity_dofs(name, c)
                x[d] = bc.evaluate(pr.space.dof_locations(d), t)[c]
    return x[pr._dirichlet_dofs]


def test_vectorised_boundary_values_equal_the_per_condition_ones(two_plates):
    inflow = VelocityBC("left", lambda x, y, t: np.array([4 * y * (1 - y) * (1 + t), 0 * y]))
    bcs = [VelocityBC(("bottom", "top"), (0.0, 0.0)), inflow, VelocityBC("a", RigidMotion((1.0, 0.2), 0.7, (0.8, 0.5))),
           VelocityBC(("b", "bottom"), RigidMotion((-0.3, 0.5), -1.1, (2.0, 0.4))),  # wins on the bottom wall
           VelocityBC("right", (0.2, 0.0), components=(1,))]
    pr = FlowProblem(FlowSpace(two_plates, "th"), 0.01, bcs)
    for t in (0.0, 0.7):
        np.testing.assert_array_equal(pr.dirichlet_values(t)[1], _loop_dirichlet(pr, t))


@pytest.mark.parametrize("element", ["th", "p2b"])
def test_rigid_modes_give_the_loads_of_body_loads(two_plates, element):
    rng = np.random.default_rng(3)
    space = FlowSpace(two_plates, element)
    centres = np.array([[0.8, 0.5], [2.0, 0.4]])
    R = RigidModes(space, ["a", "b"], centres)
    for _ in range(2):
        r = rng.standard_normal(space.n_dofs)
        F, T = R.loads(r, rho=1.3)
        for k, name in enumerate(["a", "b"]):
            L = body_loads(space, r, name, rho=1.3, center=centres[k])
            np.testing.assert_allclose([F[k, 0], F[k, 1], T[k]], [L.fx, L.fy, L.torque], rtol=1e-12, atol=1e-12)
        # on moved nodes about moved centres: the refill equals a new operator
        space = space.moved(_moved(two_plates, 0.02))
        centres = centres + [0.01, -0.02]
        R.update(space, centres)
    # the transpose is the rigid prolongation: U + ω e_z × (x − X) on the outline DOFs
    U, om = np.array([[1.0, 0.2], [-0.3, 0.0]]), np.array([0.7, -1.1])
    u = R.prolong(U, om)
    for k, name in enumerate(["a", "b"]):
        rm = RigidMotion(tuple(U[k]), om[k], tuple(centres[k]))
        for c in (0, 1):
            d = space.velocity_dofs(name, c)
            np.testing.assert_allclose(u[d], rm(*space.dof_locations(d), 0.0)[c], atol=1e-14)


def _moving_scene(solver):
    return Scene.from_dict({
        "fluid": {"model": "navier-stokes", "viscosity": 0.02, "element": "th", "solver": solver},
        "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
        "bodies": [{"shape": "rectangle", "width": 0.3, "height": 0.06, "position": [0.6, 0.5], "angle": 0.4,
                    "motion": "prescribed", "velocity": [1.0, 0.0], "omega": 1.0}],
        "mesh": {"h": 0.08, "retriangulate_every": 3}, "time": {"dt": 0.02, "t_end": 0.14}})


def _forces(sim, costs=None):
    out = []

    def progress(k, n, t, cost):
        out.append(np.concatenate([*map(np.ravel, sim.flow.loads())]))
        if costs is not None:
            costs.append(cost)

    res = sim.run(out_dir=None, progress=progress)
    if costs is not None:
        costs.append(res.totals)
    return np.array(out)


def test_moving_flow_with_reuse_gives_the_forces_of_a_full_rebuild(monkeypatch):
    """Moved problem + lagged LU against a new scikit-fem-assembled problem + fresh LU every step.

    The lagged LU solves to 1e-10 here so that the comparison measures the reuse alone (at the
    moving-mesh stepping tolerance of 1e-6 the forces differ by up to 1.1e-7 of their scale)."""
    from fluidem.coupling import moving_flow

    monkeypatch.setattr(moving_flow, "MOVING_MESH_STEPPING", {**moving_flow.MOVING_MESH_STEPPING, "rtol": 1e-10})
    reuse = Simulation(_moving_scene("auto"))
    costs = []
    F_reuse = _forces(reuse, costs)
    assert reuse.counters["transfers"] >= 1  # the run crosses a re-triangulation
    # the cost split of every step and of the run: parts read as attributes, they add up
    *steps, totals = costs
    assert all(c.mesh > 0 and c.rebuild > 0 and c.solve > 0 and c.assembly > 0 for c in steps)
    assert totals.steps == len(steps) == reuse.counters["steps"]
    assert np.isclose(totals.total, sum(c.total for c in steps)) and "solve" in str(totals)

    built = []
    orig_init = FlowProblem.__init__

    def scikit_fem_problem(self, *a, **k):
        k["moving"] = False
        built.append(1)
        orig_init(self, *a, **k)

    monkeypatch.setattr(moving_flow.MovingMeshFlow, "_refit", lambda self, t: False)
    monkeypatch.setattr(FlowProblem, "__init__", scikit_fem_problem)
    full = Simulation(_moving_scene("direct"))
    F_full = _forces(full)
    assert len(built) == full.counters["steps"] + 1 and full.counters["transfers"] == reuse.counters["transfers"]
    scale = np.abs(F_full).max(axis=0)
    assert np.all(np.abs(F_reuse - F_full) <= 1e-7 * scale), np.abs(F_reuse - F_full) / scale
    assert reuse.flow.stepper.solver.factorizations < reuse.counters["steps"]


def test_layers_import_only_what_they_may():
    """mesh does not import fluid; fluid imports neither dem nor mesh.moving nor coupling."""
    checks = [("fluidem.mesh, fluidem.mesh.transfer", ("fluidem.fluid",)),
              ("fluidem.fluid.navier_stokes, fluidem.fluid.forces, fluidem.fluid.problem",
               ("fluidem.dem", "fluidem.mesh.moving", "fluidem.coupling.fixed_flow", "fluidem.coupling.moving_flow"))]
    for mods, banned in checks:
        code = f"import sys, {mods}; bad = [m for m in sys.modules if m.startswith({banned!r})]; assert not bad, bad"
        subprocess.run([sys.executable, "-c", code], check=True)
