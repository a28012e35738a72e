"""The plan: which effects a scene needs, and why.

A :class:`fluidem.scene.Scene` says *what* to simulate; :func:`make_plan` (also
:meth:`Scene.plan`) decides which parts a run needs — fluid, inertia, moving bodies, mesh,
ALE, contacts, gravity, buoyancy, rotation, remeshing, solver — and gives the reason for
each; :class:`fluidem.Simulation` builds only those.  Scene -> plan -> simulation.

The plan is a list of named rules (:data:`fluidem.plan.rules.RULES`): one small function per
effect, note, warning or refusal, applied in order.  The package's modules:

* :mod:`fluidem.plan.effects` — :class:`Effect` and :class:`Plan`;
* :mod:`fluidem.plan.rules` — the rules and the :class:`~fluidem.plan.rules.Context` they read;
* :mod:`fluidem.plan.reach` — which bodies can meet before ``t_end``;
* :mod:`fluidem.plan.limits` — boundary fluxes, contact sub-steps, explicit coupling;
* :mod:`fluidem.plan.estimate` — the mesh's size and memory before the mesh.

Contacts are off when no two bodies (one of them movable), or a movable body and a wall,
can meet before ``t_end`` at the speeds the scene allows: prescribed speed plus |ω| r for
prescribed bodies, |v₀| t + |g| t²/2 for free bodies in a dry scene (until the first
contact only gravity acts), zero for fixed bodies (:func:`contact_candidates`).

Examples
--------
>>> from fluidem.scene import Scene
>>> from fluidem.plan import make_plan
>>> s = Scene.from_dict({"gravity": [0.0, -9.81], "domain": {"box": [0, 1, 0, 1]},
...                      "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.08]}],
...                      "contact": {"E": 1e5}, "time": {"dt": 1e-3, "t_end": 0.1}})
>>> p = make_plan(s)
>>> p.mesh, p.on("contacts"), p.contact_pairs
('none', True, 1)
>>> print(p.effect("contacts"))  # doctest: +ELLIPSIS
  contacts        on  [E=100000, mu=0.23, gamma=0.025]  — 0 body pair(s) and 1 body–wall pair(s) may meet ...
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .effects import Effect, Plan
from .estimate import (BYTES_BASE, BYTES_PER_DOF, DOFS_PER_VERTEX, MIN_EDGES_PER_BODY,  # noqa: F401 (kept here)
                       MIN_THICKNESS_PER_H, TRIANGLES_PER_AREA, machine_memory, mesh_estimate)
from .limits import (EXPLICIT_COUPLING_MIN_RATIO, FLUX_TOLERANCE, MAX_CONTACT_SUBSTEPS,  # noqa: F401 (kept here)
                     REFUSED_CONTACT_SUBSTEPS, boundary_fluxes, contact_sub_steps)
from .reach import contact_candidates, prescribed_collisions
from .rules import RULES, Context, apply_rules, moving_mesh_available

if TYPE_CHECKING:  # pragma: no cover
    from ..scene import Scene

__all__ = ["Plan", "Effect", "make_plan", "moving_mesh_available", "contact_candidates", "prescribed_collisions",
           "mesh_estimate", "machine_memory", "boundary_fluxes", "FLUX_TOLERANCE", "contact_sub_steps",
           "MAX_CONTACT_SUBSTEPS", "REFUSED_CONTACT_SUBSTEPS"]


def make_plan(scene: Scene) -> Plan:
    """The effects ``scene`` needs and why, see :class:`Plan` (:meth:`fluidem.scene.Scene.plan` calls this).

    Applies :data:`fluidem.plan.rules.RULES` in order to the scene's
    :class:`~fluidem.plan.rules.Context`, built with this module's :func:`moving_mesh_available`
    and :func:`machine_memory` (so that replacing either here reaches the plan).

    Parameters
    ----------
    scene : fluidem.scene.Scene
        A validated scene.

    Returns
    -------
    Plan
    """
    return apply_rules(scene, Context.of(scene, moving_mesh_available, machine_memory), RULES)
