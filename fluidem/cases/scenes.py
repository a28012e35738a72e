"""Built-in example scenes: TOML files in ``fluidem/cases/scenes/``, listed by name.

``fluidem examples`` lists them; ``fluidem run --example NAME`` runs one;
:func:`example_scene` loads one as a :class:`fluidem.scene.Scene`.
"""

from __future__ import annotations

from pathlib import Path

from .. import names
from ..errors import InputError

__all__ = ["SCENE_DIR", "example_names", "example_path", "example_scene", "example_descriptions"]

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
