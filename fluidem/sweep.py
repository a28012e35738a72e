"""Parameter sweeps: every combination of some scene values, each run as a task on dask.distributed.

:func:`sweep` takes a scene and ``vary = {"mesh.h": [0.04, 0.02], "fluid.element": ["th", "p3"]}``
(dotted scene keys, as in the scene reference; ``bodies.0.radius`` for a body), builds and
validates every variant first (a bad key or value gives the scene's own one-line error before
anything runs), and runs each variant as one task: one :class:`fluidem.Simulation` in one
worker process with one BLAS thread.  A single simulation never spans processes.

* Engine: a ``distributed.LocalCluster`` with one single-threaded worker process per core (or
  ``workers``) by default, or the scheduler at ``scheduler`` (an address such as
  ``tcp://10.0.0.5:8786``, or a ``distributed.Client``); the workers must share the output
  directory's file system and have fluidem installed.  Needs the ``sweep`` extra:
  ``pip install "fluidem[sweep]"``.
* Output: ``DIR/<variant>/`` is each variant's own run directory (``run.json``, history,
  fields, ...); ``DIR/sweep.csv`` and ``DIR/sweep.json`` the table of every variant's values,
  status, wall time (build and run, in the worker) and the summary quantities its ``run.json``
  records (:meth:`fluidem.Simulation.summary`: steps, DOFs, triangles, final pose, velocity and
  load of each body); ``DIR/sweep.png`` one quantity against the varied parameter and against wall time.
* Resume: a variant whose directory holds a ``run.json`` with status ``complete`` for the same
  scene (or ``stopped`` at the sweep's ``n_steps``) is not run again (its row is read back); any
  other variant is run from scratch.  A directory that holds another scene's sweep (or a
  variant run for a different scene, or a run) is refused unless ``overwrite``, which runs
  every variant again.
* Variant directory names are at most :data:`MAX_NAME_BYTES` bytes (a file system's limit per
  path component); a longer one is refused before anything runs.
* Progress: one line per finished variant on stderr.

Example (a sketch; runs on a LocalCluster of two workers)::

    from fluidem.sweep import sweep
    table = sweep("dfg.toml", {"mesh.h": [0.04, 0.02], "fluid.element": ["th", "p3"]},
                  out_dir="sweep-dfg", workers=2, quantity="cylinder.fx")
"""

from __future__ import annotations

import csv
import itertools
import json
import logging
import os
import re
import sys
import time
from pathlib import Path

from .errors import InputError, install_hint
from .validate import fail

__all__ = ["sweep", "variants", "parse_vary", "set_key", "SweepResult", "require_dask", "THREAD_ENV",
           "MAX_NAME_BYTES"]

#: environment of every worker process: one BLAS/OpenMP thread (the parallelism is one variant per process)
THREAD_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

#: longest variant directory name, bytes (UTF-8): the limit of common file systems per path component
MAX_NAME_BYTES = 255

#: body columns in sweep.csv for at most this many bodies (sweep.json has them all)
CSV_BODIES = 4

_BODY_QUANTITIES = ("x", "y", "angle", "vx", "vy", "omega", "fx", "fy", "torque")


def require_dask(what: str = "a parameter sweep") -> None:
    """Raise :class:`fluidem.errors.InputError` naming the ``sweep`` extra if dask.distributed is missing."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise InputError(f'{what} needs dask.distributed: {install_hint("sweep")}') from None


# -- variants -------------------------------------------------------------------------------------
def _split_values(text: str) -> list[str]:
    """Split ``"a,b,[1, 2]"`` at the commas outside brackets, braces and quotes."""
    out, depth, quote, cur = [], 0, None, ""
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append(cur)
            cur = ""
            continue
        cur += ch
    out.append(cur)
    return [v.strip() for v in out]


def _value(text: str):
    """A command-line value as TOML reads it (``0.02``, ``true``, ``[1, 2]``, ``"x"``), else the plain string."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except Exception:  # not a TOML value: a bare word such as th
        return text


