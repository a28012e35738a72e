"""What a linear solve reports: :class:`SolveInfo`, and the error raised when it fails.

Every solver of :mod:`fluidem.fluid.solvers` records a :class:`SolveInfo` in its
``last_info`` after each ``solve``; a solve that misses its tolerance raises
:class:`LinearSolverError` (also importable as ``SolverError``), a subclass of
:class:`fluidem.errors.SolverError` whose message ends with a summary of the residual
history and whose ``info`` is the :class:`SolveInfo` of the failed solve.

Examples
--------
>>> import numpy as np
>>> info = SolveInfo("superlu", n=12, residuals=np.array([1.0, 3e-14]),
...                  relative_residual=3e-14)
>>> print(info)
SolveInfo(superlu, n=12, iterations=0, relative_residual=3.00e-14, setup=0 s, solve=0 s)
>>> err = LinearSolverError("GMRES did not converge", info)
>>> print(err)
GMRES did not converge
  relative residual history (2 entries): 1.00e+00, 3.00e-14
>>> import fluidem.errors
>>> isinstance(err, fluidem.errors.SolverError), err.info is info
(True, True)
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from ...errors import SolverError as _FluidemSolverError

__all__ = ["SolveInfo", "LinearSolverError", "SolverError", "add_observer", "remove_observer"]


@dataclass
class SolveInfo:
    """What one solve did.

    Attributes
    ----------
    method : str
        Short description, e.g. ``"superlu"`` or
        ``"gmres+tri(amg, cahouet-chabard)"``.
    n : int
        Size of the system, ``n_u + n_p``.
    iterations : int
        Krylov iterations (preconditioner applications); 0 for a direct solve.
    residuals : (k,) float ndarray
        History of relative residual norms ``||b - K x_i|| / ||b||``
        (Krylov estimates inside a cycle, true residuals at cycle ends).
    relative_residual : float
        True final relative residual ``||b - K x||_2 / ||b||_2``.
    setup_s : float
        Seconds spent in the last ``factorize`` (LU, AMG setup), wall clock.
    solve_s : float
        Seconds spent in this ``solve``, wall clock.
    reused_setup : bool
        Whether ``factorize`` reused an earlier LU or AMG hierarchy.
    factorizations : int
        LU factorisations done so far by this solver object.
    note : str
        Free text (refactorisation, fallbacks).
    """

    method: str
    n: int
    iterations: int = 0
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    relative_residual: float = math.nan
    setup_s: float = 0.0
    solve_s: float = 0.0
    reused_setup: bool = False
    factorizations: int = 0
    note: str = ""

    def __str__(self) -> str:
        s = (
            f"SolveInfo({self.method}, n={self.n}, iterations={self.iterations}, "
            f"relative_residual={self.relative_residual:.2e}, setup={self.setup_s:.3g} s, "
            f"solve={self.solve_s:.3g} s"
        )
        if self.reused_setup:
            s += ", reused setup"
        if self.factorizations:
            s += f", factorizations={self.factorizations}"
        if self.note:
            s += f", {self.note}"
        return s + ")"


class LinearSolverError(_FluidemSolverError):
    """A linear solve failed: singular matrix, no convergence or stagnation.

    A :class:`fluidem.errors.SolverError` (so also a ``RuntimeError``); the message ends
    with a one-line summary of the relative residual history when there is one.

    Parameters
    ----------
    message : str
        What failed, naming the method and the tolerance.
    info : SolveInfo, optional
        State of the failed solve.

    Attributes
    ----------
    info : SolveInfo or None
        State of the failed solve (residual history included).
    """

    def __init__(self, message: str, info: SolveInfo | None = None):
        if info is not None and info.residuals.size:
            message = f"{message}\n  {_history_summary(info.residuals)}"
        super().__init__(message, info)


#: The name under which :class:`LinearSolverError` has always been imported.
SolverError = LinearSolverError


def _history_summary(res: np.ndarray) -> str:
    """``"relative residual history (k entries): r0, r1, ..."``: all of up to 8 entries, else
    the first 3 and the last 4."""
    res = np.asarray(res)
    if res.size <= 8:
        shown = ", ".join(f"{r:.2e}" for r in res)
    else:
        head = ", ".join(f"{r:.2e}" for r in res[:3])
        tail = ", ".join(f"{r:.2e}" for r in res[-4:])
        shown = f"{head}, ..., {tail}"
    return f"relative residual history ({res.size} entries): {shown}"


# --------------------------------------------------------------------------
# observers: who wants to hear of every solve and every LU (fluidem.diagnostics)
# --------------------------------------------------------------------------
_local = threading.local()


def add_observer(observer) -> None:
    """Tell ``observer`` of every solve and LU factorisation in this thread from now on.

    ``observer.solved(info)`` gets the :class:`SolveInfo` of each solve (Krylov or direct, also
    failed ones), ``observer.factorized(solver)`` the :class:`~.direct.DirectSolver` that has just
    computed an LU (its ``K`` and factors are current).  Solvers hold no reference to observers;
    :func:`remove_observer` ends the watch.
    """
    _local.observers = (*getattr(_local, "observers", ()), observer)


def remove_observer(observer) -> None:
    """Stop telling ``observer`` (see :func:`add_observer`); nothing if it is not watching."""
    _local.observers = tuple(o for o in getattr(_local, "observers", ()) if o is not observer)


def _notify_solve(info: SolveInfo) -> None:
    for o in getattr(_local, "observers", ()):
        o.solved(info)


def _notify_factorization(solver) -> None:
    for o in getattr(_local, "observers", ()):
        o.factorized(solver)
