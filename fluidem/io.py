"""Run output: history table, field and body-outline time series, event log, checkpoints.

Layout of an output directory::

    history.csv            one row per recorded step and body:
                           step, t, id, x, y, angle, vx, vy, omega, fx, fy, torque, contacts
    sides.csv              fluid scenes with walls, moving walls or inflow sides: one row per recorded
                           step (from step 1) and such side: step, t, side, fx, fy, the force of the
                           fluid on the side (:class:`fluidem.fluid.forces.SideLoads`)
    fields.pvd             ParaView index of fields/fields_<step>.vtu (fluid scenes)
    fields/                velocity (point data, (n, 3)), |u|, pressure (point data; element
                           averages at vertices for a discontinuous pressure), vertex values only
    fields_full.pvd        ParaView index of fields_full/fields_full_<step>.vtu (``[output]
                           full_order``, on by default): the same fields at full resolution
    fields_full/           P2/P1: quadratic triangles (VTK "triangle6", exact); P3/P2, P2+bubble,
                           MINI: each triangle split into 9 linear ones with the fields at their
                           10 nodes (:func:`full_order_fields`); cell data ``element``
    bodies.pvd             ParaView index of bodies/bodies_<step>.vtu
    bodies/                one polygon cell per body with cell data id, velocity, omega
    mesh_quality.csv       step, t, min/max angle, share of angles > 135°, inverted, nodes, triangles
    events.log             one line per event (mesh built, re-triangulation, transfer, restart, ...)
    checkpoints/           ckpt_<step>.npz: everything needed to continue the run (arrays + a JSON
                           header, :mod:`fluidem.checkpoint`; loading never executes code)
    scene.toml             the scene as run
    run.json               which scene the folder belongs to, and how far the run got: status
                           running | complete | interrupted | failed, last step and time; a complete
                           run of a Couette cell adds ``rheology`` (:mod:`fluidem.rheology`)

An output directory belongs to one run at a time:

* one writer: a run holds an exclusive OS lock on ``.fluidem.lock`` in the directory for as
  long as it runs (:class:`RunLock`, ``fcntl.flock``; released by the OS when the process
  ends, however it ends); a second run into the same directory, fresh or a restart, is
  refused with the process id of the first;
* :func:`prepare_output_dir` refuses a fresh run into a directory that holds another run's
  output unless told to overwrite it or to restart (continue) it;
* ``run.json`` lists the names a run writes (``entries``: the files and folders above);
  overwriting removes those and nothing else, and a file of one of those names that no
  ``run.json`` lists (a hand-written ``scene.toml``, say) is never removed or written over:
  the run is refused, naming it.

ParaView opens the PVD indexes (a time series); meshio reads each VTU file but not a PVD
index: :func:`read_fields` gives the fields of one step as a ``meshio.Mesh`` and
:func:`field_series` lists ``(step, t, path)`` of a series.  For a mesh that does not change
(a fixed-mesh scene) :func:`write_xdmf` (or ``[output] xdmf = true``, at the end of the run)
collects a series into one XDMF time series, ``fields_full.xdmf`` + ``fields_full.h5``, which
ParaView opens and ``meshio.xdmf.TimeSeriesReader`` reads (needs h5py: the ``xdmf`` extra).
``fx, fy, torque`` are the hydrodynamic load in fluid scenes and the contact force and
torque (without gravity) in dry scenes; ``contacts`` counts each body's contacts.

Units: those of the scene (one consistent system, nothing converted).  Every quantity is
per unit depth in 2D; the fluid's pressure is the *kinematic* pressure p/ρ (length²/time²),
while the forces and torques in history.csv are *dynamic*, i.e. the fluid density times the
kinematic load.  The VTU ``pressure`` field is dynamic too (ρ times the kinematic pressure,
which is written beside it as ``kinematic_pressure``), so loads and pressure share one
convention; run.json lists the unit of every history column (:data:`HISTORY_UNITS`).

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
import json
import os
import pickle
import re
import shutil
from pathlib import Path
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from .checkpoint import CheckpointError, checkpoint_files
from .checkpoint import load as _load_npz
from .checkpoint import save as _save_npz
from .errors import InputError, install_hint
from .validate import fail

__all__ = ["OutputWriter", "read_history", "read_sides", "SIDES_COLUMNS",
           "read_pvd", "latest_checkpoint", "load_checkpoint", "load_latest_checkpoint",
           "fluid_point_data", "full_order_fields", "read_fields", "field_series", "write_xdmf", "prepare_output_dir",
           "read_run_record", "write_run_record", "HISTORY_COLUMNS", "HISTORY_UNITS", "OUTPUT_ENTRIES",
           "OutputDirError", "RunLock", "LOCK_FILE"]

PathLike = Union[str, os.PathLike]

HISTORY_COLUMNS = ("step", "t", "id", "x", "y", "angle", "vx", "vy", "omega", "fx", "fy", "torque", "contacts",
                   "x_unwrapped", "y_unwrapped")
#: the columns before ``x_unwrapped``, ``y_unwrapped`` were added (a restart pads such rows)
_HISTORY_COLUMNS_BEFORE_UNWRAPPED = HISTORY_COLUMNS[:-2]
#: columns of sides.csv (``side`` is the side's name: bottom, right, top, left)
SIDES_COLUMNS = ("step", "t", "side", "fx", "fy")
CHECKPOINT_VERSION = 2  # 1: pickles (read only with allow_pickle=True); 2: npz + JSON (fluidem.checkpoint)

#: unit of each history column, in the scene's own unit system (see the module docstring)
HISTORY_UNITS = {"step": "1", "t": "time", "id": "1", "x": "length", "y": "length", "angle": "rad",
                 "vx": "length/time", "vy": "length/time", "omega": "rad/time", "fx": "force/depth",
                 "fy": "force/depth", "torque": "force*length/depth", "contacts": "1", "x_unwrapped": "length",
                 "y_unwrapped": "length"}

#: what a run writes into its output directory (and what overwriting it removes)
OUTPUT_ENTRIES = ("history.csv", "sides.csv", "events.log", "mesh_quality.csv", "fields.pvd", "fields_full.pvd",
                  "bodies.pvd", "fields", "fields_full", "fields.xdmf", "fields.h5", "fields_full.xdmf",
                  "fields_full.h5", "bodies", "checkpoints", "plots", "scene.toml", "run.json")


class OutputDirError(InputError):
    """The output directory cannot be used as asked (a file, under a file, or another run's output)."""


#: the lock file of an output directory (never removed: a waiting opener must find the same file)
LOCK_FILE = ".fluidem.lock"


def _make_dir(out_dir: PathLike) -> Path:
    """``out_dir`` as a Path, created with its parents; OutputDirError when that cannot be."""
    d = Path(out_dir)
    if d.exists() and not d.is_dir():
        raise OutputDirError(f"output directory {str(d)!r} is an existing file; expected a directory or a path "
                             "that does not exist yet")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        parent = next((p for p in d.parents if p.exists() and not p.is_dir()), d.parent)
        raise OutputDirError(f"output directory {str(d)!r}: {str(parent)!r} is a file, not a directory; expected a "
                             "path whose parents are directories") from None
    except OSError as exc:
        raise OutputDirError(f"output directory {str(d)!r} cannot be created ({exc.strerror or exc}); choose "
                             "another --out") from None
    return d


class RunLock:
    """One writer per output directory: an exclusive lock on ``<out_dir>/.fluidem.lock``.

    The lock is the operating system's (``fcntl.flock`` on POSIX, ``msvcrt.locking`` on
    Windows), so it is released when the holder ends, even by SIGKILL: a stale lock file
    never blocks a later run.  The holder writes its process id, host and start time into
    the file, and a refused run names them.

    Examples
    --------
    >>> import tempfile
    >>> d = tempfile.mkdtemp()
    >>> with RunLock(d):
    ...     try:
    ...         RunLock(d).acquire()
    ...     except OutputDirError as err:
    ...         print(str(err).split(" (")[0].endswith("is in use by another run"))
    True
    """

    def __init__(self, out_dir: PathLike):
        self.dir = Path(out_dir)
        self._fd = None

    def acquire(self) -> RunLock:
        """Take the lock (creating the directory), or raise :class:`OutputDirError` naming its holder."""
        import socket
        import time

        path = _make_dir(self.dir) / LOCK_FILE
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise OutputDirError(f"output directory {str(self.dir)!r}: cannot open its lock file {LOCK_FILE} "
                                 f"({exc.strerror or exc}); expected a writable directory") from None
        try:
            _lock(fd)
        except OSError:
            holder = os.read(fd, 200).decode("utf-8", "replace").strip() or "a process that has not said which"
            os.close(fd)
            raise OutputDirError(f"output directory {str(self.dir)!r} is in use by another run ({holder}); wait for "
                                 "it to end, or give another --out") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}, since "
                     f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode())
        self._fd = fd
        return self

    def release(self) -> None:
        """Let the lock go (idempotent); the file stays."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                os.ftruncate(fd, 0)
            except OSError:  # a read-only file system now: the OS lock goes with the descriptor anyway
                pass
            os.close(fd)

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _lock(fd: int) -> None:
    """An exclusive, non-blocking OS lock on ``fd`` (OSError when another holds it)."""
    try:
        import fcntl
    except ImportError:  # Windows
        import msvcrt

        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)


def prepare_output_dir(out_dir: PathLike, mode: str = "new") -> Path:
    """Make ``out_dir`` ready for a run and return it.

    Parameters
    ----------
    out_dir : path
        Created (with its parents) when missing.
    mode : {"new", "overwrite", "restart"}
        ``"new"``: refuse a directory that holds a run's output (a ``run.json``);
        ``"overwrite"``: remove the entries its ``run.json`` lists (and nothing else) first;
        ``"restart"``: keep them (the run continues).  In every mode a file or folder named
        like an output entry (:data:`OUTPUT_ENTRIES`) that no ``run.json`` lists is the
        user's: the run is refused rather than write over it.

    Raises
    ------
    OutputDirError
        (an :class:`~fluidem.errors.InputError`) naming the directory and the options.
    """
    if mode not in ("new", "overwrite", "restart"):
        raise fail("mode", mode, "one of 'new', 'overwrite', 'restart'")
    d = _make_dir(out_dir)
    rec = read_run_record(d)
    claimed = set(rec.get("entries", OUTPUT_ENTRIES)) if rec else set()  # a run.json before 'entries': all
    found = [e for e in OUTPUT_ENTRIES if (d / e).exists() or (d / e).is_symlink()]
    foreign = [e for e in found if e not in claimed]
    if foreign:
        raise OutputDirError(f"output directory {str(d)!r} holds {', '.join(foreign)}, which no run there wrote (no "
                             "run.json lists it); a run would write over it: move it away or give another --out")
    if mode == "new" and rec:
        who = f"scene {rec.get('scene')!r}, {rec.get('status', 'unknown')} at step {rec.get('step')}"
        raise OutputDirError(f"output directory {str(d)!r} holds the output of another run ({who}); give --overwrite "
                             "(overwrite=True) to clear it, --restart (restart=True) to continue it, or another --out")
    if mode == "overwrite":
        for e in found:
            p = d / e
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    return d


def read_run_record(out_dir: PathLike) -> dict:
    """The ``run.json`` record of an output directory (``{}`` when there is none or it is unreadable)."""
    try:
        rec = json.loads((Path(out_dir) / "run.json").read_text())
    except (OSError, ValueError):
        return {}
    return rec if isinstance(rec, dict) else {}


def write_run_record(out_dir: PathLike, record: dict) -> None:
    """Write ``run.json`` atomically (write, then rename), listing the run's ``entries``.

    When the directory no longer takes new files (made read-only, say) an existing
    ``run.json`` is written over in place, so its status does not stay ``running``; when
    that fails too, :class:`OutputDirError` names the directory.
    """
    path = Path(out_dir) / "run.json"
    text = json.dumps({**record, "entries": list(OUTPUT_ENTRIES)}, indent=1, allow_nan=False) + "\n"
    tmp = path.with_name("run.json.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        try:
            with open(path, "r+" if path.exists() else "x") as f:
                f.write(text)
                f.truncate()
        except OSError:
            raise OutputDirError(f"output directory {str(out_dir)!r}: run.json cannot be written "
                                 f"({exc.strerror or exc}); expected a writable directory with free space") from None


def fluid_point_data(space, x: np.ndarray, rho: float = 1.0) -> dict[str, np.ndarray]:
    """Velocity, speed and pressure at the mesh vertices, for VTU output.

    Velocity: the vertex DOFs (all element pairs here have nodal vertex values).  Pressure:
    the pressure basis evaluated at each element's vertices, averaged over the elements
    around a vertex (exact for a continuous pressure).

    Parameters
    ----------
    space : fluidem.fluid.space.FlowSpace
        Velocity/pressure spaces on the mesh (``n_u`` velocity DOFs first, then pressure).
    x : (space.n_dofs,) float
        Velocity (length/time) and kinematic pressure (p/ρ, length²/time²) DOFs.
    rho : float
        Fluid density (mass/length² in 2D): ``pressure`` is ρ times the kinematic one, the
        convention of the loads in history.csv.

    Returns
    -------
    dict
        ``"velocity"`` (n_vertices, 3) length/time with a zero z column, ``"speed"``
        (n_vertices,) length/time, ``"pressure"`` (n_vertices,) dynamic pressure (ρ p/ρ) and
        ``"kinematic_pressure"`` (n_vertices,) length²/time².
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
    return {"velocity": vel, "speed": np.hypot(vel[:, 0], vel[:, 1]), "pressure": rho * p, "kinematic_pressure": p}


