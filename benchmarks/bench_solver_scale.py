"""The sparse LU at scale: SuperLU, PARDISO and the iterative path on the coupled systems of settling suspensions.

Systems: the coupled fluid–body matrix (rigid modes of the free bodies in place of their outline
velocities) of the settling suspension of ``bench_dense.py`` (polygons at area fraction 0.35,
Navier–Stokes, P2+bubble/P1dc, h = 0.012, dt = 0.01) after its first step, for N bodies (100 → 149k
DOFs, 300 → ~450k, 1 000 → ~1.5M).  Each factorisation runs in its own process (its peak memory is
the process's): SuperLU as fluidem calls it for P2+bubble (COLAMD, threshold pivoting 0.01), and
PARDISO with the settings of :mod:`fluidem.fluid.solvers.pardiso` on one and on two threads.  Per
system: factorisation and solve seconds, entries of L + U, peak resident MiB, the relative residual
of one solve with the factors alone, and the GMRES iterations to 1e-6 (the lagged solver's tolerance
on the moving mesh) with the factors of the same matrix.  SuperLU is skipped where the fill it
reached at smaller sizes, extrapolated, would not fit in the machine's memory.

Runs: the same scenes run a few steps with ``fluid.lu_backend = "superlu"`` and ``"pardiso"``
(and ``fluid.solver = "iterative"``, memory linear in DOFs): seconds per step (median over the steps
after the first), the solve's share, LU factorisations, peak MiB.

The plan's estimate of a uniform mesh (3.6 triangles per h², measured on one-body channels) counts these
many-body scenes 1.7–1.8 times too large: 1 000 bodies at h = 0.012 are estimated at 2.7M DOFs and ~30 GB
and refused on a machine with less (1.57M DOFs and 12.3 GB peak were measured with PARDISO, with a
temporary estimate of 2.1 triangles per h²).

Run (tens of minutes; one BLAS thread)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_solver_scale.py [--part systems,runs] [--bodies 100,300,1000]

writes ``benchmarks/results/solver_scale.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, markdown_table, write_json  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
#: SuperLU's fill grew as n^1.3 on these systems (15k → 149k DOFs: 4.0M → 78M entries); 12 bytes an
#: entry (value and row index) and twice that for the factorisation's work space
SUPERLU_FILL_EXPONENT = 1.3
RUN_STEPS = 6


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def make_system(n: int, path: str) -> dict:
    """Run the scene of ``n`` bodies one step and save its coupled matrix to ``path`` (.npz)."""
    import gc
    import warnings

    import scipy.sparse as sp

    import bench_dense
    from fluidem.fluid.solvers import LaggedLUSolver
    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    sim = Simulation(Scene.from_dict(bench_dense.scene_dict(n, 1)))
    sim.run(out_dir=None, n_steps=1)
    K = next(o for o in gc.get_objects() if isinstance(o, LaggedLUSolver) and o.K is not None).K.tocsr()
    K.sort_indices()
    sp.save_npz(path, K)
    return {"dofs": int(K.shape[0]), "nnz": int(K.nnz), "make_s": time.perf_counter() - t0}


def factorise(path: str, how: str) -> dict:
    """Factorise the saved matrix with ``how`` (``superlu`` or ``pardiso``) in this process."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from fluidem.fluid.solvers.direct import COLAMD_PIVOT_THRESHOLD
    from fluidem.fluid.solvers.krylov import run_fgmres

    K = sp.load_npz(path).tocsr()
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    t0 = time.perf_counter()
    if how == "superlu":
        lu = spla.splu(K.tocsc(), permc_spec="COLAMD", diag_pivot_thresh=COLAMD_PIVOT_THRESHOLD)
        fill = int(lu.L.nnz + lu.U.nnz)
        apply = lu.solve
    else:
        from fluidem.fluid.solvers.pardiso import PardisoLU

        lu = PardisoLU(K)
        fill = lu.fill
        apply = lu.solve
    fact = time.perf_counter() - t0
    t0 = time.perf_counter()
    x = apply(b)
    solve = time.perf_counter() - t0
    relres = float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))
    M = spla.LinearOperator(K.shape, matvec=apply, dtype=float)
    _, its, _, _ = run_fgmres(K, b, M, None, rtol=1e-6, maxiter=50, restart=50, stagnation=1e3)
    return {"factorise_s": fact, "solve_s": solve, "fill": fill, "relres": relres, "gmres_its": int(its),
            "peak_mib": _peak_mib()}


