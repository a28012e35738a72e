"""An output folder is owned by one run: refuse, overwrite or restart; the folder records its scene."""

import json

import pytest

from fluidem import Scene, Simulation
from fluidem.cli import main
from fluidem.io import OUTPUT_ENTRIES, OutputDirError, read_history, read_pvd, read_run_record

DRY = """
gravity = [0.0, -9.81]
[domain]
box = [0.0, 1.0, 0.0, 1.0]
[[bodies]]
shape = "disk"
radius = 0.05
position = [0.5, 0.5]
[time]
dt = 0.01
t_end = {t_end}
[output]
every = {every}
"""


def _scene(tmp_path, name="dry.toml", t_end=0.12, every=1):
    p = tmp_path / name
    p.write_text(DRY.format(t_end=t_end, every=every))
    return p


def test_a_fresh_run_into_another_runs_folder_is_refused(tmp_path, capsys):
    s, out = _scene(tmp_path), tmp_path / "out"
    assert main(["run", str(s), "--out", str(out), "--quiet"]) == 0
    before = (out / "history.csv").read_text()
    assert main(["run", str(s), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"output directory {str(out)!r} holds the output of another run (scene 'dry', complete at step 12)" in err
    assert "--overwrite" in err and "--restart" in err and "another --out" in err
    assert (out / "history.csv").read_text() == before  # nothing touched
    with pytest.raises(OutputDirError):
        Simulation(Scene.from_toml(s)).run(out_dir=out)


def test_overwrite_clears_the_old_run_so_pvd_history_and_restart_agree(tmp_path, capsys):
    out = tmp_path / "out"
    long = _scene(tmp_path, "long.toml", t_end=0.12, every=1)
    assert main(["run", str(long), "--out", str(out), "--quiet"]) == 0
    assert len(list((out / "bodies").glob("*.vtu"))) == 13
    short = _scene(tmp_path, "short.toml", t_end=0.04, every=2)
    (out / "notes.txt").write_text("mine")
    assert main(["run", str(short), "--out", str(out), "--quiet", "--overwrite"]) == 0
    files = sorted(p.name for p in (out / "bodies").glob("*.vtu"))
    assert len(read_pvd(out / "bodies.pvd")) == len(files) == 3  # steps 0, 2, 4: no stale VTU files
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == \
        [f"ckpt_{k:07d}.npz" for k in range(1, 5)][-3:]  # the default cadence's newest three, all of this run
    assert (out / "notes.txt").read_text() == "mine"  # only run output is removed
    h = read_history(out)
    assert h["step"].tolist() == [0, 1, 2, 3, 4]
    # a restart continues *this* run: from its step 4, not the old run's step 12
    longer = _scene(tmp_path, "short2.toml", t_end=0.06, every=2)
    assert main(["run", str(longer), "--out", str(out), "--quiet", "--restart"]) == 0
    h = read_history(out)
    assert h["step"].tolist() == list(range(7)) and h["t"][-1] == pytest.approx(0.06)
    rec = read_run_record(out)
    assert rec["status"] == "complete" and rec["step"] == 6 and rec["t_end"] == 0.06


def test_the_folder_records_its_scene(tmp_path):
    out = tmp_path / "out"
    Simulation(Scene.from_toml(_scene(tmp_path))).run(out_dir=out)
    rec = json.loads((out / "run.json").read_text())
    assert rec["scene"] == "dry" and rec["status"] == "complete" and rec["source"].endswith("dry.toml")
    assert rec["units"]["fx"] == "force/depth" and "dynamic" in rec["pressure"]
    # the run's cost split: every part non-negative, the bodies' part spent (a dry scene moves only bodies)
    assert min(rec["cost"]["seconds"].values()) >= 0 and rec["cost"]["seconds"]["bodies"] > 0
    assert Scene.from_toml(out / "scene.toml").to_dict()["bodies"] == Scene.from_toml(_scene(tmp_path)).to_dict()[
        "bodies"]
    assert set(OUTPUT_ENTRIES) >= {p.name for p in out.iterdir()}


def test_restart_into_a_folder_of_another_scene_is_refused(tmp_path, capsys):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    assert main(["run", str(_scene(tmp_path)), "--out", str(out), "--quiet", "--steps", "4"]) == 0
    other = tmp_path / "other.toml"
    other.write_text(DRY.format(t_end=0.12, every=1).replace("radius = 0.05", "radius = 0.06"))
    assert main(["run", str(other), "--out", str(elsewhere), "--quiet", "--steps", "4"]) == 0
    ckpt = elsewhere / "checkpoints" / "ckpt_0000004.npz"
    assert main(["run", str(other), "--out", str(out), "--quiet", "--restart", str(ckpt)]) == 2
    err = capsys.readouterr().err
    assert "holds a run of another scene ('dry')" in err and "Traceback" not in err
    # from its own folder the same scene lists what changed
    assert main(["run", str(other), "--out", str(out), "--quiet", "--restart"]) == 2
    assert "changed bodies[0].radius 0.05 -> 0.06" in capsys.readouterr().err


def test_overwrite_and_restart_exclude_each_other(tmp_path):
    with pytest.raises(ValueError, match="restart and overwrite exclude each other"):
        Simulation(Scene.from_toml(_scene(tmp_path))).run(out_dir=tmp_path / "o", restart=True, overwrite=True)
