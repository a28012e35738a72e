"""Scene files: TOML and CSV in, TOML out.

* :func:`read_toml` reads a scene file into the nested dict that
  :meth:`fluidem.scene.Scene.from_dict` validates;
* :func:`read_bodies_table` reads the CSV of a ``[bodies_table]`` (one row per body) into
  body records;
* :func:`write_scene_toml` (also :meth:`Scene.to_toml`) writes a scene back as TOML that
  :meth:`Scene.from_toml` reads again (bodies inline, values as validated: canonical names,
  defaults filled in).

Errors are :class:`fluidem.errors.SceneError` (a ``ValueError``) naming the file, the row
or key and what is allowed.

Examples
--------
>>> import tempfile, pathlib
>>> from fluidem.scene import Scene
>>> s = Scene.from_dict({"domain": {"box": [0, 1, 0, 1]}, "fluid": {"solver": "lagged-lu"},
...                      "bodies": [{"shape": "disk", "radius": 0.1, "position": [0.5, 0.5],
...                                  "motion": "fixed"}]})
>>> path = pathlib.Path(tempfile.mkdtemp()) / "scene.toml"
>>> s.to_toml(path)
>>> Scene.from_toml(path).fluid.solver
'lagged'
"""

from __future__ import annotations

import csv
from pathlib import Path

from ..errors import SceneError
from ..validate import check_keys, fail, nearest

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["tomllib", "read_toml", "read_bodies_table", "TABLE_COLUMNS", "TABLE_KEYS", "toml_value", "scene_toml",
           "write_scene_toml"]

#: Columns a ``[bodies_table]`` CSV may have (``x``, ``y`` required; ``vx``, ``vy`` the velocity).
TABLE_COLUMNS = ("shape", "radius", "segments", "width", "height", "a", "b", "x", "y", "angle", "density", "motion",
                 "vx", "vy", "omega", "vertices", "name")
#: Keys of the ``[bodies_table]`` table: the CSV ``file`` and defaults for every row (per-row columns excepted).
TABLE_KEYS = ("file",) + tuple(k for k in TABLE_COLUMNS if k not in ("x", "y", "vx", "vy"))
_NUMERIC_COLUMNS = {"radius", "width", "height", "a", "b", "x", "y", "angle", "density", "vx", "vy", "omega"}


