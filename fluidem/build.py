"""A scene taken apart into the parts of a run: the one place that hands scene specs to the coupling layer.

The classes of :mod:`fluidem.coupling` take the specs each needs (the bodies' list of
:class:`~fluidem.scene.BodySpec` and their outlines, the :class:`~fluidem.scene.DomainSpec`,
:class:`~fluidem.scene.FluidSpec`, :class:`~fluidem.scene.ContactSpec`,
:class:`~fluidem.scene.MeshSpec`, gravity, the time step), never a :class:`~fluidem.scene.Scene`;
the functions here unpack a scene for them.  :class:`fluidem.simulation.Simulation` builds its
bodies and flow with them, :mod:`fluidem.restart` the DEM that continues closed-form motion.

Examples
--------
>>> from fluidem.scene import Scene
>>> from fluidem import build
>>> s = Scene.from_dict({"gravity": [0, -10], "domain": {"box": [0, 1, 0, 1]},
...                      "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.5, 0.8]}]})
>>> [v.shape for v in build.body_outlines(s)]
[(32, 2)]
>>> type(build.bodies_of(s, contacts=False)).__name__
'KinematicBodies'
"""

from __future__ import annotations

from .coupling.bodies import DEMBodies, FlowBodies, KinematicBodies

__all__ = ["body_frame_flow", "body_outlines", "bodies_of", "dem_from_kinematic", "fixed_mesh_flow",
           "free_body_flow", "moving_mesh_flow"]


def body_outlines(scene) -> list:
    """Every body's outline in body coordinates, list of (k_i, 2) float arrays (length), with the
    scene's vertex count for disks and ellipses (:meth:`fluidem.scene.Scene.default_segments`)."""
    return [b.local_vertices(scene.default_segments(b)) for b in scene.bodies]


def bodies_of(scene, contacts: bool):
    """The motion provider of the scene's bodies.

    Parameters
    ----------
    scene : fluidem.scene.Scene
    contacts : bool
        Whether the plan has contacts on (``plan.on("contacts")``).

    Returns
    -------
    DEMBodies or FlowBodies or KinematicBodies
        The DEM for a dry scene with contacts; bodies moved by the flow for a fluid scene with
        free bodies (its ``flow`` set once the flow exists, :func:`free_body_flow`); closed-form
        motion otherwise.
    """
    if contacts and scene.fluid is None:
        return DEMBodies(scene.bodies, body_outlines(scene), domain=scene.domain, contact=scene.contact,
                         gravity=scene.gravity)
    if scene.fluid is not None and any(b.motion == "free" for b in scene.bodies):
        return FlowBodies(scene.bodies, scene.gravity)
    return KinematicBodies(scene.bodies, scene.gravity)


def dem_from_kinematic(scene, kinematic: KinematicBodies) -> DEMBodies:
    """The DEM of the scene's bodies continuing the closed-form motion of ``kinematic`` at its
    time (:meth:`fluidem.coupling.bodies.DEMBodies.from_kinematic`; the scene is not changed)."""
    return DEMBodies.from_kinematic(kinematic, scene.bodies, body_outlines(scene), domain=scene.domain,
                                    contact=scene.contact, gravity=scene.gravity)


def fixed_mesh_flow(scene, sim):
    """The flow of a fluid scene around bodies whose outlines do not move
    (:class:`fluidem.coupling.fixed_flow.FixedMeshFlow`); ``sim``: the run, whose ``counters`` it charges."""
    from .coupling.fixed_flow import FixedMeshFlow

    return FixedMeshFlow(scene.bodies, body_outlines(scene), domain=scene.domain, fluid=scene.fluid, mesh=scene.mesh,
                         time=scene.time, sim=sim)


def body_frame_flow(scene, velocity, sim):
    """:func:`fixed_mesh_flow` started from the uniform flow ``velocity`` (length/time, (2,)) with the
    scene's boundary values: the body frame of a body translating at −``velocity`` (with walls moving
    at ``velocity``), the reference of a Galilean check against the lab frame on a moving mesh."""
    import numpy as np

    flow = fixed_mesh_flow(scene, sim)
    sp = flow.space
    u0 = np.zeros(sp.n_u)
    for c in range(2):  # interleaved velocity components
        u0[sp.ub.dofs.element_dofs[c::2].ravel()] = velocity[c]
    d, v = flow.problem.dirichlet_values(0.0)
    u0[d] = v
    flow.stepper.take_over(flow.problem, u0)
    return flow


def moving_mesh_flow(scene, sim):
    """The ALE flow of a fluid scene around prescribed bodies on the moving mesh
    (:class:`fluidem.coupling.moving_flow.MovingMeshFlow`); ``sim``: the run, whose ``counters`` it charges."""
    from .coupling.moving_flow import MovingMeshFlow

    return MovingMeshFlow(scene.bodies, body_outlines(scene), domain=scene.domain, fluid=scene.fluid,
                          mesh=scene.mesh, dt=scene.time.dt, sim=sim)


def free_body_flow(scene, sim):
    """The flow of a fluid scene with free bodies, which it moves
    (:class:`fluidem.coupling.free_flow.FreeBodyFlow`).

    ``sim``: the run, whose ``counters`` it charges and whose ``plan`` says whether contacts are on
    (then the flow gets the scene's ``contact``).
    """
    from .coupling.free_flow import FreeBodyFlow

    contact = scene.contact if sim.plan.on("contacts") else None
    return FreeBodyFlow(scene.bodies, body_outlines(scene), domain=scene.domain, fluid=scene.fluid, mesh=scene.mesh,
                        dt=scene.time.dt, gravity=scene.gravity, contact=contact, sim=sim)
