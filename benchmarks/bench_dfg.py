"""Accuracy against cost on the DFG cylinder benchmarks: element × mesh level.

Run (one BLAS thread; wall-clock figures, so the median of several rounds)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_dfg.py --benchmark-only \
        --benchmark-columns=median,min,rounds -p no:cacheprovider

Writes ``benchmarks/results/dfg_2d1.{md,json,png}`` (2D-1: relative errors of c_D, c_L, Δp
against the wall time of mesh + assembly + solve).  The PNG is the accuracy-versus-cost front
that tells which element and level to pick.  Select a subset with ``-k``, e.g. ``-k "p3"``.
The unsteady cases (2D-2, 2D-3) are in ``bench_dfg_unsteady.py``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")


import pytest  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.dfg import dfg_2d1  # noqa: E402

MATRIX_2D1 = [(e, lv) for e in ("mini", "th", "p2b", "p3") for lv in (0, 1, 2, 3)]


class _Report:
    def __init__(self, name, columns):
        self.name, self.columns, self.rows = name, columns, []

    def add(self, row):
        self.rows.append(row)

    def write(self):
        if not self.rows:
            return
        machine = machine_description()
        write_json(self.name, machine, self.rows)
        lines = [f"| {' | '.join(self.columns)} |", "|" + "---|" * len(self.columns)]
        for r in sorted(self.rows, key=lambda r: (r["element"], r["level"], r.get("dt") or 0)):
            cells = []
            for c in self.columns:
                v = r.get(c)
                cells.append(f"{v:.2e}" if isinstance(v, float) and (c.startswith("err") or abs(v) < 1e-2)
                             else f"{v:.2f}" if isinstance(v, float) else str(v))
            lines.append("| " + " | ".join(cells) + " |")
        (RESULTS / f"{self.name}.md").write_text(f"Machine: {machine}; one BLAS thread; median wall "
                                                 "seconds (mesh + assembly + solve).\n\n" + "\n".join(lines) + "\n")


@pytest.fixture(scope="session")
def report_2d1():
    rep = _Report("dfg_2d1", ["element", "level", "dofs", "wall_s", "solve_s", "err_cd", "err_cl", "err_dp"])
    yield rep
    rep.write()
    _plot_front(rep.rows)


def _plot_front(rows):
    if not rows:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharex=True)
    for ax, q in zip(axes, ("cd", "cl", "dp")):
        for el in sorted({r["element"] for r in rows}):
            rs = sorted((r for r in rows if r["element"] == el), key=lambda r: r["level"])
            ax.loglog([r["wall_s"] for r in rs], [r[f"err_{q}"] for r in rs], "o-", label=el)
            for r in rs:
                ax.annotate(str(r["level"]), (r["wall_s"], r[f"err_{q}"]), fontsize=7)
        ax.set_title(f"DFG 2D-1: relative error of {q}")
        ax.set_xlabel("wall time, s (mesh + assembly + solve)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(title="element (level)")
    fig.tight_layout()
    fig.savefig(RESULTS / "dfg_2d1.png", dpi=110)
    plt.close(fig)


@pytest.mark.parametrize("element, level", MATRIX_2D1, ids=[f"2d1-{e}-L{lv}" for e, lv in MATRIX_2D1])
def test_dfg_2d1(benchmark, report_2d1, element, level):
    rounds = 3 if level <= 2 else 1
    res = benchmark.pedantic(dfg_2d1, kwargs={"element": element, "level": level}, rounds=rounds, iterations=1)
    errs = res.relative_errors()
    row = {"element": element, "level": level, "dofs": int(res.dofs), "wall_s": benchmark.stats.stats.median,
           "solve_s": res.timings["solve"], **{f"err_{k}": v for k, v in errs.items()}}
    benchmark.extra_info.update(row)
    report_2d1.add(row)
