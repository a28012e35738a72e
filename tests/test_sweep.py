"""Parameter sweeps on dask.distributed: a two-worker LocalCluster, the table, resume, key errors."""

import csv
import json
import sys

import pytest

from fluidem import Simulation
from fluidem.cli import main
from fluidem.errors import InputError, SceneError
from fluidem.io import read_history

pytest.importorskip("distributed")

from fluidem.sweep import _finished, parse_vary, require_dask, set_key, sweep, variants  # noqa: E402
from tiny_scene import tiny_channel  # noqa: E402

TINY = tiny_channel()

VARY = {"mesh.h": [0.1, 0.07], "fluid.element": ["th", "p2b"]}


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    (d / "tiny.toml").write_text(TINY)
    table = sweep(d / "tiny.toml", VARY, out_dir=d / "out", workers=2, progress=False)
    return d, table


def test_a_two_worker_sweep_runs_every_variant_and_tabulates_its_summary(swept):
    d, table = swept
    assert [(r["mesh.h"], r["fluid.element"]) for r in table] == [(0.1, "th"), (0.1, "p2b"), (0.07, "th"),
                                                                  (0.07, "p2b")]
    assert all(r["status"] == "complete" and r["steps"] == 2 and not r["resumed"] for r in table)
    assert all(r["worker"].startswith("tcp://") for r in table)  # ran on the cluster's workers
    for r in table:  # each row is the variant's own run: its history's last load, its element and size
        h = read_history(d / "out" / r["variant"])
        assert r["cylinder.fx"] == h["fx"][-1] and r["element"] == r["fluid.element"]
    # a variant run in this process gives the same drag (one BLAS thread in both)
    (values, sc), = [v for v in variants(d / "tiny.toml", VARY) if v[0] == {"mesh.h": 0.07, "fluid.element": "p2b"}]
    sim = Simulation(sc)
    sim.run(out_dir=None)
    assert abs(sim.last_loads[0][0, 0] - table[3]["cylinder.fx"]) < 1e-12 * abs(table[3]["cylinder.fx"])
    # DOFs grow with refinement and with the richer element
    assert table[0]["dofs"] < table[1]["dofs"] and table[0]["dofs"] < table[2]["dofs"] < table[3]["dofs"]
    with open(d / "out" / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["cylinder.fx"]) for r in rows] == [r["cylinder.fx"] for r in table]
    js = json.loads((d / "out" / "sweep.json").read_text())
    assert js["meta"]["vary"] == VARY and len(js["variants"]) == 4 and len(js["meta"]["load_before"]) == 3
    assert (d / "out" / "sweep.png").stat().st_size > 10_000


def test_a_resumed_sweep_runs_only_the_unfinished_variants(swept, capsys):
    d, table = swept
    out = d / "out"
    gone = out / table[2]["variant"]
    for p in sorted(gone.rglob("*"), reverse=True):
        p.unlink() if p.is_file() else p.rmdir()
    rec = json.loads((out / table[1]["variant"] / "run.json").read_text())
    rec["status"] = "interrupted"  # a half-done variant is run again
    (out / table[1]["variant"] / "run.json").write_text(json.dumps(rec))
    kept = {k: (out / table[k]["variant"] / "run.json").stat().st_mtime_ns for k in (0, 3)}
    status = main(["sweep", str(d / "tiny.toml"), "--vary", "mesh.h=0.1,0.07", "--vary", "fluid.element=th,p2b",
                   "--workers", "2", "--out", str(out), "--no-plot"])
    assert status == 0
    err = capsys.readouterr().err
    assert "4 variants, 2 finished before, 2 to run on LocalCluster of 2 single-threaded worker processes" in err
    again = list(csv.DictReader(open(out / "sweep.csv")))
    assert [r["resumed"] for r in again] == ["True", "False", "False", "True"]
    assert {k: (out / table[k]["variant"] / "run.json").stat().st_mtime_ns for k in (0, 3)} == kept  # untouched
    assert [float(r["wall_s"]) for r in again][::3] == [table[0]["wall_s"], table[3]["wall_s"]]  # stored times
    assert [float(r["cylinder.fx"]) for r in again] == [r["cylinder.fx"] for r in table]  # recomputed: the same


