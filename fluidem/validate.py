"""Validation helpers shared by scenes, the moving mesh and the DEM.

Each helper checks one value and returns it converted (``float``, ``int``, a pair), or
raises :class:`fluidem.errors.InputError` (a :class:`ValueError`) whose one-line message
names where the value was typed, the value and what is allowed::

    fluid.viscosity = -1: expected a positive finite number

``key`` is the dotted place of the value (``"fluid.viscosity"`` in a scene,
``"MovingMesh(h=...)"``-style names in Python APIs).  ``error`` chooses the exception class
(e.g. :class:`fluidem.errors.SceneError` for scene files).

Examples
--------
>>> from fluidem.validate import positive, integer
>>> positive("mesh.h", 0.05)
0.05
>>> integer("mesh.retriangulate_every", 0)
Traceback (most recent call last):
...
fluidem.errors.InputError: mesh.retriangulate_every = 0: expected an integer >= 1
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError

__all__ = ["fail", "number", "positive", "nonnegative", "fraction", "integer", "pair", "choice", "boolean",
           "check_keys", "nearest"]

_REAL = (int, float, np.integer, np.floating)


def fail(key: str, value, allowed: str, error=InputError) -> Exception:
    """The error ``"{key} = {value!r}: expected {allowed}"`` (returned, for ``raise``)."""
    return error(f"{key} = {value!r}: expected {allowed}")


def number(key: str, value, allowed: str = "a finite number", lo=None, lo_open: bool = False, hi=None,
           hi_open: bool = False, error=InputError) -> float:
    """A finite real number, optionally bounded below by ``lo`` and above by ``hi``."""
    if isinstance(value, bool) or not isinstance(value, _REAL):
        raise fail(key, value, allowed, error)
    v = float(value)
    if not math.isfinite(v):
        raise fail(key, value, allowed, error)
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise fail(key, value, allowed, error)
    if hi is not None and (v >= hi if hi_open else v > hi):
        raise fail(key, value, allowed, error)
    return v


def positive(key: str, value, error=InputError) -> float:
    """A finite number > 0."""
    return number(key, value, "a positive finite number", lo=0.0, lo_open=True, error=error)


def nonnegative(key: str, value, error=InputError) -> float:
    """A finite number >= 0."""
    return number(key, value, "a finite number >= 0", lo=0.0, error=error)


def fraction(key: str, value, lo_open: bool = False, hi_open: bool = False, error=InputError) -> float:
    """A number in [0, 1] (ends excluded with ``lo_open``/``hi_open``)."""
    allowed = f"a number in {'(' if lo_open else '['}0, 1{')' if hi_open else ']'}"
    return number(key, value, allowed, lo=0.0, lo_open=lo_open, hi=1.0, hi_open=hi_open, error=error)


def integer(key: str, value, lo: int = 1, error=InputError, hi: int | None = None) -> int:
    """An integer >= ``lo`` (and <= ``hi`` when given; booleans are not integers here)."""
    if (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo
            or (hi is not None and value > hi)):
        raise fail(key, value, f"an integer >= {lo}" if hi is None else f"an integer from {lo} to {hi}", error)
    return int(value)


def pair(key: str, value, error=InputError) -> tuple[float, float]:
    """Two finite numbers ``[x, y]``, returned as a tuple of floats."""
    if (not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2
            or not all(isinstance(v, _REAL) and not isinstance(v, bool) and math.isfinite(float(v))
                       for v in value)):
        raise fail(key, value, "a pair of finite numbers [x, y]", error)
    return (float(value[0]), float(value[1]))


def choice(key: str, value, allowed, error=InputError):
    """One of ``allowed`` (for user-typed names use :func:`fluidem.names.lookup`, which knows aliases)."""
    if value not in allowed:
        raise fail(key, value, "one of " + ", ".join(repr(a) for a in allowed), error)
    return value


def boolean(key: str, value, error=InputError) -> bool:
    """``True`` or ``False`` (not 0/1)."""
    if not isinstance(value, bool):
        raise fail(key, value, "true or false", error)
    return value


def nearest(value: str, allowed) -> str | None:
    """The name of ``allowed`` closest to ``value`` (case ignored, :mod:`difflib`), or ``None`` if none is close.

    >>> nearest("viscocity", ("density", "viscosity", "model"))
    'viscosity'
    >>> nearest("e", ("E", "mu", "gamma"))
    'E'
    >>> nearest("colour", ("density", "viscosity")) is None
    True
    """
    import difflib

    if not isinstance(value, str):
        return None
    lower = {str(a).lower(): a for a in allowed}
    if value.lower() in lower:
        return lower[value.lower()]
    close = difflib.get_close_matches(value.lower(), list(lower), n=1, cutoff=0.6)
    return lower[close[0]] if close else None


def check_keys(table: dict, allowed, where: str, error=InputError, hints: dict | None = None) -> None:
    """Every key of ``table`` is in ``allowed``; ``where`` is the table's name (``""``: top level).

    An unknown key's message names the key, its value, the nearest allowed key (or the hint
    ``hints[key]``, for keys that belong elsewhere) and every allowed key::

        unknown key fluid.viscocity = 0.01 (did you mean fluid.viscosity?); allowed keys in [fluid]: ...
    """
    if not isinstance(table, dict):
        raise fail(where, table, "a table", error)
    unknown = [k for k in table if k not in allowed]
    if unknown:
        k = unknown[0]
        prefix = where + "." if where else ""
        best = nearest(k, allowed)
        if hints and k in hints:
            tip = f" ({hints[k]})"
        elif best is not None:
            tip = f" (did you mean {prefix}{best}?)"
        else:
            tip = ""
        raise error(f"unknown key {prefix}{k} = {table[k]!r}{tip}; "
                    f"allowed keys{' in [' + where + ']' if where else ' at the top level'}: "
                    + ", ".join(allowed))
