"""A moving body may touch a wall in a fluid scene (the moving mesh merges it with the wall)."""

from __future__ import annotations

import numpy as np
import pytest

from fluidem.errors import SceneError
from fluidem.scene import Scene
from fluidem.simulation import Simulation


def _scene(y, motion="prescribed"):
    body = {"shape": "rectangle", "width": 0.3, "height": 0.1, "position": [0.6, y], "motion": motion}
    if motion == "prescribed":
        body["velocity"] = [0.5, 0.0]
    return Scene.from_dict({"fluid": {"model": "navier-stokes", "viscosity": 0.05, "element": "th"},
                            "domain": {"box": [0.0, 2.0, 0.0, 1.0]}, "bodies": [body],
                            "mesh": {"h": 0.05}, "time": {"dt": 0.02, "t_end": 0.06}})


def test_a_block_sliding_on_the_floor_runs_and_an_overlapping_one_is_refused():
    sim = Simulation(_scene(0.05))                      # its lower face lies on the floor y = 0
    sim.run(out_dir=None)
    assert len(sim.flow.mm.walls) and np.isfinite(sim.flow.x).all()
    F, _ = sim.flow.loads()
    assert F[0, 0] < 0                                  # dragged back by the fluid it pushes
    with pytest.raises(SceneError, match="on a wall"):
        _scene(0.049)                                   # 1e-3 into the floor
    with pytest.raises(SceneError, match="strictly inside"):
        _scene(0.05, motion="fixed")                    # a fixed body is meshed once, away from walls


def test_iterative_solver_follows_the_problem_through_re_triangulations():
    """The block preconditioner holds the pressure and velocity masses of its problem: after a
    re-triangulation they must be the new problem's (they were not: a shape error)."""
    d = {"fluid": {"model": "navier-stokes", "viscosity": 0.05, "element": "th", "solver": "iterative"},
         "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
         "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.6, 0.5], "motion": "prescribed",
                     "velocity": [1.0, 0.0]}],
         "mesh": {"h": 0.08, "retriangulate_every": 2}, "time": {"dt": 0.02, "t_end": 0.1}}
    direct = dict(d, fluid=dict(d["fluid"], solver="direct"))
    a, b = Simulation(Scene.from_dict(d)), Simulation(Scene.from_dict(direct))
    a.run(out_dir=None)
    b.run(out_dir=None)
    assert a.counters["triangulations"] >= 3
    # the same flow to the Krylov tolerance (measured 5.5e-12 relative in the drag)
    assert a.flow.loads()[0][0, 0] == pytest.approx(b.flow.loads()[0][0, 0], rel=2e-11)