def parse_vary(items: list[str]) -> dict[str, list]:
    """``["mesh.h=0.04,0.02", "fluid.element=th,p3"]`` -> ``{"mesh.h": [0.04, 0.02], "fluid.element": ["th", "p3"]}``.

    Each value is read as a TOML value (numbers, booleans, arrays, quoted strings), a bare word
    as a string.  Raises :class:`fluidem.errors.InputError` for an item without ``=`` or values.

    Examples
    --------
    >>> parse_vary(["mesh.h=0.04,0.02", "fluid.element=th,p3", "domain.box=[0, 1, 0, 1]"])
    {'mesh.h': [0.04, 0.02], 'fluid.element': ['th', 'p3'], 'domain.box': [[0, 1, 0, 1]]}
    """
    vary: dict[str, list] = {}
    for item in items:
        key, eq, vals = item.partition("=")
        key = key.strip()
        if not eq or not key or not vals.strip():
            raise fail("--vary", item, "KEY=V1,V2,... with a dotted scene key, e.g. mesh.h=0.04,0.02")
        if key in vary:
            raise fail("--vary", item, f"each key once ({key} is given twice)")
        vary[key] = [_value(v) for v in _split_values(vals)]
    return vary


def set_key(data: dict, key: str, value) -> None:
    """Set the dotted scene key ``key`` (``mesh.h``, ``bodies.0.radius``) in the nested scene dict ``data``.

    A missing table is created (the scene's validation then names a key it does not know); a
    body index out of range raises :class:`fluidem.errors.InputError`.

    Examples
    --------
    >>> d = {"mesh": {"h": 0.1}, "bodies": [{"radius": 0.05}]}
    >>> set_key(d, "mesh.h", 0.02); set_key(d, "bodies.0.radius", 0.1); d
    {'mesh': {'h': 0.02}, 'bodies': [{'radius': 0.1}]}
    """
    parts = key.split(".")
    node = data
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            k = _index(node, part, ".".join(parts[:i + 1]))
            node = node[k]
            continue
        if part not in node or not isinstance(node[part], (dict, list)):
            node[part] = {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        node[_index(node, last, key)] = value
    else:
        node[last] = value


def _index(lst: list, part: str, where: str) -> int:
    if not part.isdigit() or int(part) >= len(lst):
        raise fail("sweep key", where, f"a list index 0 to {len(lst) - 1} (the scene has {len(lst)})")
    return int(part)


def _slug(values: dict) -> str:
    """The directory name of a variant: ``mesh.h=0.04,fluid.element=th`` (unsafe characters as ``_``)."""
    text = ",".join(f"{k}={_text(v)}" for k, v in values.items())
    return re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)


def _text(v) -> str:
    return repr(v) if isinstance(v, float) and not float(v).is_integer() else str(v).lower() \
        if isinstance(v, bool) else str(v)


def variants(scene, vary: dict[str, list]) -> list[tuple[dict, object]]:
    """Every combination of the values of ``vary`` (the first key varying slowest) as
    ``(values, scene)`` pairs, each scene validated.

    Parameters
    ----------
    scene : Scene, str or Path
        The base scene (or its TOML file).
    vary : dict
        Dotted scene key -> list of values.

    Raises
    ------
    fluidem.errors.SceneError
        The scene's own error for a bad key or value, prefixed with the variant.
    """
    from .scene import Scene
    from .errors import SceneError

    base = scene if isinstance(scene, Scene) else Scene.from_toml(scene)
    if not isinstance(vary, dict) or not vary or not all(isinstance(v, (list, tuple)) and v for v in vary.values()):
        raise fail("vary", vary, "a dict of dotted scene keys to non-empty lists of values")
    base_dir = Path(base.source).parent if base.source else Path(".")
    keys = list(vary)
    out = []
    for combo in itertools.product(*(vary[k] for k in keys)):
        values = dict(zip(keys, combo))
        data = base.to_dict()
        for k, v in values.items():
            set_key(data, k, v)
        try:
            sc = Scene.from_dict(data, base_dir=base_dir)
        except SceneError as exc:
            raise SceneError(f"sweep variant {_slug(values)}: {exc}") from None
        sc.source = base.source
        out.append((values, sc))
    return out