def run_scene(n: int, backend: str, solver: str) -> dict:
    """The scene of ``n`` bodies, ``RUN_STEPS`` steps with this LU backend and solver: per-step costs."""
    import warnings

    import bench_dense
    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    warnings.simplefilter("ignore")
    d = bench_dense.scene_dict(n, RUN_STEPS)
    d["fluid"]["lu_backend"] = backend
    d["fluid"]["solver"] = solver
    sim = Simulation(Scene.from_dict(d))
    rows = []

    def record(k, nsteps, t, cost):
        rows.append({"wall": cost.total, "solve": cost.parts.get("solve", 0.0)})

    error = None
    try:
        sim.run(out_dir=None, progress=record, n_steps=RUN_STEPS)
    except Exception as exc:  # a stopped run is a result too
        error = str(exc).splitlines()[0][:200]
    s = [r["wall"] for r in rows[1:]] or [np.nan]
    solver = getattr(getattr(sim.flow, "coupled", None), "solver", None) or getattr(sim.flow, "_lagged_mobility", None)
    lus = getattr(solver, "factorizations", None)
    return {"dofs": int(sim.flow.dofs), "steps": len(rows), "s_per_step": float(np.median(s)),
            "solve_share": float(sum(r["solve"] for r in rows[1:]) / max(sum(r["wall"] for r in rows[1:]), 1e-300)),
            "first_step_s": rows[0]["wall"] if rows else None, "lus": lus, "peak_mib": _peak_mib(), "error": error}


def _in_process(args: list, threads: int = 1) -> dict:
    env = dict(os.environ, PYTHONPATH=f"{HERE.parent}{os.pathsep}{HERE}", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS=str(threads))
    out = subprocess.run([sys.executable, __file__, "--worker", json.dumps(args)], env=env, capture_output=True,
                         text=True, check=False)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if not lines:
        return {"error": (out.stderr.strip().splitlines() or ["no output"])[-1][:200]}
    return json.loads(lines[-1])


def _available_mib() -> float:
    for line in pathlib.Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemAvailable:"):
            return float(line.split()[1]) / 1024.0
    return float("inf")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="systems,runs")
    ap.add_argument("--bodies", default="100,300,1000")
    ap.add_argument("--run-bodies", default="100,300")
    ap.add_argument("--run-variants", default="superlu,pardiso,iterative",
                    help="runs: SuperLU, PARDISO (as auto chooses), block GMRES, PARDISO lagged whatever the "
                         "memory rule says (pardiso-lagged); comma-separated")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        job = json.loads(a.worker)
        fn = {"make": make_system, "factorise": factorise, "run": run_scene}[job[0]]
        print(json.dumps(fn(*job[1:])), flush=True)
        return
    parts = a.part.split(",")
    machine = machine_description()
    old = RESULTS / "solver_scale.json"
    rows = json.loads(old.read_text())["rows"] if old.exists() else []
    if "systems" in parts:
        with tempfile.TemporaryDirectory() as tmp:
            seen = [r for r in rows if r["part"] == "systems" and r["how"] == "superlu" and r.get("fill")]
            for n in map(int, a.bodies.split(",")):
                path = os.path.join(tmp, f"K{n}.npz")
                made = _in_process(["make", n, path], threads=2)
                print(n, made, flush=True)
                if "error" in made:
                    continue
                rows = [r for r in rows if not (r["part"] == "systems" and r["bodies"] == n)]
                for how, threads in (("superlu", 1), ("pardiso", 1), ("pardiso", 2)):
                    row = {"part": "systems", "bodies": n, "dofs": made["dofs"], "nnz": made["nnz"], "how": how,
                           "threads": threads, "load": os.getloadavg()[0]}
                    if how == "superlu" and seen:
                        ref = max(seen, key=lambda r: r["dofs"])
                        need = 2 * 12 * ref["fill"] * (made["dofs"] / ref["dofs"]) ** SUPERLU_FILL_EXPONENT / 2**20
                        if need > 0.8 * _available_mib():
                            row["skipped"] = f"predicted {need / 1024:.0f} GiB > 80 % of the available memory"
                            rows.append(row)
                            print(row, flush=True)
                            continue
                    row.update(_in_process(["factorise", path, how], threads=threads))
                    rows.append(row)
                    if how == "superlu" and row.get("fill"):
                        seen.append(row)
                    print(row, flush=True)
                    write_json("solver_scale", machine, rows)
    if "runs" in parts:
        for n in map(int, a.run_bodies.split(",")):
            variants = {"superlu": ("superlu", "auto"), "pardiso": ("pardiso", "auto"),
                        "iterative": ("auto", "iterative"), "pardiso-lagged": ("pardiso", "lagged")}
            chosen = [variants[v] for v in a.run_variants.split(",")]
            rows = [r for r in rows if not (r["part"] == "runs" and r["bodies"] == n
                                            and (r["backend"], r["solver"]) in chosen)]
            for backend, solver in chosen:
                row = {"part": "runs", "bodies": n, "backend": backend, "solver": solver, "load": os.getloadavg()[0]}
                row.update(_in_process(["run", n, backend, solver], threads=1))
                rows.append(row)
                print(row, flush=True)
                write_json("solver_scale", machine, rows)
    write_json("solver_scale", machine, rows)
    write_markdown(rows, machine)


