"""The scene reference (docs/scenes.md), the starter commands, bad-key hints, the plot extra and plain progress."""

import io
import pathlib
import re
import sys

import pytest

from fluidem.cli import main
from fluidem.errors import SceneError, install_hint
from fluidem.scene import Scene, files, specs
from fluidem.scene.reference import WORKED_EXAMPLE, accepted_keys, markdown

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs" / "scenes.md"


def _reader_keys():
    """Every key the scene reader accepts, read off the reader's own key lists (not the reference's)."""
    keys = [f".{k}" for k in specs._TOP_KEYS]
    keys += [f"{t}.{k}" for t, spec in specs._TABLES.items() for k in spec.KEYS]
    keys += [f"domain.<side>.{k}" for k in specs.SideSpec.KEYS]
    keys += [f"domain.inflow_profile.{k}" for k in specs.DomainSpec.PROFILE_KEYS]
    keys += [f"bodies.{k}" for k in specs.BodySpec.KEYS]
    keys += [f"bodies_table.{k}" for k in files.TABLE_KEYS]
    keys += [f"bodies_table.csv.{k}" for k in files.TABLE_COLUMNS]
    keys += [f"mesh.grading.{k}" for k in specs.MeshSpec.GRADING_KEYS]
    return keys


_HEADINGS = {"Top level": "", "A side as a table": "domain.<side>", "An inflow profile": "domain.inflow_profile",
             "[[bodies]]": "bodies", "[bodies_table]": "bodies_table", "Columns of the CSV": "bodies_table.csv",
             "Mesh grading": "mesh.grading"}


def _documented(text):
    """``table.key`` of every row of every key table in the Markdown reference (with a non-empty unit and meaning)."""
    out, table = set(), None
    for line in text.splitlines():
        if line.startswith("### "):
            head = line[4:]
            table = next((v for k, v in _HEADINGS.items() if head.startswith(k)), head.strip("[]"))
        elif line.startswith("## "):
            table = None
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if table is not None and len(cells) == 6 and cells[0].startswith("`") and cells[3] and cells[5]:
            out.add(f"{table}.{cells[0].strip('`')}")
    return out


def test_reference_documents_every_key_the_reader_accepts_and_is_checked_in():
    text = markdown()
    reader = _reader_keys()
    assert sorted(accepted_keys()) == sorted(reader)
    documented = _documented(text)
    missing = [k for k in reader if k not in documented]
    assert not missing, f"keys the scene reader accepts but the reference lacks: {missing}"
    assert DOCS.read_text() == text, "docs/scenes.md differs from the generator: run 'fluidem reference > " \
                                     "docs/scenes.md'"


def test_reference_states_units_and_allowed_names():
    from fluidem import names

    text = markdown()
    assert "**kinematic** viscosity" in text and "mass/length²" in text and "per unit depth" in text
    for kind in ("element", "solver", "convection", "coupling", "side type", "shape", "motion", "strategy",
                 "profile", "fluid model"):
        for n in names.choices(kind):
            assert f"`{n}`" in text, (kind, n)
    assert '"x0 y0; x1 y1; ..."' in text  # the CSV vertex syntax
    assert re.search(r"\| `viscosity` \| number > 0 \| `0.01` \| length²/time \|", text)


def test_reference_names_a_key_missing_from_its_table(monkeypatch):
    from fluidem.errors import FluidemError
    from fluidem.scene import reference

    monkeypatch.setitem(reference.TABLES, "time", ("[time]", specs.TimeSpec, specs.TimeSpec.KEYS + ("dt_max",)))
    with pytest.raises(FluidemError, match=r"time\.dt_max"):
        reference.markdown()


def test_worked_example_validates_plans_and_is_re_40(tmp_path, capsys):
    path = tmp_path / "rotating-cylinder.toml"
    path.write_text(WORKED_EXAMPLE)
    assert WORKED_EXAMPLE in DOCS.read_text()
    s = Scene.from_toml(path)
    (cyl,) = s.bodies
    u_mean = 2.0 / 3.0 * s.domain.inflow_profile["umax"]  # mean of the parabolic profile
    assert u_mean * 2 * cyl.radius / s.fluid.viscosity == pytest.approx(40.0, rel=1e-12)
    assert cyl.omega != 0 and not cyl.outline_moves  # spinning in place
    assert main(["plan", str(path)]) == 0
    out = capsys.readouterr().out
    assert "fluid           on" in out and "mesh            on  [once]" in out and "rotation        on" in out
    assert "cannot run" not in out
    assert main(["reference"]) == 0
    assert capsys.readouterr().out == DOCS.read_text()