# -- one variant (runs in a worker) --------------------------------------------------------------------
def _run_variant(scene_dict: dict, base_dir: str, out_dir: str, values: dict, n_steps=None) -> dict:
    """Build and run one variant in ``out_dir``; returns its row (status, wall time, summary)."""
    for k, v in THREAD_ENV.items():
        os.environ.setdefault(k, v)
    from .scene import Scene
    from .simulation import Simulation

    t0 = time.perf_counter()
    row = {"status": "failed", "message": ""}
    try:
        sc = Scene.from_dict(scene_dict, base_dir=base_dir)
        sim = Simulation(sc)
        sim.run(out_dir=out_dir, overwrite=True, n_steps=n_steps)
        row["status"] = "complete"
    except Exception as exc:  # a failed variant is a row of the table, not the end of the sweep
        row["message"] = " ".join(f"{type(exc).__name__}: {exc}".splitlines())
    row["wall_s"] = time.perf_counter() - t0
    try:
        import distributed

        row["worker"] = distributed.get_worker().address
    except (ImportError, ValueError):
        row["worker"] = ""
    from .io import read_run_record

    rec = read_run_record(out_dir)
    row["summary"] = rec.get("summary", {})
    row["run_status"] = rec.get("status", "")
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    (Path(out_dir) / "variant.json").write_text(json.dumps({"values": values, **row}, indent=1) + "\n")
    return row


def _warm_up() -> None:
    """Import what a variant needs (in each worker, before the first variant's clock starts)."""
    for k, v in THREAD_ENV.items():
        os.environ.setdefault(k, v)
    from . import simulation  # noqa: F401
    from .coupling import fixed_flow, moving_flow  # noqa: F401


def _finished(out_dir: Path, sc, n_steps: int | None = None) -> dict | None:
    """The stored row of a variant already finished in ``out_dir`` for scene ``sc`` (status
    ``complete``, or ``stopped`` at ``n_steps`` when the sweep stops there), else None."""
    from .io import read_run_record
    from .simulation import scene_key

    rec = read_run_record(out_dir)
    done = rec.get("status") == "complete" or (n_steps is not None and rec.get("status") == "stopped"
                                               and rec.get("step") == n_steps)
    if not done or rec.get("scene_key") != scene_key(sc.to_dict()):
        return None
    try:
        stored = json.loads((out_dir / "variant.json").read_text())
    except (OSError, ValueError):
        stored = {}
    summary = rec.get("summary", {})
    return {"status": "complete", "message": "", "wall_s": stored.get("wall_s", summary.get("wall_s")),
            "worker": stored.get("worker", ""), "summary": summary, "run_status": "complete"}


def _check_names(names: list, vary: dict) -> None:
    """Distinct variant directory names of at most :data:`MAX_NAME_BYTES` bytes, else InputError."""
    if len(set(names)) < len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise fail("vary", vary, f"values that give distinct directory names ({dup!r} twice: values differing "
                   "only in characters other than letters, digits and ._=,+-)")
    long = next((n for n in names if len(n.encode()) > MAX_NAME_BYTES), None)
    if long is not None:
        raise fail("sweep variant", long, f"a directory name of at most {MAX_NAME_BYTES} bytes, the file system's "
                   f"limit per path component (this one has {len(long.encode())}): vary fewer keys or give shorter "
                   "values (long values such as arrays belong in the scene file)")


