"""``benchmarks/bench_dense.py --log`` reads the lines ``fluidem run --verbose`` writes
(:func:`fluidem.progress.verbose_line`): a change of their wording must not drop steps silently."""

import importlib.util
import pathlib

import pytest

from fluidem.cost import CostSplit
from fluidem.progress import verbose_line

BENCH = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bench_dense.py"


@pytest.fixture
def bench_dense(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH.parent))  # its results_io
    spec = importlib.util.spec_from_file_location("bench_dense", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_run_log_parser_reads_the_verbose_lines_of_a_contact_step(bench_dense):
    cost = CostSplit({"mesh": 0.0124, "solve": 1.1178, "dem": 0.6708, "output": 0.0073},
                     {"dem_substeps": 134, "dem_passes": 4, "dem_body_substeps": 2470})
    info = {"step": 190, "t": 1.9, "solver": "pardiso", "iterations": 0, "residual": 3.8e-16, "factorizations": 57,
            "cfl": 0.256, "dem_set_by": "the gaps' change: a quarter of a gap per sub-step; 1 cluster of at most 13 "
                                        "bodies"}
    line = verbose_line(info, 300, cost)
    quiet = verbose_line({"step": 191, "t": 1.91, "solver": "gmres+lagged-lu", "iterations": 4, "residual": 1e-5,
                          "factorizations": 57}, 300, CostSplit({"assembly": 0.1, "solve": 0.9}))
    events = ("step=0 t=0 mesh moving, initial: 17136 triangles, 159066 DOFs, polygonal\n"  # as a run writes them
              "step=190 t=1.9 retriangulation reason=quality nodes=9861 triangles=17399; fields transferred by ALE "
              "interpolation through the old mesh motion; interpolation noise 0.623 %; force change 0.47 %\n")
    parsed = bench_dense.parse_run_log(line + "\n" + quiet + "\n", events)
    assert sorted(parsed["steps"]) == [190, 191]
    step = parsed["steps"][190]
    assert (step["substeps"], step["passes"], step["lu"]) == (134, 4, 57)
    assert step["dem"] == pytest.approx(0.6708) and step["solve"] == pytest.approx(1.1178)
    assert step["total"] == pytest.approx(cost.total, abs=1e-4)
    assert parsed["steps"][191]["substeps"] == 0
    assert parsed["retri"] == {190: ("quality", 0.47)} and parsed["dofs"] == 159066
