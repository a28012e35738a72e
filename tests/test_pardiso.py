"""PARDISO as fluidem sets it up (:mod:`fluidem.fluid.solvers.pardiso`): accurate solves of
saddle-point systems, transposed solves for the condition estimate, the choice of ``"auto"`` by
size, and a run of free bodies that agrees with SuperLU's.  Skipped without ``pypardiso``
(``.ci/run`` installs it for this file after the main suite)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from fluidem.fluid.solvers import DirectSolver, LaggedLUSolver
from fluidem.fluid.solvers.direct import PARDISO_MIN_DOFS, default_direct_backend
from fluidem.fluid.solvers.memory import lu_fits, predicted_lu_bytes
from fluidem.fluid.solvers.pardiso import PardisoLU, pardiso_available

pytestmark = pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed")


@pytest.fixture(scope="module")
def saddle():
    """The P2+bubble/P1dc Stokes system of the solver tests (manufactured solution, 10 × 10)."""
    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from test_solvers import problem

    return problem(10)


def test_pardiso_factors_with_and_without_weighted_matching(saddle):
    """Without matching (the default) the zero pressure pivots are perturbed (204 here) and the factors
    alone leave a relative residual of 3.1e-7 (bound 1e-6; transposed 3.2e-7), which the direct solver's
    refinement takes to round-off in two steps (9.1e-12, 7.1e-16; bound 1e-12); the factors hold 67 690
    entries.  With
    matching (``matching=True``) no pivot is perturbed and the factors alone solve to 2.7e-15 (bound
    1e-12; transposed 2.5e-15) with 154 986 entries (2.29 times; bound: more than 1.5 times).  With MKL's
    default perturbation (1e-13) and no matching the same system left 1e-3-1e-2 (module notes)."""
    K, b = saddle.K.tocsr(), saddle.b

    def rel(A, x):
        return np.linalg.norm(A @ x - b) / np.linalg.norm(b)

    lu = PardisoLU(K)
    assert lu.perturbed > 0 and not lu.matching
    assert 1e-12 < rel(K, lu.solve(b)) < 1e-6
    assert rel(K.T, lu.solve(b, trans="T")) < 1e-6
    d = DirectSolver(backend="pardiso").factorize(K)
    assert rel(K, d.solve(b)) < 1e-12 and len(d.last_info.residuals) == 3
    matched = PardisoLU(K, matching=True)
    assert matched.perturbed == 0 and matched.fill > 1.5 * lu.fill
    x = matched.solve(b)
    assert rel(K, x) < 1e-12
    assert lu.fill > K.nnz and lu.peak_bytes > 0
    # transposed solve (the condition estimate's rmatvec): Kᵀ y = b to round-off too
    y = matched.solve(b, trans="T")
    assert rel(K.T, y) < 1e-12
    # any buffer type: an integer right-hand side is read as numbers, not as raw bytes
    bi = np.arange(K.shape[0], dtype=np.int8) % 3
    assert np.allclose(K @ matched.solve(bi), bi, atol=1e-9)
    # several right-hand sides at once keep their shape
    assert lu.solve(np.column_stack([b, 2 * b])).shape == (K.shape[0], 2)
    for f in (lu, matched):
        f.free()
        with pytest.raises(RuntimeError, match="freed"):
            f.solve(b)


def test_the_own_call_solves_as_pypardisos_bit_for_bit(saddle):
    """``PardisoLU`` calls MKL with the 1-based pattern made once an analysis: the same solutions as
    ``pypardiso``'s own call (which converts the pattern at every call) on the same factors, bit for bit,
    for one and for two right-hand sides, plain and transposed, also after a numerical refactorisation."""
    K = saddle.K.tocsr()
    K.sort_indices()
    b = saddle.b
    lu = PardisoLU(K)

    def theirs(rhs, trans=0):
        lu._ps.set_iparm(12, trans)
        lu._ps.set_phase(33)
        x = np.asarray(lu._ps._call_pardiso(lu.K, np.asfortranarray(rhs, dtype=np.float64).copy(order="F")))
        lu._ps.set_iparm(12, 0)
        return x.reshape(rhs.shape)

    B = np.column_stack([b, np.cos(np.arange(b.size))])
    assert np.array_equal(lu.solve(b), theirs(b))
    assert np.array_equal(lu.solve(B), theirs(B))
    assert np.array_equal(lu.solve(b, trans="T"), theirs(b, trans=2))
    K2 = K.copy()
    K2.data *= 1.0 + 0.01 * np.random.default_rng(2).standard_normal(K2.nnz)
    assert lu.refactor(K2)
    assert np.array_equal(lu.solve(B), theirs(B))
    lu.free()


def test_numerical_refactorisation_on_the_same_pattern(saddle):
    """A matrix of the factorised pattern with other values is factorised numerically on the first
    analysis (phase 22) and solved as accurately as by a fresh factorisation: values changed by 1 %
    leave 2.69e-7 with the factors alone, as a fresh analysis and factorisation does (the same to
    the digits shown; bound 1.5 times the fresh one's; with matching 2.6e-15 against 2.7e-14).  Another
    pattern is refused, and ``DirectSolver`` then analyses it anew."""
    K = saddle.K.tocsr()
    K.sort_indices()
    b = saddle.b
    lu = PardisoLU(K)
    K2 = K.copy()
    K2.data *= 1.0 + 0.01 * np.random.default_rng(1).standard_normal(K2.nnz)
    assert lu.refactor(K2) and lu.numeric_refactorizations == 1
    fresh = PardisoLU(K2)
    assert np.linalg.norm(K2 @ lu.solve(b) - b) < 1.5 * np.linalg.norm(K2 @ fresh.solve(b) - b)
    fresh.free()
    K3 = K2.tolil()
    K3[0, K.shape[0] - 1] = 1e-3  # one entry more: another pattern
    assert not lu.refactor(K3.tocsr()) and lu.numeric_refactorizations == 1
    lu.free()
    d = DirectSolver(backend="pardiso").factorize(K)
    assert not d.numeric_only
    assert d.factorize(K2).numeric_only and np.linalg.norm(K2 @ d.solve(b) - b) < 1e-10 * np.linalg.norm(b)
    assert not d.factorize(K3.tocsr()).numeric_only and np.linalg.norm(K3 @ d.solve(b) - b) < 1e-10 * np.linalg.norm(b)


def test_a_factorisation_dropped_without_free_releases_mkl_memory(saddle, monkeypatch):
    """MKL's memory is not Python's: a PardisoLU that goes out of scope must release it itself.
    Counted by the calls that free all of MKL's memory of the handle: one per LU, whether freed
    explicitly, replaced or dropped (none were made for a dropped LU before the finaliser)."""
    import gc

    import pypardiso
    import scipy.sparse as sp

    calls = []
    real = pypardiso.PyPardisoSolver.free_memory
    monkeypatch.setattr(pypardiso.PyPardisoSolver, "free_memory",
                        lambda self, everything=False: (calls.append(everything), real(self, everything))[1])
    K = saddle.K.tocsr()
    lu = PardisoLU(K)
    del lu
    gc.collect()
    assert calls == [True]
    lu = PardisoLU(K)
    lu.free()
    lu.free()  # a second free is harmless and frees nothing more
    del lu
    gc.collect()
    assert calls == [True, True]
    d = DirectSolver(backend="pardiso").factorize(K)
    d.factorize(K + 1e-9 * sp.eye(K.shape[0], format="csr"))  # another pattern (the pressure diagonal):
    # a new analysis, the old LU released first
    assert calls == [True, True, True]


def test_auto_keeps_the_lagged_pardiso_lu_whose_memory_it_holds(saddle, monkeypatch):
    """The memory rule runs at every factorisation; the PARDISO LU the solver holds is freed before
    the next one, so it counts as available.  Here the machine has the predicted LU and headroom free: not
    enough for a first LU (90 %), enough with the one held (before, the run switched to block GMRES
    at its second step)."""
    from fluidem.fluid.solvers import AutoSolver, memory

    K = saddle.K.tocsr()
    need = predicted_lu_bytes(K.shape[0], "pardiso") + memory.LU_HEADROOM_BYTES_PER_DOF * K.shape[0]
    s = AutoSolver(n_u=saddle.n_u, direct_options={"backend": "pardiso"},
                   iterative_options={"dt": 0.01, "pressure_mass": saddle.Mp})
    monkeypatch.setattr(memory, "available_bytes", lambda: 2.0**50)
    s.factorize(K)
    assert s.chosen == "lagged" and s._held_lu_bytes() > 0.2 * need
    monkeypatch.setattr(memory, "available_bytes", lambda: need)
    s.factorize(K)
    assert s.chosen == "lagged" and "with the LU held" in s.reason
    assert AutoSolver(n_u=saddle.n_u, direct_options={"backend": "pardiso"},
                      iterative_options={"dt": 0.01, "pressure_mass": saddle.Mp}).factorize(K).chosen == "iterative"


def test_pardiso_condition_estimate_matches_superlu(saddle):
    """‖K⁻¹‖₁ estimated from either factorisation (Hager–Higham on the LU and its transpose), each from the
    same random start (the estimator draws its starting vectors; unseeded, the two differed by 1.4 % and
    6.2 % in two runs): the same to 7.7e-5 measured over five seeds (bound 2e-4; PARDISO's factors, with
    their perturbed pressure pivots, are those of a matrix 1e-8 ‖K‖ away; with weighted matching the two
    agreed to 2.0e-14), so the condition diagnostics do not depend on the backend."""
    from scipy.sparse.linalg import onenormest

    K = saddle.K.tocsr()
    inverses = [DirectSolver(backend=backend).factorize(K).inverse_operator() for backend in ("superlu", "pardiso")]
    for seed in range(5):
        est = []
        for inverse in inverses:
            np.random.seed(seed)
            est.append(onenormest(inverse))
        assert abs(est[1] / est[0] - 1.0) < 2e-4


def test_refactorisations_on_one_pattern_are_estimated_every_stride(saddle):
    """A run's diagnostics estimate every new analysis and, of the numerical refactorisations on the
    pattern of the LU before, the CONDITION_REFACTOR_STRIDE-th (4): of one analysis and eight
    refactorisations the 1st, 5th and 9th; another pattern is estimated at once.  Every LU is counted."""
    from fluidem.diagnostics import CONDITION_REFACTOR_STRIDE, RunDiagnostics

    K = saddle.K.tocsr().copy()
    K.sort_indices()
    rng = np.random.default_rng(3)
    d, solver = RunDiagnostics(), DirectSolver(backend="pardiso")
    estimated, factorizations = [], []
    K3 = K.tolil()
    K3[0, K.shape[0] - 1] = 1e-3  # one entry more: another pattern
    with d.watching():
        for k in range(11):
            Kk = (K if k < 10 else K3).tocsr().copy()
            Kk.data *= 1.0 + 0.01 * rng.standard_normal(Kk.nnz)
            solver.factorize(Kk)
            h = d.finish_step(k + 1, 0.1 * (k + 1))
            estimated.append(h.condition is not None)
            factorizations.append(h.factorizations)
    assert CONDITION_REFACTOR_STRIDE == 4
    assert [k + 1 for k, e in enumerate(estimated) if e] == [1, 5, 9, 11] and factorizations == [1] * 11


def test_auto_is_pardiso_from_its_threshold_and_the_memory_model():
    assert default_direct_backend(PARDISO_MIN_DOFS - 1) == "superlu"
    assert default_direct_backend(PARDISO_MIN_DOFS) == "pardiso"
    # the measured fill: PARDISO's LU of 3M DOFs fits where SuperLU's does not (24 GiB machine)
    assert lu_fits(3_000_000, "pardiso", available_bytes=24 * 2**30)[0]
    assert not lu_fits(3_000_000, "superlu", available_bytes=24 * 2**30)[0]
    # the model (fitted at 1.49M DOFs) against MKL's measured peaks without matching: 238 MiB at 149 285
    # DOFs (model 9 % below), 737 MiB at 446 752 (3.0 % below) and 2 541 MiB at 1 486 304 (4.3 % above;
    # benchmarks/results/pardiso_matching.md)
    assert predicted_lu_bytes(149_285, "pardiso") == pytest.approx(238 * 2**20, rel=0.2)
    assert predicted_lu_bytes(446_752, "pardiso") == pytest.approx(737 * 2**20, rel=0.08)
    assert predicted_lu_bytes(1_486_304, "pardiso") == pytest.approx(2541 * 2**20, rel=0.1)


def test_lagged_pardiso_preconditions_as_well_as_superlu(saddle):
    """The LU of K preconditions K with its velocity diagonal 1 % heavier (the next step's matrix of a
    moving mesh differs by about that): PARDISO's factors need as many GMRES iterations to 1e-10 as
    SuperLU's (9 and 9 measured; bound: at most 2 more)."""
    import scipy.sparse as sp

    K = saddle.K.tocsr()
    d = np.r_[K.diagonal()[:saddle.n_u], np.zeros(K.shape[0] - saddle.n_u)]
    K2 = (K + sp.diags(0.01 * d)).tocsr()
    its = {}
    for backend in ("superlu", "pardiso"):
        s = LaggedLUSolver(direct=DirectSolver(backend=backend), rtol=1e-10).factorize(K)
        s.solve(saddle.b)
        x = s.factorize(K2).solve(saddle.b)
        assert s.factorizations == 1
        assert np.linalg.norm(K2 @ x - saddle.b) / np.linalg.norm(saddle.b) < 1e-10
        its[backend] = s.last_info.iterations
    assert 0 < its["pardiso"] <= its["superlu"] + 2


def test_the_lagged_pardiso_lu_refactorises_by_count_not_by_the_clock(saddle, monkeypatch):
    """The same matrices and right-hand sides give the same LUs and the same solutions to the last bit
    whatever the clock says (a busy or an idle machine): the rent-or-buy rule of the lagged PARDISO LU
    counts iterations (``PARDISO_REFACTOR_ITERATIONS``).  When it compared seconds, a factorisation
    that seemed to take no time refactorised after the first lagged solve and one that seemed to take
    hours never did; 40 steps of ``column-collapse-fluid`` with a jittering clock then moved grains by
    up to 1.1e-4 m (2.5 % of a grain's radius)."""
    import types

    import scipy.sparse as sp

    from fluidem.fluid.solvers import lagged

    K = saddle.K.tocsr()
    d = np.r_[K.diagonal()[:saddle.n_u], np.zeros(K.shape[0] - saddle.n_u)]
    # a drift of 1 % a step in the velocity diagonal (a moving mesh's matrices change about that much)
    mats = [(K + sp.diags(0.01 * k * d)).tocsr() for k in range(8)]

    def run(seed):
        # a clock whose readings are 1 µs to 1 000 s apart, at random: the machine's load
        steps = 10.0 ** np.random.default_rng(seed).uniform(-6, 3, 10_000)
        clock = iter(np.cumsum(steps))
        monkeypatch.setattr(lagged, "time", types.SimpleNamespace(perf_counter=lambda: float(next(clock))))
        s = LaggedLUSolver(direct=DirectSolver(backend="pardiso"), rtol=1e-10, max_iterations_before_refactor=50)
        xs = [s.factorize(M).solve(saddle.b) for M in mats]
        return s.factorizations, s.total_iterations, np.array(xs)

    runs = [run(seed) for seed in range(4)]
    for other in runs[1:]:
        assert other[0] == runs[0][0] and other[1] == runs[0][1]
        assert np.array_equal(other[2], runs[0][2])
    # and the rule does refactorise here, by the count alone: measured 3 LUs, the lagged solves taking
    # 9, 11 (7 + 9 past 12) | 7, 9, 10 (5 + 7 + 8 past 12) | iterations
    assert runs[0][0] >= 2


def test_free_bodies_run_the_same_with_either_lu(tmp_path):
    """Ten polygons settling in Navier–Stokes (15k DOFs) for 4 steps with fluid.lu_backend = 'pardiso'
    and 'superlu': the same body poses to 2.7e-8 measured (bound 8e-8), the bodies having moved by
    1.3e-3: the lagged LU solves each step's correction to 1e-6 of its right-hand side, and PARDISO's
    factors (perturbed pressure pivots) take other GMRES iterates there than SuperLU's (with weighted
    matching, whose factors solved to round-off alone, the two runs agreed to 9e-14); run.json says which
    LU solved."""
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_dense

    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    out = {}
    for backend in ("superlu", "pardiso"):
        d = bench_dense.scene_dict(10, 4)
        d["fluid"]["lu_backend"] = backend
        sim = Simulation(Scene.from_dict(d))
        sim.run(tmp_path / backend, overwrite=True)
        out[backend] = np.array(sim.flow.mm.body_poses)
        run = json.loads((tmp_path / backend / "run.json").read_text())
        assert run["linear_solver"]["lu_backend"] == backend and run["linear_solver"]["path"] == "lagged LU"
    moved = np.abs(out["superlu"][:, :2] - np.array([b["position"] for b in bench_dense.scene_dict(10, 4)["bodies"]]))
    assert moved.max() > 1e-4  # they did settle
    assert np.abs(out["pardiso"] - out["superlu"]).max() < 8e-8


def test_a_new_factorisation_does_not_search_the_file_system_for_mkl(saddle, monkeypatch):
    """pypardiso looks for ``mkl_rt`` at every new solver object, by a recursive search of the
    environment's library folders when the loader does not know it (0.2-0.4 s each in a virtual
    environment); the runtime found at import is handed on, so later factorisations do not search."""
    import glob
    import os

    import pypardiso

    K, b = saddle.K.tocsr(), saddle.b
    PardisoLU(K)  # the first one hands the runtime on

    def no_search(*a, **k):
        raise AssertionError(f"searched for the MKL runtime: {a}")

    monkeypatch.setattr(glob, "glob", no_search)
    monkeypatch.setattr(pypardiso.pardiso_wrapper, "find_library", lambda name: None)  # as in a venv
    lu = PardisoLU(K)
    assert os.environ["PYPARDISO_MKL_RT"] == pypardiso.ps.libmkl._name
    assert np.linalg.norm(K @ lu.solve(b) - b) < 1e-6 * np.linalg.norm(b)  # the factors alone: 3.1e-7
