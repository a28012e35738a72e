"""Writing one run's output directory: :class:`OutputWriter` (history, sides, field and
body-outline series, event log, mesh quality, checkpoints).  Units: those of the scene (see
:mod:`fluidem.io`).
"""

from __future__ import annotations

import io as _io
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..checkpoint import checkpoint_files
from ..checkpoint import save as _save_npz
from .checkpoints import CHECKPOINT_VERSION
from .layout import _HISTORY_COLUMNS_BEFORE_UNWRAPPED, HISTORY_COLUMNS, SIDES_COLUMNS, PathLike, _history_header
from .readers import read_pvd
from .sampling import _points3

__all__ = ["OutputWriter"]


class OutputWriter:
    """Writes one run's output directory (see :mod:`fluidem.io` for the layout).

    Call :meth:`close` at the end (the history and the event log stay open in between).

    Parameters
    ----------
    out_dir : str or Path
        Created if missing; a fresh writer starts ``history.csv``, ``events.log`` and
        ``mesh_quality.csv`` anew (whether the directory may be used is for
        :func:`prepare_output_dir` to say, before).
    restart_step : int or None
        When continuing from a checkpoint at this step: rows, series entries and events
        after it are dropped so the continued run appends to a consistent record.
    """

    def __init__(self, out_dir: PathLike, restart_step: int | None = None):
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self._series: dict[str, list[tuple[int, float, str]]] = {"fields": [], "fields_full": [], "bodies": []}
        hist = self.dir / "history.csv"
        if restart_step is None:
            self._hist = open(hist, "w", newline="")
            self._hist.write(_history_header())
            for f in ("events.log", "mesh_quality.csv", "sides.csv"):
                (self.dir / f).unlink(missing_ok=True)
        else:
            self._truncate_history(hist, restart_step)
            if (self.dir / "sides.csv").exists():
                self._truncate_history(self.dir / "sides.csv", restart_step, SIDES_COLUMNS)
            self._hist = open(hist, "a", newline="")
            ev = self.dir / "events.log"
            if ev.exists():
                keep = [ln for ln in ev.read_text().splitlines(True)
                        if not ln.startswith("step=") or int(ln[5:].split(" ", 1)[0]) <= restart_step]
                ev.write_text("".join(keep))
            for name in self._series:
                pvd = self.dir / f"{name}.pvd"
                if pvd.exists():
                    self._series[name] = [(s, t, f) for s, t, f in read_pvd(pvd, with_steps=True) if s <= restart_step]
        self._events = open(self.dir / "events.log", "a")
        self._sides = None  # opened at the first row: a run without such sides writes no sides.csv

    @staticmethod
    def _truncate_history(path: Path, step: int, columns: tuple = HISTORY_COLUMNS):
        if not path.exists():
            with open(path, "w") as f:
                f.write(",".join(columns) + "\n")
            return
        with open(path) as f:
            lines = f.readlines()
        before = ",".join(_HISTORY_COLUMNS_BEFORE_UNWRAPPED)
        if columns == HISTORY_COLUMNS and any(ln.strip() == before for ln in lines):
            # written before the unwrapped columns: such a run never crossed a periodic side, so
            # they repeat x and y
            lines = [_history_header() if ln.strip() == ",".join(_HISTORY_COLUMNS_BEFORE_UNWRAPPED) else
                     ln.rstrip("\n") + "," + ",".join(ln.split(",")[3:5]) + "\n"
                     if ln[:1].isdigit() and ln.strip().count(",") == len(_HISTORY_COLUMNS_BEFORE_UNWRAPPED) - 1
                     else ln for ln in lines]
        keep = [ln for ln in lines if ln.startswith("#") or not ln[:1].isdigit()]  # comments and the column line
        keep += [ln for ln in lines if ln[:1].isdigit() and ln.strip().count(",") == len(columns) - 1
                 and int(ln.split(",", 1)[0]) <= step]  # rows up to the step (a half-written last row dropped)
        with open(path, "w") as f:
            f.writelines(keep)

    # -- history ----------------------------------------------------------------------------
    def history(self, step: int, t: float, pos: ArrayLike, angle: ArrayLike, vel: ArrayLike, omega: ArrayLike,
                force: ArrayLike, torque: ArrayLike, contacts: ArrayLike, unwrapped: ArrayLike | None = None) -> None:
        """Append one row per body to history.csv (nothing for ``n = 0`` bodies).

        Parameters
        ----------
        step : int
        t : float
            Time, s.
        pos : (n, 2) float
            Body centres, m (in the box: across periodic sides, wrapped into it).
        angle : (n,) float
            Rotation angles, rad.
        vel : (n, 2) float
            Centre velocities, m/s.
        omega : (n,) float
            Angular velocities, rad/s.
        force : (n, 2) float
            Force on each body (per unit depth in 2D), N/m.
        torque : (n,) float
            Torque about each centre, N.
        contacts : (n,) int
            Number of contacts of each body.
        unwrapped : (n, 2) float or None
            The centres not wrapped across periodic sides (continuous: displacements and
            diffusivities), m; ``None``: ``pos``.
        """
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        n = len(pos)
        if n == 0:
            return
        unwrapped = pos if unwrapped is None else np.asarray(unwrapped, dtype=float).reshape(-1, 2)
        table = np.column_stack([np.full(n, step), np.full(n, t), np.arange(n), pos, angle, vel, omega, force, torque,
                                 contacts, unwrapped])
        buf = _io.StringIO()
        np.savetxt(buf, table, fmt=["%d", "%.17g", "%d"] + ["%.17g"] * 9 + ["%d", "%.17g", "%.17g"], delimiter=",")
        self._hist.write(buf.getvalue())
        self._hist.flush()

    def sides(self, step: int, t: float, names, force: ArrayLike) -> None:
        """Append one row per side to sides.csv (created with its column line at the first call).

        Parameters
        ----------
        step : int
        t : float
            Time.
        names : sequence of str
            Side names (bottom, right, top, left).
        force : (n_sides, 2) float
            Force of the fluid on each side, per unit depth (force/depth, dynamic like the body loads).
        """
        if not len(names):
            return
        if self._sides is None:
            path = self.dir / "sides.csv"
            new = not path.exists()
            self._sides = open(path, "a", newline="")
            if new:
                self._sides.write(",".join(SIDES_COLUMNS) + "\n")
        F = np.asarray(force, dtype=float).reshape(-1, 2)
        self._sides.write("".join(f"{step},{t:.17g},{n},{fx:.17g},{fy:.17g}\n" for n, (fx, fy) in zip(names, F)))
        self._sides.flush()

    # -- series -------------------------------------------------------------------------------
    def _add(self, name: str, step: int, t: float, mesh) -> Path:
        sub = self.dir / name
        sub.mkdir(exist_ok=True)
        fname = f"{name}/{name}_{step:07d}.vtu"
        mesh.write(self.dir / fname)
        self._series[name] = [e for e in self._series[name] if e[0] != step] + [(step, t, fname)]
        self._write_pvd(name)
        return self.dir / fname

    def _write_pvd(self, name):
        lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "  <Collection>"]
        for step, t, f in self._series[name]:
            lines.append(f'    <DataSet timestep="{t:.17g}" step="{step}" file="{f}"/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        (self.dir / f"{name}.pvd").write_text("\n".join(lines))

    def fields(self, step: int, t: float, points: ArrayLike, triangles: ArrayLike,
               point_data: dict[str, np.ndarray]) -> Path:
        """Write fluid fields on the vertex mesh to ``fields/fields_<step>.vtu`` and index it.

        ``points`` (n, 2) m, ``triangles`` (m, 3) int vertex indices, ``point_data`` arrays of
        first dimension n (e.g. from :func:`fluid_point_data`).  Returns the file written.
        """
        import meshio

        m = meshio.Mesh(_points3(points), [("triangle", np.asarray(triangles))], point_data=point_data)
        return self._add("fields", step, t, m)

    def fields_full(self, step: int, t: float, points: ArrayLike, cells: list, point_data: dict[str, np.ndarray],
                    cell_data: dict | None = None) -> Path:
        """Write full-resolution fluid fields to ``fields_full/fields_full_<step>.vtu`` and index it
        in ``fields_full.pvd``: ``points`` (n, 3), ``cells`` meshio cell blocks, ``point_data``
        arrays of first dimension n (the outputs of :func:`full_order_fields`).  Returns the file."""
        import meshio

        m = meshio.Mesh(np.asarray(points, float), cells, point_data=point_data, cell_data=cell_data or {})
        return self._add("fields_full", step, t, m)

    def bodies(self, step: int, t: float, outlines: list, velocity: ArrayLike, omega: ArrayLike) -> Path:
        """Write body outlines to ``bodies/bodies_<step>.vtu`` and index it.

        ``outlines``: one (n_i, 2) array of vertices (m) per body; ``velocity`` (n_bodies, 2)
        m/s and ``omega`` (n_bodies,) rad/s become cell data next to the body ``id``.  Returns
        the file written.
        """
        import meshio

        pts = _points3(np.vstack(outlines)) if outlines else np.zeros((0, 3))
        offs = np.cumsum([0] + [len(o) for o in outlines])
        groups: dict[int, list[int]] = {}
        for k, o in enumerate(outlines):  # one cell per body: small, per output step only
            groups.setdefault(len(o), []).append(k)
        cells, ids = [], []
        for nv, ks in groups.items():
            conn = np.array([np.arange(offs[k], offs[k] + nv) for k in ks])
            ctype = {3: "triangle", 4: "quad"}.get(nv, "polygon")
            cells.append((ctype, conn))
            ids.append(np.array(ks))
        v = np.asarray(velocity, float)
        cd = {"id": [i.astype(float) for i in ids],
              "velocity": [np.column_stack([v[i], np.zeros(len(i))]) for i in ids],
              "omega": [np.asarray(omega, float)[i] for i in ids]}
        m = meshio.Mesh(pts, cells, cell_data=cd if cells else {})
        return self._add("bodies", step, t, m)

    # -- log, quality, checkpoints ----------------------------------------------------------------
    def event(self, step: int, t: float, kind: str, message: str = "") -> None:
        """Append one line ``step=<step> t=<t> <kind> <message>`` to events.log."""
        self._events.write(f"step={step} t={t:.10g} {kind} {message}".rstrip() + "\n")
        self._events.flush()

    def mesh_quality(self, step: int, t: float, q) -> None:  # q: fluidem.mesh.MeshQuality
        """Append a :class:`fluidem.mesh.MeshQuality` row to mesh_quality.csv."""
        path = self.dir / "mesh_quality.csv"
        new = not path.exists()
        with open(path, "a") as f:
            if new:
                f.write("step,t,min_angle,max_angle,frac_above_135,n_inverted,n_nodes,n_triangles\n")
            f.write(f"{step},{t:.10g},{q.min_angle:.6g},{q.max_angle:.6g},{q.frac_above_135:.6g},{q.n_inverted},"
                    f"{q.n_nodes},{q.n_triangles}\n")

    def checkpoint(self, step: int, t: float, state: dict | None = None, header: dict | None = None,
                   snapshot: tuple | None = None, keep: int | None = None) -> Path:
        """Write checkpoints/ckpt_<step>.npz atomically (:func:`fluidem.checkpoint.save`).

        ``state``: the run's state (plain data, arrays, fluidem objects), or ``snapshot`` a
        ``(tree, arrays)`` pair encoded earlier; ``header``: JSON-able facts (scene, plan, dt)
        stored beside ``step`` and ``t`` (s).  ``keep``: keep only the newest ``keep``
        checkpoints.  Returns the file written.
        """
        d = self.dir / "checkpoints"
        d.mkdir(exist_ok=True)
        path = d / f"ckpt_{step:07d}.npz"
        _save_npz(path, {"version": CHECKPOINT_VERSION, "step": int(step), "t": float(t), **(header or {})}, state,
                  snapshot=snapshot)
        if keep:
            for old in checkpoint_files(self.dir)[keep:]:
                old.unlink(missing_ok=True)
        return path

    def close(self) -> None:
        """Close history.csv, sides.csv and events.log (idempotent)."""
        for f in (self._hist, self._events, self._sides):
            if f is not None and not f.closed:
                f.close()
