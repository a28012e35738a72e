"""fluidem: resolved simulation of polygonal rigid particles in 2D incompressible flow.

Finite elements on triangle meshes that fit every particle outline (no-slip on particle
surfaces), coupled to a polygonal discrete element method.
"""

__version__ = "0.1.0.dev0"

from .scene import Scene  # noqa: E402
from .simulation import Simulation, run  # noqa: E402

__all__ = ["__version__", "Scene", "Simulation", "run"]
