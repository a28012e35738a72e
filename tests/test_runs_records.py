"""What a run's record says is true: steps within t_end, final loads after a no-op restart, the
cost, summary and last fields of a failed or interrupted run, a folder made read-only mid-run,
and one-line errors for arguments of the wrong kind."""

import json
import os
import signal

import numpy as np
import pytest

from fluidem import Scene, Simulation
from fluidem.cli import main
from fluidem.errors import InputError
from fluidem.io import read_history, read_pvd, read_run_record
from fluidem.simulation import RunStopped

from test_runs_errors import DRY, _err
from tiny_scene import tiny_channel


@pytest.fixture
def channel(tmp_path):
    """The tiny channel past a fixed cylinder to t = 0.6 (6 steps), fields every 4 steps."""
    p = tmp_path / "channel.toml"
    p.write_text(tiny_channel(t_end=0.6, output="every = 4"))
    return p


def test_more_steps_than_the_scene_has_are_refused(tmp_path, capsys):
    p = tmp_path / "dry.toml"
    p.write_text(DRY)  # 5 steps to t_end = 0.05
    assert main(["run", str(p), "--out", str(tmp_path / "o"), "--steps", "7", "--quiet"]) == 2
    assert _err(capsys) == ("fluidem: error: n_steps (--steps) = 7: the scene has 5 steps to time.t_end = 0.05; "
                            "expected at most 5 (raise time.t_end to run longer)")
    assert not (tmp_path / "o").exists() or not (tmp_path / "o" / "history.csv").exists()


def test_a_restart_of_a_complete_run_keeps_its_final_loads(channel, tmp_path):
    out = tmp_path / "o"
    Simulation(channel).run(out_dir=out)
    before = read_run_record(out)["summary"]["bodies"]["cylinder"]
    h = read_history(out)
    assert before["fx"] == h["fx"][-1] != 0.0  # the drag of the last step, 0.0655 here
    Simulation(channel).run(out_dir=out, restart=True)  # nothing left to do
    after = read_run_record(out)
    assert after["status"] == "complete" and after["summary"]["bodies"]["cylinder"] == before


def _fail_after(monkeypatch, t_fail):
    import fluidem.simulation as simulation
    from fluidem.coupling.fixed_flow import FixedMeshFlow

    monkeypatch.setattr(simulation, "SNAPSHOT_RATIO", 0.0)  # a snapshot after every step
    orig = FixedMeshFlow.step

    def step(self, dt):
        orig(self, dt)  # the state moves on, then the step fails
        if self.t > t_fail:
            self.x[:] = np.nan
            raise MemoryError("out of memory")

    monkeypatch.setattr(FixedMeshFlow, "step", step)


def test_a_failed_run_records_its_cost_summary_and_the_last_good_fields(channel, tmp_path, monkeypatch):
    out = tmp_path / "o"
    _fail_after(monkeypatch, 0.25)  # step 3 fails
    with pytest.raises(RunStopped, match=r"step 3 \(t = 0.3\) failed: out of memory; the output holds steps 0 to 2"):
        Simulation(channel).run(out_dir=out)
    rec = read_run_record(out)
    assert rec["status"] == "failed" and rec["cost"]["counts"]["steps"] == 2
    h = read_history(out)
    cyl = rec["summary"]["bodies"]["cylinder"]
    assert rec["summary"]["steps"] == 2 and cyl["fx"] == h["fx"][-1] and np.isfinite(cyl["fx"])
    assert [s for s, _, _ in read_pvd(out / "fields_full.pvd", with_steps=True)] == [0, 2]  # 2: the last good step
    from fluidem.io import read_fields

    u = read_fields(out, 2).point_data["velocity"]
    assert np.isfinite(u).all() and np.abs(u).max() > 0.1  # the good state, not the failed step's NaN


def test_an_interrupted_run_records_its_summary_and_the_last_fields(channel, tmp_path):
    out = tmp_path / "o"
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        def progress(step, n, t, cost):
            if step == 3:
                os.kill(os.getpid(), signal.SIGINT)

        with pytest.raises(RunStopped, match="interrupted by SIGINT after step 3 of 6"):
            Simulation(channel).run(out_dir=out, progress=progress)
    finally:
        signal.signal(signal.SIGINT, old)
    rec = read_run_record(out)
    assert rec["status"] == "interrupted" and rec["summary"]["steps"] == 3 and rec["cost"]["counts"]["steps"] == 3
    assert rec["summary"]["bodies"]["cylinder"]["fx"] == read_history(out)["fx"][-1]
    assert [s for s, _, _ in read_pvd(out / "fields.pvd", with_steps=True)] == [0, 3]


