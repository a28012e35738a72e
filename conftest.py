"""Settings shared by the test suite (``tests/``) and the docstring examples (``fluidem/``).

* One BLAS thread and a non-interactive matplotlib backend, set before numpy or matplotlib is
  imported (a value already in the environment wins).
* A docstring example that needs an optional package is skipped when the package is missing.
* With pytest-xdist and no ``--dist`` (``python -m pytest -n 2``), tests are scheduled so the
  workers finish together.  A work unit is a test module (its tests share module fixtures and
  caches, e.g. the poured heaps of ``tests/dem/test_dem_granular.py``), or a single test of a
  module in :data:`INDEPENDENT_MODULES`.  Units are handed out longest first (the longest
  ``2 n`` in a snake order over the ``n`` workers), by the ``seconds`` of
  ``@pytest.mark.slow(seconds=S)`` (measured wall seconds of the test) or
  :data:`UNMEASURED_SLOW_SECONDS` for a slow test without a figure; fast tests count zero.
"""

import importlib.util
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import pytest  # noqa: E402

#: Docstring examples that need an optional package: module -> packages.
DOCTEST_REQUIRES = {"fluidem.plotting": ("matplotlib",)}

#: Test modules whose tests share nothing, so each may run on any worker.
INDEPENDENT_MODULES = ("tests/test_benchmarks_slow.py", "tests/test_notebooks.py")

#: Estimated wall seconds of a slow test without a ``seconds`` figure (for the order only).
UNMEASURED_SLOW_SECONDS = 60.0

_MODULE_SCHEDULER = pytest.StashKey[bool]()


def _unit(nodeid: str) -> str:
    """The work unit of a test: its module, or the test itself in an independent module."""
    module = nodeid.split("::", 1)[0]
    return nodeid if module in INDEPENDENT_MODULES else module


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    """With ``-n`` and no ``--dist``: the module scheduler below, in the workers' order."""
    if getattr(config.option, "numprocesses", None) and getattr(config.option, "dist", "no") == "no":
        config.option.dist = "loadscope"
        config.option.loadscopereorder = False
        config.stash[_MODULE_SCHEDULER] = True


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    if not config.stash.get(_MODULE_SCHEDULER, False):
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ModuleScheduling(LoadScopeScheduling):
        """Load-scope scheduling with :func:`_unit` as the scope, units in collection order."""

        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid)

    return ModuleScheduling(config, log)


def _seconds(item) -> float:
    slow = item.get_closest_marker("slow")
    if slow is None:
        return 0.0
    return float(slow.kwargs.get("seconds", UNMEASURED_SLOW_SECONDS))


def _schedule_longest_first(items, n_workers: int) -> None:
    """Reorder ``items`` unit by unit, longest unit first, the first ``2 n`` in a snake order.

    The scheduler gives each worker one unit, then a second one, then one more whenever a
    worker is almost idle: the order [1, 2, 4, 3, 5, ...] for two workers pairs the longest
    unit with the fourth and the second with the third.
    """
    units: dict[str, list] = {}
    for item in items:
        unit = units.setdefault(_unit(item.nodeid), [0.0, []])
        unit[0] += _seconds(item)
        unit[1].append(item)
    ordered = sorted(units.values(), key=lambda u: -u[0])  # stable: ties keep the collection order
    n = max(1, n_workers)
    ordered[n:2 * n] = ordered[n:2 * n][::-1]
    items[:] = [item for _, members in ordered for item in members]


def _missing(packages):
    return [p for p in packages if importlib.util.find_spec(p) is None]


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    for item in items:
        dtest = getattr(item, "dtest", None)  # a docstring example
        missing = _missing(DOCTEST_REQUIRES.get(dtest.globs.get("__name__"), ())) if dtest else []
        if missing:
            item.add_marker(pytest.mark.skip(reason=f"needs {', '.join(missing)}"))
    if hasattr(config, "workerinput"):  # an xdist worker: the controller schedules in this order
        _schedule_longest_first(items, config.workerinput.get("workercount", 1))
