"""NGSolve as the peer on the DFG cylinder benchmarks: the same cases, NGSolve's usual schemes.

The peer runs in its own environment (``benchmarks/.venv-ngsolve``, ``pip install ngsolve`` from
PyPI), one configuration per subprocess with one thread, through ``benchmarks/peer/ngsolve_dfg.py``
(which documents the schemes: Newton for 2D-1; BDF2 with extrapolated explicit convection and one
``sparsecholesky`` factorisation for 2D-2 and 2D-3; forces by the volume integral).  The series it
returns are measured here with fluidem's own :func:`~fluidem.fluid.forces.periodic_stats`, so both
codes' St, c_D,max, c_L,max come from the same post-processing.

Use from another benchmark::

    from peer_ngsolve import PEER_CONFIGS, ensure_ngsolve, run_ngsolve
    peer = ensure_ngsolve()
    if peer.python is None:
        pytest.skip(f"NGSolve peer not available: {peer.reason}")
    row = run_ngsolve("dfg-2d2", element="p3", maxh=0.07, maxh_cyl=0.02, dt=1 / 1200, python=peer.python)

Run by hand (one JSON line per configuration)::

    python benchmarks/peer_ngsolve.py --case dfg-2d2 --quick
    python benchmarks/peer_ngsolve.py --case dfg-2d2 --case dfg-2d1 --write   # the front, to results/

``--write`` stores the rows in ``benchmarks/results/peer_ngsolve.{json,md}`` with the date, the machine,
the NGSolve version and the load average at the start and end of every run.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time
from typing import NamedTuple

import numpy as np

from fluidem.cases.dfg import REFERENCE
from fluidem.fluid.forces import periodic_stats

HERE = pathlib.Path(__file__).resolve().parent
NGSOLVE_VENV = HERE / ".venv-ngsolve"
SCRIPT = HERE / "peer" / "ngsolve_dfg.py"
RESULTS = HERE / "results"
ELEMENTS = {"p2": 2, "p3": 3}            # velocity order of Taylor–Hood P_k/P_{k-1}
CASES = ("dfg-2d1", "dfg-2d2", "dfg-2d3")
THREADS_ONE = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

# Configurations that trace each case's accuracy–time front (maxh, maxh_cyl in m, dt in s).
# 2D-1: uniform meshes (maxh 0.04/0.02/0.01) and meshes refined at the cylinder, down to coarse
# far fields (maxh 0.05-0.08) where the cheapest c_D within 1e-4 lies.
# 2D-2/2D-3: P3/P2 refined at the cylinder; dt near the explicit convection's stability limit
# (diverged: maxh_cyl 0.02 at dt 1/800, maxh_cyl 0.012 at 1/1200, P2 maxh_cyl 0.006 at 1/1200).
PEER_CONFIGS = [
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.04, "maxh_cyl": 0.005},
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.02},
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.01},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.04},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.04, "maxh_cyl": 0.01},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.02, "maxh_cyl": 0.004},
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.06, "maxh_cyl": 0.005},
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.05, "maxh_cyl": 0.0075},
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.05, "maxh_cyl": 0.005},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.08, "maxh_cyl": 0.02},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.08, "maxh_cyl": 0.01},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.06, "maxh_cyl": 0.015},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.06, "maxh_cyl": 0.01},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.07, "maxh_cyl": 0.02, "dt": 1 / 1200},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.07, "maxh_cyl": 0.01, "dt": 1 / 1600},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.05, "maxh_cyl": 0.01, "dt": 1 / 1600},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.035, "maxh_cyl": 0.02, "dt": 1 / 1200},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.045, "maxh_cyl": 0.015, "dt": 1 / 1400},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.035, "maxh_cyl": 0.01, "dt": 1 / 1600},
    {"case": "dfg-2d3", "element": "p3", "maxh": 0.07, "maxh_cyl": 0.02, "dt": 1 / 1200},
    {"case": "dfg-2d3", "element": "p3", "maxh": 0.05, "maxh_cyl": 0.01, "dt": 1 / 1600},
    {"case": "dfg-2d3", "element": "p3", "maxh": 0.045, "maxh_cyl": 0.015, "dt": 1 / 1400},
    {"case": "dfg-2d3", "element": "p3", "maxh": 0.035, "maxh_cyl": 0.01, "dt": 1 / 1600},
]
# One or two cheap points per case (seconds each) for a smoke run.
QUICK_CONFIGS = [
    {"case": "dfg-2d1", "element": "p2", "maxh": 0.04},
    {"case": "dfg-2d1", "element": "p3", "maxh": 0.04, "maxh_cyl": 0.01},
    {"case": "dfg-2d2", "element": "p3", "maxh": 0.07, "maxh_cyl": 0.02, "dt": 1 / 1200},
    {"case": "dfg-2d3", "element": "p3", "maxh": 0.07, "maxh_cyl": 0.02, "dt": 1 / 1200},
]


class Peer(NamedTuple):
    """The peer's interpreter: ``python`` (None when unavailable), NGSolve ``version``, ``reason`` if not."""

    python: pathlib.Path | None
    version: str | None
    reason: str | None


