"""What accuracy costs over time: the unsteady DFG fronts (2D-2, 2D-3), with a peer beside them.

Run (one BLAS thread; about 15 minutes for fluidem's points, plus the peer's)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_dfg_unsteady.py --benchmark-only \
        -p no:cacheprovider

Each configuration is one run of :func:`fluidem.cases.dfg.dfg_2d2` / :func:`~fluidem.cases.dfg.dfg_2d3`
(element × mesh × dt × time scheme × convection), timed as a whole (mesh, assembly, solves,
loads: the seconds a user waits for the answer).  Where the peer (NGSolve, installed from PyPI
into its own environment by ``peer_ngsolve.py``) is available, its configurations run in the
same session, one process and one thread as well; otherwise they are skipped with the reason.

Writes ``benchmarks/results/dfg_2d2.{md,json,png}`` and ``dfg_2d3.{md,json,png}``: the error
of each quantity against wall time, the cheapest configuration within 1 % and within 0.3 % (of
the case's target quantities: St and c_D,max for 2D-2; c_D,max and c_L,max for 2D-3) marked.
Select with ``-k``, e.g. ``-k "2d2 and not peer"``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import time  # noqa: E402

import pytest  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.dfg import dfg_2d2, dfg_2d3  # noqa: E402

#: meshes refined at the cylinder (h0 = 0.02 there, cells growing by 1.15) up to h_max: dfg_mesh(0, **LOCAL)
LOCAL = {"h0": 0.02, "h_max": 0.08}
LOCAL_COARSE = {"h0": 0.02, "h_max": 0.12}

#: (label, element, level, mesh_options, dt, order, convection); level 0 with mesh_options is the local mesh
MATRIX_2D2 = [
    ("P3 L1 BDF2", "p3", 1, None, 0.005, 2, "semi-implicit"),
    ("P3 L1 BDF2", "p3", 1, None, 0.0025, 2, "semi-implicit"),
    ("P3 L1 BDF3", "p3", 1, None, 0.01, 3, "semi-implicit"),
    ("P3 L1 BDF3", "p3", 1, None, 0.005, 3, "semi-implicit"),
    ("P3 local BDF3", "p3", 0, LOCAL, 0.01, 3, "semi-implicit"),
    ("P3 local BDF3", "p3", 0, LOCAL, 0.0075, 3, "semi-implicit"),
    ("P3 local BDF3", "p3", 0, LOCAL, 0.005, 3, "semi-implicit"),
    ("P3 local-coarse BDF3", "p3", 0, LOCAL_COARSE, 0.01, 3, "semi-implicit"),
    ("P3 local-coarse BDF3", "p3", 0, LOCAL_COARSE, 0.0075, 3, "semi-implicit"),
    ("P3 L0 BDF3", "p3", 0, None, 0.005, 3, "semi-implicit"),
    ("P3 L0 BDF3/EXT3", "p3", 0, None, 1 / 1200, 3, "explicit"),
]
MATRIX_2D3 = [
    ("P3 L1 BDF3", "p3", 1, None, 0.005, 3, "semi-implicit"),
    ("P3 local BDF3", "p3", 0, LOCAL, 0.01, 3, "semi-implicit"),
    ("P3 local BDF3", "p3", 0, LOCAL, 0.005, 3, "semi-implicit"),
]
TARGETS = {"dfg_2d2": ("st", "cd_max"), "dfg_2d3": ("cd_max", "cl_max")}
TITLES = {"dfg_2d2": "DFG 2D-2", "dfg_2d3": "DFG 2D-3"}
QUANTITIES = {"dfg_2d2": ("st", "cd_max", "cl_max"), "dfg_2d3": ("cd_max", "cl_max", "dp_end")}


def _ids(matrix, case):
    return [f"{case}-{lab.replace(' ', '-')}-dt{dt:.3g}" for lab, *_, dt, _o, _c in matrix]


class _Front:
    """Rows of one case; written as Markdown, JSON and a plot when the session ends."""

    def __init__(self, name):
        self.name, self.rows = name, []

    def add(self, row):
        self.rows.append(row)

    def cheapest(self, tol, code="fluidem"):
        ok = [r for r in self.rows if r["code"] == code
              and max(abs(r[f"err_{q}"]) for q in TARGETS[self.name]) <= tol]
        return min(ok, key=lambda r: r["wall_s"]) if ok else None

    def write(self, machine=None):
        """Markdown, JSON and plot of the rows; ``machine``: keep this machine line (a re-plot)."""
        if not self.rows:
            return
        machine = machine or machine_description()
        marks = {tol: self.cheapest(tol) for tol in (1e-2, 3e-3)}
        peer_marks = {tol: self.cheapest(tol, "NGSolve") for tol in (1e-2, 3e-3)}
        write_json(self.name, machine, self.rows)
        cols = (["code", "label", "dt", "dofs", "steps", "wall_s", "cpu_s", "ms_per_step", "load_end"]
                + [f"err_{q}" for q in QUANTITIES[self.name]])
        lines = [f"| {' | '.join(cols)} |", "|" + "---|" * len(cols)]
        for r in sorted(self.rows, key=lambda r: r["wall_s"]):
            cells = []
            for c in cols:
                v = r.get(c)
                cells.append(f"{v:+.2e}" if c.startswith("err") and v is not None else
                             f"{v:.4g}" if isinstance(v, float) else "—" if v is None else str(v))
            lines.append("| " + " | ".join(cells) + " |")
        names = " and ".join(TARGETS[self.name])
        notes = []
        for tol, m in marks.items():
            line = f"Cheapest within {tol:.1%} on {names}: " + (
                f"{m['label']} dt {m['dt']:.4g} ({m['wall_s']:.1f} s, {m['cpu_s']:.1f} CPU s)" if m else "none")
            peer = self.cheapest(tol, "NGSolve")
            if peer:
                line += (f"; NGSolve {peer['label']} dt {peer['dt']:.4g} ({peer['wall_s']:.1f} s, "
                         f"{peer['cpu_s']:.1f} CPU s)")
                if m:
                    line += (f"; fluidem/NGSolve time ratio {m['wall_s'] / peer['wall_s']:.2f} (wall), "
                             f"{m['cpu_s'] / peer['cpu_s']:.2f} (CPU)")
            notes.append(line)
        (RESULTS / f"{self.name}.md").write_text(
            f"Machine: {machine}; one BLAS thread; wall seconds of the whole run (mesh, assembly, "
            "solves, loads), one round each.\n\n" + "\n".join(lines) + "\n\n" + "\n".join(f"- {n}" for n in notes)
            + "\n")
        _plot(self.name, self.rows, marks, peer_marks)


def _series(row):
    return row["label"] if row["code"] == "fluidem" else "NGSolve: P3/P2 IMEX BDF2/EXT2, Netgen meshes"


def _plot(name, rows, marks, peer_marks):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    qs = QUANTITIES[name]
    fig, axes = plt.subplots(1, len(qs), figsize=(4.6 * len(qs), 5.4), sharex=True)
    for ax, q in zip(axes, qs):
        for series in sorted({_series(r) for r in rows}):
            rs = sorted((r for r in rows if _series(r) == series), key=lambda r: r["wall_s"])
            peer = rs[0]["code"] != "fluidem"
            ax.loglog([r["wall_s"] for r in rs], [max(abs(r[f"err_{q}"]), 1e-7) for r in rs],
                      "ks:" if peer else "o-", mfc="none" if peer else None,
                      label=series if peer else f"fluidem: {series}")
        for tol in marks:
            ax.axhline(tol, color="0.6", lw=0.8, ls=":")
            for m, style in ((marks[tol], "r*"), (peer_marks[tol], "kx")):
                if m:
                    ax.plot([m["wall_s"]], [max(abs(m[f"err_{q}"]), 1e-7)], style, ms=12, mew=2)
        ax.set_title(f"{TITLES[name]}: |relative error| of {q}")
        ax.set_xlabel("wall time of the run, s")
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8,
               title="cheapest within 1 % / 0.3 % (dotted lines) on the targets: red star fluidem, black cross "
                     "NGSolve", title_fontsize=8)
    fig.tight_layout(rect=(0, 0.2, 1, 1))
    fig.savefig(RESULTS / f"{name}.png", dpi=110)
    plt.close(fig)


@pytest.fixture(scope="session")
def front_2d2():
    f = _Front("dfg_2d2")
    yield f
    f.write()


@pytest.fixture(scope="session")
def front_2d3():
    f = _Front("dfg_2d3")
    yield f
    f.write()


def _run(benchmark, front, fn, label, element, level, mesh_options, dt, order, convection):
    def once():
        t0, c0 = time.perf_counter(), time.process_time()
        res = fn(element=element, level=level, dt=dt, order=order, convection=convection,
                 mesh_options=mesh_options)
        return res, time.perf_counter() - t0, time.process_time() - c0

    res, wall, cpu = benchmark.pedantic(once, rounds=1, iterations=1)
    errs = {k: (res.quantities[k] - v) / abs(v) for k, v in res.reference.items() if k in res.quantities}
    steps = res.extra["steps"]
    row = {"code": "fluidem", "label": label, "element": element, "level": level, "mesh_options": mesh_options,
           "dt": dt, "order": order, "convection": convection, "dofs": int(res.dofs), "steps": steps,
           "wall_s": wall, "cpu_s": cpu, "ms_per_step": 1e3 * wall / steps, "load_end": os.getloadavg()[0],
           **{f"err_{k}": v for k, v in errs.items()},
           **{k: res.extra.get(k) for k in ("linear_solves", "factorizations", "krylov_iterations", "max_cfl")}}
    benchmark.extra_info.update(row)
    front.add(row)


@pytest.mark.parametrize("label, element, level, mesh_options, dt, order, convection", MATRIX_2D2,
                         ids=_ids(MATRIX_2D2, "2d2"))
def test_dfg_2d2(benchmark, front_2d2, label, element, level, mesh_options, dt, order, convection):
    _run(benchmark, front_2d2, dfg_2d2, label, element, level, mesh_options, dt, order, convection)


@pytest.mark.parametrize("label, element, level, mesh_options, dt, order, convection", MATRIX_2D3,
                         ids=_ids(MATRIX_2D3, "2d3"))
def test_dfg_2d3(benchmark, front_2d3, label, element, level, mesh_options, dt, order, convection):
    _run(benchmark, front_2d3, dfg_2d3, label, element, level, mesh_options, dt, order, convection)


# -- the peer, side by side ------------------------------------------------------------------
try:
    import peer_ngsolve
except ImportError as err:  # benchmarks/peer_ngsolve.py missing or broken: the peer rows are skipped
    peer_ngsolve, _PEER_MISSING = None, f"benchmarks/peer_ngsolve.py did not import: {err}"


def _peer_configs(case):
    if peer_ngsolve is None:
        return [pytest.param({}, marks=pytest.mark.skip(reason=_PEER_MISSING))]
    return [c for c in peer_ngsolve.PEER_CONFIGS if c["case"] == case]


def _peer_id(c):
    if not c:
        return "peer"
    return f"peer-{c['case'][4:]}-{c['element']}-h{c['maxh']:g}-hc{c.get('maxh_cyl') or c['maxh']:g}-dt{c['dt']:.3g}"


def _peer(benchmark, front, cfg):
    peer = peer_ngsolve.ensure_ngsolve()
    if peer.python is None:
        pytest.skip(f"NGSolve not available: {peer.reason}")
    out = benchmark.pedantic(lambda: peer_ngsolve.run_ngsolve(python=peer.python, **cfg), rounds=1, iterations=1)
    if out.get("diverged_at") is not None:
        pytest.skip(f"NGSolve diverged at t = {out['diverged_at']:g} s")
    hc = out["maxh_cyl"]
    row = {"code": "NGSolve", "label": f"P{out['element'][1]} IMEX BDF2/EXT2, maxh {out['maxh']:g}/{hc:g}",
           "element": out["element"], "dt": out["dt"], "order": 2, "convection": "explicit", "dofs": out["dofs"],
           "steps": out["steps"], "wall_s": out["wall_s"], "cpu_s": out["cpu_s"],
           "ms_per_step": out["ms_per_step"], "load_end": out["load_end"], "version": out["ngsolve_version"],
           **{f"err_{k}": v for k, v in out["errors"].items()}}
    benchmark.extra_info.update({k: v for k, v in row.items() if isinstance(v, (int, float, str))})
    front.add(row)


@pytest.mark.parametrize("cfg", _peer_configs("dfg-2d2"), ids=_peer_id)
def test_peer_2d2(benchmark, front_2d2, cfg):
    _peer(benchmark, front_2d2, cfg)


@pytest.mark.parametrize("cfg", _peer_configs("dfg-2d3"), ids=_peer_id)
def test_peer_2d3(benchmark, front_2d3, cfg):
    _peer(benchmark, front_2d3, cfg)


if __name__ == "__main__":  # re-draw the Markdown tables and plots from the JSON results
    import json

    for name in TARGETS:
        path = RESULTS / f"{name}.json"
        if path.exists():
            doc = json.loads(path.read_text())
            front = _Front(name)
            front.rows = doc["rows"]
            front.write(machine=doc["machine"])
