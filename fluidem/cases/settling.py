"""A disk settling on the centre line of a vertical channel, and its terminal velocity computed
independently in the disk's frame.

Lab frame (:func:`settling_scene`): a free disk of radius ``a`` (a regular polygon of
``segments`` sides) and density ρ_s released at rest in a closed channel of width ``2 l`` full
of fluid at rest (density ρ_f, kinematic viscosity ν), gravity (0, −g); the coupled
fluid–body solver moves it (:class:`fluidem.coupling.free_flow.FreeBodyFlow`).

Disk frame (:func:`steady_terminal_velocity`): the same disk held fixed in a channel whose
walls move up at U, with uniform inflow U at the bottom and a do-nothing top: the steady
Navier–Stokes flow past it (Newton, :func:`fluidem.fluid.navier_stokes.solve_steady`) gives
the drag D(U); the terminal velocity solves D(U) = (ρ_s − ρ_f) A g (secant iteration on U).
The two share the element pair and the mesh size at the disk but nothing else (mesh
generator, time stepping, coupling), so their agreement tests the coupled step.
"""

from __future__ import annotations

import time

import numpy as np

from ..geometry import regular_polygon
from ..scene import Scene
from .base import CaseResult, register_case

__all__ = ["settling_disk", "settling_scene", "steady_terminal_velocity"]


def _disk(a: float, segments: int) -> list:
    return regular_polygon(a, segments).tolist()


def settling_scene(a=0.1, half_width=0.5, height=6.0, start=4.0, density=1.5, nu=0.01, g=1.0, h=0.02,
                   segments=64, dt=0.01, t_end=3.0, element="p2b") -> Scene:
    """The lab-frame scene: the disk released at (0, ``start``) in [−l, l] × [0, height]."""
    return Scene.from_dict({
        "gravity": [0.0, -g], "fluid": {"model": "navier-stokes", "viscosity": nu, "density": 1.0,
                                         "element": element},
        "domain": {"box": [-half_width, half_width, 0.0, height]},
        "bodies": [{"name": "disk", "shape": "polygon", "vertices": _disk(a, segments), "position": [0.0, start],
                    "density": density}],
        "mesh": {"h": h, "grading": {"growth": 1.2, "h_max": 8 * h}},
        "time": {"dt": dt, "t_end": t_end}})


def _frame_scene(U, a, half_width, length, nu, h, segments, element) -> Scene:
    wall = {"type": "moving-wall", "velocity": [0.0, U]}
    return Scene.from_dict({
        "gravity": [0.0, 0.0], "fluid": {"model": "navier-stokes", "viscosity": nu, "density": 1.0,
                                          "element": element},
        "domain": {"box": [-half_width, half_width, -length, length], "left": wall, "right": wall,
                   "bottom": {"type": "inflow", "profile": {"type": "uniform", "umax": U, "ramp": 0.0}},
                   "top": "outflow"},
        "bodies": [{"name": "disk", "shape": "polygon", "vertices": _disk(a, segments), "position": [0.0, 0.0],
                    "motion": "fixed"}],
        "mesh": {"h": h, "grading": {"growth": 1.2, "h_max": 8 * h}},
        "time": {"dt": 1.0, "t_end": 1.0}})


def steady_terminal_velocity(a=0.1, half_width=0.5, density=1.5, nu=0.01, g=1.0, h=0.02, segments=64,
                             length=3.0, element="p2b", U0=None, tol=1e-6) -> dict:
    """Terminal velocity (length/time, downwards) from steady flows in the disk's frame.

    Returns a dict with ``U`` (the terminal speed), ``drag`` (at ``U``), ``weight`` (the buoyant
    weight it balances), ``iterations`` and ``dofs``.
    """
    from ..fluid.navier_stokes import solve_steady
    from ..simulation import Simulation

    area = 0.5 * segments * a * a * np.sin(2 * np.pi / segments)
    weight = (density - 1.0) * area * g

    def drag(U):
        sim = Simulation(_frame_scene(U, a, half_width, length, nu, h, segments, element))
        fl = sim.flow
        st = solve_steady(fl.problem)
        F, _ = fl.rigid.loads(fl.problem.steady_residual(st.x), rho=1.0)
        return float(F[0, 1]), fl.dofs

    U1 = U0 if U0 is not None else 0.5 * weight / (4 * np.pi * nu / (np.log(half_width / a) - 0.9))
    U2 = 1.2 * U1
    D1, dofs = drag(U1)
    D2, _ = drag(U2)
    it = 2
    while abs(U2 - U1) > tol * abs(U2) and it < 20:
        U1, U2, D1 = U2, U2 + (weight - D2) * (U2 - U1) / (D2 - D1), D2
        D2, _ = drag(U2)
        it += 1
    return {"U": U2, "drag": D2, "weight": weight, "iterations": it, "dofs": dofs}


def _aitken(v: np.ndarray) -> float:
    """Limit of an exponentially converging sequence from its last three (equally spaced) terms
    (Aitken's Δ² process)."""
    a, b, c = v[-3:]
    d = (c - b) - (b - a)
    return float(c if d == 0 else c - (c - b) ** 2 / d)


@register_case("settling-disk")
def settling_disk(element: str = "p2b", h: float = 0.025, dt: float = 0.01, t_end: float = 5.0,
                  progress=None) -> CaseResult:
    """A free disk settling in a channel (ρ_s/ρ_f = 1.5, Re ≈ 1.8) against its steady terminal velocity.

    Lab frame: :func:`settling_scene` (k = a/l = 0.2, ν = 0.01, g = 1), the disk released at
    rest and moved by the coupled solver until ``t_end``.  Reference: the terminal velocity of
    :func:`steady_terminal_velocity` on a mesh of the same ``h`` (an independent computation in
    the disk's frame, not a published number).  ``u_terminal`` is the settling speed
    extrapolated from the last three half-time-unit samples (Aitken's Δ²: the approach is
    exponential); ``u_end`` the speed at ``t_end``; ``drift`` the sideways displacement over
    the distance fallen.
    """
    from ..simulation import Simulation

    t0 = time.perf_counter()
    ref = steady_terminal_velocity(h=h, element=element)
    t_ref = time.perf_counter() - t0
    sim = Simulation(settling_scene(h=h, dt=dt, t_end=t_end, element=element))
    n = sim.plan.n_steps
    every = max(1, int(round(0.5 / dt)))
    samples = []

    def record(k, n_steps, t, cost):
        if k % every == 0:
            samples.append(-sim.flow.body_velocities[0, 1])
        if progress and k % max(1, n_steps // 20) == 0:
            progress(k, n_steps, t)

    t0 = time.perf_counter()
    sim.run(out_dir=None, progress=record)
    t_run = time.perf_counter() - t0
    fallen = 4.0 - sim.flow.poses[0, 1]
    q = {"u_terminal": _aitken(np.array(samples)), "u_end": float(samples[-1]),
         "drift": float(abs(sim.flow.poses[0, 0]) / fallen)}
    return CaseResult("settling-disk", element, 0, sim.flow.dofs, q, {"u_terminal": ref["U"]},
                      {"reference": t_ref, "coupled run": t_run}, "polygonal", dt,
                      extra={"steps": n, "triangulations": sim.counters["triangulations"],
                             "reference_dofs": int(ref["dofs"])})
