"""Result container and registry shared by the built-in benchmark cases."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Callable

from .. import names
from ..errors import InputError

__all__ = ["CaseResult", "CASES", "register_case", "get_case"]


@dataclass
class CaseResult:
    """Outcome of a benchmark case: quantities, their references and what they cost.

    ``quantities`` and ``reference`` map names (``cd``, ``cl``, ``dp``, ``st``, ...) to
    numbers; ``timings`` holds wall seconds per phase (``mesh``, ``assembly``, ``solve``);
    ``wall_s`` is their sum (imports excluded).  ``level`` is the mesh level, or a text naming a
    level-0 mesh with its own size field (``"0 (h0 0.0125, growth 1.25)"``).
    """

    case: str
    element: str
    level: int | str
    dofs: int
    quantities: dict
    reference: dict
    timings: dict
    geometry: str = "curved"
    dt: float | None = None
    extra: dict = field(default_factory=dict)

    @property
    def wall_s(self) -> float:
        return float(sum(self.timings.values()))

    def relative_errors(self) -> dict:
        return {k: abs(self.quantities[k] - r) / abs(r) for k, r in self.reference.items() if k in self.quantities}

    def to_dict(self) -> dict:
        d = {"case": self.case, "element": self.element, "level": self.level, "dofs": self.dofs,
             "geometry": self.geometry, "dt": self.dt, "wall_s": self.wall_s}
        d.update({f"time_{k}_s": v for k, v in self.timings.items()})
        d.update(self.quantities)
        d.update({f"ref_{k}": v for k, v in self.reference.items()})
        d.update({f"err_{k}": v for k, v in self.relative_errors().items()})
        d.update(self.extra)
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), default=lambda o: o.item() if hasattr(o, "item") else str(o))

    def __str__(self) -> str:
        lines = [f"{self.case}: element {self.element}, level {self.level}, {self.dofs} DOFs, "
                 f"{self.geometry} geometry" + (f", dt = {self.dt:g}" if self.dt else "")]
        errs = self.relative_errors()
        for k, v in self.quantities.items():
            if k in self.reference:
                lines.append(f"  {k:8s} = {v: .10g}   reference {self.reference[k]: .10g}   "
                             f"relative error {errs[k]:.2e}")
            else:
                lines.append(f"  {k:8s} = {v: .10g}")
        split = ", ".join(f"{k} {v:.2f} s" for k, v in self.timings.items())
        lines.append(f"  wall time {self.wall_s:.2f} s ({split})")
        return "\n".join(lines)


CASES: dict[str, Callable] = {}


def register_case(name: str):
    def deco(fn):
        CASES[name] = fn
        return fn
    return deco


def get_case(name: str) -> Callable:
    """The function of the benchmark case ``name`` (a name of ``names.choices("case")`` or an alias).

    Raises
    ------
    fluidem.errors.InputError
        (a ``ValueError``) naming the value and the allowed cases.

    Examples
    --------
    >>> from fluidem.cases import get_case
    >>> get_case("dfg-2d1").__name__
    'dfg_2d1'
    >>> get_case("dfg-2d4")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    fluidem.errors.InputError: case = 'dfg-2d4': expected one of 'dfg-2d1', ..., 'dkt' (benchmark case)
    """
    if isinstance(name, str) and name in CASES:  # also cases registered outside fluidem.names
        return CASES[name]
    canonical = names.lookup("case", name, where="case")
    if canonical not in CASES:  # a registry name whose module was not imported
        raise InputError(f"case = {name!r}: expected one of {', '.join(map(repr, CASES))} (benchmark case)")
    return CASES[canonical]