# ---------------------------------------------------------------------------------------
# in
# ---------------------------------------------------------------------------------------
def read_toml(path) -> dict:
    """The nested dict of the TOML file ``path``; ``SceneError`` when it is missing or not TOML."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise SceneError(f"scene file {str(path)!r} does not exist") from None
    except IsADirectoryError:
        raise SceneError(f"scene file {str(path)!r} is a directory; expected a TOML file") from None
    except (NotADirectoryError, PermissionError) as exc:
        raise SceneError(f"scene file {str(path)!r} cannot be read ({exc.strerror}); expected a readable TOML "
                         "file") from None
    except UnicodeDecodeError:
        raise SceneError(f"scene file {str(path)!r} is not a text file; expected a TOML file") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene file {str(path)!r} is not valid TOML: {exc}") from None


def read_bodies_table(tab, base_dir=".") -> list:
    """Rows of the CSV body table of ``[bodies_table]`` -> list of body records (dicts).

    Parameters
    ----------
    tab : dict
        The ``[bodies_table]`` table: ``file`` (path of the CSV, relative to ``base_dir``)
        and defaults for every row (any column of :data:`TABLE_COLUMNS` except ``x``, ``y``,
        ``vx``, ``vy``).
    base_dir : path
        Directory of the scene file.

    Returns
    -------
    list of dict
        One record per non-empty row, keyed as :class:`fluidem.scene.BodySpec` fields
        (``x``, ``y`` -> ``position``; ``vx``, ``vy`` -> ``velocity``); ``vertices`` cells
        are ``"x0 y0; x1 y1; ..."``.
    """
    if not isinstance(tab, dict):
        raise fail("bodies_table", tab, "a table { file = 'bodies.csv', ... defaults }", SceneError)
    check_keys(tab, TABLE_KEYS, "bodies_table", error=SceneError)
    if "file" not in tab or not isinstance(tab["file"], str):
        raise fail("bodies_table.file", tab.get("file"), "the path of a CSV file (relative to the scene file)",
                   SceneError)
    path = Path(base_dir) / tab["file"]
    defaults = {k: v for k, v in tab.items() if k != "file"}
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise SceneError(f"bodies_table.file = {tab['file']!r}: file {str(path)!r} does not exist") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError):
        raise SceneError(f"bodies_table.file = {tab['file']!r}: {str(path)!r} cannot be read; expected a CSV "
                         "text file") from None
    if not rows:
        raise SceneError(f"bodies_table.file = {tab['file']!r} is empty; expected a header row")
    header = [h.strip() for h in rows[0]]
    for h in header:
        if h not in TABLE_COLUMNS:
            best = nearest(h, TABLE_COLUMNS)
            raise SceneError(f"bodies_table.file {tab['file']!r}: unknown column {h!r}"
                             + (f" (did you mean {best!r}?)" if best else "") + "; allowed columns: "
                             + ", ".join(TABLE_COLUMNS))
    for need in ("x", "y"):
        if need not in header:
            raise SceneError(f"bodies_table.file {tab['file']!r}: no column {need!r}; x and y are required")
    out = []
    for r, row in enumerate(rows[1:], start=1):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise SceneError(f"bodies_table.file {tab['file']!r} row {r}: {len(row)} values for {len(header)} "
                             "columns")
        rec = dict(defaults)
        for h, c in zip(header, row):
            c = c.strip()
            if c == "":
                continue
            where = f"bodies_table row {r} column {h}"
            try:
                if h in _NUMERIC_COLUMNS:
                    rec[h] = float(c)
                elif h == "segments":
                    rec[h] = int(c)
                elif h == "vertices":  # "x0 y0; x1 y1; ..."
                    rec[h] = [[float(t) for t in p.split()] for p in c.split(";")]
                else:
                    rec[h] = c
            except ValueError:
                raise fail(where, c, "a number" if h != "vertices" else "'x0 y0; x1 y1; ...'", SceneError) from None
        for need in ("x", "y"):
            if need not in rec:
                raise SceneError(f"bodies_table.file {tab['file']!r} row {r} column {need}: empty; expected a "
                                 "number (x and y are required in every row)")
        rec["position"] = (rec.pop("x"), rec.pop("y"))
        if "vx" in rec or "vy" in rec:
            rec["velocity"] = (rec.pop("vx", 0.0), rec.pop("vy", 0.0))
        out.append(rec)
    return out


# ---------------------------------------------------------------------------------------
# out
# ---------------------------------------------------------------------------------------
_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b", "\f": "\\f"}


def toml_value(v) -> str:
    """One value as TOML: booleans, strings (basic strings, escaped), numbers, arrays, inline tables."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + "".join(_ESCAPES.get(c, f"\\u{ord(c):04x}" if ord(c) < 0x20 or c == "\x7f" else c)
                             for c in v) + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    return repr(float(v)) if isinstance(v, float) else str(v)


def scene_toml(scene) -> str:
    """The text of ``scene`` (a :class:`fluidem.scene.Scene`) as a TOML scene file, bodies inline."""
    d = scene.to_dict()
    lines = [f"name = {toml_value(d.pop('name'))}", f"description = {toml_value(d.pop('description'))}",
             f"gravity = {toml_value(d.pop('gravity'))}"]
    if "units" in d:
        lines.insert(2, f"units = {toml_value(d.pop('units'))}")
    bodies = d.pop("bodies")
    for key, tab in d.items():
        lines.append(f"\n[{key}]")
        for k, v in tab.items():
            if isinstance(v, dict) and "type" in v and key == "domain":
                v = {kk: vv for kk, vv in v.items() if not (kk == "profile" and vv is None)}
            lines.append(f"{k} = {toml_value(v)}")
    for b in bodies:
        lines.append("\n[[bodies]]")
        lines += [f"{k} = {toml_value(v)}" for k, v in b.items()]
    return "\n".join(lines) + "\n"


def write_scene_toml(scene, path) -> None:
    """Write ``scene`` as TOML to ``path`` (re-readable by :meth:`Scene.from_toml`; the scene as run)."""
    Path(path).write_text(scene_toml(scene))