def _foreign(out: Path, scene_name: str, todo: list, names: list) -> str | None:
    """What in the sweep directory ``out`` a sweep of ``scene_name`` would replace without being its
    own: a run's output, another scene's sweep, or a variant run for a different scene; None if nothing."""
    from .io import read_run_record
    from .simulation import scene_key

    if not out.is_dir():
        return None
    rec = read_run_record(out)
    if rec:
        return (f"the output of a run (scene {rec.get('scene')!r}, {rec.get('status', 'unknown')} at step "
                f"{rec.get('step')})")
    try:
        meta = json.loads((out / "sweep.json").read_text())["meta"]
    except (OSError, ValueError, KeyError, TypeError):
        meta = {}
    if isinstance(meta, dict) and meta.get("scene", scene_name) != scene_name:
        vary = meta.get("vary")
        over = f" over {', '.join(vary)}" if isinstance(vary, dict) else ""
        return f"the sweep of another scene ({meta.get('scene')!r}{over})"
    for name, (_, sc) in zip(names, todo):
        rec = read_run_record(out / name)
        if rec and rec.get("scene_key") != scene_key(sc.to_dict()):
            return (f"variant {name!r} run for a different scene (scene {rec.get('scene')!r} with other values, "
                    f"{rec.get('status', 'unknown')} at step {rec.get('step')})")
    return None


# -- the sweep ----------------------------------------------------------------------------------------
class SweepResult(list):
    """The sweep's table: one dict per variant (list order: the variants' order) with ``variant``
    (directory name), the varied keys, ``status``, ``wall_s``, ``resumed`` and the flattened
    summary (``steps``, ``dofs``, ``<body>.fx``, ...).  ``files`` lists what was written."""

    files: list


def _flat_row(name: str, values: dict, row: dict, resumed: bool, all_bodies: bool) -> dict:
    s = row.get("summary") or {}
    out = {"variant": name, **values, "status": row["status"], "wall_s": row.get("wall_s"), "resumed": resumed,
           "worker": row.get("worker", "")}
    for k in ("steps", "t", "dofs", "triangles", "element"):
        if k in s:
            out[k] = s[k]
    bodies = s.get("bodies", {})
    for b in (list(bodies) if all_bodies else list(bodies)[:CSV_BODIES]):
        for q in _BODY_QUANTITIES:
            out[f"{b}.{q}"] = bodies[b].get(q)
    if row.get("message"):
        out["message"] = row["message"]
    return out


def _client(scheduler, workers):
    """(client, cluster or None, description) for ``scheduler`` (None: a new LocalCluster)."""
    import distributed

    if isinstance(scheduler, distributed.Client):
        return scheduler, None, f"client {scheduler.scheduler.address}"
    if scheduler is not None:
        return distributed.Client(scheduler), None, f"scheduler {scheduler}"
    n = workers or os.cpu_count() or 1
    cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                       env=dict(THREAD_ENV), silence_logs=logging.ERROR)
    return distributed.Client(cluster), cluster, f"LocalCluster of {n} single-threaded worker processes"


