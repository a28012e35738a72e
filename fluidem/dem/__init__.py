"""Polygonal discrete element method: rigid convex polygons with overlap-area contacts.

Entry points::

    from fluidem.dem import Body, ContactModel, DEM
    b = Body.polygon(vertices, density=..., position=(x, y), angle=0.0, velocity=(0, 0), omega=0.0, motion="free")
    sim = DEM(bodies, walls=(xmin, xmax, ymin, ymax), gravity=(0, -9.81),
              contact=ContactModel(E=..., mu=..., gamma=...))
    sim.step(dt); sim.run(t_end, dt); sim.advance(duration)

Units
-----
fluidem has no built-in unit system: every quantity is in one consistent system the user
picks, e.g. SI (m, kg, s, N) or CGS (cm, g, s, dyn).  Docstrings give dimensions, with
SI as the example.  A 2D body stands for a slab of unit depth, so its quantities are those
of that slab:

===========================  ==============================  ========================
quantity                     dimension                       SI (CGS)
===========================  ==============================  ========================
length, position, skin       length                          m (cm)
areal density                mass/length²                    kg/m² (g/cm²)
mass                         mass                            kg (g)
moment of inertia            mass·length²                    kg·m² (g·cm²)
velocity; gravity            length/time; length/time²       m/s; m/s² (cm/s; cm/s²)
angle; angular velocity      rad; rad/time                   rad; rad/s
force; torque                force; force·length             N; N·m (dyn; dyn·cm)
E, tangential stiffness k_t  force/length                    N/m (dyn/cm)
energy, contact work         force·length                    J (erg)
time, time step              time                            s
===========================  ==============================  ========================

``E`` is the 2D modulus of the overlap law ``F = E A / l`` (Matuttis & Chen 2014, ch. 7):
a force per length, i.e. a 3D Young's modulus (force/length²) times the unit depth.

Modules: :mod:`~fluidem.dem.bodies` (shapes and mass properties),
:mod:`~fluidem.dem.contact` (the contact law and forces), :mod:`~fluidem.dem.broad_phase`
(candidate pairs), :mod:`~fluidem.dem.overlaps` (overlap geometry, the narrow phase),
:mod:`~fluidem.dem.integrate` (Gear predictor–corrector),
:mod:`~fluidem.dem.system` (the DEM system: arrays of bodies, stepping, energies),
:mod:`~fluidem.dem.periodic` (periodic boxes: the nearest image of each pair's partner);
for bodies in a fluid :mod:`~fluidem.dem.repulsion` (short-range repulsion) and
:mod:`~fluidem.dem.lubrication` (the squeeze-film correction below the mesh resolution).
"""

from .bodies import Body, random_convex_vertices
from .contact import ContactModel, Contacts
from .integrate import Gear
from .overlaps import WALL_IDS
from .system import DEM, StepCost

__all__ = ["Body", "ContactModel", "Contacts", "DEM", "Gear", "StepCost", "WALL_IDS",
           "random_convex_vertices"]
