"""Checkpoints in a safe format: numpy arrays in an ``.npz`` file plus a JSON header.

A checkpoint holds everything a run needs to continue: the scene (as a plain dict), the
plan it ran with, ``dt``, the step and the time, and the state of the bodies and of the flow.
The state is an object graph of plain values, numpy arrays and instances of fluidem's own
classes; :func:`encode` turns it into a JSON tree whose arrays are stored beside it, and
:func:`decode` rebuilds it.

Loading never executes code from the file.  A checkpoint is data: numbers, strings, arrays
(read with ``allow_pickle=False``), lists and dicts of them, shapely geometries (as
well-known binary) and the state of fluidem's own classes.  The JSON tree names a class by
``"module:QualName"``, and only the exact names in :data:`STATE_CLASSES` are looked up (one
attribute of one fluidem module, no walk through attributes; anything else is a damaged
checkpoint); such a class is created empty (``cls.__new__``, no constructor runs) and
filled with its decoded attributes (``__setstate__`` when the class defines one, which
only assigns).  :func:`encode` refuses every other class, so a state class missing from the
list fails the first save, not a user's restart.  What a checkpoint holds is then checked
against the scene before a run continues from it (:func:`mismatches`,
:meth:`fluidem.Simulation.restore`).

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
import importlib
import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["FORMAT", "STATE_CLASSES", "CheckpointError", "encode", "decode", "save", "load", "checkpoint_files",
           "mismatches"]

#: format tag in every header; a file without it is not a checkpoint of this kind
FORMAT = "fluidem-checkpoint-npz-1"


#: the classes a checkpoint may hold, as ``"module:QualName"``: the run state of bodies, flows
#: and meshes.  Decoding looks up these exact names and nothing else.
STATE_CLASSES = frozenset({
    "fluidem.cost:CostSplit",
    "fluidem.dem.bodies:Body",
    "fluidem.mesh.seam:PeriodicImages",
    "fluidem.dem.contact:ContactModel",
    "fluidem.dem.contact:Contacts",
    "fluidem.dem.integrate:Gear",
    "fluidem.dem.system:DEM",
    "fluidem.mesh.background:GradedSize",
    "fluidem.mesh.background:UniformSize",
    "fluidem.mesh.drag:DragAssociation",
    "fluidem.mesh.moving:MovingMesh",
    "fluidem.mesh.nodes:BackgroundNodes",
    "fluidem.mesh.nodes:BodyOutlines",
    "fluidem.mesh.nodes:UidSource",
    "fluidem.mesh.params:MeshParams",
    "fluidem.mesh.proximity:PolygonTable",
    "fluidem.mesh.quality:OscillationDetector",
    "fluidem.mesh.relax:MeshTopology",
    "fluidem.mesh.relax:RelaxParams",
    "fluidem.mesh.triangulate:BoxDomain",
    "fluidem.mesh.triggers:QualityBaseline",
})


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
        if type(o) is int:
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
        if name not in STATE_CLASSES:
            raise TypeError(f"{where}: a {name} cannot be checkpointed (only the classes of "
                            "fluidem.checkpoint.STATE_CLASSES)")
        if id(o) in omemo:
            return {"__objref__": omemo[id(o)]}
        key = omemo[id(o)] = len(omemo)
        keep.append(o)
        state = o.__getstate__() if hasattr(o, "__getstate__") else o.__dict__
        return {"__obj__": name, "id": key, "state": enc(state, f"{where}.{cls.__name__}")}

    return enc(obj, "state")


def _class(name) -> type:
    """The class ``name`` (``"module:QualName"``) if it is one of :data:`STATE_CLASSES`."""
    if not isinstance(name, str) or name not in STATE_CLASSES:
        raise CheckpointError(f"class = {str(name)[:80]!r}: not one of fluidem's checkpoint state classes "
                              "(fluidem.checkpoint.STATE_CLASSES); the checkpoint is damaged or was not written "
                              "by fluidem")
    module, _, qual = name.partition(":")
    cls = vars(importlib.import_module(module)).get(qual)  # one name of one module: no attribute walk
    if not (isinstance(cls, type) and cls.__module__ == module and cls.__qualname__ == qual):
        raise CheckpointError(f"class = {name!r}: not found in this version of fluidem")
    return cls


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
    try:
        state = decode(head.pop("state"), arrays)
    except CheckpointError as exc:
        raise CheckpointError(f"checkpoint {str(path)!r}: {exc}") from None
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:  # a tree that is not ours
        raise CheckpointError(f"checkpoint {str(path)!r} is damaged ({type(exc).__name__} in its state tree)") from None
    return head, state


def checkpoint_files(out_dir) -> list[Path]:
    """Checkpoint files ``checkpoints/ckpt_<step>.npz`` of a run directory, newest (highest step) first."""
    d = Path(out_dir) / "checkpoints"
    return sorted(d.glob("ckpt_*.npz"), reverse=True) if d.is_dir() else []


def _state_of(o):
    """The attributes of a fluidem object as encoded (its ``__getstate__`` dict, or ``__dict__``)."""
    st = o.__getstate__() if hasattr(o, "__getstate__") else o.__dict__
    if isinstance(st, tuple) and len(st) == 2:  # (dict, slots) of object.__getstate__
        st = {**(st[0] or {}), **(st[1] or {})}
    return st if isinstance(st, dict) else {}


#: numpy dtype kinds that hold the same kind of number
_NUMBER_KIND = {"f": "float", "i": "integer", "u": "integer", "b": "boolean", "c": "complex"}


def _kind(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "a boolean"
    if isinstance(v, (int, float, np.integer, np.floating)):
        return "a number"
    if isinstance(v, (str, bytes)):
        return "a " + type(v).__name__
    if isinstance(v, (list, tuple)):
        return "a list"
    if isinstance(v, dict):
        return "a dict"
    if isinstance(v, np.ndarray):
        return "an array"
    return f"a {type(v).__module__}.{type(v).__qualname__}"


def mismatches(value, template, where: str = "state", exact_shape=None, limit: int = 5) -> list:
    """Where a decoded state ``value`` does not have the make of ``template`` (a state of the same scene).

    The state of a run changes in size as it goes (meshes are re-triangulated, contacts come
    and go), not in make: at every place both hold, the value must be of the template's kind
    (number, string, list, dict, array) and of the same fluidem class; an array must have the
    template's number of dimensions and kind of number (float, integer, boolean), and its
    shape where ``exact_shape(where, template_shape)`` says so (e.g. the arrays of the
    bodies, whose number does not change).  ``None`` on either
    side stands for "not computed yet" and matches anything.

    Returns
    -------
    list of str
        At most ``limit`` lines ``"<where>: <what> (expected <what>)"``; empty when it fits.

    Examples
    --------
    >>> import numpy as np
    >>> mismatches({"x": np.zeros((3, 2)), "t": 0.5}, {"x": np.zeros((4, 2)), "t": 0.0})
    []
    >>> mismatches({"x": np.zeros(3), "t": "0.5"}, {"x": np.zeros((4, 2)), "t": 0.0})
    ['state.x: an array of shape (3,) (expected 2 dimensions of float)', 'state.t: a str (expected a number)']
    """
    out: list = []
    seen: set = set()

    def walk(v, t, at):
        if len(out) >= limit or v is None or t is None:
            return
        kv, kt = _kind(v), _kind(t)
        if kv != kt:
            out.append(f"{at}: {kv} (expected {kt})")
            return
        if isinstance(t, np.ndarray):
            number = _NUMBER_KIND.get(t.dtype.kind, t.dtype.kind)
            if v.ndim != t.ndim or _NUMBER_KIND.get(v.dtype.kind, v.dtype.kind) != number:
                out.append(f"{at}: an array of shape {v.shape} (expected {t.ndim} dimensions of {number})")
            elif v.shape != t.shape and exact_shape is not None and exact_shape(at, t.shape):
                out.append(f"{at}: an array of shape {v.shape} (expected {t.shape})")
            return
        if isinstance(t, dict):
            for k in t:
                if k in v:
                    walk(v[k], t[k], f"{at}.{k}")
            return
        if isinstance(t, (list, tuple)):
            for i, (a, b) in enumerate(zip(v, t)):
                walk(a, b, f"{at}[{i}]")
            return
        if type(t).__module__.startswith("fluidem") and id(v) not in seen:
            seen.add(id(v))
            walk(_state_of(v), _state_of(t), at)

    walk(value, template, where)
    return out
