"""Every stepping path checks its state each step; the history holds only good steps."""

import numpy as np
import pytest

from fluidem import Scene, Simulation
from fluidem.io import read_history, read_run_record
from fluidem.simulation import RunStopped
from fluidem.state_checks import StateError


def _disk_on_floor(E):
    return {"gravity": [0, -9.81], "domain": {"box": [0, 1, 0, 1]},
            "bodies": [{"shape": "disk", "radius": 0.05, "segments": 16, "density": 5.0, "position": [0.5, 0.06],
                        "name": "puck"}],
            "contact": {"E": E}, "time": {"dt": 0.01, "t_end": 1.0}}


@pytest.fixture
def every_step(monkeypatch):
    """A snapshot of the state after every step (cheap steps otherwise take one every few steps)."""
    import fluidem.simulation as simulation

    monkeypatch.setattr(simulation, "SNAPSHOT_RATIO", 0.0)


@pytest.mark.parametrize("E", [1.0, 10.0])
def test_too_soft_a_contact_stops_the_dem_run_naming_body_quantity_and_cause(E, tmp_path, every_step):
    with pytest.raises(RunStopped) as err:
        Simulation(Scene.from_dict(_disk_on_floor(E))).run(out_dir=tmp_path)
    msg = str(err.value)
    assert "body 'puck': overlap with a wall is" in msg and "allowed 50%" in msg
    assert f"too soft a contact for the load (contact.E = {E:g}: raise it)" in msg
    assert isinstance(err.value.__cause__, StateError) and err.value.exit_status == 3
    h = read_history(tmp_path)
    assert np.isfinite(np.column_stack(list(h.values()))).all()
    size = 2 * np.sqrt(16 * 0.5 * 0.05**2 * np.sin(2 * np.pi / 16) / np.pi)  # disk of the 16-gon's area
    assert (0.05 - h["y"]).max() <= 0.5 * size  # no row beyond the allowed overlap (a vertex points down)
    last = int(h["step"][-1])
    assert err.value.checkpoint.name == f"ckpt_{last:07d}.npz"
    assert read_run_record(tmp_path)["status"] == "failed"


def test_a_non_finite_dem_state_is_caught_before_it_is_recorded(tmp_path, monkeypatch):
    from fluidem.dem import DEM

    orig = DEM.advance

    def advance(self, dt):
        n = orig(self, dt)
        if self.time > 0.045:
            self.gear.X[1][0, 0] = np.nan
        return n

    monkeypatch.setattr(DEM, "advance", advance)
    with pytest.raises(RunStopped, match=r"body 'puck': velocity is not finite \(\[nan, "):
        Simulation(Scene.from_dict(_disk_on_floor(1e5))).run(out_dir=tmp_path)
    h = read_history(tmp_path)
    assert h["step"].tolist() == [0, 1, 2, 3, 4] and np.isfinite(h["vx"]).all()


def test_explicit_convection_blowup_leaves_only_good_rows(tmp_path, every_step):
    d = {"fluid": {"model": "navier-stokes", "viscosity": 0.001, "element": "th", "convection": "explicit"},
         "domain": {"box": [0.0, 2.0, 0.0, 1.0], "left": "inflow", "right": "outflow",
                    "inflow_profile": {"type": "parabolic", "umax": 1.5}},
         "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.6, 0.5], "motion": "fixed"}],
         "mesh": {"h": 0.1}, "time": {"dt": 0.2, "t_end": 40.0}, "output": {"every": 1000}}
    with pytest.raises(RunStopped, match="the time integration diverges; likely cause: too large a dt = 0.2") as err:
        Simulation(Scene.from_dict(d)).run(out_dir=tmp_path)
    h = read_history(tmp_path)
    assert np.isfinite(h["fx"]).all() and np.abs(h["fx"]).max() < 10.0
    assert err.value.checkpoint.name == f"ckpt_{int(h['step'][-1]):07d}.npz"


def test_a_non_finite_moving_mesh_flow_stops_the_run(tmp_path, monkeypatch):
    from fluidem.coupling.moving_flow import MovingMeshFlow

    orig = MovingMeshFlow.step

    def step(self, dt):
        orig(self, dt)
        if self.t > 0.05:
            self.x = self.x.copy()
            self.x[3] = np.inf

    monkeypatch.setattr(MovingMeshFlow, "step", step)
    d = {"fluid": {"model": "navier-stokes", "viscosity": 0.05, "element": "th"},
         "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
         "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.6, 0.5], "motion": "prescribed",
                     "velocity": [1.0, 0.0]}],
         "mesh": {"h": 0.1}, "time": {"dt": 0.02, "t_end": 0.16}}
    with pytest.raises(RunStopped, match=r"step 3 \(t = 0.06\) failed: the flow solution \(velocity or pressure\) "
                                         r"is not finite at 1 DOFs"):
        Simulation(Scene.from_dict(d)).run(out_dir=tmp_path)
    assert read_history(tmp_path)["step"].tolist() == [0, 1, 2]


def test_cheap_steps_snapshot_every_few_steps_and_say_which_state_is_saved(tmp_path):
    with pytest.raises(RunStopped, match=r"the output holds steps 0 to (\d+), the last good state (saved \(step "
                                         r"\d+\) )?is in checkpoint") as err:
        Simulation(Scene.from_dict(_disk_on_floor(1.0))).run(out_dir=tmp_path)
    h = read_history(tmp_path)
    assert int(err.value.checkpoint.name[5:12]) <= int(h["step"][-1])


def test_without_output_the_state_error_itself_propagates():
    with pytest.raises(StateError, match="body 'puck': overlap"):
        Simulation(Scene.from_dict(_disk_on_floor(1.0))).run(out_dir=None)
