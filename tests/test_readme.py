"""The README's and the user guide's Python examples run and print what they say; the README's commands are
the ones CI runs; the install it describes ships what it should."""

import pathlib
import re

import pytest

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"
DOCS = README.parent / "docs"


def test_readme_python_example(capsys):
    text = README.read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, "README has no Python example"
    exec(compile(blocks[0], "README.md", "exec"), {})
    out = capsys.readouterr().out
    cd = float(out.split("c_D =")[1].split()[0])
    assert cd == pytest.approx(5.57953523384, rel=3e-6)  # P3 on the front mesh: error measured 1.21e-6


GUIDE = ["running.md", "dem.md", "moving-mesh.md", "free-bodies.md"]  # the pages that took the README's examples


def test_guide_python_examples_run(tmp_path, monkeypatch):
    """Every Python block of the user guide pages runs (those reading a user's scene file excepted)."""
    monkeypatch.chdir(tmp_path)
    ran = 0
    for page in GUIDE:
        for code in re.findall(r"```python\n(.*?)```", (DOCS / page).read_text(), flags=re.S):
            if "my_scene.toml" in code:
                continue
            exec(compile(code, f"docs/{page}", "exec"), {})
            ran += 1
    assert ran >= 3


def test_readme_commands_are_the_ones_ci_runs():
    """The README's test command is what .ci/run installs and runs; the install command runs the bench."""
    text = README.read_text()
    blocks = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    assert "pip install . && fluidem bench settling-disk" in blocks[0]
    assert 'pip install -e ".[test]" && python -m pytest -n 2' in blocks[1]
    ci = (README.parent / ".ci" / "run").read_text()
    assert 'pip install --quiet -e ".[test]"' in ci and "python -m pytest -n 2 " in ci
    assert "python -m sphinx -W" in ci  # the documentation site is built with warnings as errors


def test_every_figure_is_on_a_documentation_page():
    """The README's figure exists, and each figure of benchmarks/results and docs/images is shown on a page."""
    shown = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", README.read_text())
    assert shown and all((README.parent / p).is_file() for p in shown)
    pages = [*DOCS.glob("*.md"), *DOCS.glob("examples/*.md")]
    images = {(page.parent / p).resolve() for page in pages
              for p in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text())}
    figures = [*(README.parent / "benchmarks" / "results").glob("*.png"), *(DOCS / "images").glob("*.png")]
    assert figures and not [f.name for f in figures if f.resolve() not in images]


def test_cli_bench_json_last_line(capsys):
    import json

    from fluidem.cli import main

    assert main(["bench", "dfg-2d1", "--element", "th", "--level", "0", "--json"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    d = json.loads(last)
    for key in ("element", "level", "dofs", "wall_s", "cd", "cl", "dp"):
        assert key in d
    assert d["element"] == "th" and d["level"] == 0 and d["dofs"] > 0


def test_cli_rejects_options_that_do_not_apply(capsys):
    from fluidem.cli import main

    with pytest.raises(SystemExit):
        main(["bench", "dfg-2d1", "--dt", "0.01"])
    assert "--dt does not apply to dfg-2d1" in capsys.readouterr().err


def test_install_takes_the_version_from_the_package_and_ships_the_type_hints():
    """One version (``fluidem/version.py``, read by pyproject and re-exported as ``fluidem.__version__``)
    and the PEP 561 marker in the wheel."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    import fluidem

    root = README.parent
    meta = tomllib.loads((root / "pyproject.toml").read_text())
    assert "version" not in meta["project"] and "version" in meta["project"]["dynamic"]
    assert meta["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "fluidem.version.__version__"}
    import fluidem.version

    assert fluidem.__version__ is fluidem.version.__version__
    assert "py.typed" in meta["tool"]["setuptools"]["package-data"]["fluidem"]
    assert (root / "fluidem" / "py.typed").is_file()
    assert re.fullmatch(r"\d+\.\d+\.\d+((a|b|rc)\d+)?(\.post\d+)?(\.dev\d+)?", fluidem.__version__)
