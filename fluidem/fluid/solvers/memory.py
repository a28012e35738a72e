"""Will an LU fit?  The memory a sparse LU of an ``n``-DOF fluidem system needs, and the memory free.

The entries of L + U grow faster than the DOFs.  Measured on the coupled systems of settling
suspensions (P2+bubble/P1dc, ``benchmarks/results/solver_scale.md``; one process per
factorisation, its peak resident memory with the matrix):

=======  ============================  ==============================
DOFs     SuperLU (COLAMD, 0.01)        PARDISO (METIS)
=======  ============================  ==============================
149 285  78.2M entries, 1 877 MiB      19.5M entries, 536 MiB
446 752  312M entries, 7 173 MiB       63.6M entries, 1 347 MiB
=======  ============================  ==============================

so fill ∝ n^1.26 for SuperLU and ∝ n^1.08 for PARDISO (nested dissection: n log n for 2D
meshes, George 1973), and the peak is about 24 bytes per entry of the factors for either (the
values, the indices and the work space).  :func:`predicted_lu_bytes` extrapolates from the
larger system; :func:`lu_fits` compares with the memory the operating system says is
available (``MemAvailable`` of ``/proc/meminfo``; unknown elsewhere: assumed to fit).

Examples
--------
>>> round(predicted_lu_bytes(446_752, "superlu") / 2**30, 1)
7.0
>>> predicted_lu_bytes(3_000_000, "pardiso") < predicted_lu_bytes(3_000_000, "superlu") / 5
True
>>> lu_fits(3_000_000, "superlu", available_bytes=24 * 2**30)[0]
False
"""

from __future__ import annotations

import pathlib

__all__ = ["predicted_lu_bytes", "lu_fits", "available_bytes", "LU_FILL_MODEL", "LU_MEMORY_FRACTION"]

#: per backend: (reference DOFs, entries of L + U there, growth exponent, peak bytes per entry)
LU_FILL_MODEL = {"superlu": (446_752, 312.2e6, 1.26, 24.0), "pardiso": (446_752, 63.6e6, 1.08, 24.0)}
#: an LU is used only while its predicted peak stays below this fraction of the available memory
LU_MEMORY_FRACTION = 0.7


def predicted_lu_bytes(n_dofs: int, backend: str) -> float:
    """Predicted peak memory (bytes) of factorising an ``n_dofs`` system with ``backend``
    (``"superlu"`` or ``"pardiso"``), from :data:`LU_FILL_MODEL`."""
    n_ref, fill_ref, exponent, per_entry = LU_FILL_MODEL[backend]
    return per_entry * fill_ref * (n_dofs / n_ref) ** exponent


def available_bytes() -> float | None:
    """Memory available to a new allocation (``MemAvailable``), bytes; ``None`` where unknown."""
    try:
        for line in pathlib.Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return 1024.0 * float(line.split()[1])
    except OSError:
        pass
    return None


def lu_fits(n_dofs: int, backend: str, available_bytes: float | None = None) -> tuple[bool, str]:
    """Whether an LU of ``n_dofs`` DOFs with ``backend`` fits in :data:`LU_MEMORY_FRACTION` of
    the available memory (``available_bytes``, default :func:`available_bytes`), and one line why."""
    need = predicted_lu_bytes(n_dofs, backend)
    avail = globals()["available_bytes"]() if available_bytes is None else available_bytes
    if avail is None:
        return True, f"{backend} LU of {n_dofs} DOFs: ~{need / 2**30:.3g} GiB predicted, available memory unknown"
    fits = need <= LU_MEMORY_FRACTION * avail
    return fits, (f"{backend} LU of {n_dofs} DOFs: ~{need / 2**30:.3g} GiB predicted, "
                  f"{avail / 2**30:.3g} GiB available ({'fits' if fits else 'does not fit'} in "
                  f"{LU_MEMORY_FRACTION:.0%})")
