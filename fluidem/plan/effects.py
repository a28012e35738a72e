"""What a plan holds: :class:`Effect` (one effect, on or off, and why) and :class:`Plan`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = ["Effect", "Plan", "readable_bytes"]


@dataclass
class Effect:
    """One effect of the plan: whether it is ``on``, a short ``value`` and the reason ``why``."""

    name: str
    on: bool
    why: str
    value: str = ""

    def __str__(self):
        state = "on " if self.on else "off"
        val = f" [{self.value}]" if self.value else ""
        return f"  {self.name:15s} {state}{val}  — {self.why}"


@dataclass
class Plan:
    """Which effects a scene needs and why; :class:`fluidem.Simulation` builds only those.

    Attributes
    ----------
    effects : list of Effect
        In order: fluid, inertia, moving-bodies, mesh, ale, contacts, gravity, buoyancy,
        coupling, rotation, remeshing, periodic, solver.
    mesh : {"none", "once", "moving"}
        No mesh (dry), a mesh built once, or a moving mesh.
    contact_pairs : int
        Pairs (body–body and body–wall) that can meet before ``t_end``.
    unsupported : list of str
        Reasons this version cannot run the scene (empty when it can).
    n_steps : int
    """

    scene_name: str
    effects: list
    mesh: str
    contact_pairs: int
    n_steps: int
    unsupported: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    #: things the run will do but should not go unsaid (a coarse or degenerate mesh, memory)
    warnings: list = field(default_factory=list)
    #: fluid scenes: rough size of the mesh and its solve before anything is built (:func:`mesh_estimate`)
    estimate: dict | None = None

    def effect(self, name) -> Effect:
        for e in self.effects:
            if e.name == name:
                return e
        raise InputError(f"effect = {name!r}: expected one of {', '.join(repr(e.name) for e in self.effects)}")

    def on(self, name) -> bool:
        return self.effect(name).on

    def __str__(self):
        lines = [f"plan for scene {self.scene_name!r}: {self.n_steps} steps"]
        lines += [str(e) for e in self.effects]
        if self.estimate:
            e = self.estimate
            if np.isfinite(e["peak_bytes"]):
                lines.append(f"  estimate: about {e['triangles']:.2g} triangles, {e['nodes']:.2g} nodes, "
                             f"{e['dofs']:.2g} DOFs, peak memory {readable_bytes(e['peak_bytes'])} (this machine: "
                             f"{readable_bytes(e['machine_bytes'])})")
            else:
                lines.append(f"  estimate: beyond 1e308 triangles (this machine: "
                             f"{readable_bytes(e['machine_bytes'])})")
        lines += [f"  note: {n}" for n in self.notes]
        lines += [f"  warning: {w}" for w in self.warnings]
        if self.unsupported:
            lines.append("  cannot run yet:")
            lines += [f"    - {u}" for u in self.unsupported]
        return "\n".join(lines)


def readable_bytes(b: float) -> str:
    """``b`` bytes in kB, MB, GB or TB, three significant digits (``"beyond 1e308 bytes"`` for inf).

    Examples
    --------
    >>> readable_bytes(16e9), readable_bytes(2500.0)
    ('16 GB', '2.5 kB')
    """
    if not np.isfinite(b):
        return "beyond 1e308 bytes"
    for unit, f in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= f:
            return f"{b / f:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"
