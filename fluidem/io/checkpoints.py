"""Finding and loading a run's checkpoints (``checkpoints/ckpt_<step>.npz``, written by
:meth:`fluidem.io.OutputWriter.checkpoint`; the file format is :mod:`fluidem.checkpoint`'s).
"""

from __future__ import annotations

import pickle
from pathlib import Path

from ..checkpoint import CheckpointError, checkpoint_files
from ..checkpoint import load as _load_npz
from ..validate import fail
from .layout import PathLike

__all__ = ["CHECKPOINT_VERSION", "latest_checkpoint", "load_checkpoint", "load_latest_checkpoint"]


CHECKPOINT_VERSION = 2  # 1: pickles (read only with allow_pickle=True); 2: npz + JSON (fluidem.checkpoint)


def latest_checkpoint(out_dir: PathLike) -> Path:
    """Newest checkpoint file in ``out_dir/checkpoints`` (not checked; see :func:`load_latest_checkpoint`).

    Raises :class:`fluidem.errors.InputError` (a ``ValueError``) if there is none.
    """
    files = checkpoint_files(out_dir)
    if not files:
        d = Path(out_dir) / "checkpoints"
        legacy = sorted(d.glob("ckpt_*.pkl")) if d.is_dir() else []
        raise fail("checkpoint directory", str(d), "a directory holding ckpt_*.npz files written by 'fluidem run'"
                   + (f" (it holds {len(legacy)} pickle checkpoint(s) of an earlier version: give one of them as "
                      "the checkpoint file, with allow_pickle=True, and only if you wrote it)" if legacy else ""))
    return files[0]


def load_checkpoint(path: PathLike, allow_pickle: bool = False) -> dict:
    """Read a checkpoint written by :meth:`OutputWriter.checkpoint` (a run directory: its newest valid one).

    Returns the state with ``version``, ``step``, ``t`` (s) and the header (``scene``,
    ``dt``, ``plan``).  Raises :class:`fluidem.checkpoint.CheckpointError` (an
    :class:`~fluidem.errors.InputError`) for a missing, damaged or foreign file.  Pickle
    checkpoints of earlier versions (``.pkl``) are read only with ``allow_pickle=True``
    (loading a pickle can execute code: only for files you wrote).
    """
    path = Path(path)
    if path.is_dir():
        return load_latest_checkpoint(path)[1]
    if path.suffix == ".pkl":
        if not allow_pickle:
            raise CheckpointError(f"checkpoint {str(path)!r} is a pickle of an earlier fluidem version; loading a "
                                  "pickle can execute code: pass allow_pickle=True only for a file you wrote")
        try:
            with open(path, "rb") as f:
                data = pickle.load(f)
        except FileNotFoundError:
            raise fail("checkpoint", str(path), "an existing checkpoint file") from None
        except Exception as exc:  # a damaged pickle raises many kinds
            raise CheckpointError(f"checkpoint {str(path)!r} is damaged ({type(exc).__name__})") from None
        if not isinstance(data, dict) or data.get("version") != 1:
            raise fail("checkpoint", str(path), "a fluidem pickle checkpoint of version 1")
        return data
    header, state = _load_npz(path)
    if header.get("version") != CHECKPOINT_VERSION or not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {str(path)!r}: version {header.get('version')!r}; expected a fluidem "
                              f"checkpoint of version {CHECKPOINT_VERSION}")
    return {**header, **state}


def load_latest_checkpoint(out_dir: PathLike) -> tuple[Path, dict, list]:
    """The newest *valid* checkpoint of a run directory: ``(path, data, skipped)``.

    A damaged newer checkpoint (empty, truncated, not a checkpoint) is skipped; ``skipped``
    lists ``(path, reason)`` of each one skipped.  Raises
    :class:`fluidem.checkpoint.CheckpointError` when none is valid.
    """
    skipped = []
    files = checkpoint_files(out_dir) or [latest_checkpoint(out_dir)]
    for path in files:
        try:
            return path, load_checkpoint(path), skipped
        except CheckpointError as exc:
            skipped.append((path, str(exc)))
    raise CheckpointError(f"no valid checkpoint in {str(Path(out_dir) / 'checkpoints')!r}: "
                          + "; ".join(r for _, r in skipped))
