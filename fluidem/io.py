"""Run output: history table, field and body-outline time series, event log, checkpoints.

Layout of an output directory::

    history.csv            one row per recorded step and body:
                           step, t, id, x, y, angle, vx, vy, omega, fx, fy, torque, contacts
    fields.pvd             ParaView index of fields/fields_<step>.vtu (fluid scenes)
    fields/                velocity (point data, (n, 3)), |u|, pressure (point data; element
                           averages at vertices for a discontinuous pressure)
    bodies.pvd             ParaView index of bodies/bodies_<step>.vtu
    bodies/                one polygon cell per body with cell data id, velocity, omega
    mesh_quality.csv       step, t, min/max angle, share of angles > 135°, inverted, nodes, triangles
    events.log             one line per event (mesh built, re-triangulation, transfer, restart, ...)
    checkpoints/           ckpt_<step>.pkl: everything needed to continue the run
    scene.toml             the scene as run

XDMF would need h5py; VTU files with a PVD index are read by ParaView and meshio alike.
``fx, fy, torque`` are the hydrodynamic load in fluid scenes and the contact force and
torque (without gravity) in dry scenes; ``contacts`` counts each body's contacts.

Examples
--------
>>> import tempfile
>>> import numpy as np
>>> from fluidem.io import OutputWriter, read_history
>>> d = tempfile.mkdtemp()
>>> w = OutputWriter(d)
>>> w.history(0, 0.0, pos=[[0.1, 0.2], [0.3, 0.4]], angle=[0.0, 0.5], vel=np.zeros((2, 2)), omega=[0.0, 1.0],
...           force=np.zeros((2, 2)), torque=[0.0, 0.0], contacts=[0, 1])
>>> w.event(0, 0.0, "start")
>>> w.close()
>>> h = read_history(d)
>>> h["id"], h["y"], h["contacts"]
(array([0, 1]), array([0.2, 0.4]), array([0, 1]))
"""

from __future__ import annotations

import io as _io
import os
import pickle
import re
from pathlib import Path
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from .validate import fail

__all__ = ["OutputWriter", "read_history", "read_pvd", "latest_checkpoint", "load_checkpoint", "fluid_point_data",
           "HISTORY_COLUMNS"]

PathLike = Union[str, os.PathLike]

HISTORY_COLUMNS = ("step", "t", "id", "x", "y", "angle", "vx", "vy", "omega", "fx", "fy", "torque", "contacts")
CHECKPOINT_VERSION = 1


def fluid_point_data(space, x: np.ndarray) -> dict[str, np.ndarray]:
    """Velocity, speed and pressure at the mesh vertices, for VTU output.

    Velocity: the vertex DOFs (all element pairs here have nodal vertex values).  Pressure:
    the pressure basis evaluated at each element's vertices, averaged over the elements
    around a vertex (exact for a continuous pressure).

    Parameters
    ----------
    space : fluidem.fluid.space.FlowSpace
        Velocity/pressure spaces on the mesh (``n_u`` velocity DOFs first, then pressure).
    x : (space.n_dofs,) float
        Velocity (m/s) and kinematic pressure (p/ρ, m²/s²) DOFs.

    Returns
    -------
    dict
        ``"velocity"`` (n_vertices, 3) m/s with a zero z column, ``"speed"`` (n_vertices,) m/s,
        ``"pressure"`` (n_vertices,) m²/s².
    """
    mesh = space.mesh
    nv = mesh.nvertices
    u = x[: space.n_u]
    nd = space.ub.nodal_dofs
    vel = np.zeros((nv, 3))
    vel[:, 0], vel[:, 1] = u[nd[0]], u[nd[1]]
    pb = space.pb
    Xref = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    Phi = np.array([pb.elem.lbasis(Xref, i)[0] for i in range(pb.Nbfun)])  # (Nbfun, 3)
    P = x[space.n_u:][pb.element_dofs]  # (Nbfun, n_elements)
    pv = Phi.T @ P  # (3, n_elements): value at local vertex k of each element
    t = mesh.t
    s = np.bincount(t.ravel(), pv.ravel(), minlength=nv)
    c = np.bincount(t.ravel(), minlength=nv)
    p = s / np.maximum(c, 1)
    return {"velocity": vel, "speed": np.hypot(vel[:, 0], vel[:, 1]), "pressure": p}


def _points3(p2):
    p2 = np.asarray(p2, dtype=float)
    return np.column_stack([p2, np.zeros(len(p2))])