def test_examples_show_and_new(tmp_path, capsys):
    from fluidem.cases.scenes import SCENE_DIR

    assert main(["examples", "--show", "dfg-cylinder"]) == 0
    assert capsys.readouterr().out == (SCENE_DIR / "dfg-cylinder.toml").read_text()
    assert main(["examples", "--show", "dry-heap"]) == 0
    out = capsys.readouterr().out
    first, rest = out.split("\n", 1)
    assert first.startswith("#") and str(SCENE_DIR / "dry-heap.csv") in first
    assert rest == (SCENE_DIR / "dry-heap.toml").read_text()
    assert main(["new", "dry-heap", str(tmp_path / "mine")]) == 0
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["dry-heap.csv", "dry-heap.toml"]
    s = Scene.from_toml(tmp_path / "mine" / "dry-heap.toml")  # the copy reads with its CSV
    assert len(s.bodies) == 144
    capsys.readouterr()
    assert main(["new", "dry-heap", str(tmp_path / "mine")]) == 2  # nothing overwritten
    assert "exists already" in capsys.readouterr().err
    assert main(["examples", "--show", "nope"]) == 2
    assert "unknown example scene 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("data,words", [
    ({"bodies": {"file": "grains.csv"}}, ["bodies.file = 'grains.csv'", "[bodies_table]", "file = 'grains.csv'"]),
    ({"bodies": [{"file": "grains.csv"}]}, ["bodies[0].file", "[bodies_table] file"]),
    ({"fluid": {"viscocity": 0.01}}, ["unknown key fluid.viscocity", "did you mean fluid.viscosity?"]),
    ({"contact": {"e": 1e5}}, ["did you mean contact.E?"]),
    ({"body": []}, ["did you mean bodies?"]),
    ({"dt": 0.1}, ["[time] dt"]),
    ({"bodies_table": {"files": "grains.csv"}}, ["did you mean bodies_table.file?"]),
    ({"fluid": {}, "mesh": {"h": 0.1, "grading": {"grow": 1.2}}}, ["did you mean mesh.grading.growth?"]),
])
def test_unknown_keys_point_to_the_right_key(data, words):
    with pytest.raises(SceneError) as exc:
        Scene.from_dict({"domain": {"box": [0, 1, 0, 1]}, **data})
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_unknown_csv_column_names_the_nearest(tmp_path):
    (tmp_path / "b.csv").write_text("shape,radius,xx,y\ndisk,0.1,0.5,0.5\n")
    with pytest.raises(SceneError, match=r"unknown column 'xx' \(did you mean 'x'\?\)"):
        files.read_bodies_table({"file": "b.csv"}, tmp_path)


def test_plot_without_matplotlib_fails_before_the_run(tmp_path, capsys, monkeypatch):
    import fluidem.simulation

    ran = []
    monkeypatch.setattr(fluidem.simulation.Simulation, "run", lambda *a, **k: ran.append(1))
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib raises ImportError
    assert main(["run", "--example", "dry-heap", "--out", str(tmp_path / "o"), "--plot"]) == 2
    err = capsys.readouterr().err
    assert err == f"fluidem: error: --plot needs matplotlib: {install_hint('plot')}\n"
    assert not ran and not (tmp_path / "o").exists()
    assert main(["plot", str(tmp_path)]) == 2
    assert capsys.readouterr().err == f"fluidem: error: 'fluidem plot' needs matplotlib: {install_hint('plot')}\n"


def test_plot_extra_in_pyproject():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    meta = tomllib.loads((DOCS.parents[1] / "pyproject.toml").read_text())["project"]
    extras = meta["optional-dependencies"]
    assert "matplotlib>=3.6" in extras["plot"] and "matplotlib>=3.6" in extras["test"]
    assert not any(d.startswith("matplotlib") for d in meta["dependencies"])


class _Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_progress_off_a_terminal_is_one_line_per_update(monkeypatch):
    import fluidem.cli as cli

    clock = _Clock()
    monkeypatch.setattr(cli.time, "perf_counter", clock)
    stream = io.StringIO()  # not a terminal
    bar = cli._ProgressBar(stream=stream)
    n = 1000
    for k in range(1, n + 1):
        clock.t += 0.001  # fast steps: a line every 5 % of the steps
        bar(k, n, k * 0.01, "fluid 1 ms")
    text = stream.getvalue()
    lines = text.splitlines()
    assert "\r" not in text and text.endswith("\n")
    assert lines[0].startswith("step 1/1000") and lines[-1].startswith("step 1000/1000")
    steps = [int(ln.split()[1].split("/")[0]) for ln in lines]
    assert steps == [1] + list(range(51, 1000, 50)) + [1000]

    stream = io.StringIO()
    bar = cli._ProgressBar(stream=stream)
    for k in range(1, 11):
        clock.t += 4.0  # slow steps: a line once 10 s have passed since the last one
        bar(k, 1000, k * 0.01, "fluid 4 s")
    steps = [int(ln.split()[1].split("/")[0]) for ln in stream.getvalue().splitlines()]
    assert steps == [1, 4, 7, 10]  # 12 s apart


def test_progress_on_a_terminal_redraws_one_line(monkeypatch):
    import fluidem.cli as cli

    class Tty(io.StringIO):
        def isatty(self):
            return True

    clock = _Clock()
    monkeypatch.setattr(cli.time, "perf_counter", clock)
    stream = Tty()
    bar = cli._ProgressBar(stream=stream)
    for k in range(1, 101):
        clock.t += 0.125  # exact in binary: a redraw at most every 0.2 s is one every second step
        bar(k, 100, k * 0.01, "")
    text = stream.getvalue()
    assert text.count("\n") == 1 and text.endswith("\n") and text.count("\r") == 50  # steps 2, 4, ..., 100


def test_reference_csv_example_reads(tmp_path):
    """The CSV body table shown in the reference is one the reader takes, vertex syntax included."""
    (block,) = re.findall(r"```text\n(.*?)```", markdown(), flags=re.S)
    (tmp_path / "bodies.csv").write_text(block)
    (tmp_path / "scene.toml").write_text('[domain]\nbox = [0.0, 0.3, 0.0, 0.1]\n[bodies_table]\nfile = "bodies.csv"\n'
                                         "density = 2000.0\n")
    s = Scene.from_toml(tmp_path / "scene.toml")
    assert [b.shape for b in s.bodies] == ["disk", "rectangle", "polygon"]
    assert s.bodies[2].vertices.shape == (3, 2) and s.bodies[1].angle == 0.3
    assert all(b.density == 2000.0 for b in s.bodies)