def _venv_python(venv_dir: pathlib.Path) -> pathlib.Path:
    return venv_dir / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def _one_line(text: str) -> str:
    lines = [ln.strip() for ln in (text or "").strip().splitlines() if ln.strip()]
    return lines[-1][:200] if lines else "no output"


def ensure_ngsolve(venv_dir: str | os.PathLike = NGSOLVE_VENV, install: bool = True, timeout: float = 900) -> Peer:
    """A Python environment with NGSolve: ``venv_dir``, created and ``pip install ngsolve`` run if missing.

    Parameters
    ----------
    venv_dir : path
        Where the virtual environment lives (default ``benchmarks/.venv-ngsolve``, ignored by git).
    install : bool
        Create the environment and install NGSolve when it is missing; otherwise only look.
    timeout : float
        Seconds allowed for the install.

    Returns
    -------
    Peer
        ``python`` is the environment's interpreter, or None with a one-line ``reason``
        (no network, no wheel for this platform, the import fails) for the caller's skip message.
    """
    venv_dir = pathlib.Path(venv_dir)
    py = _venv_python(venv_dir)

    def probe():
        try:
            out = subprocess.run([str(py), "-c", "import ngsolve; print(ngsolve.__version__)"], capture_output=True,
                                 text=True, timeout=120, env={**os.environ, **THREADS_ONE})
        except (OSError, subprocess.TimeoutExpired) as exc:
            return None, f"import ngsolve failed: {exc}"
        if out.returncode:
            return None, f"import ngsolve failed: {_one_line(out.stderr)}"
        return out.stdout.strip(), None

    if py.exists():
        version, reason = probe()
        if version or not install:
            return Peer(py if version else None, version, reason)
    elif not install:
        return Peer(None, None, f"no NGSolve environment at {venv_dir}")
    try:
        if not py.exists():
            subprocess.run([sys.executable, "-m", "venv", str(venv_dir)], check=True, capture_output=True, text=True,
                           timeout=300)
        out = subprocess.run([str(py), "-m", "pip", "install", "-q", "ngsolve"], capture_output=True, text=True,
                             timeout=timeout)
    except subprocess.CalledProcessError as exc:
        return Peer(None, None, f"creating the venv failed: {_one_line(exc.stderr)}")
    except (OSError, subprocess.TimeoutExpired) as exc:
        return Peer(None, None, f"installing ngsolve failed: {exc}")
    if out.returncode:
        return Peer(None, None, f"pip install ngsolve failed (no network or no wheel?): {_one_line(out.stderr)}")
    version, reason = probe()
    return Peer(py if version else None, version, reason)


def _quantities(case: str, out: dict, window: float) -> dict:
    """The case's quantities from the peer's output (series measured as fluidem measures its own)."""
    if case == "dfg-2d1":
        return {k: out[k] for k in ("cd", "cl", "dp")}
    t, cd, cl = (np.asarray(out[k], dtype=float) for k in ("t", "cd", "cl"))
    if case == "dfg-2d2":
        t_end = t[-1]
        sd, sl = periodic_stats(t, cd, t_end - window), periodic_stats(t, cl, t_end - window)
        return {"st": 0.1 / sl.period, "cd_max": sd.max, "cd_min": sd.min, "cl_max": sl.max, "cl_min": sl.min}
    icd, icl = int(np.argmax(cd)), int(np.argmax(cl))
    return {"cd_max": float(cd[icd]), "cl_max": float(cl[icl]), "dp_end": out["dp_end"],
            "t_cd_max": float(t[icd]), "t_cl_max": float(t[icl])}


