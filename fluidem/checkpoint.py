"""Checkpoints in a safe format: numpy arrays in an ``.npz`` file plus a JSON header.

A checkpoint holds everything a run needs to continue: the scene (as a plain dict), the
plan it ran with, ``dt``, the step and the time, and the state of the bodies and of the flow.
The state is an object graph of plain values, numpy arrays and instances of fluidem's own
classes; :func:`encode` turns it into a JSON tree whose arrays are stored beside it, and
:func:`decode` rebuilds it.

Loading never executes code from the file: the JSON tree can only name classes defined in
the ``fluidem`` package (any other name is refused), which are created empty
(``cls.__new__``) and filled with their decoded attributes (``__setstate__`` when the class
defines one); arrays are read with ``allow_pickle=False``.

Writing is atomic: the file is written under a temporary name in the same directory,
flushed to disk and renamed, so a crash leaves either the previous file or the new one.

Examples
--------
>>> import tempfile, pathlib
>>> import numpy as np
>>> from fluidem.checkpoint import save, load
>>> path = pathlib.Path(tempfile.mkdtemp()) / "ckpt_0000003.npz"
>>> _ = save(path, {"step": 3, "t": 0.3}, {"x": np.arange(3.0), "n": 2, "pair": (1, "a")})
>>> header, state = load(path)
>>> header["step"], state["x"], state["pair"]
(3, array([0., 1., 2.]), (1, 'a'))
"""

from __future__ import annotations

import base64
import enum
import importlib
import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["FORMAT", "CheckpointError", "encode", "decode", "save", "load", "checkpoint_files"]

#: format tag in every header; a file without it is not a checkpoint of this kind
FORMAT = "fluidem-checkpoint-npz-1"


class CheckpointError(InputError):
    """A checkpoint file is missing, damaged, or not a fluidem checkpoint of this format."""


# ---------------------------------------------------------------------------------------
# object graph <-> JSON tree + arrays
# ---------------------------------------------------------------------------------------
def _has_own(cls, name) -> bool:
    return getattr(cls, name, None) is not getattr(object, name, None)


def encode(obj, arrays: list, copy: bool = False):
    """The JSON-able tree of ``obj``; its numpy arrays are appended to ``arrays``.

    Parameters
    ----------
    obj : object
        Plain values (None, bool, int, float, str, bytes), lists, tuples, dicts, sets, numpy
        arrays and scalars, shapely geometries (as well-known binary), and instances of
        classes of the ``fluidem`` package (their ``__getstate__`` or ``__dict__``).  Shared
        objects and arrays stay shared.
    arrays : list
        Receives the arrays; the tree refers to them by index.
    copy : bool
        Copy the arrays (for a snapshot that later steps must not change).

    Raises
    ------
    TypeError
        For a value of any other kind (e.g. a function or an object of another package).
    """
    memo: dict[int, int] = {}  # id of an array -> its index
    omemo: dict[int, int] = {}  # id of an object -> its number
    keep: list = []  # everything memoised stays alive while encoding, so ids stay unique

    def enc(o, where):
        if o is None or isinstance(o, (bool, str)):
            return o
        if isinstance(o, int) and not isinstance(o, enum.Enum):
            return o
        if isinstance(o, float):
            return o if math.isfinite(o) else {"__float__": repr(o)}
        if isinstance(o, np.generic):
            arrays.append(np.asarray(o))
            return {"__scalar__": len(arrays) - 1}
        if isinstance(o, np.ndarray):
            if id(o) in memo:
                return {"__ref__": memo[id(o)]}
            if o.dtype.hasobject:
                raise TypeError(f"{where}: an array of Python objects cannot be checkpointed")
            arrays.append(np.array(o, copy=True) if copy else o)
            memo[id(o)] = len(arrays) - 1
            keep.append(o)
            return {"__array__": len(arrays) - 1}
        if isinstance(o, list):
            return [enc(v, f"{where}[{i}]") for i, v in enumerate(o)]
        if isinstance(o, tuple):
            return {"__tuple__": [enc(v, f"{where}[{i}]") for i, v in enumerate(o)]}
        if isinstance(o, dict):
            return {"__dict__": [[enc(k, f"{where} key"), enc(v, f"{where}[{k!r}]")] for k, v in o.items()]}
        if isinstance(o, (set, frozenset)):
            return {"__set__": [enc(v, where) for v in o], "frozen": isinstance(o, frozenset)}
        if isinstance(o, bytes):
            return {"__bytes__": base64.b64encode(o).decode("ascii")}
        if isinstance(o, complex):
            return {"__complex__": [enc(o.real, where), enc(o.imag, where)]}
        cls = type(o)
        name = f"{cls.__module__}:{cls.__qualname__}"
        if cls.__module__.startswith("shapely."):
            import shapely

            if isinstance(o, shapely.Geometry):  # as well-known binary: plain data
                return {"__shapely__": base64.b64encode(shapely.to_wkb(o)).decode("ascii")}
        if not (cls.__module__ == "fluidem" or cls.__module__.startswith("fluidem.")):
            raise TypeError(f"{where}: a {name} cannot be checkpointed (only fluidem's own classes)")
        if isinstance(o, enum.Enum):
            return {"__enum__": name, "value": enc(o.value, where)}
        if id(o) in omemo:
            return {"__objref__": omemo[id(o)]}
        key = omemo[id(o)] = len(omemo)
        keep.append(o)
        state = o.__getstate__() if hasattr(o, "__getstate__") else o.__dict__
        return {"__obj__": name, "id": key, "state": enc(state, f"{where}.{cls.__name__}")}

    return enc(obj, "state")


