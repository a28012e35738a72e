"""Will an LU fit?  The memory a sparse LU of an ``n``-DOF fluidem system needs, and the memory free.

The entries of L + U grow faster than the DOFs.  Measured on the coupled systems of settling
suspensions (P2+bubble/P1dc, ``benchmarks/results/solver_scale.md`` and, for PARDISO without weighted
matching, the default, ``benchmarks/results/pardiso_matching.md``):

=========  ============================  ==============================  ==============================
DOFs       SuperLU (COLAMD, 0.01)        PARDISO (METIS)                 PARDISO with matching
=========  ============================  ==============================  ==============================
149 285    78.2M entries, 1 877 MiB      9.10M entries, 238 MiB          19.6M entries, 326 MiB
446 752    312M entries, 7 173 MiB       30.1M entries, 737 MiB          64.5M entries, 1 022 MiB
1 486 304  –                             111M entries, 2 541 MiB         238M entries, 3 583 MiB
3 146 586  –                             –                               532M entries, 7 604 MiB
=========  ============================  ==============================  ==============================

(SuperLU: the peak of a process factorising the matrix; PARDISO: MKL's own peak of the analysis and
factorisation, ``iparm(15..17)``.)  So fill ∝ n^1.26 for SuperLU and ∝ n^1.09 for PARDISO (nested
dissection: n log n for 2D meshes, George 1973; 1.09 from 149k to 447k DOFs and from 447k to 1.49M
without matching; with it 1.08 and 1.10, which predicted 3.15M within 2.7 %).  A factorisation adds
about 24 bytes per entry of the factors for SuperLU (the values, the indices and the work space) and
25 for PARDISO: MKL's peak was 27.5, 25.7 and 24.0 bytes per entry at 149k, 447k and 1.49M DOFs
(with matching, whose factors are twice as large for the same analysis work, 15.0–17.5).
:func:`predicted_lu_bytes` extrapolates from the largest system of each; :func:`lu_fits` compares
with the memory the operating system says is available (``MemAvailable`` of ``/proc/meminfo``;
unknown elsewhere: assumed to fit).

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

__all__ = ["predicted_lu_bytes", "lu_fits", "available_bytes", "LU_FILL_MODEL", "LU_MEMORY_FRACTION",
           "LU_HEADROOM_BYTES_PER_DOF"]

#: per backend: (reference DOFs, entries of L + U there, growth exponent, peak bytes per entry)
LU_FILL_MODEL = {"superlu": (446_752, 312.2e6, 1.26, 24.0), "pardiso": (1_486_304, 111.2e6, 1.09, 25.0)}
#: what a run needs beyond its LU, bytes per DOF, on top of what it holds when the LU is chosen: a
#: re-triangulation builds the new problem while the old one lives (1 000 and 2 000 settling polygons
#: with a lagged PARDISO LU, 1.57M and 3.15M DOFs: its step peaked 1.5 and 1.3 kB a DOF above an
#: ordinary step's, and the resident memory stayed 0.5 and 0.7 kB a DOF higher after it)
LU_HEADROOM_BYTES_PER_DOF = 2.5e3
#: an LU is used only while its predicted peak and the headroom stay below this fraction of the
#: available memory (3.15M DOFs with PARDISO on a 24 GB machine: 12 GiB available after the set-up,
#: the LU and a re-triangulation took all but 1 GiB of it: the rule now refuses that LU there)
LU_MEMORY_FRACTION = 0.9


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


def lu_fits(n_dofs: int, backend: str, available_bytes: float | None = None,
            freed_bytes: float = 0.0) -> tuple[bool, str]:
    """Whether an LU of ``n_dofs`` DOFs with ``backend`` and the run's headroom
    (:data:`LU_HEADROOM_BYTES_PER_DOF`) fit in :data:`LU_MEMORY_FRACTION` of the available memory
    (``available_bytes``, default :func:`available_bytes`, plus ``freed_bytes``: memory the caller
    releases before factorising, such as the PARDISO LU it holds), and one line why.

    >>> lu_fits(1_000_000, "pardiso", available_bytes=4 * 2**30)[0]
    False
    >>> lu_fits(1_000_000, "pardiso", available_bytes=4 * 2**30, freed_bytes=2 * 2**30)[0]
    True
    """
    need = predicted_lu_bytes(n_dofs, backend)
    avail = globals()["available_bytes"]() if available_bytes is None else available_bytes
    if avail is None:
        return True, f"{backend} LU of {n_dofs} DOFs: ~{need / 2**30:.3g} GiB predicted, available memory unknown"
    avail += freed_bytes
    headroom = LU_HEADROOM_BYTES_PER_DOF * n_dofs
    fits = need + headroom <= LU_MEMORY_FRACTION * avail
    held = " with the LU held" if freed_bytes else ""
    return fits, (f"{backend} LU of {n_dofs} DOFs: ~{need / 2**30:.3g} GiB predicted and {headroom / 2**30:.3g} GiB "
                  f"for the rest of the run, {avail / 2**30:.3g} GiB available{held} "
                  f"({'fits' if fits else 'does not fit'} in {LU_MEMORY_FRACTION:.0%})")
