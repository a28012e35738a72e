"""Settings shared by the test suite (``tests/``) and the docstring examples (``fluidem/``).

* One BLAS thread and a non-interactive matplotlib backend, set before numpy or matplotlib is
  imported (a value already in the environment wins).
* A docstring example that needs an optional package is skipped when the package is missing.
* With pytest-xdist (``python -m pytest -n 2``) tests are scheduled so the workers finish
  together: ``--dist loadgroup --no-loadscope-reorder`` unless ``--dist`` is given, the slow
  tests first, longest first, and the slow tests of one module on one worker (modules share
  fixtures and caches between their slow tests).  A slow test marked
  ``@pytest.mark.slow(seconds=S)`` declares that it shares nothing and takes about ``S``
  seconds: it is scheduled alone, by that figure.
"""

import importlib.util
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import pytest  # noqa: E402

#: Docstring examples that need an optional package: module -> packages.
DOCTEST_REQUIRES = {"fluidem.plotting": ("matplotlib",)}

#: Estimated seconds of a slow test without a ``seconds`` figure (for the order only).
UNMEASURED_SLOW_SECONDS = 60.0


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    """With ``-n`` and no ``--dist``: the load-group scheduler in collection order."""
    if getattr(config.option, "numprocesses", None) and getattr(config.option, "dist", "no") == "no":
        config.option.dist = "loadgroup"
        config.option.loadscopereorder = False


def _missing(packages):
    return [p for p in packages if importlib.util.find_spec(p) is None]


def _schedule_slowest_first(items, add_groups):
    """Reorder ``items`` into work units, longest estimated unit first (stable otherwise)."""
    units = {}
    for item in items:
        slow = item.get_closest_marker("slow")
        groups = [m.args[0] if m.args else m.kwargs.get("name", "default") for m in item.iter_markers("xdist_group")]
        if groups:
            key, seconds = "@" + "_".join(sorted(map(str, groups))), UNMEASURED_SLOW_SECONDS if slow else 0.0
        elif slow is None:
            key, seconds = item.nodeid, 0.0
        elif "seconds" in slow.kwargs:
            key, seconds = item.nodeid, float(slow.kwargs["seconds"])
        else:
            key, seconds = "@" + item.nodeid.split("::")[0], UNMEASURED_SLOW_SECONDS
            if add_groups:
                item.add_marker(pytest.mark.xdist_group(key[1:]))
        unit = units.setdefault(key, [0.0, []])
        unit[0] += seconds
        unit[1].append(item)
    ordered = sorted(units.values(), key=lambda u: -u[0])  # sorted() is stable: ties keep collection order
    items[:] = [item for _, members in ordered for item in members]


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    for item in items:
        dtest = getattr(item, "dtest", None)  # a docstring example
        missing = _missing(DOCTEST_REQUIRES.get(dtest.globs.get("__name__"), ())) if dtest else []
        if missing:
            item.add_marker(pytest.mark.skip(reason=f"needs {', '.join(missing)}"))
    if hasattr(config, "workerinput"):  # an xdist worker: the controller schedules in this order
        _schedule_slowest_first(items, add_groups=config.getoption("dist") == "loadgroup")
