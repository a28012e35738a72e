"""Writing benchmark results: the machine line and the JSON rows shared by the benchmark suites."""

from __future__ import annotations

import json
import os
import pathlib
import platform
import time

RESULTS = pathlib.Path(__file__).parent / "results"


def machine_description() -> str:
    """Architecture, cores, Python version and the load average at the time of writing."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"load average {load:.1f} when written")


def write_json(name: str, machine: str, rows: list) -> None:
    """``benchmarks/results/{name}.json`` with the machine line and the result rows."""
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps({"machine": machine, "rows": rows}, indent=1,
                                                     default=lambda o: o.item()))


def markdown_table(header, rows) -> list:
    """Lines of a Markdown table: ``header`` (column titles) and ``rows`` (lists of cell strings)."""
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]


def write_results(name: str, rows: list, title: str, intro: str, header, cells, notes=()) -> str:
    """``results/{name}.json`` (``rows`` and the machine line) and ``results/{name}.md``: ``# title``,
    ``Machine: ...`` followed by ``intro``, the table of ``header`` and ``cells``, then the ``notes``
    lines; returns the machine line."""
    machine = machine_description()
    write_json(name, machine, rows)
    lines = [f"# {title}", "", f"Machine: {machine}. {intro}", "", *markdown_table(header, cells), *notes]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    return machine


def step_recorder(sim, extra=None):
    """``(rows, progress)``: a ``progress`` callback for ``sim.run`` that appends one row per step
    to ``rows``: the step, t, its wall-clock seconds, whether the moving mesh was re-triangulated
    and why, and what ``extra(sim, cost)`` (a dict) adds."""
    rows = []
    last = [time.perf_counter()]

    def progress(step, n, t, cost):
        now = time.perf_counter()
        ev = sim.flow.last_event
        row = {"step": int(step), "t": float(t), "seconds": now - last[0],
               "retriangulated": bool(ev is not None and ev.retriangulated),
               "reason": ev.reason if ev is not None and ev.retriangulated else ""}
        if extra is not None:
            row.update(extra(sim, cost))
        rows.append(row)
        last[0] = time.perf_counter()

    return rows, progress


def run_or_report(name: str, run, report) -> None:
    """A benchmark's entry point: ``--report`` rebuilds the tables from ``results/{name}.json``
    (``report(rows, machine)``), otherwise ``run()`` gives the rows, which are stored and reported."""
    import sys

    if sys.argv[1:] == ["--report"]:  # the tables again from the stored rows
        stored = json.loads((RESULTS / f"{name}.json").read_text())
        report(stored["rows"], stored["machine"])
    else:
        rows = run()
        machine = machine_description()
        write_json(name, machine, rows)
        report(rows, machine)


def rows_by_bodies(doc: str, measure, default: str = "100,300") -> list:
    """Parse ``--bodies`` (comma-separated body counts, ``default``; ``doc``: the benchmark's
    docstring) and return ``measure(n)`` for each count, printing each row as it comes."""
    import argparse

    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--bodies", default=default)
    args = ap.parse_args()
    rows = []
    for n in (int(s) for s in args.bodies.split(",")):
        rows.append(measure(n))
        print(rows[-1], flush=True)
    return rows
