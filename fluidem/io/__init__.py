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

# the submodules, one concept each; the names below are the public ones (those not in __all__
# are kept importable from here for code that imported them)
from . import layout as _layout
from . import outdir as _outdir
from .checkpoints import CHECKPOINT_VERSION as CHECKPOINT_VERSION
from .checkpoints import latest_checkpoint, load_checkpoint, load_latest_checkpoint
from .layout import HISTORY_COLUMNS
from .layout import PathLike as PathLike
from .outdir import OutputDirError, RunLock, prepare_output_dir, read_run_record, write_run_record
from .readers import field_series, read_fields, read_history, read_pvd, read_sides
from .sampling import FULL_ORDER_DIVISIONS as FULL_ORDER_DIVISIONS
from .sampling import fluid_point_data, full_order_fields
from .writer import OutputWriter
from .xdmf import require_h5py as require_h5py
from .xdmf import write_xdmf

# The public constants, each with its doc comment here, where the API reference reads it (the
# values are those of the modules that define them).
#: columns of sides.csv (``side`` is the side's name: bottom, right, top, left)
SIDES_COLUMNS = _layout.SIDES_COLUMNS
#: unit of each history column, in the scene's own unit system (see the module docstring)
HISTORY_UNITS = _layout.HISTORY_UNITS
#: what a run writes into its output directory (and what overwriting it removes)
OUTPUT_ENTRIES = _layout.OUTPUT_ENTRIES
#: the lock file of an output directory (never removed: a waiting opener must find the same file)
LOCK_FILE = _outdir.LOCK_FILE

__all__ = ["OutputWriter", "read_history", "read_sides", "SIDES_COLUMNS",
           "read_pvd", "latest_checkpoint", "load_checkpoint", "load_latest_checkpoint",
           "fluid_point_data", "full_order_fields", "read_fields", "field_series", "write_xdmf", "prepare_output_dir",
           "read_run_record", "write_run_record", "HISTORY_COLUMNS", "HISTORY_UNITS", "OUTPUT_ENTRIES",
           "OutputDirError", "RunLock", "LOCK_FILE"]
