"""The coupling layer: the only place that knows bodies, mesh and fluid.

* :mod:`~fluidem.coupling.bodies`: scene bodies as motion providers (closed-form kinematics,
  the DEM, prescribed linear paths);
* :mod:`~fluidem.coupling.boundary`: velocity conditions of a scene (box sides, inflow
  profiles, rigid no-slip on bodies);
* :mod:`~fluidem.coupling.loads`: hydrodynamic loads through the rigid-mode operator;
* :mod:`~fluidem.coupling.fixed_flow`: the flow around bodies whose outlines do not move;
* :mod:`~fluidem.coupling.moving_flow`: ALE flow on the moving mesh around prescribed bodies.

``fluidem.mesh`` does not import ``fluidem.fluid``, ``fluidem.fluid`` imports neither
``fluidem.dem`` nor ``fluidem.mesh.moving``; the submodules here import them lazily, so a dry
scene never loads the mesh or fluid layers.
"""

from .bodies import DEMBodies, KinematicBodies, LinearPath

__all__ = ["DEMBodies", "KinematicBodies", "LinearPath"]
