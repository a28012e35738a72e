"""`fluidem run | plan | examples | plot` and the PNG figures."""

import pytest

from fluidem.cli import main
from fluidem.io import read_history, read_pvd


def test_examples_and_plan(capsys):
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    for name in ("dfg-cylinder", "wall-correction", "dry-heap", "column-collapse", "column-collapse-fluid",
                 "column-collapse-fluid-dry"):
        assert name in out
    assert main(["plan", "--example", "dry-heap"]) == 0
    out = capsys.readouterr().out
    assert "mesh            off" in out and "contacts        on" in out


def test_run_plot_and_restart(tmp_path, capsys):
    out = tmp_path / "wc"
    assert main(["run", "--example", "wall-correction", "--out", str(out), "--plot"]) == 0
    captured = capsys.readouterr()
    assert "1/1" in captured.err and "ETA" in captured.err and "fluid" in captured.err
    for f in ("history.csv", "fields.pvd", "bodies.pvd", "events.log", "mesh_quality.csv", "scene.toml",
              "plots/velocity.png", "plots/pressure.png", "plots/mesh.png", "plots/trajectories.png",
              "plots/history.png"):
        assert (out / f).exists(), f
    _check_wall_correction_figures(out)
    assert len(read_pvd(out / "fields.pvd")) == 2
    h = read_history(out)
    assert h["fx"][-1] < 0  # drag on a cylinder moving in +x
    assert (out / "checkpoints").is_dir()
    # the scene as run is a valid scene file
    assert main(["plan", str(out / "scene.toml")]) == 0
    capsys.readouterr()
    assert main(["plot", str(out), "--to", str(tmp_path / "png")]) == 0
    assert (tmp_path / "png" / "velocity.png").exists()


def test_dry_run_restart_from_cli(tmp_path, capsys):
    out = tmp_path / "cc"
    assert main(["run", "--example", "column-collapse", "--out", str(out), "--steps", "4", "--quiet"]) == 0
    assert main(["run", "--example", "column-collapse", "--out", str(out), "--steps", "6", "--quiet",
                 "--restart"]) == 0
    h = read_history(out)
    assert sorted(set(h["step"].tolist())) == [0, 4, 5, 6]  # history_every = 5, and each run's last step
    assert "restart" in (out / "events.log").read_text()


