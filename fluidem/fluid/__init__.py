"""Incompressible flow on fixed or moving (ALE) triangle meshes: elements, forms, solvers, forces.

The entry points of the fluid layer, importable in one line:

* spaces and conditions: :class:`FlowSpace`, :class:`VelocityBC`, :class:`RigidMotion`,
  element pairs :func:`element_pair` / :data:`ELEMENT_PAIRS`;
* problems and solutions: :class:`FlowProblem`, :class:`FlowState`, :func:`solve_stokes`,
  :func:`solve_steady` (Newton), :class:`BDF2Stepper` (unsteady, ALE);
* linear solvers by name: :func:`make_solver` (:mod:`fluidem.fluid.solvers`);
* loads and signals: :func:`body_loads`, :func:`periodic_stats`.

Examples
--------
>>> from fluidem.fluid import FlowProblem, FlowSpace, VelocityBC, body_loads, solve_steady
>>> from fluidem.cases.dfg import dfg_mesh
>>> inflow = VelocityBC("left", lambda x, y, t: [1.2 * y * (0.41 - y) / 0.41**2, 0 * y])
>>> problem = FlowProblem(FlowSpace(dfg_mesh(0), "th"), 1e-3,
...                       [VelocityBC(("bottom", "top", "cylinder")), inflow])
>>> state = solve_steady(problem)
>>> load = body_loads(problem.space, problem.steady_residual(state.x), "cylinder")
>>> round(2 * load.fx / (0.2**2 * 0.1), 1)  # drag coefficient of DFG 2D-1 (reference 5.5795)
5.6
"""

from .elements import ELEMENT_PAIRS, ElementPair, element_pair
from .forces import BodyLoad, PeriodicStats, body_loads, periodic_stats
from .navier_stokes import BDF2Stepper, FlowProblem, FlowState, NewtonError, solve_stokes, solve_steady
from .solvers import SolveInfo, SolverError, make_solver
from .space import FlowSpace, RigidMotion, VelocityBC

__all__ = [
    "FlowSpace",
    "VelocityBC",
    "RigidMotion",
    "ElementPair",
    "ELEMENT_PAIRS",
    "element_pair",
    "FlowProblem",
    "FlowState",
    "NewtonError",
    "solve_stokes",
    "solve_steady",
    "BDF2Stepper",
    "make_solver",
    "SolveInfo",
    "SolverError",
    "BodyLoad",
    "body_loads",
    "PeriodicStats",
    "periodic_stats",
]
