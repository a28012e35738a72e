"""Inputs that cannot work are refused in one line before anything runs.

Flows with a net boundary flux and no outflow side (the plan), explicit or Newton convection
with implicitly coupled free bodies, contact cut-offs longer than the box allows, absurd mesh
sizes, boxes and segment counts, damaged run directories given to ``fluidem plot``, sweep
variant names too long for a file system and sweeps into another scene's sweep directory, and
scenes built in Python with a missing table.
"""

import json

import pytest

from fluidem import Scene, Simulation
from fluidem.cli import main
from fluidem.errors import InputError, SceneError
from fluidem.scene import BodySpec, MeshSpec
from test_runs_errors import _err
from tiny_scene import tiny_channel


def _fluid(**domain):
    """A 2 × 1 fluid box whose sides are ``domain`` (walls otherwise)."""
    return {"fluid": {"viscosity": 0.1}, "domain": {"box": [0.0, 2.0, 0.0, 1.0], **domain}, "mesh": {"h": 0.25},
            "time": {"dt": 0.1, "t_end": 0.1}}


DISK = {"shape": "disk", "radius": 0.1, "position": [0.5, 0.5], "density": 2.0}
PARABOLIC = {"type": "parabolic", "umax": 1.5}

# -- item 3: a net boundary flux without an outflow side ---------------------------------------------

NO_FLOW = "and no side is 'outflow': an incompressible flow cannot exist; expected a net flux of 0 " \
          "(periodic pairs carry none), or a side of type 'outflow'"


@pytest.mark.parametrize("domain, message", [
    ({"top": {"type": "moving-wall", "velocity": [0.3, -1.0]}},
     "domain side top (moving-wall, velocity [0.3, -1.0]: +2) carries a net flux of 2 into the box (length²/time), "
     + NO_FLOW),
    ({"left": "inflow", "inflow_profile": PARABOLIC},  # 2/3 umax L = 1
     "domain side left (inflow, parabolic umax = 1.5: +1) carries a net flux of 1 into the box (length²/time), "
     + NO_FLOW),
    ({"left": "inflow", "right": "inflow", "inflow_profile": {"type": "uniform", "umax": 1.0}},
     "domain sides right (inflow, uniform umax = 1: +1) and left (inflow, uniform umax = 1: +1) carry a net flux of "
     "2 into the box (length²/time), " + NO_FLOW),
    ({"left": "periodic", "right": "periodic", "top": {"type": "moving-wall", "velocity": [0.0, 0.1]}},
     "domain side top (moving-wall, velocity [0.0, 0.1]: -0.2) carries a net flux of 0.2 out of the box "
     "(length²/time), " + NO_FLOW),
    ({"left": "inflow", "inflow_profile": dict(PARABOLIC, ramp=0.5),
      "right": {"type": "moving-wall", "velocity": [1.0, 0.0]}},
     "domain sides right (moving-wall, velocity [1.0, 0.0]: -1) and left (inflow, parabolic umax = 1.5, ramp 0.5: "
     "+1) balance at full speed but ramp up differently (a moving wall at once, an inflow over its ramp): those "
     "with ramp 0 carry a net flux of -1 into the box (length²/time) on their own, and no side is 'outflow': an "
     "incompressible flow cannot exist while they ramp; expected the same ramp on the sides that balance each "
     "other, or a side of type 'outflow'"),
])
def test_a_net_boundary_flux_without_an_outflow_side_is_refused_by_the_plan(domain, message, tmp_path, capsys):
    s = Scene.from_dict(_fluid(**domain))
    assert s.plan().unsupported == [message]
    with pytest.raises(ValueError, match="this scene cannot run yet: domain side"):
        Simulation(s)
    s.to_toml(tmp_path / "s.toml")
    assert main(["plan", str(tmp_path / "s.toml")]) == 2
    assert _err(capsys) == f"fluidem: error: scene 'scene' cannot run: {message}"