class OutputWriter:
    """Writes one run's output directory (see the module docstring for the layout).

    Parameters
    ----------
    out_dir : str or Path
        Created if missing; a fresh run overwrites ``history.csv``, ``events.log`` and
        ``mesh_quality.csv``.
    restart_step : int or None
        When continuing from a checkpoint at this step: rows, series entries and events
        after it are dropped so the continued run appends to a consistent record.

    Call :meth:`close` at the end (the history and the event log stay open in between).
    """

    def __init__(self, out_dir: PathLike, restart_step: int | None = None):
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self._series: dict[str, list[tuple[int, float, str]]] = {"fields": [], "bodies": []}
        hist = self.dir / "history.csv"
        if restart_step is None:
            self._hist = open(hist, "w", newline="")
            self._hist.write(",".join(HISTORY_COLUMNS) + "\n")
            for f in ("events.log", "mesh_quality.csv"):
                (self.dir / f).unlink(missing_ok=True)
        else:
            self._truncate_history(hist, restart_step)
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

    @staticmethod
    def _truncate_history(path: Path, step: int):
        if not path.exists():
            with open(path, "w") as f:
                f.write(",".join(HISTORY_COLUMNS) + "\n")
            return
        with open(path) as f:
            lines = f.readlines()
        keep = [lines[0]] + [ln for ln in lines[1:] if ln.strip() and int(ln.split(",", 1)[0]) <= step]
        with open(path, "w") as f:
            f.writelines(keep)

    # -- history ----------------------------------------------------------------------------
    def history(self, step: int, t: float, pos: ArrayLike, angle: ArrayLike, vel: ArrayLike, omega: ArrayLike,
                force: ArrayLike, torque: ArrayLike, contacts: ArrayLike) -> None:
        """Append one row per body to history.csv (nothing for ``n = 0`` bodies).

        Parameters
        ----------
        step : int
        t : float
            Time, s.
        pos : (n, 2) float
            Body centres, m.
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
        """
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        n = len(pos)
        if n == 0:
            return
        table = np.column_stack([np.full(n, step), np.full(n, t), np.arange(n), pos, angle, vel, omega, force, torque,
                                 contacts])
        buf = _io.StringIO()
        np.savetxt(buf, table, fmt=["%d", "%.17g", "%d"] + ["%.17g"] * 9 + ["%d"], delimiter=",")
        self._hist.write(buf.getvalue())
        self._hist.flush()

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

    def checkpoint(self, step: int, t: float, state: dict) -> Path:
        """Pickle ``state`` (plain data and fluidem objects) to checkpoints/ckpt_<step>.pkl."""
        d = self.dir / "checkpoints"
        d.mkdir(exist_ok=True)
        path = d / f"ckpt_{step:07d}.pkl"
        tmp = path.with_suffix(".tmp")
        with open(tmp, "wb") as f:
            pickle.dump({"version": CHECKPOINT_VERSION, "step": step, "t": t, **state}, f,
                        protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
        return path

    def close(self) -> None:
        """Close history.csv and events.log (idempotent)."""
        for f in (self._hist, self._events):
            if not f.closed:
                f.close()


def read_history(path: PathLike) -> dict[str, np.ndarray]:
    """history.csv (or the one in a run directory) as a dict of column name -> (n_rows,) array.

    Columns are :data:`HISTORY_COLUMNS`; ``step``, ``id`` and ``contacts`` are int, the
    others float (SI units: m, rad, m/s, rad/s, N/m, N).
    """
    path = Path(path)
    if path.is_dir():
        path = path / "history.csv"
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    out = {}
    for k, name in enumerate(header):
        col = data[:, k] if data.size else np.zeros(0)
        out[name] = col.astype(int) if name in ("step", "id", "contacts") else col
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


def latest_checkpoint(out_dir: PathLike) -> Path:
    """Newest checkpoint file in ``out_dir/checkpoints``.

    Raises :class:`fluidem.errors.InputError` (a ``ValueError``) if there is none.
    """
    d = Path(out_dir) / "checkpoints"
    files = sorted(d.glob("ckpt_*.pkl")) if d.is_dir() else []
    if not files:
        raise fail("checkpoint directory", str(d), "a directory holding ckpt_*.pkl files written by 'fluidem run' "
                   "with output.checkpoint_every")
    return files[-1]


def load_checkpoint(path: PathLike) -> dict:
    """Read a checkpoint written by :meth:`OutputWriter.checkpoint` (a run directory: its newest).

    Returns the pickled state with ``version``, ``step`` and ``t`` (s).  Raises
    :class:`fluidem.errors.InputError` (a ``ValueError``) for a missing file or a file that is
    not a checkpoint of this version.  Only load checkpoints you wrote: they are pickles.
    """
    path = Path(path)
    if path.is_dir():
        path = latest_checkpoint(path)
    try:
        with open(path, "rb") as f:
            data = pickle.load(f)
    except FileNotFoundError:
        raise fail("checkpoint", str(path), "an existing checkpoint file") from None
    if not isinstance(data, dict) or data.get("version") != CHECKPOINT_VERSION:
        raise fail("checkpoint", str(path), f"a fluidem checkpoint of version {CHECKPOINT_VERSION}")
    return data