def _class(name: str):
    module, _, qual = name.partition(":")
    if not (module == "fluidem" or module.startswith("fluidem.")):
        raise CheckpointError(f"class = {name!r}: expected a class of the fluidem package")
    try:
        obj = importlib.import_module(module)
        for part in qual.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError):
        raise CheckpointError(f"class = {name!r}: not found in this version of fluidem") from None
    if not isinstance(obj, type):
        raise CheckpointError(f"class = {name!r}: expected a class")
    return obj


def decode(tree, arrays):
    """Rebuild the object graph of :func:`encode` from its tree and ``arrays`` (index -> array)."""
    objects: dict[int, object] = {}
    cache: dict[int, np.ndarray] = {}

    def array(i):
        if i not in cache:
            cache[i] = arrays[i]
        return cache[i]

    def dec(t):
        if t is None or isinstance(t, (bool, int, float, str)):
            return t
        if isinstance(t, list):
            return [dec(v) for v in t]
        if not isinstance(t, dict) or len(t) == 0:
            raise CheckpointError(f"checkpoint tree entry {str(t)[:40]!r}: expected a tagged value")
        if "__array__" in t:
            return array(int(t["__array__"]))
        if "__ref__" in t:
            return array(int(t["__ref__"]))
        if "__scalar__" in t:
            return arrays[int(t["__scalar__"])][()]
        if "__float__" in t:
            return float(t["__float__"])
        if "__tuple__" in t:
            return tuple(dec(v) for v in t["__tuple__"])
        if "__dict__" in t:
            out = {}
            for k, v in t["__dict__"]:
                k = dec(k)
                out[k] = dec(v)
            return out
        if "__set__" in t:
            vals = [dec(v) for v in t["__set__"]]
            return frozenset(vals) if t.get("frozen") else set(vals)
        if "__bytes__" in t:
            return base64.b64decode(t["__bytes__"])
        if "__complex__" in t:
            re, im = t["__complex__"]
            return complex(dec(re), dec(im))
        if "__shapely__" in t:
            import shapely

            return shapely.from_wkb(base64.b64decode(t["__shapely__"]))
        if "__enum__" in t:
            return _class(t["__enum__"])(dec(t["value"]))
        if "__objref__" in t:
            return objects[int(t["__objref__"])]
        if "__obj__" in t:
            cls = _class(t["__obj__"])
            o = cls.__new__(cls)
            objects[int(t["id"])] = o
            state = dec(t["state"])
            if _has_own(cls, "__setstate__"):
                o.__setstate__(state)
            elif isinstance(state, tuple) and len(state) == 2:  # (dict, slots) of object.__getstate__
                if state[0]:
                    o.__dict__.update(state[0])
                for k, v in (state[1] or {}).items():
                    object.__setattr__(o, k, v)
            elif isinstance(state, dict):
                o.__dict__.update(state)
            return o
        raise CheckpointError(f"checkpoint tree entry with keys {sorted(t)[:3]}: not a known tag")

    return dec(tree)


# ---------------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------------
def save(path, header: dict, state, snapshot: tuple | None = None) -> Path:
    """Write ``header`` (JSON-able dict) and ``state`` (see :func:`encode`) to ``path`` atomically.

    ``snapshot``: a ``(tree, arrays)`` pair already encoded (e.g. the state of the last good
    step), written instead of ``state``.  Returns the path written.
    """
    path = Path(path)
    if snapshot is None:
        arrays: list = []
        tree = encode(state, arrays)
    else:
        tree, arrays = snapshot
    head = {"format": FORMAT, **header, "n_arrays": len(arrays), "state": tree}
    blob = np.frombuffer(json.dumps(head, allow_nan=False).encode("utf-8"), dtype=np.uint8)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        np.savez(f, header=blob, **{f"a{i}": a for i, a in enumerate(arrays)})
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def load(path) -> tuple[dict, object]:
    """``(header, state)`` of a checkpoint written by :func:`save`.

    Raises
    ------
    CheckpointError
        (an :class:`~fluidem.errors.InputError`) naming the file and what is wrong with it:
        missing, empty, truncated, not an npz archive, or not of this format.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {str(path)!r} does not exist; expected a checkpoint file")
    if path.stat().st_size == 0:
        raise CheckpointError(f"checkpoint {str(path)!r} is empty (0 bytes)")
    try:
        with np.load(path, allow_pickle=False) as z:
            head = json.loads(bytes(z["header"]).decode("utf-8"))
            if not isinstance(head, dict) or head.get("format") != FORMAT:
                raise CheckpointError(f"checkpoint {str(path)!r}: not a fluidem checkpoint of format {FORMAT!r}")
            arrays = [z[f"a{i}"] for i in range(int(head["n_arrays"]))]
    except CheckpointError:
        raise
    except (zipfile.BadZipFile, ValueError, KeyError, OSError, EOFError, UnicodeDecodeError, TypeError) as exc:
        raise CheckpointError(f"checkpoint {str(path)!r} is damaged or truncated ({type(exc).__name__}: "
                              f"{str(exc)[:80]})") from None
    state = decode(head.pop("state"), arrays)
    return head, state


def checkpoint_files(out_dir) -> list[Path]:
    """Checkpoint files ``checkpoints/ckpt_<step>.npz`` of a run directory, newest (highest step) first."""
    d = Path(out_dir) / "checkpoints"
    return sorted(d.glob("ckpt_*.npz"), reverse=True) if d.is_dir() else []
