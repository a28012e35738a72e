"""A run's field series as one XDMF time series (:func:`write_xdmf`, needs h5py: the ``xdmf``
extra).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError, install_hint
from ..validate import fail
from .layout import PathLike
from .readers import field_series

__all__ = ["require_h5py", "write_xdmf"]


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
