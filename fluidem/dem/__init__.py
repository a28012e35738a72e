"""Polygonal discrete element method: rigid convex polygons with overlap-area contacts.

Entry points::

    from fluidem.dem import Body, ContactModel, DEM
    b = Body.polygon(vertices, density=..., position=(x, y), angle=0.0, velocity=(0, 0), omega=0.0, motion="free")
    sim = DEM(bodies, walls=(xmin, xmax, ymin, ymax), gravity=(0, -9.81), contact=ContactModel(E=..., mu=..., gamma=...))
    sim.step(dt); sim.run(t_end, dt); sim.advance(duration)

Modules: :mod:`~fluidem.dem.bodies` (shapes and mass properties),
:mod:`~fluidem.dem.contact` (broad phase, overlap geometry, force law),
:mod:`~fluidem.dem.integrate` (Gear predictor–corrector),
:mod:`~fluidem.dem.system` (the DEM system: arrays of bodies, stepping, energies).
"""

from .bodies import Body, random_convex_vertices
from .contact import WALL_IDS, ContactModel, Contacts
from .integrate import Gear
from .system import DEM, StepCost

__all__ = ["Body", "ContactModel", "Contacts", "DEM", "Gear", "StepCost", "WALL_IDS",
           "random_convex_vertices"]