#: subdivision of each triangle for the full-order output: 2 (quadratic "triangle6" cells) for a
#: P2 velocity with a P1 pressure, 3 (nine linear sub-triangles, nodes at the points i/3 of the
#: barycentric lattice) for cubic velocity spaces (P3, P2 + cubic bubble, P1 + cubic bubble)
FULL_ORDER_DIVISIONS = {"th": 2, "p3": 3, "p2b": 3, "mini": 3}


def _lattice(r: int):
    """Reference points (2, n_loc) of the barycentric lattice of order ``r`` on the triangle
    (0,0), (1,0), (0,1), their ``(a, b)`` indices (x = a/r, y = b/r) and the linear
    sub-triangles (r², 3) as local point indices, counter-clockwise."""
    ab = [(a, b) for b in range(r + 1) for a in range(r + 1 - b)]
    index = {q: k for k, q in enumerate(ab)}
    sub = [(index[a, b], index[a + 1, b], index[a, b + 1]) for (a, b) in ab if a + b <= r - 1]
    sub += [(index[a + 1, b], index[a + 1, b + 1], index[a, b + 1]) for (a, b) in ab if a + b <= r - 2]
    ab = np.array(ab)
    return ab.T / r, ab, np.array(sub)


def _lattice_numbering(t: np.ndarray, nv: int, ab: np.ndarray, r: int) -> np.ndarray:
    """Global indices (n_elements, n_loc) of the lattice points of every triangle ``t`` (3, m),
    shared between neighbours: a vertex point is its vertex, an edge point is numbered by the
    edge and its distance from the edge's lower-numbered vertex, interior points per element."""
    m = t.shape[1]
    a, b = ab[:, 0], ab[:, 1]
    c = r - a - b
    ids = np.empty((m, len(ab)), dtype=np.int64)
    corner = {(0, 0): 0, (r, 0): 1, (0, r): 2}
    for k, (ak, bk) in enumerate(ab):
        if (ak, bk) in corner:
            ids[:, k] = t[corner[ak, bk]]
    # edges: local (0,1) where b = 0, (1,2) where c = 0, (2,0) where a = 0; position from the first vertex
    local_edges = ((0, 1, (b == 0) & (a > 0) & (a < r), a), (1, 2, (c == 0) & (b > 0) & (b < r), b),
                   (2, 0, (a == 0) & (c > 0) & (c < r), c))
    pairs = np.concatenate([np.sort(t[[i, j]], axis=0) for i, j, _, _ in local_edges], axis=1)  # (2, 3m)
    _, edge_id = np.unique(pairs, axis=1, return_inverse=True)
    edge_id = edge_id.reshape(3, m)
    for e, (i, j, on, pos) in enumerate(local_edges):
        ks = np.flatnonzero(on)
        s = np.where((t[i] < t[j])[:, None], pos[ks][None, :], r - pos[ks][None, :])  # (m, len(ks))
        ids[:, ks] = nv + edge_id[e][:, None] * (r - 1) + (s - 1)
    inner = np.flatnonzero((a > 0) & (b > 0) & (c > 0))
    n_edges = int(edge_id.max()) + 1
    ids[:, inner] = nv + n_edges * (r - 1) + np.arange(m)[:, None] * len(inner) + np.arange(len(inner))[None, :]
    return ids


