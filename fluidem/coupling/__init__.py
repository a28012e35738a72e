"""The coupling layer: the only place that knows bodies, mesh and fluid.

* :mod:`~fluidem.coupling.bodies`: bodies as motion providers (closed-form kinematics,
  the DEM, prescribed linear paths);
* :mod:`~fluidem.coupling.boundary`: velocity conditions of a domain and its bodies (box sides,
  inflow profiles, rigid no-slip on bodies);
* :mod:`~fluidem.coupling.loads`: hydrodynamic loads through the rigid-mode operator;
* :mod:`~fluidem.coupling.fixed_flow`: the flow around bodies whose outlines do not move;
* :mod:`~fluidem.coupling.moving_flow`: ALE flow on the moving mesh around prescribed bodies.

Its classes and functions take the specs they need (the bodies' :class:`~fluidem.scene.BodySpec`
list and outlines, the :class:`~fluidem.scene.DomainSpec`, :class:`~fluidem.scene.FluidSpec`,
:class:`~fluidem.scene.ContactSpec`, :class:`~fluidem.scene.MeshSpec`, gravity, the time step),
never a whole :class:`~fluidem.scene.Scene`; :mod:`fluidem.build` takes a scene apart for them.

``fluidem.mesh`` does not import ``fluidem.fluid``, ``fluidem.fluid`` imports neither
``fluidem.dem`` nor ``fluidem.mesh.moving``; the submodules here import them lazily, so a dry
run never loads the mesh or fluid layers.
"""

from .bodies import DEMBodies, KinematicBodies, LinearPath

__all__ = ["DEMBodies", "KinematicBodies", "LinearPath"]
