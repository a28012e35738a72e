"""Built-in example scenes: TOML files in ``fluidem/cases/scenes/``, listed by name.

``fluidem examples`` lists them; ``fluidem run --example NAME`` runs one;
:func:`example_scene` loads one as a :class:`fluidem.scene.Scene`.  To start a scene of your
own, ``fluidem examples --show NAME`` prints one (:func:`example_text`) and ``fluidem new
NAME DIR`` copies it with its CSV body table (:func:`copy_example`).
"""

from __future__ import annotations

from pathlib import Path

from .. import names
from ..errors import InputError

__all__ = ["SCENE_DIR", "example_names", "example_path", "example_scene", "example_descriptions", "example_files",
           "example_text", "copy_example"]

SCENE_DIR = Path(__file__).with_name("scenes")


def example_names() -> list:
    """Names of the built-in scenes (file stems), sorted."""
    return sorted(p.stem for p in SCENE_DIR.glob("*.toml"))


def example_path(name: str) -> Path:
    """Path of the built-in scene ``name`` (a name of ``names.choices("example")`` or an alias).

    Raises
    ------
    fluidem.errors.InputError
        (a ``ValueError``) naming the value and the allowed example scenes.
    """
    try:
        canonical = names.lookup("example", name)
    except InputError:
        allowed = ", ".join(repr(n) for n in names.choices("example"))
        raise InputError(f"unknown example scene {name!r}: expected one of {allowed} (see 'fluidem examples')") \
            from None
    return SCENE_DIR / f"{canonical}.toml"


def example_scene(name: str):
    """Load and validate the built-in scene ``name`` (see :func:`example_path`).

    Examples
    --------
    >>> from fluidem.cases.scenes import example_scene
    >>> example_scene("dry-heap").fluid is None
    True
    """
    from ..scene import Scene

    return Scene.from_toml(example_path(name))


def example_descriptions() -> dict:
    """name -> one-line description (the scene's ``description``)."""
    from ..scene import tomllib

    out = {}
    for n in example_names():
        with open(example_path(n), "rb") as f:
            out[n] = str(tomllib.load(f).get("description", "")).strip().splitlines()[0:1] or [""]
        out[n] = out[n][0]
    return out


def example_files(name: str) -> list:
    """The files of the built-in scene ``name``: its TOML file, then its ``bodies_table`` CSV if it has one."""
    from ..scene import tomllib

    path = example_path(name)
    with open(path, "rb") as f:
        table = tomllib.load(f).get("bodies_table")
    out = [path]
    if isinstance(table, dict) and isinstance(table.get("file"), str):
        out.append(path.parent / table["file"])
    return out


def example_text(name: str) -> str:
    """The scene file of the built-in scene ``name``, to copy (what ``fluidem examples --show NAME`` prints).

    A scene with a CSV body table gets a comment line at the top naming the CSV file to copy
    next to it (the text stays a valid scene file).

    Examples
    --------
    >>> from fluidem.cases.scenes import example_text
    >>> print(example_text("dry-heap").splitlines()[0])  # doctest: +ELLIPSIS
    # bodies_table.file = "dry-heap.csv": copy .../dry-heap.csv next to this file (or 'fluidem new dry-heap DIR')
    """
    files = example_files(name)
    text = files[0].read_text()
    if len(files) > 1:
        text = (f'# bodies_table.file = "{files[1].name}": copy {files[1]} next to this file '
                f"(or 'fluidem new {files[0].stem} DIR')\n" + text)
    return text


def copy_example(name: str, dest) -> list:
    """Copy the files of the built-in scene ``name`` (:func:`example_files`) into the directory ``dest``.

    ``dest`` is created if missing.  Returns the paths written.

    Raises
    ------
    fluidem.errors.InputError
        When ``dest`` is a file or one of the files is there already (nothing is overwritten).
    """
    import shutil

    dest = Path(dest)
    if dest.exists() and not dest.is_dir():
        raise InputError(f"DIR = {str(dest)!r} is a file; expected a directory (created if missing)")
    files = example_files(name)
    there = [dest / f.name for f in files if (dest / f.name).exists()]
    if there:
        raise InputError(f"{str(there[0])!r} exists already; expected a directory without "
                         f"{', '.join(f.name for f in files)} (nothing is overwritten)")
    dest.mkdir(parents=True, exist_ok=True)
    out = []
    for f in files:
        shutil.copyfile(f, dest / f.name)
        out.append(dest / f.name)
    return out
