"""Sphinx configuration of the fluidem documentation site.

Build it (the CI runs the same, warnings as errors)::

    pip install -e ".[docs]"
    python -m sphinx -W --keep-going -b html docs docs/_build/html

The pages are Markdown (MyST); the API reference is generated from the numpy-style docstrings
(autodoc + napoleon), whose Sphinx roles (``:class:``, ``:func:``, ``:math:``) become links and
formulas; the walkthroughs of ``notebooks/`` are rendered from their stored outputs, never
executed here.  Files the pages use from outside ``docs/`` (the walkthroughs, the benchmark result
tables and figures) are read where they are; the notebooks are copied into ``docs/walkthroughs/``
and a page per benchmark result table is written into ``docs/results/`` (both ignored by git) at
the start of a build, because Sphinx only builds documents inside its source folder.
"""

from __future__ import annotations

import pathlib
import re
import shutil
import sys

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))

import fluidem  # noqa: E402

project = "fluidem"
author = "the fluidem authors"
copyright = "the fluidem authors, MIT licence"
release = fluidem.__version__
version = release

extensions = [
    "myst_nb",  # Markdown pages (myst-parser) and notebooks from their stored outputs
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",  # numpy-style docstrings
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]

# --- the walkthroughs: copied from notebooks/ (the executed .ipynb and their index) -----------------
_WALK = DOCS / "walkthroughs"
if _WALK.exists():
    shutil.rmtree(_WALK)
_WALK.mkdir()
for _src in sorted((ROOT / "notebooks").glob("*.ipynb")):
    shutil.copy2(_src, _WALK / _src.name)
# the index of notebooks/README.md, its links to the sources kept pointing at notebooks/
_readme = (ROOT / "notebooks" / "README.md").read_text()
_toc = "\n".join(p.stem for p in sorted(_WALK.glob("*.ipynb")))
(_WALK / "index.md").write_text(_readme + f"\n```{{toctree}}\n:hidden:\n\n{_toc}\n```\n")

# --- the benchmark result tables: one page each, included from benchmarks/results/ ------------------
_RESULTS = DOCS / "results"
if _RESULTS.exists():
    shutil.rmtree(_RESULTS)
_RESULTS.mkdir()
for _src in sorted((ROOT / "benchmarks" / "results").glob("*.md")):
    _lines = _src.read_text().splitlines()
    _titled = _lines[0].startswith("# ")
    _title = _lines[0][2:] if _titled else _src.stem
    # a table whose sections start at ### gets a ## above them (headings go down one level at a time)
    _levels = [len(s) - len(s.lstrip("#")) for s in _lines[int(_titled):] if s.startswith("#")]
    _bridge = "## Tables\n\n" if _levels and min(_levels) == 3 else ""
    (_RESULTS / _src.name).write_text(
        f"# {_title}\n\n`benchmarks/results/{_src.name}`, as the benchmark wrote it.\n\n{_bridge}"
        f"```{{include}} ../../benchmarks/results/{_src.name}\n:relative-images:\n"
        + (":start-line: 1\n" if _titled else "") + "```\n")

nb_execution_mode = "off"  # render the stored outputs; tests/test_notebooks.py runs the scripts
nb_merge_streams = True

# --- Markdown ---------------------------------------------------------------------------------
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
myst_enable_extensions = ["colon_fence"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "**/.ipynb_checkpoints"]

# --- API reference ----------------------------------------------------------------------------
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_class_signature = "separated"
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True
# free-form sections of the package's docstrings, rendered as headed paragraphs
napoleon_custom_sections = ["Units", "Names", "Sizes", "The gap test", "Reachable fractions"]

# --- HTML -------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"fluidem {release}"
html_theme_options = {
    "navigation_depth": 2,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_static_path: list[str] = []


# --- docstrings -------------------------------------------------------------------------------
# Docstrings write absolute values and norms as in a textbook, |u| or |ρ_s − ρ_f|; reStructuredText
# would read |...| as a substitution.  Outside inline literals and roles such a pair of bars is escaped.
_LITERAL = re.compile(r"(``.*?``|`[^`]*`)")
_BARS = re.compile(r"(?<![\\|\w])\|(?=\S)([^|\n]*?\S)\|(?![|\w])")


def _escape_bars(line: str) -> str:
    parts = _LITERAL.split(line)  # odd items: ``literals`` and `roles`, left alone
    for i in range(0, len(parts), 2):
        parts[i] = _BARS.sub(lambda m: "\\|" + m.group(1) + "\\|", parts[i])
    return "".join(parts)


def _docstring_bars(app, what, name, obj, options, lines):
    in_math = False
    for i, line in enumerate(lines):
        stripped = line.strip()
        if stripped.startswith(".. math::"):
            in_math = True
        elif in_math and stripped and not line.startswith((" ", "\t")):
            in_math = False
        if not in_math and "|" in line:
            lines[i] = _escape_bars(line)


def setup(app):
    app.connect("autodoc-process-docstring", _docstring_bars)
