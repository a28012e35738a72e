"""A body oscillating by a fraction of an element in a channel flow: snap-back against dragging.

The paper (Sec. 3.3, Fig. 5) regenerates the mesh at every step (the older method: the
background nodes snap back to their grid and the whole pipeline runs again) and observes that a
small motion of the bodies toggles elements between two triangulations, each toggle transferring
the fields by interpolation; dragging the mesh with the bodies (Sec. 4.2) keeps the connectivity
and transfers nothing.  The case: a square body of side 0.2 (a polygon), centred at the origin of
the channel [−1, 2] × [−0.5, 0.5], uniform inflow U = 1 on the left (from rest, raised smoothly
over ``ramp``), outflow on the right, walls top and bottom, Navier–Stokes ν = 0.01 (Re = U · 0.2 /
ν = 20), P2+bubble/P1dc, moved by a prescribed vertical oscillation

.. math::

    y(t) = A \\sin(2 \\pi t / T), \\qquad v(t) = \\tfrac{2 \\pi A}{T} \\cos(2 \\pi t / T),

of amplitude ``A`` a fraction of the mesh size ``h`` and period ``T`` a few steps, so that the
body goes back and forth across the same few positions.  The body's velocity condition at each
step is v at the end of the step.  Strategies (:mod:`fluidem.mesh.moving`): ``"regenerate"``
(a new mesh every step), the same with fewer relaxation sweeps (``relax_iterations``; 20 by
default), and ``"drag"`` (the default: 3 sweeps, a re-triangulation every 30 steps or when a
trigger fires).  The reference is the same motion dragged on a mesh of half the size.

Per step (:func:`oscillation_run`): the interpolation noise of the step's re-triangulation
(:func:`fluidem.coupling.moving_flow.transfer_change`), the condition estimate κ₁ of the step's
LUs and the oscillating nodes of the relaxation (:class:`fluidem.diagnostics.RunDiagnostics`,
:class:`fluidem.mesh.quality.OscillationDetector`), whether it re-triangulated and the force on
the body.  :func:`force_deviation` compares a run's force history with the reference's.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..scene import Scene

__all__ = ["SIDE", "oscillation_scene", "OscillatingPath", "oscillation_run", "force_deviation"]

#: side of the square body (length)
SIDE = 0.2


def oscillation_scene(h: float = 0.05, dt: float = 0.02, t_end: float = 0.8, strategy: str = "drag",
                      ramp: float = 0.2, nu: float = 0.01, element: str = "p2b",
                      velocity: tuple[float, float] = (0.0, 1.0)) -> Scene:
    """The channel with the square body at the origin, prescribed with a constant ``velocity``
    (:func:`oscillation_run` replaces it by the oscillation; a body at rest would be meshed once);
    LUs by SuperLU (``fluid.lu_backend``), so that runs with and without PARDISO agree.

    Parameters
    ----------
    h : float
        Mesh size (length), uniform.
    dt, t_end : float
        Time step and end time (time).
    strategy : {"drag", "regenerate"}
        The moving mesh's strategy.
    ramp : float
        Time over which the inflow rises from 0 to U = 1 (time).
    nu : float
        Kinematic viscosity (length²/time).
    element : str
        Element pair of the fluid.
    velocity : (2,) float
        The body's constant velocity (length/time).

    Examples
    --------
    >>> s = oscillation_scene(0.05, strategy="regenerate")
    >>> s.mesh.strategy, s.bodies[0].motion
    ('regenerate', 'prescribed')
    """
    a = SIDE / 2.0
    return Scene.from_dict({
        "gravity": [0.0, 0.0],
        # SuperLU whatever extras are installed: the case compares mesh strategies under one LU
        # policy (a lagged PARDISO LU also refactorises by cost: 7 LUs in 20 drag steps, not 1)
        "fluid": {"model": "navier-stokes", "viscosity": nu, "density": 1.0, "element": element,
                  "lu_backend": "superlu"},
        "domain": {"box": [-1.0, 2.0, -0.5, 0.5],
                   "left": {"type": "inflow", "profile": {"type": "uniform", "umax": 1.0, "ramp": ramp}},
                   "right": "outflow"},
        "bodies": [{"name": "square", "shape": "polygon", "vertices": [[-a, -a], [a, -a], [a, a], [-a, a]],
                    "position": [0.0, 0.0], "motion": "prescribed", "density": 1.0,
                    "velocity": [float(v) for v in velocity]}],
        "mesh": {"h": h, "strategy": strategy},
        "time": {"dt": dt, "t_end": t_end}})


class OscillatingPath:
    """Prescribed vertical oscillation ``path(t) -> (position (2,), angle)`` about ``position``.

    Parameters
    ----------
    position : (2,) float
        Centre of the oscillation (length).
    amplitude : float
        A (length).
    period : float
        T (time).

    Examples
    --------
    >>> p = OscillatingPath((0.0, 0.0), 0.01, 0.08)
    >>> pos, angle = p(0.02)
    >>> [round(float(v), 12) for v in pos], angle
    ([0.0, 0.01], 0.0)
    >>> round(float(p.velocity(0.0)[1]), 6)   # 2π A / T
    0.785398
    """

    def __init__(self, position, amplitude: float, period: float):
        self.position = np.asarray(position, float)
        self.amplitude = float(amplitude)
        self.period = float(period)

    def __call__(self, t):
        y = self.amplitude * np.sin(2.0 * np.pi * t / self.period)
        return self.position + np.array([0.0, y]), 0.0

    def velocity(self, t) -> np.ndarray:
        """Velocity (2,) at ``t`` (length/time)."""
        w = 2.0 * np.pi / self.period
        return np.array([0.0, self.amplitude * w * np.cos(w * t)])


def oscillation_run(h: float = 0.05, strategy: str = "drag", relax_iterations: int | None = None,
                    amplitude: float = 0.25, period_steps: int = 4, steps: int = 40, dt: float = 0.02,
                    ramp: float = 0.2) -> dict:
    """Run the oscillating body and record the mesh's and the solver's health at every step.

    Parameters
    ----------
    h : float
        Mesh size (length).
    strategy : {"drag", "regenerate"}
    relax_iterations : int, optional
        Relaxation sweeps per step (``MeshParams.relax_iterations``, not a scene key); the
        strategy's default (3 drag, 20 regenerate) if not given.
    amplitude : float
        A over the reference size 0.05 (so that every mesh moves the body along the same path).
    period_steps : int
        T over dt.
    steps : int
        Steps to run.
    dt, ramp : float
        Time step and inflow ramp time (time).

    Returns
    -------
    dict
        Settings and, per step (lists of length ``steps``): ``t``, ``y`` (body centre, length),
        ``noise`` (relative L2 change of u by the step's transfer, or None), ``condition`` (largest
        κ₁ of the step's LUs, or None), ``oscillating`` (nodes), ``retriangulated`` (bool),
        ``force`` ((2,) on the body, force per unit depth), ``force_change`` (|F_n − F_{n−1}|, the
        first None); and ``triangulations`` (in the steps), ``noise_total`` (sum of the noise),
        ``dofs`` (at the start), ``step_median`` (s), ``run_seconds`` (the steps).
    """
    from ..simulation import Simulation

    path = OscillatingPath((0.0, 0.0), amplitude * 0.05, period_steps * dt)
    sim = Simulation(oscillation_scene(h, dt=dt, t_end=steps * dt, strategy=strategy, ramp=ramp,
                                       velocity=tuple(path.velocity(0.0))))
    flow = sim.flow
    mm = flow.mm
    if relax_iterations is not None:
        mm.params = dataclasses.replace(mm.params, relax_iterations=int(relax_iterations))
    flow.path[0] = path
    spec = flow.body_specs[0]
    diag = sim.diagnostics
    diag.finish_step(0, 0.0)  # the set-up's LUs belong to no step
    out = {k: [] for k in ("t", "y", "noise", "condition", "oscillating", "retriangulated", "force",
                           "force_change")}
    dofs = int(flow.dofs)
    seconds = []
    prev = None
    for n in range(steps):
        t_new = (n + 1) * dt
        flow.body_specs[0] = dataclasses.replace(spec, velocity=tuple(path.velocity(t_new)))
        t0 = time.perf_counter()
        with diag.watching():
            flow.step(dt)
        force = np.array(flow.loads()[0][0], float)
        seconds.append(time.perf_counter() - t0)
        ev = flow.last_event
        health = diag.finish_step(n + 1, t_new, ev, mm)
        out["t"].append(t_new)
        out["y"].append(float(path(t_new)[0][1]))
        out["noise"].append(health.noise)
        out["condition"].append(health.condition)
        out["oscillating"].append(int(health.oscillating))
        out["retriangulated"].append(bool(ev.retriangulated))
        out["force"].append(force.tolist())
        out["force_change"].append(None if prev is None else float(np.linalg.norm(force - prev)))
        prev = force
    return {"h": float(h), "strategy": strategy, "relax_iterations": mm.relax_iterations,
            "amplitude": float(amplitude), "period_steps": int(period_steps), "dt": float(dt),
            "steps": int(steps), "dofs": dofs, **out,
            "triangulations": int(sum(out["retriangulated"])),
            "noise_total": float(sum(v for v in out["noise"] if v is not None)),
            "step_median": float(np.median(seconds)), "run_seconds": float(np.sum(seconds))}


def force_deviation(run: dict, reference: dict, skip: int = 0, component: int = 0) -> dict:
    """One component of a run's force history against the reference's (same dt, same steps).

    Parameters
    ----------
    run, reference : dict
        :func:`oscillation_run` results.
    skip : int
        Steps left out at the start (the inflow's start-up).
    component : int
        0: the drag F_x (along the channel); 1: the lift F_y (along the oscillation, dominated by
        the force that moves the body).

    Returns
    -------
    dict
        ``mean`` (mean of F − F_ref), ``rms`` (root mean square of F − F_ref), ``jitter`` (root
        mean square of the step-to-step change of F − F_ref), ``jitter_ref`` (the reference's own
        step-to-step change), all relative to the reference's mean |F| of that component.

    Examples
    --------
    >>> ref = {"force": [[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]}
    >>> r = {"force": [[1.1, 0.0], [0.9, 0.0], [1.1, 0.0]]}
    >>> d = force_deviation(r, ref)
    >>> [round(d[k], 12) for k in ("rms", "jitter", "jitter_ref")]
    [0.1, 0.2, 0.0]
    """
    F = np.asarray(run["force"], float)[skip:, component]
    R = np.asarray(reference["force"], float)[skip:, component]
    scale = float(np.abs(R).mean())
    e = F - R
    return {"mean": float(e.mean()) / scale, "rms": float(np.sqrt(np.mean(e ** 2))) / scale,
            "jitter": float(np.sqrt(np.mean(np.diff(e) ** 2))) / scale,
            "jitter_ref": float(np.sqrt(np.mean(np.diff(R) ** 2))) / scale}