def run_ngsolve(case: str, element: str = "p3", maxh: float = 0.04, maxh_cyl: float | None = None,
                dt: float | None = None, t_end: float | None = None, window: float = 2.0,
                python: str | os.PathLike | None = None, timeout: float = 900) -> dict:
    """Run one DFG configuration in NGSolve (a subprocess, one thread) and measure it.

    Parameters
    ----------
    case : {"dfg-2d1", "dfg-2d2", "dfg-2d3"}
    element : {"p2", "p3"}
        Taylor–Hood P2/P1 or P3/P2; the mesh is curved to the velocity order.
    maxh, maxh_cyl : float
        Netgen's global cell size and the size on the cylinder (default ``maxh``), m.
    dt : float
        Time step, s (2D-2, 2D-3 only; required there).
    t_end : float, optional
        End time, s (default 6 for 2D-2, 8 for 2D-3).
    window : float
        2D-2: quantities measured on ``[t_end − window, t_end]``, s.
    python : path, optional
        The peer's interpreter (default: :func:`ensure_ngsolve`'s, installing if needed).
    timeout : float
        Seconds before the run is abandoned.

    Returns
    -------
    dict
        ``case``, ``element``, ``maxh``, ``maxh_cyl``, ``dofs``, ``dt``, ``steps``, ``wall_s`` (inside the
        script: mesh + assembly + solve, perf_counter), ``cpu_s`` (the same by process_time: what a loaded
        machine does not inflate), ``subprocess_s`` (the whole subprocess, with
        the NGSolve import), ``timings`` (the parts), ``ms_per_step``, ``quantities``, ``errors``
        (relative, against :data:`fluidem.cases.dfg.REFERENCE`), ``load_start``/``load_end`` (1-minute
        load average) and ``ngsolve_version``; ``diverged_at`` (s) when the run blew up (no quantities then).
    """
    if case not in CASES:
        raise ValueError(f"case = {case!r}: expected one of {', '.join(CASES)}")
    if element not in ELEMENTS:
        raise ValueError(f"element = {element!r}: expected one of {', '.join(ELEMENTS)}")
    if case != "dfg-2d1" and not (dt and dt > 0):
        raise ValueError(f"dt = {dt!r}: {case} needs a positive time step in seconds")
    if python is None:
        peer = ensure_ngsolve()
        if peer.python is None:
            raise RuntimeError(f"NGSolve peer not available: {peer.reason}")
        python = peer.python
    cfg = {"case": case, "order": ELEMENTS[element], "maxh": maxh, "maxh_cyl": maxh_cyl or maxh}
    if case != "dfg-2d1":
        cfg["dt"] = dt
        if t_end is not None:
            cfg["t_end"] = t_end
    with tempfile.TemporaryDirectory() as tmp:
        out_file = pathlib.Path(tmp) / "out.json"
        load_start = os.getloadavg()[0]
        t0 = time.perf_counter()
        proc = subprocess.run([str(python), str(SCRIPT), json.dumps(cfg), str(out_file)], capture_output=True,
                              text=True, timeout=timeout, env={**os.environ, **THREADS_ONE})
        subprocess_s = time.perf_counter() - t0
        load_end = os.getloadavg()[0]
        if proc.returncode:
            raise RuntimeError(f"NGSolve run {cfg} failed: {_one_line(proc.stderr)}")
        out = json.loads(out_file.read_text())
    row = {"case": case, "element": element, "maxh": maxh, "maxh_cyl": maxh_cyl or maxh, "dofs": out["dofs"],
           "dt": dt if case != "dfg-2d1" else None, "steps": out.get("steps"),
           "wall_s": out["wall_seconds"], "cpu_s": out.get("cpu_seconds"), "subprocess_s": subprocess_s,
           "timings": out["timings"],
           "ms_per_step": out.get("ms_per_step"), "load_start": load_start, "load_end": load_end,
           "ngsolve_version": out["ngsolve_version"], "diverged_at": out.get("diverged_at")}
    if case == "dfg-2d1":
        row["newton_iterations"] = out.get("newton_iterations")
    if row["diverged_at"] is None:
        q = _quantities(case, out, window)
        ref = REFERENCE[case]
        row["quantities"] = q
        row["errors"] = {k: q[k] / ref[k] - 1.0 for k in ref if k in q}
    return row


