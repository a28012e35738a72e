"""fluidem: resolved simulation of polygonal rigid particles in 2D incompressible flow.

Finite elements on triangle meshes that fit every particle outline (no-slip on particle
surfaces), coupled to a polygonal discrete element method.  A run goes scene -> plan ->
simulation: :class:`Scene` (:mod:`fluidem.scene`) says what to simulate, its plan
(:mod:`fluidem.plan`) which parts that needs and why, :class:`Simulation` builds only those.

Units
-----
fluidem has no built-in unit system.  Every quantity is in the one consistent system the
user picks — SI (m, kg, s, N, Pa) or CGS (cm, g, s, dyn), say — and nothing converts.
Quantities are two-dimensional and per unit depth: densities are mass/length² (a 3D density
times the unit depth), and masses, moments of inertia and forces are per unit depth too.
Viscosity in scenes is *kinematic*, ν = μ/ρ in length²/time (the dynamic viscosity is
density × viscosity); the fluid is solved for the kinematic pressure p/ρ.  Docstrings name
quantities in these terms (length, time, mass; length/time² for gravity).

Names
-----
Every name a user types (element pairs, solvers, convection schemes, mesh strategies, body
shapes and motions, side types, sides, cases, example scenes) is one entry of
:data:`fluidem.names.REGISTRY`, shared by scene files, the command line and the Python
factories; bad input raises :class:`fluidem.errors.FluidemError` subclasses with one-line
messages.
"""

from .scene import Scene
from .simulation import Simulation, run
from .version import __version__

__all__ = ["__version__", "Scene", "Simulation", "run"]
