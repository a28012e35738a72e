"""One run per output directory: the lock a run holds on it (:class:`RunLock`), the check
before a run writes into it (:func:`prepare_output_dir`) and its ``run.json`` record
(:func:`read_run_record`, :func:`write_run_record`).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from ..errors import InputError
from ..validate import fail
from .layout import OUTPUT_ENTRIES, PathLike

__all__ = ["OutputDirError", "LOCK_FILE", "RunLock", "prepare_output_dir", "read_run_record", "write_run_record"]


class OutputDirError(InputError):
    """The output directory cannot be used as asked (a file, under a file, or another run's output)."""


#: the lock file of an output directory (never removed: a waiting opener must find the same file)
LOCK_FILE = ".fluidem.lock"


def _make_dir(out_dir: PathLike) -> Path:
    """``out_dir`` as a Path, created with its parents; OutputDirError when that cannot be."""
    d = Path(out_dir)
    if d.exists() and not d.is_dir():
        raise OutputDirError(f"output directory {str(d)!r} is an existing file; expected a directory or a path "
                             "that does not exist yet")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        parent = next((p for p in d.parents if p.exists() and not p.is_dir()), d.parent)
        raise OutputDirError(f"output directory {str(d)!r}: {str(parent)!r} is a file, not a directory; expected a "
                             "path whose parents are directories") from None
    except OSError as exc:
        raise OutputDirError(f"output directory {str(d)!r} cannot be created ({exc.strerror or exc}); choose "
                             "another --out") from None
    return d


class RunLock:
    """One writer per output directory: an exclusive lock on ``<out_dir>/.fluidem.lock``.

    The lock is the operating system's (``fcntl.flock`` on POSIX, ``msvcrt.locking`` on
    Windows), so it is released when the holder ends, even by SIGKILL: a stale lock file
    never blocks a later run.  The holder writes its process id, host and start time into
    the file, and a refused run names them.

    Examples
    --------
    >>> import tempfile
    >>> d = tempfile.mkdtemp()
    >>> with RunLock(d):
    ...     try:
    ...         RunLock(d).acquire()
    ...     except OutputDirError as err:
    ...         print(str(err).split(" (")[0].endswith("is in use by another run"))
    True
    """

    def __init__(self, out_dir: PathLike):
        self.dir = Path(out_dir)
        self._fd = None

    def acquire(self) -> RunLock:
        """Take the lock (creating the directory), or raise :class:`OutputDirError` naming its holder."""
        import socket
        import time

        path = _make_dir(self.dir) / LOCK_FILE
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise OutputDirError(f"output directory {str(self.dir)!r}: cannot open its lock file {LOCK_FILE} "
                                 f"({exc.strerror or exc}); expected a writable directory") from None
        try:
            _lock(fd)
        except OSError:
            holder = os.read(fd, 200).decode("utf-8", "replace").strip() or "a process that has not said which"
            os.close(fd)
            raise OutputDirError(f"output directory {str(self.dir)!r} is in use by another run ({holder}); wait for "
                                 "it to end, or give another --out") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}, since "
                     f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode())
        self._fd = fd
        return self

    def release(self) -> None:
        """Let the lock go (idempotent); the file stays."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                os.ftruncate(fd, 0)
            except OSError:  # a read-only file system now: the OS lock goes with the descriptor anyway
                pass
            os.close(fd)

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _lock(fd: int) -> None:
    """An exclusive, non-blocking OS lock on ``fd`` (OSError when another holds it)."""
    try:
        import fcntl
    except ImportError:  # Windows
        import msvcrt

        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)


def prepare_output_dir(out_dir: PathLike, mode: str = "new") -> Path:
    """Make ``out_dir`` ready for a run and return it.

    Parameters
    ----------
    out_dir : path
        Created (with its parents) when missing.
    mode : {"new", "overwrite", "restart"}
        ``"new"``: refuse a directory that holds a run's output (a ``run.json``);
        ``"overwrite"``: remove the entries its ``run.json`` lists (and nothing else) first;
        ``"restart"``: keep them (the run continues).  In every mode a file or folder named
        like an output entry (:data:`OUTPUT_ENTRIES`) that no ``run.json`` lists is the
        user's: the run is refused rather than write over it.

    Raises
    ------
    OutputDirError
        (an :class:`~fluidem.errors.InputError`) naming the directory and the options.
    """
    if mode not in ("new", "overwrite", "restart"):
        raise fail("mode", mode, "one of 'new', 'overwrite', 'restart'")
    d = _make_dir(out_dir)
    rec = read_run_record(d)
    claimed = set(rec.get("entries", OUTPUT_ENTRIES)) if rec else set()  # a run.json before 'entries': all
    found = [e for e in OUTPUT_ENTRIES if (d / e).exists() or (d / e).is_symlink()]
    foreign = [e for e in found if e not in claimed]
    if foreign:
        raise OutputDirError(f"output directory {str(d)!r} holds {', '.join(foreign)}, which no run there wrote (no "
                             "run.json lists it); a run would write over it: move it away or give another --out")
    if mode == "new" and rec:
        who = f"scene {rec.get('scene')!r}, {rec.get('status', 'unknown')} at step {rec.get('step')}"
        raise OutputDirError(f"output directory {str(d)!r} holds the output of another run ({who}); give --overwrite "
                             "(overwrite=True) to clear it, --restart (restart=True) to continue it, or another --out")
    if mode == "overwrite":
        for e in found:
            p = d / e
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    return d


def read_run_record(out_dir: PathLike) -> dict:
    """The ``run.json`` record of an output directory (``{}`` when there is none or it is unreadable)."""
    try:
        rec = json.loads((Path(out_dir) / "run.json").read_text())
    except (OSError, ValueError):
        return {}
    return rec if isinstance(rec, dict) else {}


def write_run_record(out_dir: PathLike, record: dict) -> None:
    """Write ``run.json`` atomically (write, then rename), listing the run's ``entries``.

    When the directory no longer takes new files (made read-only, say) an existing
    ``run.json`` is written over in place, so its status does not stay ``running``; when
    that fails too, :class:`OutputDirError` names the directory.
    """
    path = Path(out_dir) / "run.json"
    text = json.dumps({**record, "entries": list(OUTPUT_ENTRIES)}, indent=1, allow_nan=False) + "\n"
    tmp = path.with_name("run.json.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        try:
            with open(path, "r+" if path.exists() else "x") as f:
                f.write(text)
                f.truncate()
        except OSError:
            raise OutputDirError(f"output directory {str(out_dir)!r}: run.json cannot be written "
                                 f"({exc.strerror or exc}); expected a writable directory with free space") from None