def sweep(scene, vary: dict[str, list], out_dir="sweep", scheduler=None, workers: int | None = None,
          n_steps: int | None = None, quantity: str | None = None, reference: float | None = None,
          progress=True, plot: bool = True, overwrite: bool = False) -> SweepResult:
    """Run every combination of ``vary`` as one task on dask.distributed; write the table and a plot.

    Parameters
    ----------
    scene : Scene, str or Path
        The base scene (or its TOML file).
    vary : dict
        Dotted scene key -> list of values, e.g. ``{"mesh.h": [0.04, 0.02]}``
        (:func:`parse_vary` reads the command line's ``KEY=V1,V2``).
    out_dir : str or Path
        The sweep directory: one run directory per variant, ``sweep.csv``, ``sweep.json``,
        ``sweep.png``.
    scheduler : str, distributed.Client or None
        An existing scheduler's address or client; None starts a LocalCluster.
    workers : int, optional
        Worker processes of the LocalCluster (default: one per core).
    n_steps : int, optional
        Stop every variant after this many steps (default: the scene's ``t_end``).
    quantity : str, optional
        The plotted column (e.g. ``cylinder.fx``); default: the first body's ``fx``, else
        ``dofs``.
    reference : float, optional
        Plot the relative error ``|q - reference| / |reference|`` of ``quantity`` (log scale).
    progress : bool or file-like
        One line per finished variant (stderr, or the given stream).
    plot : bool
        Write ``sweep.png`` (needs matplotlib; skipped with a note without it).
    overwrite : bool
        Run every variant again, also in a directory that holds another scene's sweep (or a run),
        which is refused otherwise.

    Returns
    -------
    SweepResult
        The table (also in ``sweep.csv`` / ``sweep.json``).

    Raises
    ------
    fluidem.errors.InputError
        Before anything runs: a bad key or value (the scene's own error), a variant directory name
        longer than :data:`MAX_NAME_BYTES`, or (without ``overwrite``) ``out_dir`` holding another
        scene's sweep or a run.
    """
    from .io import OutputDirError

    require_dask()
    todo = variants(scene, vary)
    names = [_slug(v) for v, _ in todo]
    _check_names(names, vary)
    out = Path(out_dir)
    other = None if overwrite else _foreign(out, todo[0][1].name, todo, names)
    if other is not None:
        raise OutputDirError(f"sweep directory {str(out)!r} holds {other}; give --overwrite (overwrite=True) to run "
                             "every variant again over it, or another --out")
    out.mkdir(parents=True, exist_ok=True)
    stream = sys.stderr if progress is True else (progress or None)

    def say(msg):
        if stream is not None:
            print(f"sweep: {msg}", file=stream, flush=True)

    rows: dict[int, tuple[dict, bool]] = {}
    for i, (values, sc) in enumerate(todo):
        done = None if overwrite else _finished(out / names[i], sc, n_steps)
        if done is not None:
            rows[i] = (done, True)
    pending = [i for i in range(len(todo)) if i not in rows]
    load0 = _load()
    t0 = time.perf_counter()
    engine = "none (every variant finished before)"
    if pending:
        client, cluster, engine = _client(scheduler, workers)
        say(f"{len(todo)} variants, {len(rows)} finished before, {len(pending)} to run on {engine}")
        try:
            import distributed

            client.run(_warm_up)  # imports outside the variants' wall time
            futures = {}
            for i in pending:
                values, sc = todo[i]
                base_dir = str(Path(sc.source).parent) if sc.source else "."
                f = client.submit(_run_variant, sc.to_dict(), base_dir, str((out / names[i]).resolve()), values,
                                  n_steps, key=f"fluidem-{names[i]}-{time.time_ns()}", pure=False)
                futures[f] = i
            for k, f in enumerate(distributed.as_completed(futures), 1):
                i = futures[f]
                row = f.result()
                rows[i] = (row, False)
                say(f"{k}/{len(pending)} {names[i]}: {row['status']} in {row['wall_s']:.1f} s"
                    + (f" ({row['message']})" if row.get("message") else ""))
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    else:
        say(f"{len(todo)} variants, all finished before: nothing to run")
    wall = time.perf_counter() - t0
    table = SweepResult(_flat_row(names[i], todo[i][0], *rows[i], all_bodies=False) for i in range(len(todo)))
    full = [_flat_row(names[i], todo[i][0], *rows[i], all_bodies=True) for i in range(len(todo))]
    meta = {"scene": todo[0][1].name, "vary": vary, "engine": engine, "wall_s": wall, "cpu_count": os.cpu_count(),
            "load_before": load0, "load_after": _load(), "n_steps": n_steps,
            "note": "wall_s per variant: build and run in its worker process; load: 1/5/15-minute load averages"}
    files = [_write_csv(out / "sweep.csv", table),
             _write_json(out / "sweep.json", {"meta": meta, "variants": full})]
    if plot:
        try:
            files.append(plot_sweep(table, out / "sweep.png", list(vary), quantity, reference))
        except ImportError:
            say(f'no plot: it needs matplotlib: {install_hint("plot")}')
    table.files = files
    n_bad = sum(r["status"] != "complete" for r in table)
    say(f"done in {wall:.1f} s: {len(table) - n_bad} complete, {n_bad} failed; table {files[0]}")
    return table


def _load():
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):  # pragma: no cover - not on every system
        return None


def _write_csv(path: Path, table: list) -> Path:
    cols: list = []
    for r in table:
        cols += [k for k in r if k not in cols]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in table:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in cols})
    return path


