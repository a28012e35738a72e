r"""Time-step convergence of the ALE BDF2 step on a moving mesh with a known answer.

The Taylor–Green vortex on the unit square, an exact solution of the Navier–Stokes
equations (kinematic form, no body force),

.. math::

    u = F(t)\,(\sin \pi x \cos \pi y,\; -\cos \pi x \sin \pi y), \qquad
    p = \tfrac14 F(t)^2 (\cos 2\pi x + \cos 2\pi y), \qquad F(t) = e^{-2 \pi^2 \nu t},

with the exact velocity as Dirichlet data on the whole boundary, on a structured mesh
whose interior nodes follow the prescribed smooth motion

.. math::

    x(X, t) = X + a \sin(\pi X_1) \sin(\pi X_2) \sin(2 \pi t / T_m)\,(1, 1)

(boundary nodes at rest).  Each step moves the problem to the new node positions
(:meth:`fluidem.fluid.problem.FlowProblem.update_geometry`, the path of
:class:`fluidem.coupling.moving_flow.MovingMeshFlow` between re-triangulations) and takes a
BDF2 step in the non-conservative ALE form with the mass matrix at t^{n+1} (Formaggia &
Nobile 2004, CMAME 193, 4097–4116; Donea & Huerta 2003, *Finite Element Methods for Flow
Problems*, Ch. 7) and the mesh velocity

* ``order=2``: w^{n+1} = (3x^{n+1} − 4x^n + x^{n−1}) / (2Δt), the derivative of the node
  trajectories at t^{n+1} (second order);
* ``order=1``: w^{n+1} = (x^{n+1} − x^n) / Δt, the former scheme (first order: its error
  w − ẋ = O(Δt) enters the convection (u − w)·∇u).

Errors at the final time: the velocity L2 error and the force (traction) on the bottom
wall, from the residual of the last step (:func:`fluidem.fluid.forces.body_loads`), both
against a reference run with a small time step on the same meshes (the node positions are
a function of time only, so the spatial error cancels), and the velocity against the exact
solution for scale.  A uniform flow is kept to round-off under any mesh motion (the
discrete geometric conservation law of the non-conservative form: the ALE derivative of a
constant is zero and its gradient vanishes).

Examples
--------
>>> r = run(4, 0.25, 0.5, uniform=(1.0, -0.5))   # uniform flow, moving mesh
>>> bool(r["err_exact"] < 1e-12)
True
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["exact_velocity", "exact_pressure", "mesh_positions", "run", "convergence"]


def exact_velocity(x, y, t, nu):
    """Taylor–Green velocity (2, n) at points ``x, y`` (n,), time ``t``, viscosity ``nu``."""
    F = np.exp(-2.0 * np.pi ** 2 * nu * t)
    return np.array([F * np.sin(np.pi * x) * np.cos(np.pi * y), -F * np.cos(np.pi * x) * np.sin(np.pi * y)])


def exact_pressure(x, y, t, nu):
    """Taylor–Green kinematic pressure (n,) (zero mean over the unit square)."""
    F = np.exp(-2.0 * np.pi ** 2 * nu * t)
    return 0.25 * F ** 2 * (np.cos(2 * np.pi * x) + np.cos(2 * np.pi * y))


def mesh_positions(X: np.ndarray, t: float, amplitude: float, period: float) -> np.ndarray:
    """Node positions (2, n) at time ``t`` of the reference nodes ``X`` (2, n) of the unit square."""
    s = amplitude * np.sin(np.pi * X[0]) * np.sin(np.pi * X[1]) * np.sin(2 * np.pi * t / period)
    return X + s[None, :]


def _box_mesh(n: int):
    from skfem import MeshTri

    m = MeshTri.init_symmetric().refined(int(np.log2(n))) if n & (n - 1) == 0 else None
    if m is None:
        raise ValueError(f"n = {n!r}: expected a power of two (elements per side)")
    return m.with_boundaries({"left": lambda x: x[0] < 1e-12, "right": lambda x: x[0] > 1 - 1e-12,
                              "bottom": lambda x: x[1] < 1e-12, "top": lambda x: x[1] > 1 - 1e-12})


def run(n: int, dt: float, t_end: float = 1.0, order: int = 2, nu: float = 0.05, amplitude: float = 0.08,
        period: float = 1.0, element: str = "th", uniform=None, conservative: bool = False) -> dict:
    """One run to ``t_end``; returns the final velocity, the bottom-wall force and the exact errors.

    Parameters
    ----------
    n : int
        Elements per side (power of two).
    dt : float
        Time step; ``t_end / dt`` must be an integer.
    order : {1, 2}
        Mesh-velocity formula (module docstring).
    uniform : (2,) float, optional
        Instead of the vortex, the uniform flow of this velocity (the GCL check).
    conservative : bool
        The conservative ALE form (:meth:`~fluidem.fluid.navier_stokes.BDF2Stepper.use_conservative_form`).

    Returns
    -------
    dict with ``u`` (n_u,), ``force`` (2,) (bottom wall, kinematic units), ``err_exact`` (velocity
    L2 error against the exact solution), ``space``.
    """
    from ..coupling.moving_flow import p1_at_dofs
    from ..fluid.forces import body_loads
    from ..fluid.navier_stokes import BDF2Stepper
    from ..fluid.problem import FlowProblem
    from ..fluid.space import FlowSpace, VelocityBC

    steps = int(round(t_end / dt))
    if abs(steps * dt - t_end) > 1e-9 * t_end:
        raise ValueError(f"dt = {dt!r}: expected t_end / dt to be an integer")
    if uniform is None:
        def value(x, y, t):
            return exact_velocity(x, y, t, nu)
    else:
        U = np.asarray(uniform, float)

        def value(x, y, t):
            return np.broadcast_to(U[:, None], (2, len(x))).copy()
    mesh0 = _box_mesh(n)
    X = mesh0.p.copy()
    bcs = [VelocityBC(("left", "right", "bottom", "top"), value)]
    space = FlowSpace(mesh0, element)
    problem = FlowProblem(space, nu, bcs, moving=True)
    stepper = BDF2Stepper(problem, dt, solver=problem.direct_solver())
    # start from the interpolated exact field (velocity DOFs at their locations)
    locs = space.ub.doflocs
    comp = np.zeros(space.n_u, dtype=int)
    comp[space.ub.split_indices()[1]] = 1
    u0 = value(locs[0], locs[1], 0.0)[comp, np.arange(space.n_u)]
    nodal = np.isfinite(locs).all(axis=0)
    u0[~nodal] = 0.0
    stepper.take_over(problem, u0)
    if conservative:
        stepper.use_conservative_form()
    hist = [X, X]  # x^n, x^{n-1}
    mesh = mesh0
    for k in range(steps):
        t_new = (k + 1) * dt
        x_new = mesh_positions(X, t_new, amplitude, period)
        if order == 2 and k > 0:
            w_nodes = (3.0 * x_new - 4.0 * hist[0] + hist[1]) / (2.0 * dt)
        else:
            w_nodes = (x_new - hist[0]) / dt
        hist = [x_new, hist[0]]
        mesh = dataclasses.replace(mesh, doflocs=np.ascontiguousarray(x_new))
        problem.update_geometry(mesh)
        space = problem.space
        stepper.take_over(problem, stepper.state.u, stepper.previous_velocity,
                          mesh_velocity=p1_at_dofs(space, w_nodes.T))
        stepper.step()
    u = stepper.state.u.copy()
    load = body_loads(space, stepper.last_residual(), "bottom")
    force = (load.fx, load.fy)
    ub = space.ub
    xq = np.asarray(ub.global_coordinates())
    uq = np.asarray(ub.interpolate(u))
    ex = value(xq[0].ravel(), xq[1].ravel(), t_end).reshape(uq.shape)
    err = float(np.sqrt((ub.dx * ((uq - ex) ** 2).sum(axis=0)).sum()))
    return {"u": u, "force": np.asarray(force, float), "err_exact": err, "space": space}


def convergence(n: int = 16, dts=(0.1, 0.05, 0.025, 0.0125), dt_ref: float = 0.003125, t_end: float = 1.0,
                **kw) -> list[dict]:
    """Rows (order, dt, velocity error, force error, their rates, exact error) of both mesh-velocity orders.

    Errors against the order-2 run at ``dt_ref`` on the same meshes: the velocity in the L2
    norm (relative to the reference's norm), the bottom-wall force (relative to its magnitude).
    """
    ref = run(n, dt_ref, t_end, order=2, **kw)
    ub = ref["space"].ub
    norm = float(np.sqrt((ub.dx * (np.asarray(ub.interpolate(ref["u"])) ** 2).sum(axis=0)).sum()))
    fnorm = float(np.linalg.norm(ref["force"]))
    rows = []
    for order in (2, 1):
        prev = None
        for dt in dts:
            r = run(n, dt, t_end, order=order, **kw)
            eu = float(np.sqrt((ub.dx * (np.asarray(ub.interpolate(r["u"] - ref["u"])) ** 2).sum(axis=0)).sum())) / norm
            ef = float(np.linalg.norm(r["force"] - ref["force"])) / fnorm
            row = {"order": order, "dt": dt, "velocity_error": eu, "force_error": ef,
                   "exact_error": r["err_exact"] / norm, "velocity_rate": None, "force_rate": None}
            if prev is not None:
                q = np.log(prev["dt"] / dt)
                row["velocity_rate"] = float(np.log(prev["velocity_error"] / eu) / q)
                row["force_rate"] = float(np.log(prev["force_error"] / ef) / q)
            rows.append(row)
            prev = row
    return rows
