"""An output folder is owned by one run: refuse, overwrite or restart; the folder records its scene."""

import json

import pytest

from fluidem import Scene, Simulation
from fluidem.cli import main
from fluidem.io import LOCK_FILE, OUTPUT_ENTRIES, OutputDirError, read_history, read_pvd, read_run_record

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
    assert set(OUTPUT_ENTRIES) | {LOCK_FILE} >= {p.name for p in out.iterdir()}  # the lock file stays


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


# -- one writer per folder ---------------------------------------------------------------------
def test_a_second_run_into_a_folder_in_use_is_refused_naming_the_first(tmp_path, capsys):
    from fluidem.io import RunLock

    s, out = _scene(tmp_path), tmp_path / "out"
    with RunLock(out):  # another run holds the folder (flock: a second open of the file conflicts)
        assert main(["run", str(s), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        import os

        assert len(err) == 1 and err[0].startswith(f"fluidem: error: output directory {str(out)!r} is in use by "
                                                   f"another run (pid {os.getpid()} on ")
        assert "wait for it to end, or give another --out" in err[0]
        with pytest.raises(OutputDirError, match="is in use by another run"):
            Simulation(Scene.from_toml(s)).run(out_dir=out, restart=True)
        assert not (out / "history.csv").exists()
    assert main(["run", str(s), "--out", str(out), "--quiet"]) == 0  # released: the folder is free again
    assert main(["run", str(s), "--out", str(out), "--quiet", "--restart"]) == 0  # and after a run ends


def test_a_restart_into_a_run_in_progress_in_another_process_is_refused(tmp_path):
    """The case that wrote NUL bytes into history.csv under a 'complete' run.json: a second
    process restarting into the folder of a run still in progress."""
    import os
    import subprocess
    import sys
    import time

    s, out, go = _scene(tmp_path), tmp_path / "out", tmp_path / "go"
    script = ("import pathlib, sys, time\nfrom fluidem import Scene, Simulation\n"
              "def wait(k, n, t, cost):\n"
              "    while k == 2 and not pathlib.Path(sys.argv[3]).exists():\n        time.sleep(0.02)\n"
              "Simulation(Scene.from_toml(sys.argv[1])).run(out_dir=sys.argv[2], progress=wait)\n")
    first = subprocess.Popen([sys.executable, "-c", script, str(s), str(out), str(go)], stderr=subprocess.PIPE,
                             text=True)  # holds the folder at step 2 until told to go on
    try:
        deadline = time.monotonic() + 60
        while read_run_record(out).get("status") != "running" and time.monotonic() < deadline:
            time.sleep(0.05)
        assert read_run_record(out).get("status") == "running"
        second = subprocess.run([sys.executable, "-m", "fluidem", "run", str(s), "--out", str(out), "--restart",
                                 "--quiet"], capture_output=True, text=True, timeout=120)
        assert second.returncode == 2
        assert f"is in use by another run (pid {first.pid} on " in second.stderr
    finally:
        go.touch()
        first.wait(timeout=300)
    assert first.returncode == 0, first.stderr
    assert b"\0" not in (out / "history.csv").read_bytes() and read_run_record(out)["status"] == "complete"
    assert read_history(out)["step"].tolist() == list(range(13))
    assert os.path.exists(out / LOCK_FILE) and (out / LOCK_FILE).read_text() == ""  # released, left empty


# -- only the run's own files ------------------------------------------------------------------
def test_a_hand_written_scene_toml_in_the_folder_is_never_removed_or_written_over(tmp_path, capsys):
    out = tmp_path / "work"
    out.mkdir()
    mine = out / "scene.toml"
    mine.write_text(DRY.format(t_end=0.03, every=1) + "# my notes\n")
    assert main(["run", str(mine), "--out", str(out), "--quiet", "--restart"]) == 2  # no checkpoints there
    for flags in ([], ["--overwrite"]):
        assert main(["run", str(mine), "--out", str(out), "--quiet", *flags]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err[-1] == (f"fluidem: error: output directory {str(out)!r} holds scene.toml, which no run there wrote "
                           "(no run.json lists it); a run would write over it: move it away or give another --out")
        assert mine.read_text().endswith("# my notes\n")


def test_run_json_lists_what_overwrite_may_remove(tmp_path):
    s, out = _scene(tmp_path), tmp_path / "out"
    Simulation(Scene.from_toml(s)).run(out_dir=out)
    assert read_run_record(out)["entries"] == list(OUTPUT_ENTRIES)
    rec = read_run_record(out)
    rec["entries"] = [e for e in rec["entries"] if e != "events.log"]  # a run that did not write events.log
    (out / "run.json").write_text(json.dumps(rec))
    with pytest.raises(OutputDirError, match="holds events.log, which no run there wrote"):
        Simulation(Scene.from_toml(s)).run(out_dir=out, overwrite=True)
    assert (out / "events.log").exists() and (out / "history.csv").exists()
