"""What the figures of a run (:mod:`fluidem.plotting`) read from its directory: the VTU files,
the history and mesh-quality tables, the scene as run and its bodies' masses.

A run may still be writing, or have been stopped mid-row: a half-written last row of a CSV
table is dropped with a :class:`PlotWarning`; any other damage is an
:class:`~fluidem.errors.InputError` naming the file (``meshio.read`` would exit the
interpreter on a damaged VTU file instead).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .errors import InputError
from .io import read_history

__all__ = ["PlotWarning", "read_vtu", "repaired_table", "read_run_history", "body_outlines", "scene_as_run",
           "mass_inertia", "read_mesh_quality"]


class PlotWarning(UserWarning):
    """Something in a run directory the figures work around (a half-written last row of a CSV file)."""


def read_vtu(path):
    """A VTU file of a run directory as a ``meshio.Mesh``.

    ``meshio.read`` prints and exits the interpreter on a file it cannot read; this raises
    :class:`fluidem.errors.InputError` naming the file instead (missing, truncated or damaged).
    """
    import zlib

    import meshio

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: missing; expected the VTU file that the run's .pvd index lists (run the scene "
                         "again to write it)")
    try:
        return meshio.vtu.read(str(path))
    except (meshio.ReadError, ValueError, KeyError, IndexError, EOFError, zlib.error) as exc:
        why = " ".join(str(exc).split())
        raise InputError(f"{path}: not a complete VTU file ({why + '; ' if why else ''}{path.stat().st_size} "
                         "bytes): truncated or damaged, e.g. by a run stopped while writing it; expected the file as "
                         "'fluidem run' writes it (run the scene again to rewrite it)") from None


def _row_problem(line: str, n: int) -> str | None:
    """What is wrong with one data row of a CSV file of ``n`` numeric columns, or None."""
    parts = line.strip().split(",")
    if len(parts) != n:
        return f"{len(parts)} values, expected {n}"
    for p in parts:
        try:
            float(p)
        except ValueError:
            return f"{p!r} is not a number"
    return None


def repaired_table(path: Path) -> tuple[list, np.ndarray]:
    """(header, data (n_rows, n_cols)) of a numeric CSV file that ``np.loadtxt`` refused.

    A half-written last row (a run still writing, or stopped mid-row) is dropped with a
    :class:`PlotWarning`; any other bad row raises :class:`fluidem.errors.InputError` naming
    the file, the line and what is wrong.
    """
    with open(path) as f:
        rows = [(k, ln) for k, ln in enumerate(f, 1) if ln.strip() and not ln.startswith("#")]
    if not rows:
        raise InputError(f"{path}: empty; expected a header line of column names and rows of numbers")
    header = rows[0][1].strip().split(",")
    rows = rows[1:]
    bad = [(k, why) for k, ln in rows if (why := _row_problem(ln, len(header))) is not None]  # only when damaged
    if not bad:  # pragma: no cover - np.loadtxt refused a file every row of which parses
        raise InputError(f"{path}: cannot be read as a table of numbers; expected {len(header)} comma-separated "
                         "numbers per row")
    k, why = bad[0]
    if len(bad) > 1 or k != rows[-1][0]:
        raise InputError(f"{path}, line {k}: {why}; expected {len(header)} comma-separated numbers per row "
                         f"({', '.join(header)}): the file is damaged (only a half-written last line is skipped)")
    warnings.warn(f"{path}: its last line {k} is half-written ({why}; a run still writing, or stopped mid-row): "
                  "drawn without it", PlotWarning, stacklevel=3)
    rows = rows[:-1]
    data = np.loadtxt([ln for _, ln in rows], delimiter=",", ndmin=2) if rows else np.zeros((0, len(header)))
    return header, data


def read_run_history(out_dir: Path) -> dict:
    """:func:`fluidem.io.read_history` of ``out_dir``, but a half-written last row is dropped with a
    :class:`PlotWarning` and a damaged file is an :class:`~fluidem.errors.InputError` naming it."""
    path = out_dir / "history.csv"
    try:
        return read_history(path)
    except (ValueError, IndexError):  # a row np.loadtxt cannot read, or an empty file
        header, data = repaired_table(path)
    return {name: (data[:, k].astype(int) if name in ("step", "id", "contacts") else data[:, k])
            for k, name in enumerate(header)}


def body_outlines(vtu) -> list:
    """The body outlines of one ``bodies/bodies_<step>.vtu`` file: a list of (n_i, 2) vertex
    arrays (length), one per cell."""
    m = read_vtu(vtu)
    out = []
    for block in m.cells:
        for conn in block.data:
            out.append(m.points[conn, :2])
    return out


def scene_as_run(out_dir: Path):
    """The :class:`fluidem.scene.Scene` of ``out_dir/scene.toml``, or ``None`` when it is missing or
    does not read."""
    try:  # the scene as run
        from .scene import Scene

        return Scene.from_toml(out_dir / "scene.toml")
    except (ValueError, OSError):
        return None


def mass_inertia(scene) -> tuple[np.ndarray, np.ndarray] | None:
    """Mass and moment of inertia about the centre of each body of ``scene`` (per unit depth)."""
    from . import geometry as geo

    if scene is None or not scene.bodies:
        return None
    m, J = [], []
    for b in scene.bodies:  # once per figure
        v = b.local_vertices(scene.default_segments(b))
        a, c = geo.polygon_area(v), geo.polygon_centroid(v)
        m.append(b.density * a)
        J.append(b.density * (geo.polygon_polar_moment(v) - a * float(c @ c)))
    return np.array(m), np.array(J)


def read_mesh_quality(out_dir: Path) -> dict | None:
    """``mesh_quality.csv`` of ``out_dir`` as column name -> (n_rows,) array, or ``None`` when the run
    wrote no rows (a half-written last row dropped with a :class:`PlotWarning`)."""
    path = out_dir / "mesh_quality.csv"
    if not path.exists():
        return None
    lines = path.read_text().splitlines()
    if len(lines) < 2:
        return None
    try:
        header, data = lines[0].split(","), np.loadtxt(lines[1:], delimiter=",", ndmin=2)
    except ValueError:  # a half-written last row (dropped with a warning) or a damaged file
        header, data = repaired_table(path)
    return {k: data[:, i] for i, k in enumerate(header)}
