"""Stress suite: moving packings in Stokes flow, and fluid pockets enclosed by touching bodies.

Two kinds of runs, each a few seconds on small meshes:

* :func:`stress_run` — a random convex packing (:func:`fluidem.cases.packings.packing`: ``n``
  polygons of diameters 0.5–1.5 at area fraction ``phi``, gaps down to ``min_gap``, 1 % of the
  mean size by default) in a walled box, every body moved by
  :class:`fluidem.cases.packings.RandomMotion` (random small translations and turns that keep
  every gap ≥ ``min_gap``), prescribed on the moving mesh, Stokes, P2+bubble/P1dc.  Per step it
  records the condition estimate of the step's LU and the solve's residual
  (:class:`fluidem.diagnostics.RunDiagnostics`), whether the fields are finite
  (:class:`fluidem.state_checks.StateCheck`), the mesh's smallest angle and inverted elements
  (:meth:`fluidem.mesh.MovingMesh.quality`), re-triangulations and enclosed pockets.  A run
  either *finishes* with every figure inside :data:`BOUNDS` or *stops* with fluidem's own error
  (:class:`fluidem.errors.FluidemError`: the state check's, the solver's, the mesher's, a
  pocket's), whose message it records; any other exception propagates.
* :func:`pocket_scene` / :func:`pocket_run` — a square frame of four bars touching end to side
  (gap ``gap``, below the moving mesh's contact gap, so they are meshed as one closed outline)
  around a 0.6 × 0.6 pocket of fluid, in a box with an outflow side or walled all round, moved as
  a whole (``"translate"``, ``"rotate"``: the pocket keeps its area and its fluid moves rigidly)
  or with the top bar pushed in (``"piston"``: the pocket would shrink, which incompressible fluid
  cannot; :class:`fluidem.fluid.pockets.PocketError`).

Examples
--------
>>> r = pocket_run("translate")
>>> r["ended"], r["pockets"], r["pocket_area"]
('finished', 1, 0.36)
>>> bool(r["pocket_velocity_error"] < 1e-12)    # relative to the frame's speed
True
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..errors import FluidemError, InputError
from ..scene import Scene
from .packings import RandomMotion, hexagon_packing, packing

__all__ = ["BOUNDS", "RANDOM_PHI_MAX", "POCKET_MOTIONS", "pocket_scene", "pocket_run", "rigid_velocity",
           "SequencePath", "stress_scene", "stress_run", "within_bounds"]

#: What a finished run's diagnostics must stay within: largest condition estimate κ₁ of a step's LU
#: (1e14: about 1/100 of 1/ε, so that a solve keeps 2 digits; the runs measured 2e8–1.2e11,
#: ``benchmarks/results/stability_stress.md``), largest relative residual of a solve (the direct
#: solver's own check, :class:`fluidem.fluid.solvers.DirectSolver`), smallest angle of the mesh
#: (degrees, all elements; > 0: none degenerate) and inverted elements.
BOUNDS = {"condition": 1e14, "residual": 1e-8, "min_angle": 0.0, "inverted": 0}

#: Random placement jams near this area fraction; :func:`stress_run` builds denser packings on a lattice.
RANDOM_PHI_MAX = 0.55

#: motions of :func:`pocket_scene`
POCKET_MOTIONS = ("translate", "rotate", "piston")

#: the frame: outer side 1.0, bars 0.2 wide, the pocket 0.6 × 0.6
_FRAME = {"bar_left": (-0.5, -0.3, -0.5, 0.5), "bar_right": (0.3, 0.5, -0.5, 0.5),
          "bar_bottom": (-0.3, 0.3, -0.5, -0.3), "bar_top": (-0.3, 0.3, 0.3, 0.5)}


def pocket_scene(motion: str = "translate", gap: float = 1e-6, h: float = 0.08, speed: float = 0.1,
                 outflow: bool = True, element: str = "p2b", dt: float = 0.01, steps: int = 1) -> Scene:
    """Four bars touching in a square frame around a fluid pocket, in the 2.5 × 2.5 box (Stokes, ν = 1).

    Parameters
    ----------
    motion : {"translate", "rotate", "piston"}
        ``"translate"``: every bar at velocity (speed, speed/2); ``"rotate"``: the frame turns as a
        whole about its centre (1.25, 1.25) at ω = speed rad/time (each bar's velocity ω × (X − c));
        ``"piston"``: the top bar moves down at ``speed`` between the side bars, the others rest.
    gap : float
        Gap between the bottom/top bars and the side bars, length (below the mesh's contact gap
        ``1e-3 h``: the frame is meshed as one closed outline with a pore).
    h : float
        Mesh size, length.
    speed : float
        Length/time (rad/time for ``"rotate"``).
    outflow : bool
        The right side of the box is an outflow (the outer fluid is open); False: walls all round.
    element : str
        Element pair.
    dt : float
        Time step.
    steps : int
        Steps to ``t_end`` (at least 2: a scene of one quasi-steady Stokes step is meshed once, without
        the moving mesh).

    Raises
    ------
    InputError
        ``motion`` unknown.

    Examples
    --------
    >>> s = pocket_scene("piston")
    >>> [b.name for b in s.bodies], s.bodies[3].velocity
    (['bar_left', 'bar_right', 'bar_bottom', 'bar_top'], (0.0, -0.1))
    """
    if motion not in POCKET_MOTIONS:
        raise InputError(f"pocket motion = {motion!r}: expected one of {POCKET_MOTIONS}")
    c = np.array([1.25, 1.25])
    bodies = []
    for name, (x0, x1, y0, y1) in _FRAME.items():  # four bars
        if name in ("bar_bottom", "bar_top"):
            x0, x1 = x0 + gap, x1 - gap
        v = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        cen = v.mean(axis=0)
        vel, omega = (0.0, 0.0), 0.0
        if motion == "translate":
            vel = (speed, 0.5 * speed)
        elif motion == "rotate":
            vel, omega = (-speed * float(cen[1]), speed * float(cen[0])), speed
        elif name == "bar_top":
            vel = (0.0, -speed)
        bodies.append({"name": name, "shape": "polygon", "vertices": (v - cen).tolist(),
                       "position": (cen + c).tolist(), "motion": "prescribed", "velocity": list(vel),
                       "omega": omega, "density": 1.0})
    domain = {"box": [0.0, 2.5, 0.0, 2.5]}
    if outflow:
        domain["right"] = "outflow"
    return Scene.from_dict({"gravity": [0.0, 0.0],
                            "fluid": {"model": "stokes", "viscosity": 1.0, "density": 1.0, "element": element},
                            "domain": domain, "bodies": bodies, "mesh": {"h": h},
                            "time": {"dt": dt, "t_end": max(steps, 2) * dt}})


def pocket_run(motion: str = "translate", steps: int = 1, **kw) -> dict:
    """Run :func:`pocket_scene` and measure the flow in the pocket.

    Parameters
    ----------
    motion : {"translate", "rotate", "piston"}
    steps : int
    **kw
        Passed to :func:`pocket_scene` (``gap``, ``h``, ``speed``, ``outflow``, ``element``, ``dt``).

    Returns
    -------
    dict
        ``ended`` (``"finished"`` or ``"stopped"``), ``error`` (the error's type and message, or
        None), ``pockets`` (enclosed pockets of the mesh), ``pocket_area`` (length², rounded to 1e-6),
        ``pocket_velocity_error`` (largest |u − u_rigid| at the quadrature points of the pocket's elements,
        :func:`rigid_velocity`, relative to the frame's largest speed there), ``pocket_pressure``
        (the L2 norm of p over the pocket, per unit area, which a rigid motion leaves at its zero mean,
        over ν · speed / side), ``divergence`` (the L2 norm of div u over the pocket, per unit area, over
        speed / side),         ``area_rate`` (dA/dt imposed on the pocket, length²/time), ``dofs``, ``seconds``.
    """
    from ..fluid.pockets import pocket_area_rates
    from ..simulation import Simulation

    speed = float(kw.get("speed", 0.1))
    scene = pocket_scene(motion, steps=steps, **kw)
    dt = scene.time.dt
    t0 = time.perf_counter()
    out = {"motion": motion, "ended": "finished", "error": None, "pockets": 0, "pocket_area": None,
           "pocket_velocity_error": None, "pocket_pressure": None, "divergence": None, "area_rate": None}
    try:
        sim = Simulation(scene)
        flow = sim.flow
        fc = flow.problem.components
        out["pockets"] = int(len(fc.pockets))
        if len(fc.pockets):
            out["pocket_area"] = round(float(fc.areas[fc.pockets[0]]), 6)
        specs = list(flow.body_specs)
        p0 = np.array([[*b.position, b.angle] for b in specs])
        for s in range(steps):
            t1 = (s + 1) * dt
            if motion == "rotate":  # the frame turns about its centre: the bars on circles, not lines
                a = speed * t1
                c, sn = np.cos(a), np.sin(a)
                ctr = np.array([1.25, 1.25])
                r = (p0[:, :2] - ctr) @ np.array([[c, -sn], [sn, c]]).T
                seq = np.stack([p0, np.column_stack([ctr + r, p0[:, 2] + a])])
                flow.path = [SequencePath(seq[:, k], t1) for k in range(len(specs))]
                flow.body_specs = [dataclasses.replace(b, velocity=(-speed * float(v[1]), speed * float(v[0])))
                                   for b, v in zip(specs, r)]  # ω × (X(t) − c), each bar's centre X(t)
            flow.step(dt)
    except FluidemError as err:
        out.update(ended="stopped", error=f"{type(err).__name__}: {err}")
        out["seconds"] = time.perf_counter() - t0
        return out
    pr, sp = flow.problem, flow.space
    fc = pr.components
    pk = int(fc.pockets[0]) if len(fc.pockets) else None
    out["dofs"] = int(sp.n_dofs)
    if pk is not None:
        x = flow.x
        el = fc.element_label == pk
        u = sp.ub.interpolate(x[: sp.n_u])  # at the quadrature points, (2, n_elements, n_qp)
        val, grad = np.asarray(u)[:, el], np.asarray(u.grad)[:, :, el]
        xy = np.asarray(sp.ub.global_coordinates())[:, el]
        rigid = rigid_velocity(motion, speed, xy, flow.t)
        scale = speed * {"translate": np.hypot(1.0, 0.5), "rotate": 0.45, "piston": 1.0}[motion]
        out["pocket_velocity_error"] = float(np.abs(val - rigid).max() / scale)
        dx = sp.ub.dx[el]
        p = np.asarray(sp.pb.interpolate(x[sp.n_u:]))[el]
        out["pocket_pressure"] = float(np.sqrt((p ** 2 * dx).sum() / dx.sum()) / (pr.nu * scale / 0.6))
        div = grad[0, 0] + grad[1, 1]
        out["divergence"] = float(np.sqrt((div ** 2 * dx).sum() / dx.sum()) / (scale / 0.6))
        out["area_rate"] = float(pocket_area_rates(pr, flow.t, [pk])[0][0])
    out["seconds"] = time.perf_counter() - t0
    return out


def rigid_velocity(motion: str, speed: float, xy: np.ndarray, t: float) -> np.ndarray:
    """The velocity (2, ...) of :func:`pocket_scene`'s fluid pocket moving with its frame at points ``xy (2, ...)``
    at time ``t``: the translation, the rotation ω × (x − c) about the frame's centre, or rest (``"piston"``:
    the velocity it would have if the top bar stood still)."""
    if motion == "translate":
        return np.stack([np.full(xy.shape[1:], speed), np.full(xy.shape[1:], 0.5 * speed)])
    if motion == "rotate":
        return np.stack([-speed * (xy[1] - 1.25), speed * (xy[0] - 1.25)])
    return np.zeros_like(xy)


class SequencePath:
    """A body's pose along a sequence of poses one time step apart, linear in between:
    ``path(t) -> (position (2,), angle)`` (the path interface of
    :class:`fluidem.coupling.moving_flow.MovingMeshFlow`).

    Parameters
    ----------
    poses : (m, 3) float
        x, y, angle at t = 0, dt, 2 dt, ...
    dt : float

    Examples
    --------
    >>> p = SequencePath(np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.2]]), 0.5)
    >>> pos, angle = p(0.25)
    >>> pos.tolist(), round(angle, 12)
    ([0.05, 0.0], 0.1)
    """

    def __init__(self, poses, dt: float):
        self.poses = np.asarray(poses, float)
        self.dt = float(dt)

    def __call__(self, t):
        s = min(max(t / self.dt, 0.0), len(self.poses) - 1.0)
        k = min(int(np.floor(s)), len(self.poses) - 2)
        f = s - k
        p = (1.0 - f) * self.poses[k] + f * self.poses[k + 1]
        return p[:2].copy(), float(p[2])


def stress_scene(bodies, poses, box, h: float, dt: float, steps: int, velocities, element: str = "p2b") -> Scene:
    """A Stokes scene (ν = 1) of prescribed polygons ``bodies`` at ``poses (n, 3)`` in the walled ``box``
    (x0, x1, y0, y1), mesh size ``h``, with ``velocities (n, 3)`` (vx, vy, ω: those of the first step; the
    scene's bodies must move for the moving mesh); :func:`stress_run` sets their motion step by step."""
    return Scene.from_dict({
        "gravity": [0.0, 0.0],
        "fluid": {"model": "stokes", "viscosity": 1.0, "density": 1.0, "element": element},
        "domain": {"box": [float(v) for v in box]},
        "bodies": [{"name": f"p{k}", "shape": "polygon", "vertices": np.asarray(v).tolist(),
                    "position": [float(p[0]), float(p[1])], "angle": float(p[2]), "motion": "prescribed",
                    "velocity": [float(w[0]), float(w[1])], "omega": float(w[2]), "density": 1.0}
                   for k, (v, p, w) in enumerate(zip(bodies, poses, velocities))],
        "mesh": {"h": h},
        "time": {"dt": dt, "t_end": steps * dt}})


def stress_run(n: int = 8, phi: float = 0.3, seed: int = 0, motion_seed: int = 1, steps: int = 10,
               h: float = 0.25, min_gap: float = 0.01, sigma_x: float = 0.02, sigma_a: float = 0.04,
               dt: float = 0.1, element: str = "p2b", layout: str | None = None) -> dict:
    """A moving packing in Stokes flow, its numerical health recorded every step (module docstring).

    Parameters
    ----------
    n, phi, seed
        The packing (:func:`fluidem.cases.packings.packing`, diameters 0.5–1.5).
    motion_seed : int
        Seed of the random motion.
    steps : int
        Time steps.
    h : float
        Mesh size, length.
    min_gap : float
        Smallest gap of the packing and of the motion, length (0.01: 1 % of the mean diameter).
    sigma_x, sigma_a : float
        Standard deviations of a step's translation (length) and turn (rad) of every body.
    dt : float
        Time step (the body velocities are the pose changes over dt).
    element : str
        Element pair.
    layout : {"random", "hexagons"} or None
        :func:`~fluidem.cases.packings.packing` (random convex polygons, diameters 0.5–1.5) or
        :func:`~fluidem.cases.packings.hexagon_packing` (hexagons of width 0.9–1.0 on a lattice,
        ``ceil(√n)`` per row: ``n`` rounded up to fill the rows); None: random up to
        φ = :data:`RANDOM_PHI_MAX`, hexagons above.

    Returns
    -------
    dict
        Settings, ``ended`` (``"finished"``, ``"stopped"`` or ``"out of bounds"``: finished with a
        figure outside :data:`BOUNDS`), ``error`` (type and message of fluidem's error, or None),
        ``steps_done``, per step (lists): ``condition`` (largest κ₁ of the step's LUs), ``residual``
        (largest relative residual of its solves), ``finite`` (all flow DOFs finite),
        ``min_angle`` (degrees, all elements), ``inverted``, ``retriangulated``, ``pockets``,
        ``min_gap`` (smallest gap between bodies, length); and ``retriangulations``,
        ``max_condition``, ``max_residual``, ``min_angle_run``, ``min_gap_run``, ``dofs`` (at the
        start), ``seconds``.

    Raises
    ------
    InputError
        ``phi`` too high for the packing.
    """
    from ..simulation import Simulation
    from ..state_checks import StateCheck

    if layout is None:
        layout = "hexagons" if phi > RANDOM_PHI_MAX else "random"
    if layout == "random":
        bodies, poses0, box = packing(n=n, phi=phi, min_gap=min_gap, seed=seed)
    elif layout == "hexagons":
        nx = int(np.ceil(np.sqrt(n)))
        bodies, poses0, box = hexagon_packing(nx, int(np.ceil(n / nx)), phi=phi, min_gap=min_gap, seed=seed)
        n = len(bodies)
    else:
        raise InputError(f"layout = {layout!r}: expected 'random', 'hexagons' or None")
    motion = RandomMotion(bodies, poses0, box, sigma_x=sigma_x, sigma_a=sigma_a, min_gap=min_gap, seed=motion_seed)
    seq = np.array([poses0] + [motion.step() for _ in range(steps)])  # (steps + 1, n, 3)
    v0 = (seq[-1] - seq[0]) / (steps * dt)
    v0[0, 0] += 1e-9  # a scene whose bodies all rest is meshed once: the run moves them step by step anyway
    scene = stress_scene(bodies, poses0, box, h, dt, max(steps, 2), v0, element)
    out = {"n": int(n), "phi": float(phi), "layout": layout, "seed": int(seed), "motion_seed": int(motion_seed),
           "h": float(h), "min_gap": float(min_gap), "steps": int(steps), "ended": "finished", "error": None,
           "steps_done": 0, "dofs": None}
    rec = {k: [] for k in ("condition", "residual", "finite", "min_angle", "inverted", "retriangulated", "pockets",
                           "min_gap")}
    t0 = time.perf_counter()
    try:
        sim = Simulation(scene)
        flow = sim.flow
        out["dofs"] = int(flow.dofs)
        flow.path = [SequencePath(seq[:, k], dt) for k in range(n)]
        specs = list(flow.body_specs)
        check = StateCheck.for_scene(scene)
        check.speed = max(float(np.abs(np.diff(seq[:, :, :2], axis=0)).max()) / dt, 1e-12)
        diag = sim.diagnostics
        diag.finish_step(0, 0.0)
        for s in range(steps):
            vel = (seq[s + 1] - seq[s]) / dt  # (n, 3): the step's velocities
            flow.body_specs = [dataclasses.replace(b, velocity=(float(v[0]), float(v[1])), omega=float(v[2]))
                               for b, v in zip(specs, vel)]  # the conditions of this step
            with diag.watching():
                flow.step(dt)
            x = flow.x
            nd = flow.space.ub.nodal_dofs
            check.flow(x[nd[0]], x[nd[1]], flow.mesh.p, flow.t, x=x)
            hl = diag.finish_step(s + 1, flow.t, flow.last_event, flow.mm, flow.problem)
            q = flow.mm.quality()
            motion.poses = seq[s + 1]
            rec["condition"].append(hl.condition)
            rec["residual"].append(hl.residual)
            rec["finite"].append(bool(np.isfinite(x).all()))
            rec["min_angle"].append(float(q.min_angle_all))
            rec["inverted"].append(int(q.n_inverted))
            rec["retriangulated"].append(bool(flow.last_event.retriangulated))
            rec["pockets"].append(int(hl.pockets))
            rec["min_gap"].append(motion.min_gap_now())
            out["steps_done"] = s + 1
    except FluidemError as err:
        out.update(ended="stopped", error=f"{type(err).__name__}: {err}")
    out.update(rec)
    out["seconds"] = time.perf_counter() - t0
    cond = [c for c in rec["condition"] if c is not None]
    res = [r for r in rec["residual"] if r is not None]
    out.update(retriangulations=int(sum(rec["retriangulated"])), max_condition=max(cond, default=None),
               max_residual=max(res, default=None), min_angle_run=min(rec["min_angle"], default=None),
               min_gap_run=min(rec["min_gap"], default=None), pockets_max=max(rec["pockets"], default=0))
    if out["ended"] == "finished" and not within_bounds(out):
        out["ended"] = "out of bounds"
    return out


def within_bounds(run: dict) -> bool:
    """A finished :func:`stress_run` whose every step has finite fields and diagnostics inside :data:`BOUNDS`.

    >>> within_bounds({"finite": [True], "condition": [1e8], "residual": [1e-14], "min_angle": [3.0],
    ...                "inverted": [0]})
    True
    """
    b = BOUNDS
    return (all(run["finite"])
            and all(c is None or (np.isfinite(c) and c < b["condition"]) for c in run["condition"])
            and all(r is None or r <= b["residual"] for r in run["residual"])
            and all(a > b["min_angle"] for a in run["min_angle"])
            and all(i <= b["inverted"] for i in run["inverted"]))