def write_results(rows: list, path: pathlib.Path = RESULTS / "peer_ngsolve.json", note: str = "") -> None:
    """Store ``rows`` with the date, the machine and the NGSolve version (merging with rows of other cases)."""
    old = json.loads(path.read_text()) if path.exists() else {}
    cases = {r["case"] for r in rows}
    kept = [r for r in old.get("rows", []) if r["case"] not in cases]
    doc = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
           "machine": f"{platform.machine()}, {os.cpu_count()} cores, one thread per run, nice 10",
           "ngsolve_version": rows[0]["ngsolve_version"] if rows else old.get("ngsolve_version"),
           "note": note or old.get("note", ""), "rows": kept + rows}
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(doc, indent=1) + "\n")
    path.with_suffix(".md").write_text(markdown_table(doc))


def markdown_table(doc: dict) -> str:
    """The rows of a results document as one Markdown table per case."""
    parts = [f"NGSolve {doc['ngsolve_version']} ({doc['date']}; {doc['machine']}). wall_s: mesh + assembly + "
             "solve inside the run (perf_counter); cpu_s: the same as process time; subprocess_s: the whole "
             "subprocess with the NGSolve import; "
             "load: 1-minute load average at the start and end of the run.", ""]
    if doc.get("note"):
        parts += [doc["note"], ""]
    for case in CASES:
        rows = [r for r in doc["rows"] if r["case"] == case]
        if not rows:
            continue
        names = list(REFERENCE[case])
        names = [k for k in names if any(k in r.get("errors", {}) for r in rows)]
        head = ["element", "maxh", "maxh_cyl", "dofs", "dt", "steps", "wall_s", "cpu_s", "subprocess_s", "ms/step",
                "load"]
        parts += [f"### {case}", "", "| " + " | ".join(head + [f"err_{k}" for k in names]) + " |",
                  "|" + "---|" * (len(head) + len(names))]
        for r in sorted(rows, key=lambda r: r["wall_s"]):
            dt = f"1/{1 / r['dt']:.0f}" if r["dt"] else "—"
            ms = f"{r['ms_per_step']:.2f}" if r.get("ms_per_step") else "—"
            errs = ([f"{r['errors'][k]:+.2e}" for k in names] if "errors" in r
                    else [f"diverged at t = {r['diverged_at']:.2f}"] + [""] * (len(names) - 1))
            cells = [r["element"], f"{r['maxh']:g}", f"{r['maxh_cyl']:g}", str(r["dofs"]), dt, str(r["steps"] or "—"),
                     f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}" if r.get("cpu_s") else "—",
                     f"{r['subprocess_s']:.2f}", ms,
                     f"{r['load_start']:.1f}–{r['load_end']:.1f}"] + errs
            parts.append("| " + " | ".join(cells) + " |")
        parts.append("")
    return "\n".join(parts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", choices=CASES, help="case to run (repeatable; default all)")
    ap.add_argument("--quick", action="store_true", help="only the cheap smoke points")
    ap.add_argument("--write", action="store_true", help="store the rows in benchmarks/results/peer_ngsolve.json")
    ap.add_argument("--note", default="", help="note stored with --write")
    args = ap.parse_args(argv)
    peer = ensure_ngsolve()
    if peer.python is None:
        print(json.dumps({"skipped": peer.reason}))
        return 0
    cases = args.case or list(CASES)
    configs = [c for c in (QUICK_CONFIGS if args.quick else PEER_CONFIGS) if c["case"] in cases]
    rows = []
    for c in configs:
        row = run_ngsolve(**c, python=peer.python)
        rows.append(row)
        print(json.dumps(row), flush=True)
    if args.write:
        write_results(rows, note=args.note)
    return 0


if __name__ == "__main__":
    sys.exit(main())
