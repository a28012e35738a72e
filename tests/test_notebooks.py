"""The walkthroughs of ``notebooks/``: each paired script runs and its checks against the
references pass (slow), and each ``.ipynb`` is the executed twin of its script (default suite).

A walkthrough is a jupytext percent-format script ``notebooks/NAME.py`` and the notebook
``NAME.ipynb`` generated from it with its outputs (``jupytext --to ipynb --execute NAME.py``,
the ``notebooks`` extra), so it renders with its figures where notebooks are shown.  The slow
tests run the scripts themselves (no kernel): the cells hold the asserts.
"""

import runpy
from pathlib import Path

import pytest

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"

#: name -> measured wall seconds of the script under pytest (2-core machine, one worker,
#: load average ~9 from other jobs): 67 s together
WALKTHROUGHS = {"accuracy_cost": 11, "moving_mesh": 3, "dry_heap": 23, "settling_disk": 30}


def test_every_walkthrough_is_tested():
    assert sorted(p.stem for p in NOTEBOOKS.glob("*.py")) == sorted(WALKTHROUGHS)
    assert sorted(p.stem for p in NOTEBOOKS.glob("*.ipynb")) == sorted(WALKTHROUGHS)


@pytest.mark.parametrize("name", sorted(WALKTHROUGHS))
def test_notebook_is_the_executed_script(name):
    jupytext = pytest.importorskip("jupytext")  # in the test extra; it brings nbformat
    import nbformat

    script = jupytext.read(NOTEBOOKS / f"{name}.py")
    nb = nbformat.read(NOTEBOOKS / f"{name}.ipynb", as_version=4)
    # the same cells, in the same order, with the same sources
    assert [(c.cell_type, c.source) for c in nb.cells] == [(c.cell_type, c.source) for c in script.cells]
    code = [c for c in nb.cells if c.cell_type == "code"]
    # executed top to bottom in one kernel, without errors, with its figures
    assert [c.execution_count for c in code] == list(range(1, len(code) + 1))
    outputs = [o for c in code for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    assert sum("image/png" in o.get("data", {}) for o in outputs) >= 2


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow(seconds=s))
                                  for n, s in sorted(WALKTHROUGHS.items())])
def test_walkthrough_runs(name, monkeypatch):
    plt = pytest.importorskip("matplotlib.pyplot")
    monkeypatch.chdir(NOTEBOOKS)
    try:
        runpy.run_path(str(NOTEBOOKS / f"{name}.py"), run_name="__main__")
    finally:
        plt.close("all")
