"""The exception family of fluidem; the command line catches :class:`FluidemError` as a whole.

Every error raised at the boundary of the package for something a user typed or built names
the offending value and what is allowed, in one line.

* :class:`InputError` — a value is not allowed (a name, a range, a shape); also a
  :class:`ValueError`, so ``except ValueError`` keeps working.
* :class:`SceneError` — an :class:`InputError` in a scene description (file or dict).
* :class:`MeshError` — the geometry cannot be meshed as asked (bodies too close to a wall,
  a triangulation that fails); also a :class:`RuntimeError`.
* :class:`SolverError` — a linear or nonlinear solve failed (singular matrix, no
  convergence, stagnation); also a :class:`RuntimeError`.
* :class:`RunStopped` — a run stopped before its end (interrupted, or a step failed), its
  output closed at the last good step.
* :class:`RunWarning` — not an error: something a run did that its output should say.

Examples
--------
>>> from fluidem.errors import FluidemError, SceneError
>>> try:
...     raise SceneError("fluid.viscosity = -1: expected a positive finite number")
... except FluidemError as err:
...     print(type(err).__name__, isinstance(err, ValueError))
SceneError True
"""

from __future__ import annotations

__all__ = ["FluidemError", "InputError", "SceneError", "MeshError", "SolverError", "RunStopped", "RunWarning",
           "install_hint", "one_line"]


def install_hint(extra: str) -> str:
    """How to add an optional extra, for the message of a missing dependency: the plain form and the
    editable one (a plain ``pip install ".[extra]"`` replaces an editable checkout by a copy).

    >>> install_hint("plot")
    'pip install "fluidem[plot]" (in an editable checkout: pip install -e ".[plot]")'
    """
    return f'pip install "fluidem[{extra}]" (in an editable checkout: pip install -e ".[{extra}]")'


def one_line(exc: BaseException) -> str:
    r"""The message of ``exc`` on one line (its type's name when it has none), for events.log and run.json.

    >>> one_line(OSError("disk\nfull")), one_line(MemoryError())
    ('disk full', 'MemoryError')
    """
    return " ".join(str(exc).splitlines()) or type(exc).__name__


class FluidemError(Exception):
    """Base class of every error fluidem raises on purpose."""


class InputError(FluidemError, ValueError):
    """A value given to fluidem is not allowed; the message names it and what is allowed."""


class SceneError(InputError):
    """A scene description (TOML file, dict or CSV table) holds a value that is not allowed."""


class MeshError(FluidemError, RuntimeError):
    """The geometry cannot be meshed as asked; the message says which body, gap or setting."""


class SolverError(FluidemError, RuntimeError):
    """A linear or nonlinear solve failed: singular matrix, no convergence or stagnation.

    Attributes
    ----------
    info : object or None
        State of the failed solve (for linear solves a ``SolveInfo`` with the residual
        history), when known.
    """

    def __init__(self, message: str, info=None):
        super().__init__(message)
        self.info = info


class RunStopped(FluidemError):
    """A run stopped before its end: interrupted (SIGINT/SIGTERM) or a step failed.

    The :class:`~fluidem.simulation.Simulation` itself is left where it stopped (after a failed
    step: in the bad state); continue with a new one, ``Simulation(scene).run(out_dir, restart=True)``.

    Attributes
    ----------
    status : {"interrupted", "failed"}
    exit_status : int
        130 (SIGINT), 143 (SIGTERM) or 3 (a failed step): the command line's exit status.
    checkpoint : Path or None
        The checkpoint of the last good step.
    """

    def __init__(self, message, status="failed", exit_status=3, checkpoint=None):
        super().__init__(message)
        self.status = status
        self.exit_status = exit_status
        self.checkpoint = checkpoint


class RunWarning(UserWarning):
    """Something a run did that its output should say: a damaged checkpoint skipped, a coarse mesh."""