@pytest.mark.parametrize("domain", [
    {"top": {"type": "moving-wall", "velocity": [1.0, 0.0]}},  # a lid: tangential only
    {"left": "inflow", "right": "outflow", "inflow_profile": PARABOLIC},
    {"left": "inflow", "inflow_profile": PARABOLIC, "right": {"type": "moving-wall", "velocity": [1.0, 0.0]}},
    {"bottom": {"type": "inflow", "profile": {"type": "uniform", "umax": 1.0}},
     "top": {"type": "moving-wall", "velocity": [0.0, 1.0]}},
    {"left": "periodic", "right": "periodic", "top": {"type": "moving-wall", "velocity": [1.0, 0.0]}},
])
def test_balanced_or_open_boxes_are_not_refused(domain):
    d = _fluid(**domain)
    d["bodies"] = [dict(DISK, motion="prescribed", velocity=[0.2, 0.0])]  # a rigid outline carries no net flux
    assert Scene.from_dict(d).plan().unsupported == []


# -- item 7: unclear or raw errors ------------------------------------------------------------------------

@pytest.mark.parametrize("convection", ["explicit", "newton"])
def test_free_bodies_with_implicit_coupling_take_semi_implicit_convection_only(convection):
    d = _fluid()
    d["fluid"]["convection"] = convection
    d["bodies"] = [DISK]
    with pytest.raises(SceneError, match=(
            rf"^fluid.convection = '{convection}' with free bodies \(bodies\[0\] 'body0'\) and fluid.coupling = "
            r"'implicit': the coupled fluid-body step takes convection 'semi-implicit' only; expected "
            r"fluid.convection = 'semi-implicit', or fluid.coupling = 'explicit' \(the staggered step, which takes "
            r"every convection\)$")):
        Scene.from_dict(d)
    d["fluid"]["coupling"] = "explicit"  # the staggered step runs the fluid's own stepper
    Scene.from_dict(d)
    d["fluid"].update(coupling="implicit", model="stokes")  # no convection
    Scene.from_dict(d)
    d["fluid"]["model"] = "navier-stokes"
    d["bodies"] = [dict(DISK, motion="fixed")]
    Scene.from_dict(d)


@pytest.mark.parametrize("key", ["repulsion_range", "lubrication_range"])
def test_contact_cut_offs_longer_than_half_the_box_are_refused(key):
    d = _fluid()
    d["bodies"] = [DISK]
    d["contact"] = {key: 0.5}
    with pytest.raises(SceneError, match=(
            rf"^contact.{key} = 0.5: expected a positive number below 0.5, half the shorter side of domain.box = "
            r"\[0.0, 2.0, 0.0, 1.0\] \(a short-range cut-off, of the order of mesh.h = 0.25; a longer one reaches "
            r"a wall from anywhere in the box\)$")):
        Scene.from_dict(d)
    d["contact"] = {key: 0.25}
    Scene.from_dict(d)


def test_a_mesh_far_beyond_the_machine_is_refused_by_the_plan_not_a_crash(tmp_path, capsys):
    d = _fluid()
    d["mesh"]["h"] = 1e-170
    d["bodies"] = [dict(DISK, motion="fixed")]  # its default outline is capped, not 1e169 vertices
    s = Scene.from_dict(d)
    s.to_toml(tmp_path / "s.toml")
    assert main(["plan", str(tmp_path / "s.toml")]) == 2
    assert _err(capsys).startswith("fluidem: error: scene 'scene' cannot run: mesh.h = 1e-170 in the box 2 × 1: more "
                                   "than 1e308 nodes (the estimate overflows), far beyond this machine's ")
    assert "estimate: beyond 1e308 triangles" in str(s.plan())
    d["mesh"]["grading"] = {"growth": 1.2}
    assert "more than 1e308 nodes" in Scene.from_dict(d).plan().unsupported[0]


def test_a_box_beyond_double_precision_is_refused_at_validation(tmp_path, capsys):
    (tmp_path / "s.toml").write_text("[fluid]\n[domain]\nbox = [0.0, 1e300, 0.0, 1e300]\n")
    assert main(["plan", str(tmp_path / "s.toml")]) == 2
    assert _err(capsys) == ("fluidem: error: domain.box = [0.0, 1e+300, 0.0, 1e+300]: expected coordinates of "
                            "magnitude at most 1e+50 and sides at least 1e-50 long (squares and fourth powers of "
                            "lengths must stay finite and nonzero in double precision; pick a unit that fits)")
    with pytest.raises(SceneError, match=r"^domain.box = \[0, 1e-60, 0, 1\]: expected coordinates"):
        Scene.from_dict({"domain": {"box": [0, 1e-60, 0, 1]}})