def test_a_folder_made_read_only_mid_run_is_named_and_run_json_does_not_stay_running(channel, tmp_path, monkeypatch):
    """Root ignores permission bits, so the read-only folder is simulated: from step 2 no new file
    can be made in it (the VTU series and every write-then-rename fail), files open stay writable."""
    from fluidem.io import OutputWriter

    out = tmp_path / "o"
    add, replace = OutputWriter._add, os.replace

    def no_new_files(self, name, step, t, mesh):
        if step >= 2:
            raise PermissionError(13, "Permission denied", str(self.dir / f"{name}/{name}_{step:07d}.vtu"))
        return add(self, name, step, t, mesh)

    def no_rename(src, dst):
        if "run.json" in str(dst) or "ckpt_0000002" in str(dst):
            raise PermissionError(13, "Permission denied", str(src))
        return replace(src, dst)

    monkeypatch.setattr(OutputWriter, "_add", no_new_files)
    monkeypatch.setattr(os, "replace", no_rename)
    with pytest.raises(RunStopped) as err:
        Simulation(channel).run(out_dir=out, n_steps=4)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("step 2 (t = 0.2) failed: writing the output failed (Permission denied: ")
    assert f"expected a writable output directory {str(out)!r} with free space" in msg
    monkeypatch.setattr(os, "replace", replace)
    rec = json.loads((out / "run.json").read_text())  # written over in place
    assert rec["status"] == "failed" and rec["message"] == msg


_TINY = {"domain": {"box": [0, 1, 0, 1]}, "time": {"dt": 0.1, "t_end": 0.2}}


@pytest.mark.parametrize("call,message", [
    (lambda: Simulation(None), "Simulation(scene = 'None'): expected a Scene, a scene dict or the path of a TOML "
                               "scene file"),
    (lambda: Simulation(5), "Simulation(scene = '5'): expected a Scene"),
    (lambda: Simulation(_TINY).run(out_dir=5),
     "out_dir = 5: expected the path of a directory (str or Path), 'scene' for [output] dir, or None to write "
     "nothing"),
    (lambda: Simulation(_TINY).run(out_dir=""), "out_dir = '': expected the path"),
    (lambda: Simulation(_TINY).run(out_dir=None, progress=5),
     "progress = 5: expected None or a callable progress(step, n_steps, t, cost)"),
    (lambda: Simulation(_TINY).run(out_dir=None, verbose=5), "verbose = 5: expected True, False or a text stream"),
])
def test_arguments_of_the_wrong_kind_are_one_line(call, message):
    with pytest.raises(InputError) as err:
        call()
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_a_scene_dict_runs():
    sim = Simulation({"gravity": [0, -10], "bodies": [{"shape": "disk", "radius": 0.1, "position": [0, 1]}],
                      "domain": {"box": [-1, 1, -1, 2]}, "time": {"dt": 0.1, "t_end": 0.2}})
    assert isinstance(sim.scene, Scene) and sim.run(out_dir=None).steps == 2
    assert sim.bodies.positions[0, 1] == pytest.approx(1 - 10 * 0.2**2 / 2, rel=1e-14)  # free fall, closed form


def test_a_dry_scene_without_contacts_whose_body_reaches_the_floor_is_warned(tmp_path, capsys):
    from test_runs_output import DRY as TEMPLATE

    falls = tmp_path / "falls.toml"
    falls.write_text(TEMPLATE.format(t_end=1.0, every=50))  # from y = 0.5 it falls 4.9 in 1 s: through the floor
    assert main(["plan", str(falls)]) == 0
    out = capsys.readouterr()
    assert ("no [contact] table: 0 body pair(s) and 1 body–wall pair(s) can meet before t_end = 1, and without "
            "contacts bodies pass through each other and through the walls") in out.out + out.err
    stays = tmp_path / "stays.toml"
    stays.write_text(TEMPLATE.format(t_end=0.12, every=1))  # falls 0.07: never reaches the floor, no warning
    assert Scene.from_toml(stays).plan().warnings == []


def test_a_recorded_step_evaluates_the_residual_once_for_the_body_and_the_sides(channel, tmp_path, monkeypatch):
    """The bodies' loads and the sides' forces of a recorded step come from one residual (a pass over all
    elements; two before), and a later fresh evaluation gives the same sides.csv and history.csv rows bit
    for bit."""
    import csv

    from fluidem.fluid.forces import side_loads
    from fluidem.fluid.navier_stokes import BDFStepper

    calls = []
    original = BDFStepper.last_residual

    def counted(self):
        calls.append(1)
        return original(self)

    monkeypatch.setattr(BDFStepper, "last_residual", counted)
    sim = Simulation(Scene.from_toml(channel))
    sim.run(out_dir=tmp_path / "o")
    assert len(calls) == 6  # six steps, each recorded (history every step): one residual each
    rows = [r for r in csv.DictReader(open(tmp_path / "o" / "sides.csv")) if int(r["step"]) == 6]
    names = [r["side"] for r in rows]
    fresh = side_loads(sim.flow.space, sim.flow.residual(), names, rho=sim.scene.fluid.density)
    assert np.array_equal(np.array([[float(r["fx"]), float(r["fy"])] for r in rows]), fresh)
    F, _ = sim.flow.loads()
    last = [r for r in csv.DictReader(open(tmp_path / "o" / "history.csv")) if int(r["step"]) == 6]
    assert np.array_equal(np.array([[float(r["fx"]), float(r["fy"])] for r in last]), F)