def test_vary_values_keys_and_errors(tmp_path):
    assert parse_vary(["mesh.h=0.1, 2e-2", "fluid.element=th,p3", "domain.box=[0, 1, 0, 1],[0, 2, 0, 1]",
                       "mesh.curved=true,false"]) == {
        "mesh.h": [0.1, 0.02], "fluid.element": ["th", "p3"], "domain.box": [[0, 1, 0, 1], [0, 2, 0, 1]],
        "mesh.curved": [True, False]}
    with pytest.raises(InputError, match=r"--vary = 'mesh.h': expected KEY=V1,V2"):
        parse_vary(["mesh.h"])
    data = {"bodies": [{"radius": 1.0}], "mesh": {"h": 1.0}}
    set_key(data, "bodies.0.radius", 2.0)
    set_key(data, "contact.stiffness", 5.0)
    assert data == {"bodies": [{"radius": 2.0}], "mesh": {"h": 1.0}, "contact": {"stiffness": 5.0}}
    with pytest.raises(InputError, match=r"sweep key = 'bodies.3': expected a list index 0 to 0"):
        set_key(data, "bodies.3.radius", 1.0)
    (tmp_path / "s.toml").write_text(TINY)
    with pytest.raises(SceneError, match=r"sweep variant mesh.hh=0.1: unknown key mesh.hh = 0.1 \(did you mean "
                                         r"mesh.h\?\)"):
        variants(tmp_path / "s.toml", {"mesh.hh": [0.1]})
    with pytest.raises(SceneError, match=r"fluid.element = 'q9': expected one of"):
        variants(tmp_path / "s.toml", {"fluid.element": ["th", "q9"]})
    assert main(["sweep", str(tmp_path / "s.toml"), "--vary", "mesh.hh=0.1"]) == 2  # before any cluster starts


def test_without_dask_the_error_names_the_extra(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(InputError, match=r'a parameter sweep needs dask.distributed: pip install "fluidem\[sweep\]" '
                                         r'\(in an editable checkout: pip install -e "\.\[sweep\]"\)'):
        require_dask()
    (tmp_path / "s.toml").write_text(TINY)
    assert main(["sweep", str(tmp_path / "s.toml"), "--vary", "mesh.h=0.1"]) == 2
    assert capsys.readouterr().err.strip() == ("fluidem: error: 'fluidem sweep' needs dask.distributed: "
                                               'pip install "fluidem[sweep]" (in an editable checkout: '
                                               'pip install -e ".[sweep]")')


def test_a_variant_counts_as_finished_only_when_complete_for_the_same_scene(tmp_path):
    (tmp_path / "s.toml").write_text(TINY)
    (_, sc), (_, other) = variants(tmp_path / "s.toml", {"mesh.h": [0.1, 0.07]})
    Simulation(sc).run(out_dir=tmp_path / "v", n_steps=1)  # stopped after 1 of 2 steps
    assert _finished(tmp_path / "v", sc) is None  # a full sweep runs it again
    row = _finished(tmp_path / "v", sc, n_steps=1)  # a sweep with --steps 1 keeps it
    assert row["status"] == "complete" and row["summary"]["steps"] == 1
    assert _finished(tmp_path / "v", other, n_steps=1) is None  # another scene's run


def test_the_sweep_plot_puts_the_quantity_against_the_varied_parameter_with_units(tmp_path, monkeypatch):
    """sweep.png drew the quantity against wall time only and named columns without units: the left panel
    now has it against the varied parameter (each line one value of the other keys), the right against the
    cost; both axes carry the columns' dimensions."""
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from fluidem.sweep import plot_sweep

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    table = [{"mesh.h": h, "fluid.element": e, "status": "complete", "wall_s": w, "cylinder.fx": fx}
             for h, e, w, fx in [(0.1, "th", 1.0, 5.1), (0.05, "th", 4.0, 5.5), (0.1, "p2b", 1.5, 5.4),
                                 (0.05, "p2b", 6.0, 5.57)]]
    plot_sweep(table, tmp_path / "sweep.png", ["fluid.element", "mesh.h"], "cylinder.fx")
    left, right = drawn[0].axes
    assert left.get_xlabel() == "mesh.h [length]" and left.get_ylabel() == "cylinder.fx [force/depth]"
    assert [list(line.get_xdata()) for line in left.lines] == [[0.1, 0.05], [0.1, 0.05]]
    assert [list(line.get_ydata()) for line in left.lines] == [[5.1, 5.5], [5.4, 5.57]]
    assert [t.get_text() for t in left.get_legend().get_texts()] == ["fluid.element = th", "fluid.element = p2b"]
    assert right.get_xlabel() == "wall time per variant [s]"
    assert [list(line.get_xdata()) for line in right.lines] == [[1.0, 4.0], [1.5, 6.0]]