def test_a_segment_count_has_an_upper_bound():
    d = {"domain": {"box": [0, 1, 0, 1]}, "bodies": [dict(DISK, segments=2**63 - 1)]}
    with pytest.raises(SceneError, match=r"^bodies\[0\].segments = 9223372036854775807: expected an integer from 3 "
                                         r"to 100000$"):
        Scene.from_dict(d)
    d["bodies"][0]["segments"] = 100_000
    assert len(Scene.from_dict(d).world_outlines()[0]) == 100_000


# -- fluidem plot on a damaged run directory -------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A two-step fluid run (fields at every step) to damage in copies."""
    d = tmp_path_factory.mktemp("plot")
    (d / "tiny.toml").write_text(tiny_channel(output="every = 1"))
    Simulation(Scene.from_toml(d / "tiny.toml")).run(out_dir=d / "run")
    return d / "run"


def _copy(run, tmp_path):
    import shutil

    return shutil.copytree(run, tmp_path / "run")


def test_plot_drops_a_half_written_last_history_row_with_a_warning(tiny_run, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    run = _copy(tiny_run, tmp_path)
    lines = (run / "history.csv").read_text().splitlines(keepends=True)
    lines[-1] = ",".join(lines[-1].split(",")[:13])  # the last row cut after its 13th value
    (run / "history.csv").write_text("".join(lines))
    assert main(["plot", str(run)]) == 0
    out = capsys.readouterr()
    assert out.err.strip() == (f"fluidem: warning: {run / 'history.csv'}: its last line 4 is half-written (13 "
                               "values, expected 15; a run still writing, or stopped mid-row): drawn without it")
    assert "history.png" in out.out


def test_plot_names_a_damaged_history_row(tiny_run, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    run = _copy(tiny_run, tmp_path)
    lines = (run / "history.csv").read_text().splitlines(keepends=True)
    lines[1] = "0,0,0,0.3,zz,0,0,0,0,0,0,0,0,0.3,0\n"
    (run / "history.csv").write_text("".join(lines))
    assert main(["plot", str(run)]) == 2
    assert _err(capsys) == (f"fluidem: error: {run / 'history.csv'}, line 2: 'zz' is not a number; expected 15 "
                            "comma-separated numbers per row (step, t, id, x, y, angle, vx, vy, omega, fx, fy, torque, "
                            "contacts, x_unwrapped, y_unwrapped): the file is damaged (only a half-written last "
                            "line is skipped)")


def test_plot_names_a_truncated_vtu_file(tiny_run, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    run = _copy(tiny_run, tmp_path)
    vtu = run / "fields" / "fields_0000002.vtu"
    vtu.write_bytes(vtu.read_bytes()[:3000])
    assert main(["plot", str(run)]) == 2
    assert _err(capsys) == (f"fluidem: error: {vtu}: not a complete VTU file (3000 bytes): truncated or damaged, "
                            "e.g. by a run stopped while writing it; expected the file as 'fluidem run' writes it "
                            "(run the scene again to rewrite it)")


# -- sweeps -----------------------------------------------------------------------------------------------

DRY = {"domain": {"box": [0.0, 1.0, 0.0, 1.0]}, "gravity": [0.0, -1.0],
       "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.5]}], "time": {"dt": 0.01, "t_end": 0.02}}


def test_a_sweep_variant_name_too_long_for_a_file_system_is_refused_before_anything_runs(tmp_path):
    pytest.importorskip("distributed")
    from fluidem.sweep import sweep

    name = "b" * 250
    with pytest.raises(InputError, match=(
            rf"^sweep variant = 'bodies.0.name={name}': expected a directory name of at most 255 bytes, the file "
            r"system's limit per path component \(this one has 264\): vary fewer keys or give shorter values \(long "
            r"values such as arrays belong in the scene file\)$")):
        sweep(Scene.from_dict(DRY), {"bodies.0.name": [name, "b"]}, out_dir=tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_a_sweep_into_another_scenes_sweep_is_refused_unless_overwrite(tmp_path):
    distributed = pytest.importorskip("distributed")
    from fluidem.sweep import sweep

    vary = {"bodies.0.radius": [0.05]}
    a = Scene.from_dict(dict(DRY, name="a"))
    b = Scene.from_dict(dict(DRY, name="b", gravity=[0.0, -2.0]))
    out = tmp_path / "out"

    def run(scene, **kw):
        with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
            return sweep(scene, vary, out_dir=out, scheduler=c, progress=False, plot=False, **kw)

    run(a)
    record = out / "bodies.0.radius=0.05" / "run.json"
    before = record.read_text()
    with pytest.raises(InputError, match=(
            rf"^sweep directory '{out}' holds the sweep of another scene \('a' over bodies.0.radius\); give "
            r"--overwrite \(overwrite=True\) to run every variant again over it, or another --out$")):
        run(b)
    assert record.read_text() == before
    meta = json.loads((out / "sweep.json").read_text())
    meta["meta"]["scene"] = "b"  # the same name, but the variant was run for a different scene
    (out / "sweep.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match=r"holds variant 'bodies.0.radius=0.05' run for a different scene \(scene "
                                         r"'a' with other values, complete at step 2\)"):
        run(b)
    meta["meta"]["scene"] = "a"
    (out / "sweep.json").write_text(json.dumps(meta))
    assert run(a)[0]["resumed"]  # its own sweep resumes
    table = run(b, overwrite=True)
    assert not table[0]["resumed"] and json.loads(record.read_text())["scene"] == "b"


def test_a_sweep_into_a_run_directory_is_refused(tmp_path, capsys):
    pytest.importorskip("distributed")
    (tmp_path / "s.toml").write_text(tiny_channel())
    Simulation(Scene.from_toml(tmp_path / "s.toml")).run(out_dir=tmp_path / "run", n_steps=1)
    assert main(["sweep", str(tmp_path / "s.toml"), "--vary", "mesh.h=0.1", "--out", str(tmp_path / "run")]) == 2
    assert _err(capsys) == (f"fluidem: error: sweep directory '{tmp_path / 'run'}' holds the output of a run (scene "
                            "'tiny-channel', stopped at step 1); give --overwrite (overwrite=True) to run every "
                            "variant again over it, or another --out")


# -- the Python API ---------------------------------------------------------------------------------------

def test_scene_loaders_name_a_wrong_argument():
    with pytest.raises(InputError, match=r"^Scene.from_toml\(path\) = None: expected the path of a TOML file "
                                         r"\(str or Path\)$"):
        Scene.from_toml(None)
    with pytest.raises(InputError, match=r"^Scene.from_dict\(data\) = None: expected a dict of the scene's tables"):
        Scene.from_dict(None)


@pytest.mark.parametrize("kw, message", [
    ({"mesh": None}, r"Scene\(mesh=...\) = None: expected a MeshSpec \(Scene.from_dict takes the \[mesh\] table as "
                     r"a dict\)"),
    ({"time": None}, r"Scene\(time=...\) = None: expected a TimeSpec \("),
    ({"output": None}, r"Scene\(output=...\) = None: expected an OutputSpec \("),
    ({"fluid": {}}, r"Scene\(fluid=...\) = \{\}: expected a FluidSpec or None \("),
    ({"bodies": None}, r"Scene\(bodies=...\) = None: expected a list of BodySpec \(empty: no bodies\)"),
    ({"name": None}, r"Scene\(name=...\) = None: expected a string"),
])
def test_a_scene_built_in_python_with_a_missing_table_is_refused_in_one_line(kw, message):
    with pytest.raises(SceneError, match="^" + message):
        Scene(**kw).validate()
    with pytest.raises(SceneError, match="^" + message):  # never validated: the plan (and so a run) says it too
        Simulation(Scene(**kw))
    Scene(mesh=MeshSpec(h=0.1), bodies=(BodySpec(radius=0.1, position=(0.5, 0.5)),)).validate()
