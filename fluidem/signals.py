"""SIGINT and SIGTERM during a run: stop after the step in progress, not in the middle of it.

:class:`SignalGuard` is the context manager :meth:`fluidem.simulation.Simulation.run` steps in:
the first SIGINT or SIGTERM only sets :attr:`SignalGuard.signal`, so the loop finishes the step,
checkpoints it and stops (:class:`fluidem.errors.RunStopped`); a second Ctrl-C raises
``KeyboardInterrupt`` at once.  The handlers the process had before are put back on exit.
"""

from __future__ import annotations

import sys

__all__ = ["SignalGuard"]


class SignalGuard:
    """SIGINT and SIGTERM set :attr:`signal` (the run stops after the step in progress); a second
    SIGINT raises ``KeyboardInterrupt`` at once.  Installed only in the main thread, and not for a
    signal the process ignores.

    Attributes
    ----------
    signal : str or None
        The name of the signal received (``"SIGINT"`` or ``"SIGTERM"``), None before one.

    Examples
    --------
    >>> with SignalGuard() as guard:
    ...     pass   # the steps of a run; after each: ``if guard.signal: stop``
    >>> guard.signal is None
    True
    """

    def __init__(self):
        self.signal = None
        self._old = {}

    def __enter__(self):
        import signal
        import threading

        if threading.current_thread() is not threading.main_thread():
            return self
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                old = signal.getsignal(sig)
                if old is signal.SIG_IGN or old is None:
                    continue
                self._old[sig] = signal.signal(sig, self._handle)
            except (ValueError, OSError):  # pragma: no cover - not allowed here
                pass
        return self

    def _handle(self, signum, frame):
        import signal

        name = signal.Signals(signum).name
        if self.signal is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.signal = name
        print(f"fluidem: {name}: stopping after this step (Ctrl-C again to stop at once)", file=sys.stderr,
              flush=True)

    def __exit__(self, *exc):
        import signal

        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}
        return False
