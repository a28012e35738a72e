"""The force jump at a re-triangulation: a turning ellipse, prescribed and settling, on the moving mesh.

Between re-triangulations the dragged mesh keeps its connectivity and the velocity stays on its
nodes; at a re-triangulation u^n and u^{n−1} are carried over to the new mesh
(:meth:`fluidem.coupling.moving_flow.MovingMeshFlow._transfer`) and the discrete geometry
changes.  Both show in the force of that step.  This module measures how large the force change
of a re-triangulation step is against the ordinary step-to-step change of the same run.

Cases (both Navier–Stokes, P2+bubble/P1dc, mesh graded from the body, growth 1.2 up to
min(8 h, 0.1)):

* :func:`turning_ellipse_scene`: an ellipse of semi-axes 0.15 × 0.075 (a polygon of about
  perimeter / h sides, so the outline has that many mesh edges), centre (0.8, 0.5), angle 0.3,
  prescribed U = (1, 0) and ω = 0.5 in the closed channel [0, 3] × [0, 1], ν = 0.01
  (Re = U·2a/ν = 30): the plate case of ``benchmarks/bench_plate_history.py`` with a smooth
  outline.
* :func:`settling_ellipse_scene`: a free ellipse 0.1 × 0.05, density 2 in fluid of density 1,
  released at rest at angle 0.6 in the closed channel [−0.5, 0.5] × [0, 4], g = 1, ν = 0.01: it
  settles and turns broadside.

Figures of a run (:func:`jump_figures`): per step the relative force change
|F_k − F_{k−1}| / |F_{k−1}| (the force vector of the fluid on the body); *ordinary* steps are those
with no re-triangulation (the first ``skip`` steps, the start, are left out); the *jump ratio* is the
median relative change at re-triangulation steps over the median ordinary one (also the largest
over the median, and the median over the 90th percentile).  The ordinary change is mostly the
force's own trend; what a re-triangulation adds to it shows in the second difference
|F_k − 2F_{k−1} + F_{k−2}| (the *kink*, over the rms force).  Measured
(``benchmarks/results/stability_jumps.md``, docs "Stability"): with 40 or more outline edges the
ratio is 0.83–1.03 and the kink 0.015–0.15 % of the rms force, about the interpolation noise of the
transfer.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..geometry import ellipse_polygon
from ..scene import Scene

__all__ = ["INGREDIENTS", "ellipse_perimeter", "ellipse_sides", "jump_figures", "jump_run", "settling_ellipse_scene",
           "switch_ingredient", "turning_ellipse_scene"]


def ellipse_perimeter(a: float, b: float) -> float:
    """Perimeter (length) of an ellipse with semi-axes ``a``, ``b``: Ramanujan's approximation
    π [3(a + b) − √((3a + b)(a + 3b))] (Ramanujan 1914, Quart. J. Math. 45, 350–372), exact for a
    circle and within 3e-6 relative at a/b = 2."""
    return float(np.pi * (3 * (a + b) - np.sqrt((3 * a + b) * (a + 3 * b))))


def ellipse_sides(a: float, b: float, h: float, least: int = 12) -> int:
    """Sides of the ellipse polygon at mesh size ``h``: the even number nearest perimeter / h, at least ``least``."""
    return max(least, 2 * int(round(ellipse_perimeter(a, b) / h / 2)))


def turning_ellipse_scene(h: float, steps: int = 120, dt: float = 0.01, omega: float = 0.5,
                          plain: bool = False, sides: int | None = None) -> Scene:
    """The prescribed translating and turning ellipse at Re 30 (module docstring).

    ``sides``: the polygon's sides (default :func:`ellipse_sides` at ``h``).
    ``plain``: the scene as written with the fewest keys instead: ``shape = "ellipse"`` with its
    default outline (2π·0.15 / h sides, even, ≥ 16) on a uniform mesh.
    """
    a, b = 0.15, 0.075
    body = {"name": "ellipse", "position": [0.8, 0.5], "angle": 0.3, "motion": "prescribed",
            "velocity": [1.0, 0.0], "omega": omega}
    mesh = {"h": h, "strategy": "drag"}
    if plain:
        body |= {"shape": "ellipse", "a": a, "b": b}
    else:
        n = sides or ellipse_sides(a, b, h)
        body |= {"shape": "polygon", "vertices": ellipse_polygon(a, b, n).tolist()}
        mesh["grading"] = {"region": "bodies", "growth": 1.2, "h_max": min(8 * h, 0.1)}
    return Scene.from_dict({
        "fluid": {"model": "navier-stokes", "viscosity": 0.01},
        "domain": {"box": [0.0, 3.0, 0.0, 1.0]},
        "bodies": [body], "mesh": mesh, "time": {"dt": dt, "t_end": dt * steps}})


def settling_ellipse_scene(h: float, steps: int = 120, dt: float = 0.01, density: float = 2.0) -> Scene:
    """The free ellipse settling and turning in a closed channel (module docstring)."""
    a, b = 0.1, 0.05
    return Scene.from_dict({
        "gravity": [0.0, -1.0],
        "fluid": {"model": "navier-stokes", "viscosity": 0.01, "density": 1.0},
        "domain": {"box": [-0.5, 0.5, 0.0, 4.0]},
        "bodies": [{"name": "ellipse", "shape": "polygon",
                    "vertices": ellipse_polygon(a, b, ellipse_sides(a, b, h)).tolist(), "position": [0.0, 3.0],
                    "angle": 0.6, "density": density}],
        "mesh": {"h": h, "strategy": "drag", "grading": {"region": "bodies", "growth": 1.2, "h_max": min(8 * h, 0.1)}},
        "time": {"dt": dt, "t_end": dt * steps}})


def _l2_transfer(flow):
    """Switch: u^n, u^{n−1} carried over by the conservative L2 projection on the supermesh
    (:func:`fluidem.mesh.transfer.project_l2`) instead of interpolation at the new DOFs."""
    from skfem import Basis, ElementVector, MeshTri

    from ..coupling.moving_flow import transfer_change
    from ..mesh import transfer

    def _transfer(ev, old_space, u_n, u_p):
        src = ev.old_points if ev.history == "ale" else ev.prev_points
        old = MeshTri(np.asarray(src, float).T.copy(), np.asarray(ev.old_triangles).T.copy())
        ob = Basis(old, ElementVector(old_space.pair.velocity()))
        sm = transfer.supermesh(old, flow.space.ub.mesh)
        new_n = transfer.project_l2(ob, u_n, flow.space.ub, sm=sm)
        new_p = None if u_p is None else transfer.project_l2(ob, u_p, flow.space.ub, sm=sm)
        ev.transfer_change = transfer_change(ob, u_n, flow.space.ub, new_n)
        return new_n, new_p

    flow._transfer = _transfer


def _bdf1_restart(flow):
    """Switch: the step after a re-triangulation is BDF1 (u^{n−1} dropped) instead of BDF2."""
    inner = flow._transfer

    def _transfer(ev, old_space, u_n, u_p):
        return inner(ev, old_space, u_n, None)[0], None

    flow._transfer = _transfer


def _first_order_w(flow):
    """Switch: at a re-triangulation step the mesh velocity is the last step's displacement over dt,
    new nodes taking their old neighbours' mean (``MovingMesh.node_velocity(order=1)``), instead of the
    BDF2 derivative of the inherited node trajectories."""
    mm = flow.mm
    inner = mm.node_velocity

    def node_velocity(dt, order=1):
        return inner(dt, order=1 if flow.last_event.retriangulated else order)

    mm.node_velocity = node_velocity


#: the ingredients :func:`switch_ingredient` can change, and what each does
INGREDIENTS = {"l2": _l2_transfer, "bdf1": _bdf1_restart, "first-order-w": _first_order_w}


def switch_ingredient(flow, name: str) -> None:
    """Change one ingredient of the re-triangulation step of ``flow`` (a ``MovingMeshFlow``), to measure it.

    ``"l2"``: u^n, u^{n−1} by the conservative L2 projection; ``"bdf1"``: the step after a
    re-triangulation is BDF1; ``"first-order-w"``: the mesh velocity of that step from the last
    displacement (new nodes: their old neighbours' mean).  The package's own step is none of these
    (interpolation at t + dt, BDF2, the BDF2 derivative of the inherited node trajectories).
    """
    INGREDIENTS[name](flow)


def jump_run(scene: Scene, min_angle_margin: float | None = None, flow_hook=None) -> dict:
    """Run ``scene``; per step the force on the body, whether and why the mesh was re-triangulated, the
    interpolation noise of the transfer (relative L2 change of u^n) and the wall time.

    Parameters
    ----------
    min_angle_margin : float, optional
        Degrees: ``MeshParams.min_angle_margin`` for this run (default: the package default, 0).
    flow_hook : callable, optional
        ``flow_hook(sim.flow)`` before the first step (to switch one ingredient of the step).

    Returns
    -------
    dict
        ``rows`` (per step: ``step``, ``t``, ``force`` (2,) kinematic force per unit depth,
        ``torque``, ``reason`` ('' at an ordinary step), ``noise``, ``seconds``), ``dofs``, ``edges``
        (mesh edges on the outline at the start).
    """
    from ..mesh.moving_triangulation import set_quality_baseline
    from ..simulation import Simulation

    sim = Simulation(scene)
    if min_angle_margin is not None:
        mm = sim.flow.mm
        mm.params = dataclasses.replace(mm.params, min_angle_margin=float(min_angle_margin))
        set_quality_baseline(mm)
    if flow_hook is not None:
        flow_hook(sim.flow)
    rows = []
    last = [time.perf_counter()]

    def record(k, n, t, cost):
        F, T = sim.last_loads
        ev = sim.flow.last_event
        noise = getattr(ev, "transfer_change", None) if ev.retriangulated else None
        now = time.perf_counter()
        rows.append({"step": int(k), "t": float(t), "force": [float(F[0, 0]), float(F[0, 1])],
                     "torque": float(np.ravel(T)[0]), "reason": ev.reason if ev.retriangulated else "",
                     "noise": None if noise is None else float(noise), "seconds": now - last[0]})
        last[0] = now

    sides = len(scene.world_outlines()[0])
    sim.run(out_dir=None, progress=record)
    return {"rows": rows, "dofs": int(sim.flow.dofs), "edges": sides}


def jump_figures(rows: list, skip: int = 5) -> dict:
    """Relative force changes at re-triangulation steps against ordinary steps (module docstring).

    Returns ``rms_force`` (rms of |F| after ``skip``), ``step_rms_ordinary_median`` and
    ``step_rms_jump_max`` (|ΔF| over the rms force), ``d2_ordinary_median``, ``d2_jump_median``,
    ``d2_jump_max`` (second differences |F_k − 2F_{k−1} + F_{k−2}| over the rms force; at a
    re-triangulation step k the larger of those at k and k + 1), ``ordinary_median``,
    ``ordinary_p90``, ``jump_median``, ``jump_max`` (relative changes),
    ``ratio`` (jump median / ordinary median), ``ratio_max`` (jump max / ordinary median),
    ``ratio_p90`` (jump median / ordinary p90), ``jumps`` (per re-triangulation: step, reason,
    change, noise), ``retriangulations`` and ``noise_median``.
    """
    F = np.array([r["force"] for r in rows])
    rel = np.linalg.norm(np.diff(F, axis=0), axis=1) / np.maximum(np.linalg.norm(F[:-1], axis=1), 1e-300)
    step = np.arange(1, len(rows))
    retri = np.array([bool(rows[k]["reason"]) for k in step])
    keep = step >= skip
    ordinary, at = rel[keep & ~retri], rel[keep & retri]
    med, p90 = float(np.median(ordinary)), float(np.percentile(ordinary, 90))
    jumps = [{"step": rows[k]["step"], "reason": rows[k]["reason"], "change": float(rel[k - 1]),
              "noise": rows[k]["noise"]} for k in step[keep & retri]]
    noise = [j["noise"] for j in jumps if j["noise"] is not None]
    jm = float(np.median(at)) if len(at) else float("nan")
    # against the rms force of the run, and the second differences (the kink a jump leaves):
    # d2[k] = |F_k − 2 F_{k−1} + F_{k−2}|; a jump entering step k shows at k and k + 1
    rms = float(np.sqrt(np.mean(np.sum(F[skip:] ** 2, axis=1))))
    step_rms = np.linalg.norm(np.diff(F, axis=0), axis=1) / rms
    d2 = np.zeros(len(rows))
    d2[2:] = np.linalg.norm(F[2:] - 2 * F[1:-1] + F[:-2], axis=1) / rms
    flag = np.array([bool(r["reason"]) for r in rows])
    near = flag.copy()
    near[1:] |= flag[:-1]
    idx = np.arange(len(rows))
    d2_ord = d2[(idx >= skip + 1) & ~near]
    d2_at = [max(d2[k], d2[k + 1] if k + 1 < len(rows) else 0.0) for k in idx[flag & (idx >= skip)]]
    for j, k in zip(jumps, step[keep & retri]):
        j["change_rms"] = float(step_rms[k - 1])
    return {"rms_force": rms, "step_rms_ordinary_median": float(np.median(step_rms[keep & ~retri])),
            "step_rms_jump_max": float(step_rms[keep & retri].max()) if len(at) else float("nan"),
            "d2_ordinary_median": float(np.median(d2_ord)),
            "d2_jump_median": float(np.median(d2_at)) if d2_at else float("nan"),
            "d2_jump_max": float(np.max(d2_at)) if d2_at else float("nan"),
            "ordinary_median": med, "ordinary_p90": p90, "jump_median": jm,
            "jump_max": float(at.max()) if len(at) else float("nan"),
            "ratio": jm / med, "ratio_max": (float(at.max()) / med) if len(at) else float("nan"),
            "ratio_p90": jm / p90, "jumps": jumps, "retriangulations": int(sum(bool(r["reason"]) for r in rows)),
            "noise_median": float(np.median(noise)) if noise else None}
