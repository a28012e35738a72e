"""Where the wall time goes: one cost-split type for steps, solves and whole runs.

A :class:`CostSplit` holds wall seconds per named part (``"mesh"``, ``"assembly"``,
``"solve"``, ``"broad"``, ...) in the order the parts were first charged, plus integer
counters (``steps``, ``contacts``, ...).  Parts read as attributes (``cost.solve``; an
unknown part is 0.0), add up with ``+=``, and print as one line in milliseconds.  The
DEM, the flow solvers and :class:`fluidem.Simulation` all report with it.

Examples
--------
>>> from fluidem.cost import CostSplit
>>> c = CostSplit()
>>> c.add("assembly", 0.002); c.add("solve", 0.010)
>>> with c.timer("loads"):
...     pass
>>> c.solve, round(c.total - c.loads, 6)
(0.01, 0.012)
>>> str(CostSplit({"mesh": 0.001, "solve": 0.0025}))
'mesh 1.0 + solve 2.5 = 3.5 ms'
"""

from __future__ import annotations

import time
from contextlib import contextmanager

__all__ = ["CostSplit"]


class CostSplit:
    """Wall seconds per part and integer counters.

    Parameters
    ----------
    parts : dict, optional
        Initial seconds per part name.
    counts : dict, optional
        Initial counters (``steps``, ``contacts``, ...).
    """

    __slots__ = ("parts", "counts")

    def __init__(self, parts: dict | None = None, counts: dict | None = None):
        self.parts = {k: float(v) for k, v in (parts or {}).items()}
        self.counts = {k: int(v) for k, v in (counts or {}).items()}

    def add(self, part: str, seconds: float) -> None:
        """Charge ``seconds`` to ``part``."""
        self.parts[part] = self.parts.get(part, 0.0) + float(seconds)

    def count(self, name: str, n: int = 1) -> None:
        """Add ``n`` to counter ``name``."""
        self.counts[name] = self.counts.get(name, 0) + int(n)

    @contextmanager
    def timer(self, part: str):
        """Charge the wall time of the ``with`` block to ``part``."""
        t0 = time.perf_counter()
        try:
            yield self
        finally:
            self.add(part, time.perf_counter() - t0)

    @property
    def total(self) -> float:
        """Seconds over all parts."""
        return sum(self.parts.values())

    def per_step(self, steps: int | None = None) -> dict:
        """Seconds per step of each part and ``"total"`` (``steps`` defaults to the ``steps`` counter)."""
        n = max(int(self.counts.get("steps", 1) if steps is None else steps), 1)
        out = {k: v / n for k, v in self.parts.items()}
        out["total"] = self.total / n
        return out

    def copy(self) -> "CostSplit":
        return CostSplit(self.parts, self.counts)

    def __iadd__(self, other: "CostSplit") -> "CostSplit":
        for k, v in other.parts.items():
            self.add(k, v)
        for k, v in other.counts.items():
            self.count(k, v)
        return self

    def __add__(self, other: "CostSplit") -> "CostSplit":
        out = self.copy()
        out += other
        return out

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        parts = object.__getattribute__(self, "parts")
        if name in parts:
            return parts[name]
        counts = object.__getattribute__(self, "counts")
        if name in counts:
            return counts[name]
        return 0.0

    def __eq__(self, other) -> bool:
        return isinstance(other, CostSplit) and self.parts == other.parts and self.counts == other.counts

    def __repr__(self) -> str:
        return f"CostSplit({self.parts!r}, {self.counts!r})"

    def __str__(self) -> str:
        shown = [(k, v) for k, v in self.parts.items() if v]
        if not shown:
            return "0 ms"
        body = " + ".join(f"{k} {1e3 * v:.1f}" for k, v in shown)
        return f"{body} = {1e3 * self.total:.1f} ms" if len(shown) > 1 else f"{body} ms"

    def __getstate__(self):
        return {"parts": self.parts, "counts": self.counts}

    def __setstate__(self, state):
        self.parts = state["parts"]
        self.counts = state["counts"]