def _values_at(basis, coeffs: np.ndarray, X: np.ndarray) -> np.ndarray:
    """A finite element function (coefficients ``coeffs`` of ``basis``) at the reference points
    ``X`` (2, n_loc) of every element: (n_elements, n_loc) for a scalar field, (2, n_elements,
    n_loc) for a vector one (scikit-fem's global basis, so edge orientations are respected)."""
    C = coeffs[basis.element_dofs]  # (Nbfun, n_elements)
    out = 0.0
    for i in range(basis.Nbfun):  # a loop over the local basis functions (<= 20), not over elements
        out = out + np.asarray(basis.elem.gbasis(basis.mapping, X, i)[0]) * C[i][:, None]
    return np.asarray(out)


def full_order_fields(space, x: np.ndarray, rho: float = 1.0):
    """Velocity and pressure at full resolution, for VTU output.

    Every triangle is split by the barycentric lattice of order ``r`` =
    :data:`FULL_ORDER_DIVISIONS` of the element pair, and the fields are evaluated with the
    element's own basis at the lattice points (mapped by the element map, curved
    elements included).  P2/P1 (``r = 2``) gives one quadratic VTK ``triangle6`` cell per
    triangle: velocity and pressure are represented *exactly* (a P1 pressure is linear on
    it).  Cubic velocity spaces (``r = 3``) give nine linear triangles per triangle whose
    nodes carry the exact point values (the field between them is linear).  Lattice points
    shared by neighbouring triangles are written once; a discontinuous pressure (P2+bubble
    pair) is averaged over the triangles around a shared point.

    Parameters
    ----------
    space : fluidem.fluid.space.FlowSpace
    x : (space.n_dofs,) float
        Velocity (length/time) and kinematic pressure (length²/time²) DOFs.
    rho : float
        Fluid density: ``pressure`` is ρ times the kinematic one (see :func:`fluid_point_data`).

    Returns
    -------
    points : (n, 3) float
        Lattice points (length), z = 0.
    cells : list of (str, (k, q) int)
        ``[("triangle6", (m, 6))]`` or ``[("triangle", (9 m, 3))]``, counter-clockwise.
    point_data : dict
        ``velocity`` (n, 3), ``speed`` (n,), ``pressure`` (n,) dynamic and
        ``kinematic_pressure`` (n,), as in :func:`fluid_point_data`.
    cell_data : dict
        ``element``: index of the mesh triangle each cell belongs to.

    Examples
    --------
    >>> import numpy as np
    >>> from skfem import MeshTri
    >>> from fluidem.fluid.space import FlowSpace
    >>> space = FlowSpace(MeshTri(), "th")  # two triangles on the unit square
    >>> x = np.zeros(space.n_dofs)
    >>> x[:space.n_u] = space.ub.project(lambda X: np.array([X[0] ** 2, X[0] * X[1]]))
    >>> points, cells, pd, cd = full_order_fields(space, x)
    >>> cells[0][0], cells[0][1].shape, points.shape
    ('triangle6', (2, 6), (9, 3))
    >>> bool(np.allclose(pd["velocity"][:, 0], points[:, 0] ** 2))  # exact at the midpoints too
    True
    """
    mesh = space.mesh
    r = FULL_ORDER_DIVISIONS[space.element]
    X, ab, sub = _lattice(r)
    t = mesh.t
    nv = mesh.nvertices
    ids = _lattice_numbering(t, nv, ab, r)
    used, inv = np.unique(ids, return_inverse=True)
    loc = inv.reshape(ids.shape)  # (m, n_loc) compact point indices
    n = len(used)
    xy = np.asarray(space.ub.mapping.F(X))  # (2, m, n_loc)
    pts = np.zeros((n, 2))
    pts[loc.ravel()] = xy.reshape(2, -1).T
    U = _values_at(space.ub, x[: space.n_u], X)  # (2, m, n_loc)
    vel = np.zeros((n, 3))
    vel[loc.ravel(), 0], vel[loc.ravel(), 1] = U[0].ravel(), U[1].ravel()
    P = _values_at(space.pb, x[space.n_u:], X)  # (m, n_loc)
    p = np.bincount(loc.ravel(), P.ravel(), minlength=n) / np.maximum(np.bincount(loc.ravel(), minlength=n), 1)
    pc = mesh.p[:, t]  # (2, 3, m) corners
    cw = ((pc[0, 1] - pc[0, 0]) * (pc[1, 2] - pc[1, 0]) - (pc[1, 1] - pc[1, 0]) * (pc[0, 2] - pc[0, 0])) < 0
    if r == 2:  # VTK triangle6: corners 0, 1, 2, then the midpoints of edges 01, 12, 20
        k = {tuple(q): i for i, q in enumerate(ab)}
        order = np.array([k[0, 0], k[2, 0], k[0, 2], k[1, 0], k[1, 1], k[0, 1]])
        flip = np.array([k[0, 0], k[0, 2], k[2, 0], k[0, 1], k[1, 1], k[1, 0]])
        conn = np.where(cw[:, None], loc[:, flip], loc[:, order])
        cells, element = [("triangle6", conn)], np.arange(len(conn))
    else:
        tri = loc[:, sub]  # (m, r², 3)
        tri = np.where(cw[:, None, None], tri[:, :, ::-1], tri)
        cells, element = [("triangle", tri.reshape(-1, 3))], np.repeat(np.arange(t.shape[1]), len(sub))
    pd = {"velocity": vel, "speed": np.hypot(vel[:, 0], vel[:, 1]), "pressure": rho * p, "kinematic_pressure": p}
    return _points3(pts), cells, pd, {"element": [element.astype(float)]}


