"""Time-step convergence of the ALE BDF2 step on a moving mesh (:mod:`fluidem.cases.ale_convergence`).

The Taylor–Green vortex (ν = 0.05, t_end = 1) on the unit square, 16 × 16 Taylor–Hood
elements, interior nodes moving by a · sin(πX) sin(πY) sin(2πt) (a = 0.08), exact velocity
on the whole boundary.  For dt = 0.1 … 0.0125: the relative L2 velocity error and the
relative error of the force on the bottom wall at t_end, against a run at dt = 0.003125 on the
same meshes, with the observed rates, for the BDF2 mesh velocity (3x^{n+1} − 4x^n + x^{n−1})/(2dt)
and the former BDF1 one (x^{n+1} − x^n)/dt.  Written to
``benchmarks/results/ale_convergence.{md,json}``.

Run (about a minute)::

    OPENBLAS_NUM_THREADS=1 python -m pytest benchmarks/bench_ale_convergence.py -p no:cacheprovider -q
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

from results_io import RESULTS, machine_description, write_json  # noqa: E402

from fluidem.cases.ale_convergence import convergence  # noqa: E402

N, DTS, DT_REF = 16, (0.1, 0.05, 0.025, 0.0125), 0.003125


def _fmt(v, spec):
    return "–" if v is None else format(v, spec)


def write(rows, seconds):
    machine = machine_description()
    write_json("ale_convergence", machine, rows)
    lines = ["| mesh velocity | dt | velocity error | rate | force error | rate | velocity error vs exact |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        name = "BDF2 (new)" if r["order"] == 2 else "BDF1 (former)"
        lines.append(f"| {name} | {r['dt']:g} | {r['velocity_error']:.3e} | {_fmt(r['velocity_rate'], '.2f')} | "
                     f"{r['force_error']:.3e} | {_fmt(r['force_rate'], '.2f')} | {r['exact_error']:.3e} |")
    (RESULTS / "ale_convergence.md").write_text(
        f"Machine: {machine}; {seconds:.0f} s.\n\n"
        f"Taylor–Green vortex (ν = 0.05, t = 1) on a moving {N} × {N} Taylor–Hood mesh, errors relative to a "
        f"dt = {DT_REF:g} run on the same meshes (velocity: L2; force: bottom wall); the last column against "
        "the exact solution (its floor is the spatial error).\n\n" + "\n".join(lines) + "\n")


def test_ale_convergence():
    t0 = time.perf_counter()
    rows = convergence(N, dts=DTS, dt_ref=DT_REF)
    write(rows, time.perf_counter() - t0)
    new = [r for r in rows if r["order"] == 2]
    assert all(r["velocity_rate"] > 1.8 for r in new[1:])


if __name__ == "__main__":
    test_ale_convergence()
    print((RESULTS / "ale_convergence.md").read_text())