def _write_json(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data, indent=1, default=str) + "\n")
    return path


def _column_unit(column: str) -> str:
    """The dimension of a sweep table column: a varied scene key's (``mesh.h`` -> ``length``), a body's history
    quantity (``disk.vy`` -> ``length/time``), or "" where none applies."""
    from .io import HISTORY_UNITS
    from .scene.reference import KEY_DOCS

    if column in KEY_DOCS:
        unit = KEY_DOCS[column][1]
        return "" if unit in ("—", "1") else unit
    if column == "wall_s":
        return "s"
    tail = column.rsplit(".", 1)[-1]
    return HISTORY_UNITS.get(tail, "") if "." in column and HISTORY_UNITS.get(tail) != "1" else ""


def _labelled(column: str) -> str:
    unit = _column_unit(column)
    return f"{column} [{unit}]" if unit else column


def plot_sweep(table: list, path, keys: list, quantity: str | None = None, reference: float | None = None) -> Path:
    """``quantity`` against the varied parameter (left) and against the wall time of its variant (right:
    what the accuracy costs), one line per combination of the varied keys but one, which varies along each
    line (the first key with numeric values, else the first key, its values then in their order); a
    relative error on a log scale with ``reference``.  Axes name the columns with their dimensions.

    Returns the PNG written.  Raises ``ImportError`` without matplotlib.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    ok = [r for r in table if r["status"] == "complete" and r.get("wall_s")]
    if quantity is None:
        quantity = next((k for k in (ok[0] if ok else {}) if k.endswith(".fx")), "dofs")
    if ok and quantity not in ok[0]:
        raise fail("quantity", quantity, "a column of the sweep table: " + ", ".join(
            k for k in ok[0] if k not in ("variant", "status", "resumed", "worker")))
    numeric = [k for k in keys if ok and all(isinstance(r[k], (int, float)) and not isinstance(r[k], bool) for r in ok)]
    if numeric:  # the first numeric key varies along each line
        keys = [numeric[0]] + [k for k in keys if k != numeric[0]]
    order = {v: i for i, v in enumerate(dict.fromkeys(r[keys[0]] for r in ok))} if ok else {}
    fig, (ax_p, ax_w) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    groups: dict = {}
    for r in ok:
        groups.setdefault(tuple(r[k] for k in keys[1:]), []).append(r)
    for g, rs in groups.items():
        y = [r[quantity] for r in rs]
        if reference is not None:
            y = [abs(v - reference) / abs(reference) for v in y]
        label = ", ".join(f"{k} = {v}" for k, v in zip(keys[1:], g)) or quantity
        xp = [r[keys[0]] if numeric else order[r[keys[0]]] for r in rs]
        line, = ax_p.plot(xp, y, "o-", label=label)
        x = [r["wall_s"] for r in rs]
        ax_w.plot(x, y, "o-", color=line.get_color(), label=label)
        for r, xi, yi in zip(rs, x, y):
            ax_w.annotate(f"{keys[0]} = {r[keys[0]]}", (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=7)
    xs = [r[keys[0]] for r in ok]
    if numeric and xs and min(xs) > 0 and max(xs) >= 4 * min(xs):
        ax_p.set_xscale("log")
    if not numeric and order:
        ax_p.set_xticks(range(len(order)), [str(v) for v in order])
    ax_p.set_xlabel(_labelled(keys[0]))
    ax_w.set_xscale("log")
    ax_w.set_xlabel("wall time per variant [s]")
    for ax in (ax_p, ax_w):
        if reference is not None:
            ax.set_yscale("log")
            ax.set_ylabel(f"relative error of {quantity} (reference {reference:.12g})")
        else:
            ax.set_ylabel(_labelled(quantity))
        ax.grid(True, which="both", alpha=0.3)
    if groups:
        ax_p.legend(fontsize=8)
    fig.suptitle(f"sweep over {', '.join(keys)}: {quantity} against {keys[0]} and against the cost", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