@pytest.mark.parametrize("argv,words", [
    (["run"], ["no scene"]),
    (["run", "--example", "nope"], ["unknown example scene 'nope'", "dry-heap"]),
    (["plan", "missing.toml"], ["does not exist"]),
    (["plot", "."], ["not a fluidem run directory"]),
])
def test_cli_errors(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err


def test_errors_are_one_line_and_debug_shows_the_traceback(capsys, tmp_path, monkeypatch):
    from fluidem.errors import FluidemError, SceneError

    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text('[domain]\nbox = [0.0, 1.0, 0.0, 1.0]\nleft = "slippery"\n')
    assert main(["plan", "bad.toml"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fluidem: error: domain.left = 'slippery': expected one of")
    assert "Traceback" not in err
    for argv in (["--debug", "plan", "bad.toml"], ["plan", "bad.toml", "--debug"]):
        with pytest.raises(SceneError, match="slippery"):
            main(argv)

    class Broken(FluidemError):
        pass

    def fail(*args, **kw):
        raise Broken("the mesher gave up\non two lines")

    import fluidem.cases.scenes

    monkeypatch.setattr(fluidem.cases.scenes, "example_scene", fail)
    assert main(["plan", "--example", "dry-heap"]) == 2
    assert capsys.readouterr().err == "fluidem: error: the mesher gave up on two lines\n"


def test_cli_accepts_registry_aliases():
    from fluidem.cli import _build_parser

    args = _build_parser().parse_args(["bench", "dfg-2d2", "--solver", "lagged-lu"])
    assert args.solver == "lagged"
    with pytest.raises(SystemExit):
        _build_parser().parse_args(["bench", "dfg-2d2", "--solver", "lu"])


def _check_wall_correction_figures(out):
    """A 24:1 box is cropped to a 4:1 view around the body; the body drawn over the field is the field mesh's hole."""
    import matplotlib.pyplot as plt
    import numpy as np

    from fluidem.plotting import figures

    figs = figures(out)
    (ax,) = [a for a in figs["velocity"].axes if a.get_label() != "<colorbar>"]
    x0, x1 = ax.get_xlim()
    assert x1 - x0 == pytest.approx(8.0) and ax.get_ylim() == (-1.0, 1.0) and "view" in ax.get_title()
    assert ax.get_xlabel() == "x [length]" and ax.get_ylabel() == "y [length]"
    # the quasi-steady flow of the single step is computed around x = 0, where the body was; its outline
    # record at the end of the step is at x = 1: the field figure draws the hole of the field's mesh
    holes = [c for c in ax.collections if c.__class__.__name__ == "PolyCollection"]
    pts = np.vstack([p.vertices for c in holes for p in c.get_paths()])
    assert 0.5 * (pts[:, 0].min() + pts[:, 0].max()) == pytest.approx(0.0, abs=1e-9)
    assert pts[:, 0].max() == pytest.approx(0.2, rel=1e-9)  # the radius-0.2 disk about x = 0
    assert read_history(out)["x"][-1] == pytest.approx(1.0)
    for f in figs.values():
        plt.close(f)


_CANNOT_RUN = """name = "cannot-run"
[fluid]
model = "stokes"
viscosity = 1.0
[domain]
box = [0.0, 10.0, 0.0, 10.0]
[[bodies]]
shape = "disk"
radius = 0.5
position = [5.0, 5.0]
motion = "prescribed"
velocity = [1.0, 0.0]
[mesh]
h = 1e-4
strategy = "fixed"
[time]
dt = 0.1
t_end = 0.2
"""


def test_plan_exits_non_zero_for_a_scene_it_cannot_run_one_line_per_reason(tmp_path, capsys, monkeypatch):
    """Two reasons: a mesh far above any machine's memory, and a fixed mesh under a moving outline."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text(_CANNOT_RUN)
    assert main(["plan", "bad.toml"]) == 2
    cap = capsys.readouterr()
    assert "cannot run yet:" in cap.out and "estimate:" in cap.out  # the plan itself is still printed
    lines = cap.err.splitlines()
    assert len(lines) == 2 and all(s.startswith("fluidem: error: scene 'cannot-run' cannot run: ") for s in lines)
    assert "use strategy 'drag' or 'regenerate'" in lines[0] and "more than this machine's" in lines[1]
    # a scene that can run: status 0 and nothing on stderr
    assert main(["plan", "--example", "wall-correction"]) == 0 and capsys.readouterr().err == ""


def test_run_refuses_a_scene_it_cannot_run_before_building_anything(tmp_path, capsys, monkeypatch):
    import fluidem.simulation

    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text(_CANNOT_RUN)
    built = []
    monkeypatch.setattr(fluidem.simulation.Simulation, "__init__", lambda self, *a, **k: built.append(1))
    assert main(["run", "bad.toml", "--out", "o"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "strategy = 'fixed'" in err[0] and "more than this machine's" in err[1]
    assert not built and not (tmp_path / "o").exists()
    # a dry scene with a fluid side condition
    (tmp_path / "per.toml").write_text('[domain]\nbox = [0.0, 1.0, 0.0, 1.0]\n'
                                       'top = { type = "moving-wall", velocity = [1.0, 0.0] }\n'
                                       '[time]\ndt = 0.1\nt_end = 0.1\n')
    assert main(["run", "per.toml", "--out", "p"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "domain sides top are fluid conditions; a dry scene allows" in err
    assert not built and not (tmp_path / "p").exists()
