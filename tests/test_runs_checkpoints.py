"""Checkpoints: safe format, atomic, default cadence, interrupts and failures, damaged files, restart rules."""

import json
import os
import signal
import zipfile

import numpy as np
import pytest

from fluidem import Scene, Simulation
from fluidem.checkpoint import CheckpointError, load
from fluidem.cli import main
from fluidem.io import load_checkpoint, read_history, read_run_record
from fluidem.simulation import RunStopped, RunWarning

DRY = {"gravity": [0.0, -9.81], "domain": {"box": [0.0, 0.4, 0.0, 0.4]},
       "bodies": [{"shape": "disk", "radius": 0.015, "segments": 6, "density": 100.0, "angle": 0.1 * i,
                   "position": [0.1 + 0.04 * (i % 5), 0.03 + 0.04 * (i // 5)]} for i in range(10)],
       "contact": {"E": 1e5, "mu": 0.3, "gamma": 0.1}, "time": {"dt": 4e-3, "t_end": 0.08}}


def _same_history(a, b):
    a, b = read_history(a), read_history(b)
    assert np.array_equal(a["step"], b["step"])
    return max(float(np.abs(a[k] - b[k]).max()) for k in a)


def test_checkpoints_are_npz_with_a_json_header_written_atomically_at_a_default_cadence(tmp_path):
    Simulation(Scene.from_dict(DRY)).run(out_dir=tmp_path)
    files = sorted((tmp_path / "checkpoints").iterdir())
    assert [f.name for f in files] == ["ckpt_0000016.npz", "ckpt_0000018.npz", "ckpt_0000020.npz"]  # every 2
    with zipfile.ZipFile(files[-1]) as z:
        assert all(n.endswith(".npy") for n in z.namelist())
        with z.open("header.npy") as f:
            arr = np.lib.format.read_array(f, allow_pickle=False)
    head = json.loads(bytes(arr).decode())
    assert head["format"] == "fluidem-checkpoint-npz-1" and head["step"] == 20 and head["dt"] == 0.004
    assert head["scene"]["contact"]["E"] == 1e5 and head["plan"]["bodies"] == "DEMBodies"
    header, state = load(files[-1])
    assert state["bodies"]["dem"].positions.shape == (10, 2)
    assert not list((tmp_path / "checkpoints").glob("*.tmp"))


def test_wall_clock_cadence(tmp_path):
    d = dict(DRY, output={"checkpoint_every": 0, "checkpoint_seconds": 1e-9})
    Simulation(Scene.from_dict(d)).run(out_dir=tmp_path, n_steps=5)
    assert len(list((tmp_path / "checkpoints").iterdir())) == 5


def test_loading_never_executes_code(tmp_path):
    bad = tmp_path / "ckpt_0000001.npz"
    head = {"format": "fluidem-checkpoint-npz-1", "version": 2, "step": 1, "t": 0.1, "n_arrays": 0,
            "state": {"__obj__": "os:system", "id": 0, "state": "echo hacked"}}
    np.savez(bad, header=np.frombuffer(json.dumps(head).encode(), np.uint8))
    with pytest.raises(CheckpointError, match="class = 'os:system': not one of fluidem's checkpoint state classes"):
        load(bad)
    obj = tmp_path / "ckpt_0000002.npz"
    np.savez(obj, header=np.frombuffer(json.dumps(dict(head, state=None, n_arrays=1)).encode(), np.uint8),
             a0=np.array([{"a": 1}], dtype=object))
    with pytest.raises(CheckpointError, match="is damaged or truncated"):
        load(obj)
    pkl = tmp_path / "ckpt_0000003.pkl"
    pkl.write_bytes(b"\x80\x04K\x01.")
    with pytest.raises(CheckpointError, match="loading a pickle can execute code"):
        load_checkpoint(pkl)


def _crafted(path, tree):
    head = {"format": "fluidem-checkpoint-npz-1", "version": 2, "step": 10, "t": 0.04, "n_arrays": 0, "state": tree}
    path.write_bytes(b"")
    with open(path, "wb") as f:
        np.savez(f, header=np.frombuffer(json.dumps(head).encode(), np.uint8))


@pytest.mark.parametrize("tag", ["__enum__", "__obj__"])
def test_a_crafted_checkpoint_naming_a_class_through_a_module_attribute_runs_nothing(tmp_path, capsys, tag):
    """A class reached by walking attributes from a fluidem module (here subprocess.Popen through
    numpy.f2py) is not looked up; a restart skips the file with a warning and continues from the
    previous checkpoint, as if the file were damaged."""
    marker = tmp_path / "ran"
    name = "fluidem.checkpoint:np.f2py.subprocess.Popen"
    tree = {"__dict__": [["bodies", {tag: name, "value": ["touch", str(marker)], "id": 0, "state": {"__dict__": []}}]]}
    with pytest.raises(CheckpointError):
        _crafted(tmp_path / "c.npz", tree)
        load(tmp_path / "c.npz")
    for bad in ("fluidem.dem.system:np.f2py", "fluidem.dem.system:DEM.__init__", "fluidem.dem.system:DEM ",
                ["fluidem.dem.system:DEM"]):
        _crafted(tmp_path / "d.npz", {"__obj__": bad, "id": 0, "state": {"__dict__": []}})
        with pytest.raises(CheckpointError, match="not one of fluidem's checkpoint state classes"):
            load(tmp_path / "d.npz")
    scene = tmp_path / "s.toml"
    Scene.from_dict(DRY).to_toml(scene)
    out = tmp_path / "o"
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--steps", "10"]) == 0
    _crafted(out / "checkpoints" / "ckpt_0000010.npz", tree)
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--restart"]) == 0
    assert not marker.exists()
    err = capsys.readouterr().err
    assert "ckpt_0000010.npz" in err and "continuing from the previous valid checkpoint" in err
    assert "Traceback" not in err


def _edit_newest(out, edit):
    """Load the newest checkpoint of ``out``, change its state with ``edit(state)`` and save it again."""
    from fluidem.checkpoint import save

    path = sorted((out / "checkpoints").glob("ckpt_*.npz"))[-1]
    header, state = load(path)
    edit(state)
    header.pop("n_arrays")
    save(path, header, state)
    return path


def _drop_a_body(state):
    g = state["bodies"]["dem"].gear
    g.X = g.X[:, :-1].copy()


def _swap_class(state):
    from fluidem.dem.contact import Contacts

    state["bodies"]["dem"] = Contacts.empty()


@pytest.mark.parametrize("edit,why", [(_drop_a_body, r"state.bodies.dem.gear.X: an array of shape \(3, 9, 3\) "
                                                     r"\(expected \(3, 10, 3\)\)"),
                                      (_swap_class, "state.bodies.dem: a fluidem.dem.contact.Contacts "
                                                    "\\(expected a fluidem.dem.system.DEM\\)")])
def test_a_checkpoint_edited_by_hand_is_damaged_and_the_previous_one_is_used(tmp_path, edit, why):
    out, full = tmp_path / "o", tmp_path / "full"
    Simulation(Scene.from_dict(DRY)).run(out_dir=out, n_steps=10)
    path = _edit_newest(out, edit)
    aside = tmp_path / path.name
    aside.write_bytes(path.read_bytes())
    with pytest.warns(RunWarning, match=f"checkpoint {str(path)!r} does not fit the scene: {why}; continuing from "
                                        "the previous valid checkpoint .*ckpt_0000009.npz"):
        Simulation(Scene.from_dict(DRY)).run(out_dir=out, restart=True)
    Simulation(Scene.from_dict(DRY)).run(out_dir=full)
    assert _same_history(full, out) == 0.0
    with pytest.raises(CheckpointError, match="does not fit the scene"):  # given by name: no fall-back
        Simulation(Scene.from_dict(DRY)).run(out_dir=tmp_path / "o2", restart=aside)


def test_a_flow_vector_of_another_size_is_damaged(tmp_path):
    from tiny_scene import tiny_channel

    scene = tmp_path / "s.toml"
    scene.write_text(tiny_channel(t_end=0.3))
    out = tmp_path / "o"
    Simulation(scene).run(out_dir=out, n_steps=2)
    path = _edit_newest(out, lambda s: s["flow"].update(x=s["flow"]["x"][:-3].copy()))
    sim = Simulation(scene)
    n = sim.flow.dofs
    with pytest.raises(CheckpointError, match=rf"does not fit the scene: flow of shape \({n - 3},\) \(expected finite "
                                              rf"numbers of shape \({n},\)\)$"):
        sim.run(out_dir=out, restart=path)


@pytest.fixture(autouse=True)
def _signals_handled():
    """Ctrl-C and SIGTERM as an interactive shell leaves them: a shell starting the tests in the
    background sets SIGINT to 'ignore', which a run rightly leaves alone."""
    old = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    yield
    for sig, handler in old.items():
        signal.signal(sig, handler)


def _interrupt_at(k, sig=signal.SIGINT):
    def progress(step, n, t, cost):
        if step == k:
            os.kill(os.getpid(), sig)
    return progress


def test_sigint_checkpoints_the_last_step_says_how_to_restart_and_the_restart_matches(tmp_path):
    full, part = tmp_path / "full", tmp_path / "part"
    Simulation(Scene.from_dict(DRY)).run(out_dir=full)
    with pytest.raises(RunStopped) as err:
        Simulation(Scene.from_dict(DRY)).run(out_dir=part, progress=_interrupt_at(7))
    e = err.value
    assert e.exit_status == 130 and e.status == "interrupted" and e.checkpoint.name == "ckpt_0000007.npz"
    assert "interrupted by SIGINT after step 7 of 20" in str(e)
    assert f"continue with: fluidem run {part / 'scene.toml'} --out {part} --restart" in str(e)
    assert read_history(part)["step"][-1] == 7 and read_run_record(part)["status"] == "interrupted"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # handlers restored
    Simulation(Scene.from_dict(DRY)).run(out_dir=part, restart=True)
    assert _same_history(full, part) == 0.0


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signals_through_the_command_line(tmp_path, capsys, monkeypatch, sig, code):
    import fluidem.cli as cli

    scene = tmp_path / "s.toml"
    Scene.from_dict(DRY).to_toml(scene)
    monkeypatch.setattr(cli, "_ProgressBar", lambda: _interrupt_at(3, sig))
    assert main(["run", str(scene), "--out", str(tmp_path / "o")]) == code
    out = capsys.readouterr()
    err = out.err.strip().splitlines()
    assert "Traceback" not in out.err and "KeyboardInterrupt" not in out.err
    assert err[-1].startswith(f"fluidem: error: interrupted by {sig.name} after step 3 of 20")
    assert err[-1].endswith(f"continue with: fluidem run {scene} --out {tmp_path / 'o'} --restart")


def test_an_error_inside_a_step_checkpoints_the_step_before(tmp_path, monkeypatch):
    import fluidem.simulation as simulation
    from fluidem.coupling.bodies import DEMBodies

    monkeypatch.setattr(simulation, "SNAPSHOT_RATIO", 0.0)  # a snapshot after every step

    full, part = tmp_path / "full", tmp_path / "part"
    Simulation(Scene.from_dict(DRY)).run(out_dir=full)
    orig = DEMBodies.step

    def step(self, dt):
        orig(self, dt)  # the state moves on, then the step fails half-way
        if self.dem.time > 0.0225:
            raise MemoryError("out of memory")

    monkeypatch.setattr(DEMBodies, "step", step)
    with pytest.raises(RunStopped, match=r"step 6 \(t = 0.024\) failed: out of memory; the output holds steps 0 "
                                         r"to 5, the last good state is in checkpoint .*ckpt_0000005.npz") as err:
        Simulation(Scene.from_dict(DRY)).run(out_dir=part)
    assert isinstance(err.value.__cause__, MemoryError)
    monkeypatch.setattr(DEMBodies, "step", orig)
    Simulation(Scene.from_dict(DRY)).run(out_dir=part, restart=True)
    assert _same_history(full, part) == 0.0


@pytest.mark.parametrize("damage", ["truncate", "empty", "garbage"])
def test_a_damaged_newest_checkpoint_falls_back_to_the_previous(tmp_path, capsys, damage):
    scene = tmp_path / "s.toml"
    Scene.from_dict(DRY).to_toml(scene)
    out = tmp_path / "o"
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--steps", "10"]) == 0
    newest = out / "checkpoints" / "ckpt_0000010.npz"
    data = newest.read_bytes()
    newest.write_bytes({"truncate": data[: len(data) // 2], "empty": b"", "garbage": b"not a zip"}[damage])
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--restart"]) == 0
    err = capsys.readouterr().err
    assert f"fluidem: warning: checkpoint {str(newest)!r} is" in err
    assert "continuing from the previous valid checkpoint" in err and "ckpt_0000009.npz" in err  # every step
    assert "Traceback" not in err
    full = tmp_path / "full"
    Simulation(Scene.from_dict(DRY)).run(out_dir=full)
    assert _same_history(full, out) == 0.0


def test_no_valid_checkpoint_is_one_line(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    Scene.from_dict(DRY).to_toml(scene)
    out = tmp_path / "o"
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--steps", "2"]) == 0
    for f in (out / "checkpoints").iterdir():
        f.write_bytes(b"")
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--restart"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("fluidem: error: no valid checkpoint in ") and "is empty" in err[0]
    with pytest.raises(CheckpointError, match="no valid checkpoint"):
        Simulation(Scene.from_dict(DRY)).run(out_dir=out, restart=True)


def test_restart_with_a_changed_dt_or_body_is_refused_with_the_list_of_changes(tmp_path):
    out = tmp_path / "o"
    Simulation(Scene.from_dict(DRY)).run(out_dir=out, n_steps=4)
    d = json.loads(json.dumps(DRY))
    d["time"] = {"dt": 2e-3, "t_end": 0.16}
    d["bodies"][3]["density"] = 50.0
    with pytest.raises(ValueError) as err:
        Simulation(Scene.from_dict(d)).run(out_dir=out, restart=True)
    msg = str(err.value)
    assert "belongs to a different scene: changed time.dt 0.004 -> 0.002; bodies[3].density 100.0 -> 50.0" in msg
    assert "a restart may change only time.t_end and [output]" in msg and "t_end" not in msg.split(";")[0]


def test_a_key_added_since_a_run_was_written_does_not_count_as_a_change_at_its_old_value():
    """``[mesh] repair`` was added after runs had been written: a scene without it ran with
    ``false``, so an older checkpoint (or run.json digest) continues with ``false`` and is refused with
    ``true`` (``fluidem.restart.ADDED_KEYS``)."""
    from fluidem.restart import scene_changes, scene_key

    old = {"fluid": {"viscosity": 0.01}, "mesh": {"h": 0.05}}
    same = {"fluid": {"viscosity": 0.01}, "mesh": {"h": 0.05, "repair": False}}
    on = {"fluid": {"viscosity": 0.01}, "mesh": {"h": 0.05, "repair": True}}
    assert scene_changes(old, same) == [] and scene_key(old) == scene_key(same)
    assert scene_changes(old, on) == ["mesh.repair (absent) -> True"] and scene_key(old) != scene_key(on)


def _off_centre_polygons():
    """Ten pentagons and hexagons given off their centroid: loading shifts each onto it, leaving
    coordinates such as 1e-20 that a second load shifts again in the last digit."""
    def outline(i):
        a = 2 * np.pi * np.arange(5 + i % 2) / (5 + i % 2) + 0.3 * i
        r = 0.012 * (1 + 0.05 * i)
        return np.column_stack([0.7 + r * np.cos(a), 0.2 + r * np.sin(a)]).tolist()

    d = json.loads(json.dumps(DRY))
    d["bodies"] = [{"shape": "polygon", "vertices": outline(i), "density": 100.0,
                    "position": [0.06 + 0.065 * (i % 5), 0.03 + 0.04 * (i // 5)]} for i in range(10)]
    return d


def test_a_run_continues_from_its_own_written_scene_file(tmp_path, capsys):
    # the scene.toml a run writes, read back, differs from the run's scene in the last digit of every
    # outline (10 of 10 bodies compared exactly); a restart from it must not count that as another scene
    out = tmp_path / "o"
    Simulation(Scene.from_dict(_off_centre_polygons())).run(out_dir=out, n_steps=8)
    assert main(["run", str(out / "scene.toml"), "--out", str(out), "--restart", "--quiet"]) == 0
    assert "20 steps to t = 0.08" in capsys.readouterr().out
    full = tmp_path / "full"
    Simulation(Scene.from_dict(_off_centre_polygons())).run(out_dir=full)
    assert _same_history(full, out) < 1e-9
    # with no scene given, a restart continues the scene.toml of the run it continues: that of --out, or of
    # the run directory holding a checkpoint named by path (which then is the output directory too)
    for argv, steps in ((["--out", str(out), "--restart"], 8), ([], 4)):
        out2 = tmp_path / f"o{steps}"
        Simulation(Scene.from_dict(_off_centre_polygons())).run(out_dir=out2, n_steps=steps)
        ck = sorted((out2 / "checkpoints").glob("*.npz"))[-1]
        args = [a.replace(str(out), str(out2)) for a in argv] or ["--restart", str(ck)]
        assert main(["run", *args, "--quiet"]) == 0
        assert "20 steps to t = 0.08" in capsys.readouterr().out
        assert _same_history(full, out2) < 1e-9
    assert main(["run", "--out", str(tmp_path / "none"), "--restart", "--quiet"]) == 2
    assert "no scene: give a scene TOML file or --example NAME" in capsys.readouterr().err


def test_a_refused_restart_names_the_first_changes_and_counts_the_rest(tmp_path):
    out = tmp_path / "o"
    Simulation(Scene.from_dict(_off_centre_polygons())).run(out_dir=out, n_steps=2)
    d = _off_centre_polygons()
    for b in d["bodies"]:
        b["density"] = 120.0
    with pytest.raises(ValueError) as err:
        Simulation(Scene.from_dict(d)).run(out_dir=out, restart=True)
    msg = str(err.value)
    assert "changed bodies[0].density 100.0 -> 120.0; bodies[1].density" in msg and "; and 7 more;" in msg
    assert "bodies[3]" not in msg and len(msg) < 600


def _falling(t_end):
    return {"gravity": [0.0, -10.0], "domain": {"box": [0.0, 1.0, 0.0, 1.0]},
            "bodies": [{"shape": "disk", "radius": 0.05, "segments": 12, "density": 10.0, "position": [0.5, 0.4]}],
            "contact": {"E": 1e4, "gamma": 0.05}, "time": {"dt": 0.01, "t_end": t_end},
            "output": {"checkpoint_every": 5}}


def test_a_longer_t_end_under_another_file_name_and_with_contacts_switched_on(tmp_path, capsys):
    short, longer = tmp_path / "drop.toml", tmp_path / "copy of drop (2).toml"
    Scene.from_dict(_falling(0.1)).to_toml(short)
    Scene.from_dict(_falling(0.4)).to_toml(longer)
    assert not Scene.from_toml(short).plan().on("contacts") and Scene.from_toml(longer).plan().on("contacts")
    out = tmp_path / "o"
    assert main(["run", str(short), "--out", str(out), "--quiet"]) == 0
    assert main(["run", str(longer), "--out", str(out), "--quiet", "--restart"]) == 0
    assert "40 steps to t = 0.4" in capsys.readouterr().out
    h = read_history(out)
    assert np.array_equal(h["step"], np.arange(41)) and np.allclose(h["t"], 0.01 * h["step"], rtol=1e-15, atol=0)
    assert h["contacts"].max() == 1 and "contacts are on" in (out / "events.log").read_text()
    full = tmp_path / "full"
    Simulation(Scene.from_dict(_falling(0.4))).run(out_dir=full)
    assert _same_history(full, out) < 1e-9


def test_a_restart_before_the_checkpoint_time_is_refused(tmp_path):
    out = tmp_path / "o"
    Simulation(Scene.from_dict(_falling(0.1))).run(out_dir=out)
    with pytest.raises(ValueError, match=r"time.t_end = 0.05: the checkpoint .* is at t = 0.1 \(step 10\)"):
        Simulation(Scene.from_dict(_falling(0.05))).run(out_dir=out, restart=True)


def test_a_pickle_checkpoint_of_an_earlier_version_loads_only_when_allowed(tmp_path, capsys):
    import pickle

    out = tmp_path / "o"
    Simulation(Scene.from_dict(DRY)).run(out_dir=out, n_steps=6)
    data = load_checkpoint(out / "checkpoints" / "ckpt_0000006.npz")
    legacy = tmp_path / "ckpt_0000006.pkl"
    legacy.write_bytes(pickle.dumps({**data, "version": 1}))
    with pytest.raises(CheckpointError, match="pass allow_pickle=True only for a file you wrote"):
        Simulation(Scene.from_dict(DRY)).run(out_dir=out, restart=legacy)
    Simulation(Scene.from_dict(DRY)).run(out_dir=out, restart=legacy, allow_pickle=True)
    full = tmp_path / "full"
    Simulation(Scene.from_dict(DRY)).run(out_dir=full)
    assert _same_history(full, out) == 0.0
