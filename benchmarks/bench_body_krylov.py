"""Cost of the coupled fluid–body solve: block-preconditioned GMRES against the lagged LU.

A disk settling from rest (:func:`fluidem.cases.settling.settling_scene`: a = 0.1 with 64 sides,
channel [−0.5, 0.5] × [0, 1.5], released at height 0.6, ρ_s/ρ_f = 1.5, ν = 0.01, g = 1,
Navier–Stokes, the default element P2+bubble/P1dc, dt = 0.01), N = 15 steps, at three mesh
sizes h at the disk (the mesh graded to 8 h away from it) giving about 10k, 40k and 150k DOFs.
The coupled system of each step is solved with

* ``fluid.solver = "lagged"``: GMRES preconditioned by the LU of an earlier coupled matrix
  (refactorised when it needs more than 25 iterations), and
* ``fluid.solver = "iterative"``: :class:`fluidem.coupling.body_krylov.BodyBlockKrylovSolver`
  (GMRES, AMG on the velocity block holding the body rows, Cahouet–Chabard Schur).

Both simulations live in the same process and are advanced alternately, one step each (the one
that goes first alternates from step to step), so a change of the machine's load hits both.
Recorded per step: the seconds of the coupled solve (``flow.last_cost.solve``, factorisation or
AMG setup included), the solver's GMRES iterations and the body velocity (u, v, ω).  Reported:
medians over steps 3..N (the first steps hold the factorisations), the first step's solve
seconds (setup), the ratio iterative/lagged of the medians, seconds per 1k DOFs, the iteration
counts, the means over steps 3..N (which, unlike the medians, carry the LUs the lagged solver
recomputes after a re-triangulation of the moving mesh), and the largest difference of the body
velocities between the two solvers, written to
``benchmarks/results/body_krylov.{md,json}``.

Run (about 10 minutes on one core)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_body_krylov.py

``FLUIDEM_BENCH_QUICK=1`` runs the smallest mesh for 5 steps only.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.settling import settling_scene  # noqa: E402
from fluidem.scene import Scene  # noqa: E402
from fluidem.simulation import Simulation  # noqa: E402

SOLVERS = ("lagged", "iterative")
#: mesh size at the disk for about 10k, 40k and 150k DOFs (measured: 10 695, 41 138, 147 700)
SIZES = {"10k": 0.02, "40k": 0.0058, "150k": 0.0026}
STEPS = 15
FIRST_MEDIAN_STEP = 3  # medians over steps 3..N
DT = 0.01
if os.environ.get("FLUIDEM_BENCH_QUICK"):
    SIZES, STEPS = {"10k": 0.02}, 5


def scene(h: float, solver: str, steps: int = STEPS) -> Scene:
    """The settling disk at mesh size ``h`` with the coupled solver ``solver``."""
    sc = settling_scene(a=0.1, half_width=0.5, height=1.5, start=0.6, density=1.5, nu=0.01, g=1.0, h=h,
                        segments=64, dt=DT, t_end=steps * DT)
    d = sc.to_dict()
    d["fluid"]["solver"] = solver
    return Scene.from_dict(d)


def _iterations(sim: Simulation) -> int:
    info = getattr(sim.flow.coupled.solver, "last_info", None)
    return -1 if info is None else int(info.iterations)


def run_pair(h: float, steps: int = STEPS) -> dict:
    """Both solvers on the mesh of size ``h``, advanced alternately one step at a time."""
    sims = {s: Simulation(scene(h, s, steps)) for s in SOLVERS}
    rec = {s: {"solve_s": [], "step_s": [], "iterations": [], "factorizations": [], "V": []} for s in SOLVERS}
    for k in range(1, steps + 1):
        order = SOLVERS if k % 2 else SOLVERS[::-1]
        for s in order:
            sim, r = sims[s], rec[s]
            t0 = time.perf_counter()
            sim.run(out_dir=None, n_steps=k)
            r["step_s"].append(time.perf_counter() - t0)
            r["solve_s"].append(float(sim.flow.last_cost.solve))
            r["iterations"].append(_iterations(sim))
            r["factorizations"].append(int(getattr(sim.flow.coupled.solver, "factorizations", -1)))
            r["V"].append(np.array(sim.flow.body_velocities[0], float).tolist())
    dofs = {s: int(sims[s].flow.dofs) for s in SOLVERS}
    out = {"h": h, "dofs": dofs["iterative"], "steps": steps,
           "coupled_solver": {s: type(sims[s].flow.coupled.solver).__name__ for s in SOLVERS},
           "triangulations": {s: int(sims[s].counters["triangulations"]) for s in SOLVERS}}
    if dofs["lagged"] != dofs["iterative"]:
        out["dofs_lagged"] = dofs["lagged"]
    m0 = FIRST_MEDIAN_STEP - 1
    for s in SOLVERS:
        r = rec[s]
        solve, its = np.array(r["solve_s"]), np.array(r["iterations"])
        med = float(np.median(solve[m0:]))
        out[s] = {**r, "median_solve_s": med, "mean_solve_s": float(solve[m0:].mean()),
                  "median_step_s": float(np.median(r["step_s"][m0:])), "first_solve_s": float(solve[0]),
                  "first_step_s": float(r["step_s"][0]), "s_per_1k_dofs": med / (dofs[s] / 1000.0),
                  "iterations_min": int(its[m0:].min()), "iterations_median": float(np.median(its[m0:])),
                  "iterations_max": int(its[m0:].max()), "first_iterations": int(its[0])}
    out["ratio_median_solve"] = out["iterative"]["median_solve_s"] / out["lagged"]["median_solve_s"]
    V_lu, V_it = np.array(rec["lagged"]["V"]), np.array(rec["iterative"]["V"])
    dV = np.abs(V_it - V_lu).max(axis=1)
    out["dV_max"] = float(dV.max())
    out["dV_rel_to_max_V"] = float(dV.max() / np.abs(V_lu).max())  # largest difference / largest velocity
    out["dV_rel_per_step"] = float((dV / np.abs(V_lu).max(axis=1)).max())  # largest step-wise relative
    return out


def measure() -> list:
    rows = []
    for label, h in SIZES.items():
        t0 = time.perf_counter()
        r = run_pair(h)
        r["label"], r["wall_s"] = label, time.perf_counter() - t0
        print(f"{label}: {r['dofs']} DOFs, lagged {r['lagged']['median_solve_s']:.3f} s, iterative "
              f"{r['iterative']['median_solve_s']:.3f} s, ratio {r['ratio_median_solve']:.2f}, "
              f"wall {r['wall_s']:.0f} s", flush=True)
        rows.append(r)
    return rows


def write(rows: list, wall_s: float) -> None:
    machine = machine_description()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    write_json("body_krylov", machine, rows)
    n = rows[0]["steps"]
    lines = ["# Coupled fluid–body solve: block-preconditioned GMRES against the lagged LU", "",
             f"Machine: {machine}; load average (1, 5, 15 min) {load} at the end of the run; "
             f"one BLAS thread; total wall time {wall_s:.0f} s.", "",
             "Disk a = 0.1 (64 sides) settling from rest in [−0.5, 0.5] × [0, 1.5] from height 0.6, ρ_s/ρ_f = 1.5, "
             f"NS ν = 0.01, g = 1, P2+bubble/P1dc, dt = {DT}, {n} steps, mesh graded from h at the disk to 8 h "
             "(`benchmarks/bench_body_krylov.py`).  Both solvers in one process, advanced alternately one step "
             f"each.  Solve seconds = `flow.last_cost.solve` (factorisation / AMG setup included); medians over "
             f"steps {FIRST_MEDIAN_STEP}..{n}; first = step 1 (LU or AMG hierarchy built).  Iterations: GMRES "
             f"iterations of the coupled solve, min/median/max over steps {FIRST_MEDIAN_STEP}..{n} (lagged: "
             "GMRES with the lagged LU to rtol 1e-6; iterative: block-preconditioned GMRES to rtol 1e-10).  "
             "Means over the same steps include the steps where the lagged solver recomputes its LU (after a "
             "re-triangulation of the moving mesh; `meshes` counts the triangulations of the run, the first "
             "included; `LUs` the lagged solver's factorisations).  ΔV: largest |V_iterative − V_lagged| over "
             "the steps and (u, v, ω), relative to the largest lagged velocity component.", "",
             "| DOFs | h | lagged median s/step | iterative median s/step | ratio it/lagged | lagged s/1k DOFs | "
             "iterative s/1k DOFs | lagged its min/med/max | iterative its min/med/max | lagged first s | "
             "iterative first s | lagged mean s/step | iterative mean s/step | meshes | lagged LUs | "
             "max ΔV / max V |", "|---" * 16 + "|"]
    for r in rows:
        lu, it = r["lagged"], r["iterative"]

        def its(x):
            return f"{x['iterations_min']}/{x['iterations_median']:g}/{x['iterations_max']}"

        lines.append(f"| {r['dofs']} | {r['h']:g} | {lu['median_solve_s']:.3f} | {it['median_solve_s']:.3f} | "
                     f"{r['ratio_median_solve']:.2f} | {lu['s_per_1k_dofs']:.4f} | {it['s_per_1k_dofs']:.4f} | "
                     f"{its(lu)} | {its(it)} | {lu['first_solve_s']:.2f} | {it['first_solve_s']:.2f} | "
                     f"{lu['mean_solve_s']:.3f} | {it['mean_solve_s']:.3f} | {r['triangulations']['lagged']} | "
                     f"{lu['factorizations'][-1]} | {r['dV_rel_to_max_V']:.1e} |")
    (RESULTS / "body_krylov.md").write_text("\n".join(lines) + "\n")


def main() -> None:
    t0 = time.perf_counter()
    rows = measure()
    write(rows, time.perf_counter() - t0)
    print((RESULTS / "body_krylov.md").read_text())


if __name__ == "__main__":
    main()
