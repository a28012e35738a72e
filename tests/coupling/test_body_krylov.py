"""Block-preconditioned GMRES for the coupled fluid–body system (fluidem.coupling.body_krylov):
the bodies in the velocity block of the fluid's preconditioner."""

import numpy as np
import pytest

from fluidem.cases.settling import settling_scene
from fluidem.scene import Scene
from fluidem.simulation import Simulation


def _run(solver, steps=30):
    sc = settling_scene(a=0.1, half_width=0.5, height=1.5, start=0.6, density=1.5, nu=0.01, g=1.0, h=0.04,
                        segments=32, dt=0.02, t_end=steps * 0.02)
    d = sc.to_dict()
    d["fluid"]["solver"] = solver
    d["mesh"]["retriangulate_every"] = 10
    scene = Scene.from_dict(d)
    sim = Simulation(scene)
    fl = sim.flow
    rows = []

    def record(*_):
        info = getattr(fl.coupled.solver, "last_info", None)
        rows.append((*fl.body_velocities[0], -1 if info is None else info.iterations))

    sim.run(out_dir=None, progress=record)
    return scene, sim, np.array(rows)


def test_body_block_gmres_moves_the_body_as_the_lu_does_through_re_triangulations():
    """A disk settling from rest (ρ_s/ρ_f = 1.5, 5.1k DOFs, 30 steps, a re-triangulation every 10):
    ``solver = "iterative"`` solves the coupled system by GMRES with the block preconditioner (AMG
    on the velocity block that holds the body rows, Cahouet–Chabard Schur approximation) and
    gives the body velocities of the lagged LU.  Measured: largest difference 7.6e-8 of the
    largest velocity (both solvers stop at their residual tolerances); 26–35 GMRES iterations
    per step, median 30, the same whether or not a re-triangulation came before."""
    from fluidem.coupling.body_krylov import BodyBlockKrylovSolver

    _, _, lu = _run("lagged")
    scene, sim, it = _run("iterative")
    assert isinstance(sim.flow.coupled.solver, BodyBlockKrylovSolver)
    assert sim.counters["transfers"] == 3
    assert "block-preconditioned GMRES with the body velocities in the velocity block" in str(scene.plan())
    V_lu, V_it = lu[:, :3], it[:, :3]
    assert np.abs(V_it - V_lu).max() < 2e-7 * np.abs(V_lu).max()
    assert it[:, 3].max() <= 70  # measured 35


@pytest.mark.parametrize("solver", ["lagged", "iterative"])
def test_a_re_triangulation_builds_the_new_system_without_the_old_lu(solver):
    """The LU of the old mesh is dropped before the new problem and coupled system are built (it is
    refactorised for the new DOFs anyway): held through the build, it raised the peak memory of 1 000
    settling polygons from 9.6 to 16.3 GB.  The settling disk above, 25 steps with two re-triangulations:
    at each build no LU (``"lagged"``) or block preconditioner (``"iterative"``) and no coupled index maps
    are held, and the body velocities are those of the same run holding them (the solver is set up afresh
    either way): bit for bit, with block GMRES too (pyamg's random start vectors are drawn under a fixed
    seed, :mod:`fluidem.fluid.solvers.seeded`; unseeded they differed by up to 7e-13 of the largest
    velocity)."""
    from fluidem.coupling.moving_flow import MovingMeshFlow

    build = MovingMeshFlow._build

    def run(release):
        held = []

        def spy(self, t):
            coupled = getattr(self, "coupled", None)
            if coupled is not None:  # not the first build
                s = coupled.solver
                held.append((s.direct._lu is not None if solver == "lagged" else s.inner is not None,
                             coupled.system is not None))
            return build(self, t)

        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(MovingMeshFlow, "_build", spy)
            if not release:
                from fluidem.coupling.free_flow import FreeBodyFlow

                mp.setattr(FreeBodyFlow, "_release_factors", lambda self: None)
            _, sim, rows = _run(solver, steps=25)
        return held, rows, getattr(sim.flow.coupled.solver, "factorizations", None)

    held, rows, lus = run(True)
    held_before, rows_before, lus_before = run(False)
    assert held == [(False, False), (False, False)] and held_before == [(True, True), (True, True)]
    assert np.array_equal(rows[:, :3], rows_before[:, :3]) and lus == lus_before
