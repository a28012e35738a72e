"""One-line errors instead of tracebacks, and the small things a run must not do silently."""

import numpy as np
import pytest

import fluidem
from fluidem import Scene, Simulation
from fluidem.cli import main
from fluidem.errors import SceneError
from fluidem.io import read_history

from test_runs_output import DRY as DRY_TEMPLATE

DRY = DRY_TEMPLATE.format(t_end=0.05, every=1)  # the output cadence does not matter here


def _err(capsys):
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("fluidem: error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def dry(tmp_path):
    p = tmp_path / "dry.toml"
    p.write_text(DRY)
    return p


def test_out_naming_an_existing_file_or_a_path_under_a_file(dry, tmp_path, capsys):
    f = tmp_path / "afile"
    f.write_text("x")
    assert main(["run", str(dry), "--out", str(f), "--quiet"]) == 2
    assert "is an existing file" in _err(capsys)
    assert main(["run", str(dry), "--out", str(f / "sub"), "--quiet"]) == 2
    assert "is a file, not a directory" in _err(capsys)


def test_scene_path_that_is_a_directory(tmp_path, capsys):
    assert main(["run", str(tmp_path), "--quiet"]) == 2
    assert "is a directory; expected a TOML file" in _err(capsys)
    assert main(["plan", str(tmp_path)]) == 2
    assert "is a directory" in _err(capsys)


def test_csv_row_with_an_empty_cell(tmp_path, capsys):
    (tmp_path / "b.csv").write_text("x,y\n0.3,0.3\n0.6,\n")
    (tmp_path / "s.toml").write_text("[domain]\nbox = [0.0, 1.0, 0.0, 1.0]\n[bodies_table]\nfile = \"b.csv\"\n"
                                     "shape = \"disk\"\nradius = 0.05\n")
    assert main(["plan", str(tmp_path / "s.toml")]) == 2
    line = _err(capsys)
    assert "row 2 column y: empty" in line and "x and y are required" in line


def test_touching_bodies_in_a_fluid_are_refused_at_validation():
    sq = {"shape": "rectangle", "width": 0.2, "height": 0.2, "motion": "fixed"}
    d = {"fluid": {"model": "stokes", "viscosity": 0.1}, "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
         "bodies": [dict(sq, position=[0.8, 0.5]), dict(sq, position=[1.0, 0.5])],
         "time": {"dt": 0.1, "t_end": 0.1}}
    with pytest.raises(SceneError, match=r"touch at start; in a fluid scene bodies need fluid between them"):
        Scene.from_dict(d)
    del d["fluid"]  # dry: touching is fine
    Scene.from_dict(d)


def test_fixed_strategy_with_a_moving_body_is_refused_before_the_first_step(capsys, tmp_path):
    d = {"fluid": {"model": "stokes", "viscosity": 0.1}, "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
         "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.8, 0.5], "motion": "prescribed",
                     "velocity": [0.5, 0.0]}],
         "mesh": {"h": 0.1, "strategy": "fixed"}, "time": {"dt": 0.1, "t_end": 0.3}}
    s = Scene.from_dict(d)
    assert any("strategy = 'fixed'" in u for u in s.plan().unsupported)
    with pytest.raises(ValueError, match="use strategy 'drag' or 'regenerate'"):
        Simulation(s)


def test_t_end_not_a_multiple_of_dt_is_refused_and_the_last_step_lands_on_t_end(tmp_path):
    with pytest.raises(SceneError, match=r"time.t_end = 0.2: expected a whole number of steps dt = 0.03 "
                                         r"\(e.g. 0.18 or 0.21\)"):
        Scene.from_dict({"domain": {"box": [0, 1, 0, 1]}, "time": {"dt": 0.03, "t_end": 0.2}})
    s = Scene.from_dict({"domain": {"box": [0, 1, 0, 1]}, "time": {"dt": 0.1, "t_end": 0.3},
                         "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.5]}]})
    r = Simulation(s).run(out_dir=tmp_path / "o")
    assert r.steps == 3 and r.t == pytest.approx(0.3, abs=0, rel=1e-15)
    assert read_history(tmp_path / "o")["t"][-1] == pytest.approx(0.3, rel=1e-15)


@pytest.mark.parametrize("value", ["-3", "0", "two"])
def test_negative_or_zero_steps_are_usage_errors(dry, value, capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", str(dry), "--steps", value])
    assert e.value.code == 2
    assert "expected a positive integer" in capsys.readouterr().err


def test_missing_time_table_is_named_by_the_plan(tmp_path, capsys):
    p = tmp_path / "s.toml"
    p.write_text(DRY.split("[time]")[0])
    assert main(["plan", str(p)]) == 0
    assert "no [time] table: default dt = 0.001, t_end = 1" in capsys.readouterr().out


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"fluidem {fluidem.__version__}"


def test_an_unexpected_error_inside_a_run_is_one_line(dry, tmp_path, capsys, monkeypatch):
    from fluidem.coupling.bodies import KinematicBodies

    def boom(self, dt):
        raise IndexError("index 7 is out of bounds")

    monkeypatch.setattr(KinematicBodies, "step", boom)
    assert main(["run", str(dry), "--out", str(tmp_path / "o"), "--quiet"]) == 3
    line = _err(capsys)
    assert "step 1 (t = 0.01) failed: index 7 is out of bounds" in line
    # a failure of the scene and its state recurs on a restart: the line says so instead of advising one
    assert "continue with" not in line and "a --restart from the checkpoint repeats it" in line
    assert np.array_equal(read_history(tmp_path / "o")["step"], [0])


def test_a_failure_of_the_machine_advises_a_restart_that_then_passes(tmp_path):
    """A full disk or memory (:data:`fluidem.simulation.TRANSIENT_FAILURES`) is the machine's: the message
    says how to continue, and the restart completes the run."""
    from fluidem.coupling.bodies import KinematicBodies
    from fluidem.io import read_run_record
    from fluidem.simulation import RunStopped

    orig = KinematicBodies.step
    calls = []

    def full_disk(self, dt):
        calls.append(dt)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        orig(self, dt)

    scene_file = tmp_path / "s.toml"
    scene_file.write_text(DRY)
    scene = Scene.from_toml(scene_file)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(KinematicBodies, "step", full_disk)
        with pytest.raises(RunStopped) as err:
            Simulation(scene).run(out_dir=tmp_path / "o")
    assert "continue with: fluidem run" in str(err.value) and str(err.value).endswith("--restart")
    Simulation(scene).run(out_dir=tmp_path / "o", restart=True)
    assert read_run_record(tmp_path / "o")["status"] == "complete"


def test_an_unexpected_error_outside_a_run_is_one_line_and_debug_shows_it(dry, tmp_path, capsys, monkeypatch):
    import fluidem.simulation as simulation

    def broken(self, scene):
        raise RuntimeError("Triangulation failed")

    monkeypatch.setattr(simulation.Simulation, "__init__", broken)
    assert main(["run", str(dry), "--out", str(tmp_path / "o"), "--quiet"]) == 1
    assert "RuntimeError: Triangulation failed (an unexpected error: run again with --debug" in _err(capsys)
    with pytest.raises(RuntimeError):
        main(["run", str(dry), "--out", str(tmp_path / "o2"), "--quiet", "--debug"])
