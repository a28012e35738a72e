"""What an output directory holds: the entries a run writes into it and the columns of its
tables (the layout itself is described in :mod:`fluidem.io`).
"""

from __future__ import annotations

import os
from typing import Union

__all__ = ["PathLike", "HISTORY_COLUMNS", "SIDES_COLUMNS", "HISTORY_UNITS", "OUTPUT_ENTRIES"]


PathLike = Union[str, os.PathLike]

#: columns of history.csv, one row per recorded step and body
HISTORY_COLUMNS = ("step", "t", "id", "x", "y", "angle", "vx", "vy", "omega", "fx", "fy", "torque", "contacts",
                   "x_unwrapped", "y_unwrapped")
#: the columns before ``x_unwrapped``, ``y_unwrapped`` were added (a restart pads such rows)
_HISTORY_COLUMNS_BEFORE_UNWRAPPED = HISTORY_COLUMNS[:-2]
#: columns of sides.csv (``side`` is the side's name: bottom, right, top, left)
SIDES_COLUMNS = ("step", "t", "side", "fx", "fy")

#: unit of each history column, in the scene's own unit system (see :mod:`fluidem.io`)
HISTORY_UNITS = {"step": "1", "t": "time", "id": "1", "x": "length", "y": "length", "angle": "rad",
                 "vx": "length/time", "vy": "length/time", "omega": "rad/time", "fx": "force/depth",
                 "fy": "force/depth", "torque": "force*length/depth", "contacts": "1", "x_unwrapped": "length",
                 "y_unwrapped": "length"}

#: what a run writes into its output directory (and what overwriting it removes)
OUTPUT_ENTRIES = ("history.csv", "sides.csv", "events.log", "mesh_quality.csv", "fields.pvd", "fields_full.pvd",
                  "bodies.pvd", "fields", "fields_full", "fields.xdmf", "fields.h5", "fields_full.xdmf",
                  "fields_full.h5", "bodies", "checkpoints", "plots", "scene.toml", "run.json")


def _history_header() -> str:
    """The column line of history.csv (units: :data:`HISTORY_UNITS`, also in run.json)."""
    return ",".join(HISTORY_COLUMNS) + "\n"
