"""A settling disk on a uniform mesh against graded meshes of the same size at the body.

The paper (Sec. 2.3, Fig. 3) grades the background mesh from fine near the particles to coarse
away from them.  The case: the lab-frame settling disk of :func:`fluidem.cases.settling.settling_scene`
(a free disk of radius a = 0.1, a regular 64-gon, ρ_s/ρ_f = 1.5, released at rest at (0, 4) in the
closed channel [−0.5, 0.5] × [0, 6], Navier–Stokes, ν = 0.01, g = 1, P2+bubble/P1dc) run to a
fixed time t* on

- a *uniform* mesh of target edge length ``h`` (``mesh.grading`` absent), and
- a *graded* one: ``mesh.grading = {region = "bodies", growth = g, h_max = H}``, size ``h`` at the
  disk growing by the factor g per cell away from it up to H.

The quantity of interest is the settling speed at t* (:func:`sedimentation_run`).  The polygon is
the same on every mesh (its edges, 2π a / 64 ≈ 0.0098, are finer than every ``h`` used), so the
meshes differ only in the fluid away from the outline.  The benchmark
(``benchmarks/bench_stability_graded.py``, ``docs/stability.md``) takes the finest graded run as
the reference; :func:`richardson_limit` extrapolates a sequence h, h/r, h/r² to h → 0 (on the
uniform meshes it shows that their sequence is not one of mesh size alone: the coarser ones
re-triangulate at every step).  :func:`size_near_body` measures the mesh size next to the disk,
which a grading keeps at about the uniform value.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..scene import Scene
from .settling import settling_scene

__all__ = ["graded_settling_scene", "sedimentation_run", "size_near_body", "richardson_limit"]


def graded_settling_scene(h: float, grading: tuple[float, float] | None = None, dt: float = 0.02,
                          t_end: float = 0.6, element: str = "p2b") -> Scene:
    """The settling-disk scene with a uniform (``grading=None``) or graded mesh.

    Parameters
    ----------
    h : float
        Mesh size at the disk (length); the whole mesh's for a uniform one.
    grading : (growth, h_max_over_h) or None
        Size ratio of neighbouring cells away from the disk (≥ 1) and the largest cell size over ``h``.
    dt, t_end : float
        Time step and end time (time).
    element : str
        Element pair of the fluid.

    Examples
    --------
    >>> graded_settling_scene(0.05).mesh.grading is None
    True
    >>> graded_settling_scene(0.05, (1.2, 8.0)).mesh.grading["h_max"]
    0.4
    """
    data = settling_scene(h=h, dt=dt, t_end=t_end, element=element).to_dict()
    if grading is None:
        data["mesh"].pop("grading", None)
    else:
        growth, ratio = grading
        data["mesh"]["grading"] = {"region": "bodies", "growth": float(growth), "h_max": float(ratio) * h}
    return Scene.from_dict(data)


def size_near_body(sim, within: float = 0.1) -> float:
    """Mean edge length (length) of the fluid cells whose centroid lies within ``within`` (length)
    of the first body's outline: the mesh size at the body.  Assumes a disk-like outline (the
    distance is measured from the body's centre less its largest vertex radius)."""
    mesh = sim.flow.mesh
    centre = sim.flow.poses[0, :2]
    radius = float(np.linalg.norm(np.asarray(sim.scene.bodies[0].vertices, float), axis=1).max())
    p = mesh.p[:, mesh.t]  # (2, 3, cells)
    centroid = p.mean(axis=1)
    near = np.linalg.norm(centroid - centre[:, None], axis=0) - radius < within
    edges = np.linalg.norm(p[:, [1, 2, 0], :] - p, axis=0)  # (3, cells)
    return float(edges[:, near].mean())


def sedimentation_run(h: float, grading: tuple[float, float] | None = None, t_star: float = 0.6,
                      dt: float = 0.02, element: str = "p2b", min_angle_margin: float | None = None) -> dict:
    """Run the settling disk to ``t_star`` on one mesh and measure it.

    Parameters
    ----------
    h, grading, element
        As :func:`graded_settling_scene`.
    t_star : float
        End time (time); a whole number of steps ``dt``.
    dt : float
        Time step (time).
    min_angle_margin : float, optional
        Degrees the smallest angle of an element may fall below its bound before it triggers a
        re-triangulation (:class:`fluidem.mesh.params.MeshParams`; not a scene key); the moving
        mesh's default (0) if not given.

    Returns
    -------
    dict
        ``u_star`` (settling speed at ``t_star``, length/time, downwards positive), ``dofs``
        (velocity and pressure unknowns at the start), ``cells`` (triangles at the start),
        ``h_body`` (:func:`size_near_body` at the start, length), ``steps``,
        ``triangulations``, ``step_median`` (median wall time of a step, s), ``run_seconds``
        (the steps), ``build_seconds`` (scene to first mesh and solver set-up).
    """
    from ..mesh.moving_triangulation import set_quality_baseline
    from ..simulation import Simulation

    t0 = time.perf_counter()
    sim = Simulation(graded_settling_scene(h, grading, dt=dt, t_end=t_star, element=element))
    if min_angle_margin is not None:  # the quality thresholds of the first mesh again, with this margin
        mm = sim.flow.mm
        mm.params = dataclasses.replace(mm.params, min_angle_margin=float(min_angle_margin))
        set_quality_baseline(mm)
    build = time.perf_counter() - t0
    dofs, cells, h_body = int(sim.flow.dofs), int(sim.flow.mesh.t.shape[1]), size_near_body(sim)
    stamps = [time.perf_counter()]
    sim.run(out_dir=None, progress=lambda *args: stamps.append(time.perf_counter()))
    steps = np.diff(stamps)
    return {"h": float(h), "grading": None if grading is None else [float(v) for v in grading],
            "element": element, "dt": dt, "t_star": t_star, "u_star": float(-sim.flow.body_velocities[0, 1]),
            "dofs": dofs, "cells": cells,
            "h_body": h_body, "steps": len(steps), "triangulations": int(sim.counters["triangulations"]),
            "step_median": float(np.median(steps)), "run_seconds": float(stamps[-1] - stamps[0]),
            "build_seconds": build, "min_angle_margin": min_angle_margin}


def richardson_limit(h, u) -> tuple[float, float]:
    """Limit h → 0 of ``u`` from three runs at sizes h, h/r, h/r² (Richardson extrapolation).

    Returns ``(u_0, p)``: the limit and the observed order p = log(|u₁ − u₀| / |u₂ − u₁|) / log r.

    Examples
    --------
    >>> u0, p = richardson_limit([0.4, 0.2, 0.1], [1 + 0.16, 1 + 0.04, 1 + 0.01])
    >>> round(u0, 12), round(p, 12)
    (1.0, 2.0)
    """
    h = np.asarray(h, float)
    u = np.asarray(u, float)
    r = h[0] / h[1]
    p = float(np.log(abs(u[1] - u[0]) / abs(u[2] - u[1])) / np.log(r))
    return float(u[2] + (u[2] - u[1]) / (r ** p - 1.0)), p