def write_markdown(rows: list, machine: str) -> None:
    def table(header, cells):
        return markdown_table(header, [[str(c) for c in row] for row in cells])

    def g(r, k, fmt):
        v = r.get(k)
        return "–" if v is None else format(v, fmt)

    sysrows = sorted((r for r in rows if r["part"] == "systems"), key=lambda r: (r["dofs"], r["how"], r["threads"]))
    runrows = sorted((r for r in rows if r["part"] == "runs"), key=lambda r: (r["bodies"], r["backend"], r["solver"]))
    lines = ["# The sparse LU at scale: coupled systems of settling suspensions", "",
             f"Machine: {machine}.  `benchmarks/bench_solver_scale.py` (its docstring has the set-up); one BLAS "
             "thread, PARDISO on the threads given; each factorisation in its own process (peak = that process's "
             "resident memory, the matrix included); the load average when each row ran is beside it.", "",
             "## Factorisations", ""]
    lines += table(
        ["bodies", "DOFs", "nnz(K)", "LU", "threads", "factorise s", "solve s", "L+U entries", "entries/DOF",
         "peak MiB", "residual (factors alone)", "GMRES its to 1e-6", "load"],
        [[r["bodies"], r["dofs"], r["nnz"], r["how"], r["threads"],
          r.get("skipped") or g(r, "factorise_s", ".3g"), g(r, "solve_s", ".3g"), g(r, "fill", ".3g"),
          "–" if not r.get("fill") else f"{r['fill'] / r['dofs']:.0f}", g(r, "peak_mib", ".0f"),
          g(r, "relres", ".1e"), g(r, "gmres_its", "d"), f"{r['load']:.1f}"] for r in sysrows])
    if runrows:
        lines += ["", f"## Runs ({RUN_STEPS} steps)", ""]
        lines += table(
            ["bodies", "DOFs", "lu_backend", "solver", "s/step (median)", "first step s", "solve share", "LUs",
             "peak MiB", "load", "stopped"],
            [[r["bodies"], r.get("dofs", "–"), r["backend"], r["solver"], g(r, "s_per_step", ".3g"),
              g(r, "first_step_s", ".3g"), g(r, "solve_share", ".0%"),
              r.get("lus") if r.get("lus") is not None else "–",
              g(r, "peak_mib", ".0f"), f"{r['load']:.1f}", r.get("error") or ""] for r in runrows])
    (RESULTS / "solver_scale.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
