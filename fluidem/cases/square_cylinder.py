"""Flow past a square cylinder at Re = 100 (Sohankar, Norberg & Davidson 1998).

Square of side D = 1 centred at the origin, uniform inflow U∞ = 1 at x = −10 D, do-nothing
outflow at x = +20 D, free-slip (symmetry) walls at y = ±10 D (blockage D/H = 5 %), ν = 0.01
(Re = U∞ D / ν = 100).  References at 5 % blockage: C_D = 1.478, St = 0.146, rms C_L = 0.153
(Sohankar et al. 1998); Sen, Mittal & Biswas (2011) give St = 0.145, C_D = 1.53.  The inlet
and outlet distances and the outflow condition move these by a few percent.

Mesh levels: cell size h₀ = 0.1 D / 2^level at the square, growing by 1.15 per cell to
h_max = 2 D / 2^level.
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

from ..errors import InputError
from ..fluid.forces import body_loads, periodic_stats
from ..fluid.navier_stokes import BDF2Stepper, FlowProblem
from ..fluid.solvers import make_solver
from ..fluid.space import FlowSpace, RigidMotion, VelocityBC
from ..geometry import rectangle
from ..mesh.background import GradedSize
from ..mesh.triangulate import Obstacle, to_skfem, triangulate_box
from .base import CaseResult, register_case

__all__ = ["square_cylinder", "square_cylinder_mesh", "REFERENCE", "DOMAIN"]

REFERENCE = {"cd_mean": 1.478, "st": 0.146, "cl_rms": 0.153}
DOMAIN = (-10.0, 20.0, -10.0, 10.0)


def square_cylinder_mesh(level: int = 1):
    """Graded mesh around the unit square in the 5 %-blockage channel :data:`DOMAIN`.

    Parameters
    ----------
    level : int
        0 to 5; the cell size at the square is 0.1 D / 2^level.

    Returns
    -------
    skfem.MeshTri
        With boundaries ``left`` (inflow), ``right`` (outflow), ``bottom``, ``top`` and ``square``.

    Examples
    --------
    >>> from fluidem.cases.square_cylinder import square_cylinder_mesh
    >>> sorted(square_cylinder_mesh(level=0).boundaries)
    ['bottom', 'left', 'right', 'square', 'top']
    """
    if int(level) != level or not 0 <= level <= 5:
        raise InputError(f"mesh level must be an integer from 0 to 5, got {level!r}")
    h0 = 0.1 / 2**level
    sq = Obstacle(rectangle(1.0, 1.0), "square")
    size = GradedSize(h_min=h0, growth=1.15, h_max=2.0 / 2**level, region=[sq.vertices])
    return to_skfem(triangulate_box(DOMAIN, [sq], size))


@register_case("square-cylinder")
def square_cylinder(element: str = "th", level: int = 1, dt: float = 0.05, t_end: float = 150.0,
                    window: float = 50.0, convection: str = "semi-implicit",
                    progress: Callable[[int, int, float], None] | None = None,
                    solver: str = "lagged") -> CaseResult:
    """Square cylinder at Re = 100, 5 % blockage: St, mean C_D and rms C_L on the last ``window``.

    Units are those of the case (D = U∞ = ρ = 1, ν = 0.01): times in D / U∞.  A short
    rotation of the square (t < 2) triggers the shedding.

    Parameters
    ----------
    element : str
        Element pair name.
    level : int
        Mesh level of :func:`square_cylinder_mesh`.
    dt, t_end, window : float
        BDF2 time step, end time and length of the measuring window ``[t_end − window, t_end]``.
    convection : str
        Treatment of the convection term by :class:`~fluidem.fluid.navier_stokes.BDF2Stepper`.
    progress : callable, optional
        ``progress(step, n_steps, t)``, called 20 times during the run.
    solver : str
        A name of :func:`~fluidem.fluid.solvers.make_solver`.

    Returns
    -------
    CaseResult
        Quantities ``st``, ``cd_mean``, ``cl_rms`` against :data:`REFERENCE`, and ``cd_max``,
        ``cl_max``.
    """
    if not 0 < window < t_end:
        raise InputError(f"window = {window:g}: expected a positive window shorter than t_end ({t_end:g})")
    t0 = time.perf_counter()
    mesh = square_cylinder_mesh(level)
    t_mesh = time.perf_counter() - t0
    kick = RigidMotion(omega=lambda t: 0.5 * np.sin(np.pi * t / 2.0) if t < 2.0 else 0.0)
    bcs = [
        VelocityBC(("bottom", "top"), (0.0, 0.0), components=(1,)),  # free slip
        VelocityBC("left", (1.0, 0.0)),
        VelocityBC("square", kick),
    ]
    pr = FlowProblem(FlowSpace(mesh, element), 0.01, bcs)
    stepper = BDF2Stepper(pr, dt, convection=convection, solver=make_solver(solver, problem=pr, dt=dt))
    n = int(round(t_end / dt))
    ts, cd, cl = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        stepper.step()
        load = body_loads(pr.space, stepper.last_residual(), "square")
        ts[k], cd[k], cl[k] = stepper.t, 2.0 * load.fx, 2.0 * load.fy  # ρ = U∞ = D = 1
        if progress and (k + 1) % max(1, n // 20) == 0:
            progress(k + 1, n, stepper.t)
    sl = periodic_stats(ts, cl, t_end - window)
    sd = periodic_stats(ts, cd, t_end - window)
    q = {"st": 1.0 / sl.period, "cd_mean": sd.mean, "cl_rms": sl.rms, "cd_max": sd.max, "cl_max": sl.max}
    return CaseResult("square-cylinder", element, level, pr.space.n_dofs, q, REFERENCE,
                      {"mesh": t_mesh, "assembly": pr.timings.assembly, "solve": pr.timings.solve},
                      "polygonal", dt, extra={"steps": stepper.n_steps, "periods_measured": sl.n_periods,
                                              "convection": convection, **stepper.solver_summary()})
