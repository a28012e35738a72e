"""Reading a run's output back: the history and sides tables, the PVD indexes and the field
files.  Units: those of the scene (see :mod:`fluidem.io`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..validate import fail
from .layout import SIDES_COLUMNS, PathLike

__all__ = ["read_history", "read_sides", "read_pvd", "field_series", "read_fields"]


def read_history(path: PathLike) -> dict[str, np.ndarray]:
    """history.csv (or the one in a run directory) as a dict of column name -> (n_rows,) array.

    Columns are :data:`HISTORY_COLUMNS`; ``step``, ``id`` and ``contacts`` are int, the
    others float (SI units: m, rad, m/s, rad/s, N/m, N).
    """
    path = Path(path)
    if path.is_dir():
        path = path / "history.csv"
    with open(path) as f:
        lines = [ln for ln in f if not ln.startswith("#")]
    header = lines[0].strip().split(",")
    data = np.loadtxt(lines[1:], delimiter=",", ndmin=2) if len(lines) > 1 else np.zeros((0, len(header)))
    out = {}
    for k, name in enumerate(header):
        col = data[:, k] if data.size else np.zeros(0)
        out[name] = col.astype(int) if name in ("step", "id", "contacts") else col
    return out


def read_sides(path: PathLike) -> dict[str, np.ndarray]:
    """sides.csv (or the one in a run directory) as a dict of column name -> (n_rows,) array.

    Columns are :data:`SIDES_COLUMNS`: ``step`` int, ``side`` str, ``t``, ``fx``, ``fy`` float
    (force/depth: the force of the fluid on the side).  Empty arrays when the run wrote none.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "sides.csv"
    out = {"step": np.zeros(0, int), "t": np.zeros(0), "side": np.zeros(0, str), "fx": np.zeros(0), "fy": np.zeros(0)}
    if not path.exists():
        return out
    with open(path) as f:
        rows = [ln.strip().split(",") for ln in f if ln[:1].isdigit()]
    rows = [r for r in rows if len(r) == len(SIDES_COLUMNS)]
    if rows:
        cols = list(zip(*rows))
        out = {"step": np.array(cols[0], dtype=int), "t": np.array(cols[1], dtype=float),
               "side": np.array(cols[2], dtype=str), "fx": np.array(cols[3], dtype=float),
               "fy": np.array(cols[4], dtype=float)}
    return out


def read_pvd(path: PathLike, with_steps: bool = False) -> list[tuple]:
    """Entries of a PVD index, in file order.

    Returns a list of ``(t, path)`` (time in s, the data file's path), or with
    ``with_steps`` of ``(step, t, file)`` with the file relative to the index (step -1 when
    the index has no step attribute).
    """
    path = Path(path)
    text = path.read_text()
    out = []
    for m in re.finditer(r'timestep="([^"]+)"(?: step="(\d+)")? file="([^"]+)"', text):
        t, s, f = float(m.group(1)), int(m.group(2) or -1), m.group(3)
        out.append((s, t, f) if with_steps else (t, path.parent / f))
    return out


def field_series(out_dir: PathLike, full: bool = True) -> list[tuple[int, float, Path]]:
    """``(step, t, path)`` of each field file of a run directory, in time order.

    ``full``: the full-resolution series (``fields_full.pvd``) when the run wrote one, else
    the vertex series (``fields.pvd``); ``False``: the vertex series.  ``[]`` when the run
    wrote no fields.
    """
    d = Path(out_dir)
    for name in (("fields_full", "fields") if full else ("fields",)):
        if (d / f"{name}.pvd").exists():
            return [(s, t, d / f) for s, t, f in read_pvd(d / f"{name}.pvd", with_steps=True)]
    return []


def read_fields(out_dir: PathLike, step: int | None = None, full: bool = True):
    """The fields of one output step of a run directory as a ``meshio.Mesh``.

    Parameters
    ----------
    out_dir : path
        Output directory of a fluid run.
    step : int, optional
        Step number (default: the last one written).
    full : bool
        Full resolution when the run wrote it (see :func:`field_series`).

    Returns
    -------
    meshio.Mesh
        ``points`` (n, 3) and ``point_data`` ``velocity`` (n, 3), ``speed``, ``pressure``
        (dynamic), ``kinematic_pressure`` (units: see :mod:`fluidem.io`); its
        ``field_data["t"]`` is the time of the step.
    """
    import meshio

    series = field_series(out_dir, full)
    if not series:
        raise fail("output directory", str(out_dir), "the directory of a fluid run that wrote fields "
                   "(fields.pvd)")
    if step is None:
        s, t, path = series[-1]
    else:
        hit = [e for e in series if e[0] == step]
        if not hit:
            raise fail("step", step, "one of the output steps " + ", ".join(str(e[0]) for e in series[:20])
                       + (" ..." if len(series) > 20 else ""))
        s, t, path = hit[0]
    m = meshio.read(path)
    m.field_data["t"] = np.array([t])
    return m
