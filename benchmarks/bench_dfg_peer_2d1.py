"""DFG 2D-1 side by side with NGSolve: time to a given c_D accuracy, both codes in one session.

Run (one BLAS thread; about 5 minutes)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_dfg_peer_2d1.py --benchmark-only -p no:cacheprovider

fluidem: Taylor–Hood and P3/P2 on the default ``dfg_mesh`` levels 0–2 and on coarser meshes graded
faster away from the cylinder (:data:`COARSE`; Newton, median of 3 rounds, mesh + assembly + solve, as
in ``bench_dfg.py``); NGSolve: the 2D-1 configurations of
``peer_ngsolve.PEER_CONFIGS`` (Newton, its own timing of mesh + assembly + solve).  Writes
``benchmarks/results/dfg_2d1_peer.{md,json}`` with, for c_D within 1e-4, 1e-5 and 1e-6, the
cheapest configuration of each code and the fluidem/NGSolve ratio of their seconds.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import time  # noqa: E402

import pytest  # noqa: E402
from bench_dfg_unsteady import _peer_configs, _peer_id, peer_ngsolve  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.dfg import dfg_2d1  # noqa: E402

# (element, level, dfg_mesh options): the default levels 0-2, and below level 1 meshes graded
# faster away from the cylinder (growth 1.25 instead of 1.15, h0 and h_max as given), which trace the
# front between levels 0 and 1 where the cheapest c_D within 1e-4 lies.
COARSE = [("p3", {"h0": 0.02, "growth": 1.25}), ("p3", {"h0": 0.02, "growth": 1.25, "h_max": 0.1}),
          ("p3", {"h0": 0.015, "growth": 1.25}), ("p3", {"h0": 0.0125, "growth": 1.25}),
          ("th", {"h0": 0.01, "growth": 1.15, "h_max": 0.1}), ("th", {"h0": 0.0075, "growth": 1.25})]
FLUIDEM = [(e, lv, None) for e in ("th", "p3") for lv in (0, 1, 2)] + [(e, 0, o) for e, o in COARSE]
TOLERANCES = (1e-4, 1e-5, 1e-6)


def _cheapest(rows, code, tol):
    ok = [r for r in rows if r["code"] == code and abs(r["err_cd"]) <= tol]
    return min(ok, key=lambda r: r["cpu_s"]) if ok else None


@pytest.fixture(scope="session")
def rows():
    out = []
    yield out
    if not out:
        return
    machine = machine_description()
    write_json("dfg_2d1_peer", machine, out)
    cols = ["code", "label", "dofs", "wall_s", "cpu_s", "load_end", "err_cd", "err_cl", "err_dp"]
    lines = [f"| {' | '.join(cols)} |", "|" + "---|" * len(cols)]
    for r in sorted(out, key=lambda r: r["cpu_s"]):
        lines.append("| " + " | ".join(f"{r[c]:+.2e}" if c.startswith("err") else f"{r[c]:.3g}"
                                         if isinstance(r[c], float) else str(r[c]) for c in cols) + " |")
    notes = []
    for tol in TOLERANCES:
        a, b = _cheapest(out, "fluidem", tol), _cheapest(out, "NGSolve", tol)
        line = f"c_D within {tol:g}: fluidem " + (f"{a['label']} ({a['cpu_s']:.2f} CPU s)" if a else "none")
        line += "; NGSolve " + (f"{b['label']} ({b['cpu_s']:.2f} CPU s)" if b else "none")
        if a and b:
            line += f"; ratio {a['cpu_s'] / b['cpu_s']:.2f} (CPU), {a['wall_s'] / b['wall_s']:.2f} (wall)"
        notes.append(line)
    (RESULTS / "dfg_2d1_peer.md").write_text(
        f"Machine: {machine}; one BLAS thread; seconds of mesh + assembly + solve (fluidem: median of 3 "
        "rounds; NGSolve: one run, timed inside its process).\n\n" + "\n".join(lines) + "\n\n"
        + "\n".join(f"- {n}" for n in notes) + "\n")


def _label(element, level, options):
    if not options:
        return f"{element} level {level}"
    return f"{element} " + " ".join(f"{k} {v:g}" for k, v in options.items())


@pytest.mark.parametrize("element, level, options", FLUIDEM,
                         ids=[_label(*c).replace(" ", "-") for c in FLUIDEM])
def test_fluidem_2d1(benchmark, rows, element, level, options):
    cpu = []

    def once():
        c0 = time.process_time()
        res = dfg_2d1(element, level, mesh_options=options)
        cpu.append(time.process_time() - c0)
        return res

    res = benchmark.pedantic(once, rounds=3, iterations=1)
    errs = res.relative_errors()
    rows.append({"code": "fluidem", "label": _label(element, level, options), "dofs": int(res.dofs),
                 "wall_s": benchmark.stats.stats.median, "cpu_s": sorted(cpu)[1], "load_end": os.getloadavg()[0],
                 **{f"err_{k}": v for k, v in errs.items()}})


@pytest.mark.parametrize("cfg", _peer_configs("dfg-2d1"), ids=lambda c: _peer_id({**c, "dt": 0}) if c else "peer")
def test_peer_2d1(benchmark, rows, cfg):
    peer = peer_ngsolve.ensure_ngsolve()
    if peer.python is None:
        pytest.skip(f"NGSolve not available: {peer.reason}")
    out = benchmark.pedantic(lambda: peer_ngsolve.run_ngsolve(python=peer.python, **cfg), rounds=1, iterations=1)
    rows.append({"code": "NGSolve", "label": f"P{out['element'][1]} maxh {out['maxh']:g}/{out['maxh_cyl']:g}",
                 "dofs": out["dofs"], "wall_s": out["wall_s"], "cpu_s": out["cpu_s"], "load_end": out["load_end"],
                 **{f"err_{k}": v for k, v in out["errors"].items()}})
