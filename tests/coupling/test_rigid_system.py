"""The coupled fluid–body matrix: equal to Tᵀ K T, and the Stokes mobility of a free disk (Faxén)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fluidem.coupling.rigid_system import RigidBodySystem
from fluidem.fluid.forces import RigidModes
from fluidem.fluid.problem import FlowProblem
from fluidem.fluid.space import FlowSpace, RigidMotion, VelocityBC
from fluidem.geometry import rectangle
from fluidem.mesh.triangulate import Obstacle, to_skfem, triangulate_box


def _problem(element="th", h=0.1):
    obs = [Obstacle(rectangle(0.3, 0.2) + [0.6, 0.5], "a"), Obstacle(rectangle(0.2, 0.2) + [1.4, 0.5], "b")]
    m = to_skfem(triangulate_box((0, 2, 0, 1), obs, h))
    space = FlowSpace(m, element)
    bcs = [VelocityBC(["left", "right", "bottom", "top"], (0.0, 0.0)),
           VelocityBC("a", RigidMotion((0.0, 0.0), 0.0, (0.6, 0.5))), VelocityBC("b", (0.0, 0.0))]
    pr = FlowProblem(space, 0.1, bcs)
    return pr, RigidModes(space, ["a", "b"], [[0.6, 0.5], [1.4, 0.5]])


@pytest.mark.parametrize("element", ["th", "p2b"])
def test_coupled_matrix_is_the_bordered_product(element):
    pr, rm = _problem(element)
    sysm = RigidBodySystem(pr, rm, bodies=[0])
    rng = np.random.default_rng(0)
    data = rng.standard_normal(pr.assembler.nnz)
    diag = rng.standard_normal(3)
    Kz = sysm.matrix(data, diag)
    K = sp.bmat([[pr.assembler.matrix(data), pr.B.T], [pr.B, None]]).tocsr()
    n = K.shape[0]
    S = sp.csr_matrix((np.ones(len(pr.free)), (pr.free, np.arange(len(pr.free)))), shape=(n, len(pr.free)))
    Pi = sp.vstack([rm.matrix[:3].T, sp.csr_matrix((pr.space.n_p, 3))])
    T = sp.hstack([S, Pi]).tocsr()
    ref = (T.T @ K @ T).toarray()
    ref[-3:, -3:] += np.diag(diag)
    assert np.abs(Kz.toarray() - ref).max() < 1e-12 * np.abs(ref).max()
    # the vectors: restrict is Tᵀ, prolong is T (plus the Dirichlet part)
    r = rng.standard_normal(n)
    assert np.allclose(sysm.restrict(r), T.T @ r, rtol=0, atol=1e-12)
    z = rng.standard_normal(sysm.shape[0])
    xd = np.zeros(n)
    assert np.allclose(sysm.prolong(z, xd), T @ z, rtol=0, atol=1e-12)



def test_the_coupled_matrix_does_not_depend_on_how_many_entries_are_expanded_at_a_time(monkeypatch):
    """The maps are built a chunk of K entries at a time (memory); every chunk size gives the same matrix bit
    for bit (the same sums in the same order), here 997 entries at a time against all at once."""
    pr, rm = _problem("p2b")
    rng = np.random.default_rng(1)
    data, diag = rng.standard_normal(pr.assembler.nnz), rng.standard_normal(6)
    whole = RigidBodySystem(pr, rm, bodies=[0, 1]).matrix(data, diag)
    monkeypatch.setattr(RigidBodySystem, "CHUNK", 997)
    chunked = RigidBodySystem(pr, rm, bodies=[0, 1]).matrix(data, diag)
    assert pr.assembler.nnz > 20 * 997  # many chunks
    assert np.array_equal(whole.indptr, chunked.indptr) and np.array_equal(whole.indices, chunked.indices)
    assert np.array_equal(whole.data, chunked.data)

def faxen(k):
    """F/(μU) of a cylinder between two plane walls (Faxén 1946, REFERENCES.md)."""
    return 4 * math.pi / (math.log(1 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6
                          - 4.5913 * k**8)


@pytest.mark.parametrize("k", [0.2])
def test_free_disk_between_walls_moves_at_the_faxen_mobility(k):
    """Stokes mobility: a force F along the centre line of a closed channel moves a free disk at
    U = F / (μ Faxén(k)); the hydrodynamic force balances F exactly and the disk does not spin."""
    from fluidem.cases.scenes import example_scene
    from fluidem.simulation import Simulation

    s = example_scene("wall-correction")  # half-width 1, 48 long, Stokes, Taylor-Hood, curved disk
    s.bodies[0].radius = k
    s.bodies[0].velocity = [0.0, 0.0]
    s.mesh.h = k / 8
    s.validate()
    fl = Simulation(s).flow
    pr = fl.problem
    sysm = RigidBodySystem(pr, fl.rigid, bodies=[0])
    Kz = sysm.matrix(pr.A_data, np.zeros(3)).tocsc()
    f_ext = np.array([1.0, 0.0, 0.0])  # kinematic force per unit depth (μ = ρν = 1)
    r0 = sysm.restrict(pr.steady_residual(pr.initial_vector(0.0), convection=False))
    z = spla.spsolve(Kz, np.concatenate([np.zeros(sysm.n_fluid), f_ext]) - r0)
    x = sysm.prolong(z, pr.initial_vector(0.0))
    V = sysm.split(z)[1][0]
    F, T = fl.rigid.loads(pr.steady_residual(x, convection=False))
    assert F[0] == pytest.approx([-1.0, 0.0], abs=1e-10)       # force balance (measured 1e-16)
    assert abs(T[0]) < 1e-10
    # measured U μ Faxén − 1 = −1.26e-4 (the resistance test of the prescribed disk gives +1.26e-4)
    assert abs(V[0] * faxen(k) - 1) < 3e-4
    assert abs(V[1]) < 1e-4 * V[0] and abs(V[2]) < 1e-4 * V[0] / k  # measured 2e-5, 5e-5 (mesh asymmetry)


def test_a_free_body_run_never_builds_the_fluids_own_condensed_structure():
    """The coupled system has its own structure (:class:`RigidBodySystem`); the flow problem's condensed
    one (:attr:`FlowProblem.system`) is built only when asked for: a run of ten settling polygons (two
    steps, one re-triangulation-free mesh motion) leaves it unbuilt, where it took 2.6 s and 962 MiB at
    1 000 polygons (1.57M DOFs).  Asked for, it gives the free-DOF block of the bordered product."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import bench_dense

    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    sim = Simulation(Scene.from_dict(bench_dense.scene_dict(10, 2)))
    sim.run(out_dir=None)
    assert sim.flow.problem._system is None
    pr, _ = _problem("p2b")
    assert pr._system is None
    data = np.random.default_rng(2).standard_normal(pr.assembler.nnz)
    K = sp.bmat([[pr.assembler.matrix(data), pr.B.T], [pr.B, None]]).tocsr()
    ref = K[pr.free][:, pr.free].toarray()
    assert np.abs(pr.condensed_matrix(data).toarray() - ref).max() <= 1e-14 * np.abs(ref).max()
    assert pr._system is not None