def _points3(p2):
    p2 = np.asarray(p2, dtype=float)
    return np.column_stack([p2, np.zeros(len(p2))])


class OutputWriter:
    """Writes one run's output directory (see the module docstring for the layout).

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
        (dynamic), ``kinematic_pressure`` (units in the module docstring); its
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


def require_h5py(what: str = "XDMF output") -> None:
    """Raise :class:`fluidem.errors.InputError` naming the ``xdmf`` extra if h5py is missing."""
    try:
        import h5py  # noqa: F401
    except ImportError:
        raise InputError(f'{what} needs h5py: {install_hint("xdmf")}') from None


def _TimeSeriesWriter(path: Path):
    """``meshio.xdmf.TimeSeriesWriter`` with its HDF5 file beside the XDMF file (meshio 5.3
    puts it in the working directory)."""
    import h5py
    import meshio

    class Writer(meshio.xdmf.TimeSeriesWriter):
        def __enter__(self):
            self.h5_filename = str(self.filename.with_suffix(".h5"))
            self.h5_file = h5py.File(self.h5_filename, "w")
            return self

    return Writer(path)


def write_xdmf(out_dir: PathLike, full: bool = True) -> Path:
    """Collect a run's field series into one XDMF time series (``<series>.xdmf`` + ``.h5``).

    Parameters
    ----------
    out_dir : path
        Output directory of a fluid run.
    full : bool
        The full-resolution series when the run wrote one (see :func:`field_series`).

    Returns
    -------
    Path
        The ``.xdmf`` file: the mesh once, then ``velocity``, ``speed``, ``pressure`` and
        ``kinematic_pressure`` (point data, units as in the VTU files) at every output time;
        read it with ``meshio.xdmf.TimeSeriesReader`` or open it in ParaView.

    Raises
    ------
    InputError
        Without h5py (naming the ``xdmf`` extra), for a directory without fields, or when the
        mesh changes between steps (a moving mesh: read the VTU series with :func:`read_fields`).
    """
    import meshio

    require_h5py()
    series = field_series(out_dir, full)
    if not series:
        raise fail("output directory", str(out_dir), "the directory of a fluid run that wrote fields (fields.pvd)")
    name = series[0][2].parent.name  # fields_full or fields
    path = Path(out_dir) / f"{name}.xdmf"
    first = meshio.read(series[0][2])
    changed = None
    with _TimeSeriesWriter(path) as w:
        w.write_points_cells(first.points, first.cells)
        for step, t, f in series:
            m = first if f == series[0][2] else meshio.read(f)
            if m.points.shape != first.points.shape or not np.array_equal(m.points, first.points) or \
                    any(not np.array_equal(a.data, b.data) for a, b in zip(m.cells, first.cells)):
                changed = step
                break
            w.write_data(t, point_data=m.point_data)
    if changed is not None:  # no half series left behind
        path.unlink(missing_ok=True)
        path.with_suffix(".h5").unlink(missing_ok=True)
        raise InputError(f"{name}: the mesh changes at step {changed} (a moving mesh); an XDMF time series holds "
                         "one mesh: read the VTU series with fluidem.io.read_fields instead")
    return path


def _history_header() -> str:
    """The column line of history.csv (units: :data:`HISTORY_UNITS`, also in run.json)."""
    return ",".join(HISTORY_COLUMNS) + "\n"


def latest_checkpoint(out_dir: PathLike) -> Path:
    """Newest checkpoint file in ``out_dir/checkpoints`` (not checked; see :func:`load_latest_checkpoint`).

    Raises :class:`fluidem.errors.InputError` (a ``ValueError``) if there is none.
    """
    files = checkpoint_files(out_dir)
    if not files:
        d = Path(out_dir) / "checkpoints"
        legacy = sorted(d.glob("ckpt_*.pkl")) if d.is_dir() else []
        raise fail("checkpoint directory", str(d), "a directory holding ckpt_*.npz files written by 'fluidem run'"
                   + (f" (it holds {len(legacy)} pickle checkpoint(s) of an earlier version: give one of them as "
                      "the checkpoint file, with allow_pickle=True, and only if you wrote it)" if legacy else ""))
    return files[0]


def load_checkpoint(path: PathLike, allow_pickle: bool = False) -> dict:
    """Read a checkpoint written by :meth:`OutputWriter.checkpoint` (a run directory: its newest valid one).

    Returns the state with ``version``, ``step``, ``t`` (s) and the header (``scene``,
    ``dt``, ``plan``).  Raises :class:`fluidem.checkpoint.CheckpointError` (an
    :class:`~fluidem.errors.InputError`) for a missing, damaged or foreign file.  Pickle
    checkpoints of earlier versions (``.pkl``) are read only with ``allow_pickle=True``
    (loading a pickle can execute code: only for files you wrote).
    """
    path = Path(path)
    if path.is_dir():
        return load_latest_checkpoint(path)[1]
    if path.suffix == ".pkl":
        if not allow_pickle:
            raise CheckpointError(f"checkpoint {str(path)!r} is a pickle of an earlier fluidem version; loading a "
                                  "pickle can execute code: pass allow_pickle=True only for a file you wrote")
        try:
            with open(path, "rb") as f:
                data = pickle.load(f)
        except FileNotFoundError:
            raise fail("checkpoint", str(path), "an existing checkpoint file") from None
        except Exception as exc:  # a damaged pickle raises many kinds
            raise CheckpointError(f"checkpoint {str(path)!r} is damaged ({type(exc).__name__})") from None
        if not isinstance(data, dict) or data.get("version") != 1:
            raise fail("checkpoint", str(path), "a fluidem pickle checkpoint of version 1")
        return data
    header, state = _load_npz(path)
    if header.get("version") != CHECKPOINT_VERSION or not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {str(path)!r}: version {header.get('version')!r}; expected a fluidem "
                              f"checkpoint of version {CHECKPOINT_VERSION}")
    return {**header, **state}


def load_latest_checkpoint(out_dir: PathLike) -> tuple[Path, dict, list]:
    """The newest *valid* checkpoint of a run directory: ``(path, data, skipped)``.

    A damaged newer checkpoint (empty, truncated, not a checkpoint) is skipped; ``skipped``
    lists ``(path, reason)`` of each one skipped.  Raises
    :class:`fluidem.checkpoint.CheckpointError` when none is valid.
    """
    skipped = []
    files = checkpoint_files(out_dir) or [latest_checkpoint(out_dir)]
    for path in files:
        try:
            return path, load_checkpoint(path), skipped
        except CheckpointError as exc:
            skipped.append((path, str(exc)))
    raise CheckpointError(f"no valid checkpoint in {str(Path(out_dir) / 'checkpoints')!r}: "
                          + "; ".join(r for _, r in skipped))
