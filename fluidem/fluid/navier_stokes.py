"""Stokes, steady Navier–Stokes (Newton) and unsteady Navier–Stokes (BDF2) on one mesh.

Equations, in kinematic form (pressure p divided by the density ρ), on the fluid domain Ω:

    ∂u/∂t + (b · ∇) u − ν Δu + ∇p = f,     div u = 0,

with b = u on a fixed mesh and b = u − w (w: mesh velocity) on a moving one (ALE).  Velocity
Dirichlet data on walls, inflow and obstacles; the do-nothing condition ν ∂u/∂n − p n = 0 on
every boundary without a velocity condition.

Time stepping: BDF of order 2 (default) or 3, started with the lower orders (BDF1, then BDF2;
Hairer & Wanner, *Solving ODEs II*, Sec. V.1):

    BDF2: (3/2 u^{n+1} − 2 u^n + 1/2 u^{n−1}) / Δt,
    BDF3: (11/6 u^{n+1} − 3 u^n + 3/2 u^{n−1} − 1/3 u^{n−2}) / Δt,

with the extrapolation of the same order for everything taken from the past,
EXT2: 2u^n − u^{n−1}, EXT3: 3u^n − 3u^{n−1} + u^{n−2}.  Convection either

* ``"semi-implicit"``: linear in u^{n+1} with the extrapolated convecting velocity b = EXT(u)
  (one linear solve per step, of the scheme's order; Simo & Armero 1994),
* ``"newton"``: fully implicit, solved by Newton's method each step, or
* ``"explicit"``: the whole convection term extrapolated, (b·∇)b with b = EXT(u)
  (BDF/EXT, "SBDF": Karniadakis, Israeli & Orszag 1991; Ascher, Ruuth & Wetton 1995): the
  matrix never changes, so one factorisation serves the whole run, but the time step is
  bounded by the convection's stability (``last_cfl``).  On the imaginary axis SBDF2 amplifies
  every undamped mode (|ζ| = 1 + O((λΔt)⁴): it leans on the viscosity), while SBDF3 damps
  |λΔt| up to ≈ 0.6 (roots of the characteristic polynomials; Ascher, Ruuth & Wetton 1995).
  Measured with P3/P2 on DFG 2D-2 the bound is the same for both, set by the fast cells next
  to the cylinder: both ran on ``dfg_mesh(0)`` at Δt = 1/1200 (largest CFL 0.095, longest
  edges), both diverged on ``dfg_mesh(1)`` (SBDF2 at Δt = 1/1600, SBDF3 at 1/1200); SBDF3
  ran on ``dfg_mesh(0, h0=0.02, h_max=0.08)`` at 1/1800 (CFL 0.074).

Steady Navier–Stokes: Newton's method from a Stokes start (Girault & Raviart 1986, Ch. IV),
with a stop on the residual norm (the lift coefficient of DFG 2D-1 needs ≲ 1e-11).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from ..cost import CostSplit
from .problem import FlowProblem, FlowState
from .solvers import AutoSolver, LaggedLUSolver, make_solver

__all__ = ["FlowProblem", "FlowState", "NewtonError", "solve_stokes", "solve_steady", "BDFStepper", "BDF2Stepper",
           "Timings", "make_flow_solver"]

#: Former name of the per-phase timing record; the solvers now report a :class:`fluidem.cost.CostSplit`.
Timings = CostSplit


class NewtonError(RuntimeError):
    """Newton's method did not converge; ``history`` holds the residual norms."""

    def __init__(self, message, history):
        super().__init__(message + "; residual history: " + ", ".join(f"{r:.3e}" for r in history))
        self.history = list(history)


def make_flow_solver(problem: FlowProblem, method: str = "auto", dt: float | None = None):
    """A linear solver for the condensed systems of ``problem``: :func:`fluidem.fluid.solvers.make_solver`.

    Kept for existing callers; ``make_flow_solver(pr, m, dt)`` is ``make_solver(m, problem=pr, dt=dt)``.
    """
    return make_solver(method, problem=problem, dt=dt)


def _solve_free(problem: FlowProblem, uu_data: np.ndarray, rhs_full: np.ndarray, solver,
                refactorize: bool = False) -> np.ndarray:
    """Solve K δ = rhs on the free DOFs (δ = 0 on fixed ones); K from velocity-block data.

    ``refactorize``: a lagged LU factorises this K now (the DOF numbering changed).
    """
    K = problem.condensed_matrix(uu_data)
    if refactorize and isinstance(solver, (LaggedLUSolver, AutoSolver)):
        solver.factorize(K, force=True)
    else:
        solver.factorize(K)
    return problem.expand(solver.solve(problem.reduce(rhs_full)))


def solve_stokes(problem: FlowProblem, t: float = 0.0, solver=None) -> FlowState:
    """Stokes solution (no convection) with the velocity conditions at time ``t``."""
    solver = solver or problem.direct_solver()
    x = problem.initial_vector(t)
    t0 = time.perf_counter()
    r = problem.steady_residual(x, convection=False)
    problem.timings.add("assembly", time.perf_counter() - t0)
    t0 = time.perf_counter()
    x -= _solve_free(problem, problem.A_data, r, solver)
    problem.timings.add("solve", time.perf_counter() - t0)
    problem.normalise_pressure(x)
    return FlowState(x, problem.space.n_u, t)


def solve_steady(problem: FlowProblem, tol: float = 1e-11, max_iter: int = 25, start: FlowState | None = None,
                 solver=None, verbose: bool = False) -> FlowState:
    """Steady Navier–Stokes by Newton's method.

    Parameters
    ----------
    tol : float
        Stop when the Euclidean norm of the residual on free DOFs is below ``tol``.
    start : FlowState, optional
        Initial guess; by default zero velocity with the boundary data, whose first Newton
        step is an Oseen (nearly Stokes) solve.

    Raises
    ------
    NewtonError
        If the residual does not fall below ``tol`` within ``max_iter`` iterations or grows
        beyond 1e8 times its initial value; the message carries the residual history.
    """
    # One LU per Newton step: reusing an old LU as a GMRES preconditioner was measured
    # slower here (20-100 iterations per step on DFG 2D-1, P3/P2).
    solver = solver or problem.direct_solver()
    x = start.x.copy() if start is not None else problem.initial_vector(0.0)
    d, v = problem.dirichlet_values(0.0)
    x[d] = v
    history = []
    for it in range(max_iter + 1):
        t0 = time.perf_counter()
        r = problem.steady_residual(x)
        res = float(np.linalg.norm(problem.reduce(r)))
        history.append(res)
        if verbose:
            print(f"  Newton {it:2d}: |R| = {res:.3e}")
        if res < tol:
            problem.timings.add("assembly", time.perf_counter() - t0)
            problem.normalise_pressure(x)
            return FlowState(x, problem.space.n_u, 0.0, history)
        if not np.isfinite(res) or res > 1e8 * max(history[0], tol):
            break
        J = problem.A_data + problem.newton_data(x[: problem.space.n_u])
        problem.timings.add("assembly", time.perf_counter() - t0)
        t0 = time.perf_counter()
        x -= _solve_free(problem, J, r, solver)
        problem.timings.add("solve", time.perf_counter() - t0)
    raise NewtonError(f"steady Navier-Stokes did not converge to |R| < {tol:g} in {max_iter} Newton iterations",
                      history)


#: BDF coefficients (a0, a1, ...) of (a0 u^{n+1} + a1 u^n + a2 u^{n−1} + ...) / Δt, by order.
BDF_COEFFICIENTS = {1: (1.0, -1.0), 2: (1.5, -2.0, 0.5), 3: (11.0 / 6.0, -3.0, 1.5, -1.0 / 3.0)}
#: Extrapolation weights (e1, e2, ...) of e1 u^n + e2 u^{n−1} + ... to t^{n+1}, by order.
EXTRAPOLATION = {1: (1.0,), 2: (2.0, -1.0), 3: (3.0, -3.0, 1.0)}


class BDFStepper:
    """Unsteady Navier–Stokes with BDF2 or BDF3 (started with the lower orders).

    Parameters
    ----------
    problem : FlowProblem
    dt : float
        Time step (time units), > 0.
    convection : {"semi-implicit", "newton"}
        Linearisation of the convection term, see module docstring.
    solver : object with ``factorize(K)`` and ``solve(b)``
        Default: an LU reused as a GMRES preconditioner across steps, refactorised when
        the iteration count grows (:class:`~fluidem.fluid.solvers.LaggedLUSolver`).
    newton_tol : float
        Tolerance on the Euclidean norm of the residual (free DOFs, kinematic units) of the
        Newton iteration per step (``"newton"`` only).
    order : {2, 3}
        Order of the BDF formula and of the extrapolations (see the module docstring).  Order 3
        needs a fixed mesh (:meth:`take_over` restarts it at order 2 for one step).

    Attributes
    ----------
    conservative : bool
        The conservative ALE form on a moving mesh (set with :meth:`use_conservative_form`):
        the time derivative (a0 M^{n+1}u^{n+1} + a1 M^n u^n + a2 M^{n−1}u^{n−1})/Δt with each
        mass matrix of its own time level (Formaggia & Nobile 2004, §3: the conservative
        formulation), and the convection in divergence form div(u ⊗ c)·v =
        ((c·∇)u + (div c) u)·v with c = EXT(u) − w, set to zero on ``no_flux_dofs`` (body
        outlines, where c would otherwise be the O(Δt²) difference of two velocities of the
        same outline).  Tested with a constant v every term but the time derivative is a
        boundary flux, so the momentum ∫ u dA (plus that of free bodies) changes only
        through the boundary: to solver tolerance in a closed periodic box.  Its discrete GCL
        is not exact in general (the BDF2 derivative of the element areas is not ∫ div w);
        on the moving Taylor–Green mesh of :mod:`fluidem.cases.ale_convergence` a uniform flow
        is still kept to 2.8e-15 (the defect goes into the pressure), the velocity converges
        at second order with 1.9× the error of the default form.  Semi-implicit convection,
        order 2.

    The state advances with :meth:`step`; ``self.state`` holds the newest solution and
    ``self.residual(...)`` the discrete residual used for forces.
    """

    CONVECTION = ("semi-implicit", "newton", "explicit")

    def __init__(self, problem: FlowProblem, dt: float, convection: str = "semi-implicit", solver=None,
                 start: FlowState | None = None, t0: float = 0.0, newton_tol: float = 1e-9,
                 mesh_velocity: np.ndarray | None = None, order: int = 2):
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"time step dt must be a positive number, got {dt!r}")
        if convection not in self.CONVECTION:
            raise ValueError(f"convection must be one of {self.CONVECTION}, got {convection!r}")
        if order not in (2, 3):
            raise ValueError(f"BDF order must be 2 or 3, got {order!r}")
        self.order = int(order)
        self.problem = problem
        self.dt = float(dt)
        self.convection = convection
        self.solver = solver or LaggedLUSolver(direct=problem.direct_solver())
        self.newton_tol = newton_tol
        self.t = float(t0)
        x0 = start.x.copy() if start is not None else problem.initial_vector(t0)
        self.state = FlowState(x0, problem.space.n_u, self.t)
        self._u_prev = None  # u^{n-1}
        self._u_prev2 = None  # u^{n-2} (order 3 only)
        self.mesh_velocity = mesh_velocity
        self.n_steps = 0
        self.last_b = None
        self.last_cfl = None
        self.max_cfl = None  # the largest last_cfl of the run (explicit convection)
        self._explicit_conv = None
        self._explicit_a0 = None
        self._explicit_rhs = None  # hist + convection − f of the last explicit step, for its residual
        self._refactorize = False
        self.last_cost = CostSplit()
        self.conservative = False
        self.no_flux_dofs = None
        self._mass_history = None  # [M^n u^n, M^{n-1} u^{n-1}] (conservative form)

    def use_conservative_form(self, no_flux_dofs=None) -> None:
        """Switch to the conservative ALE form (class docstring) from the current state, whose
        mass-weighted velocities are taken on the current geometry; ``no_flux_dofs`` (k,) int:
        velocity DOFs where the convecting velocity c is set to zero (body outlines)."""
        if self.convection != "semi-implicit" or self.order != 2:
            raise ValueError("the conservative ALE form needs semi-implicit convection and order 2, got "
                             f"convection = {self.convection!r}, order {self.order}")
        self.conservative = True
        self.no_flux_dofs = None if no_flux_dofs is None else np.asarray(no_flux_dofs, dtype=np.int64)
        self._mass_history = self._mass_weighted(self.problem.M)

    def _mass_weighted(self, M) -> list:
        """[M u^n] or [M u^n, M u^{n−1}]: the mass-weighted velocities with the mass matrix ``M``."""
        return [M @ self.state.u] + ([] if self._u_prev is None else [M @ self._u_prev])

    @property
    def mass_history(self) -> list | None:
        """[M^n u^n, M^{n−1} u^{n−1}] (each (n_u,)) of the conservative form, else None."""
        return self._mass_history

    @property
    def previous_velocity(self) -> np.ndarray | None:
        """u^{n−1} (n_u,), or None before the first step (the next step is then BDF1)."""
        return self._u_prev

    def take_over(self, problem: FlowProblem, u: np.ndarray, u_prev: np.ndarray | None = None,
                  mesh_velocity: np.ndarray | None = None, renumbered: bool = False, mass_history=None,
                  no_flux_dofs=None) -> None:
        """Continue on ``problem`` (a moved or new mesh) from velocities given on its DOFs.

        Parameters
        ----------
        problem : FlowProblem
            The problem of the next step (same time step, model and solver).
        u, u_prev : (problem.space.n_u,) float
            u^n and u^{n−1} on the new DOFs (``u_prev`` None: the next step is BDF1); the
            pressure restarts from zero (the next step solves for it).
        mesh_velocity : (n_u,) float, optional
            ALE mesh velocity w of the next step (convection with u − w); None: Eulerian.
        renumbered : bool
            The DOF numbering changed (a re-triangulation): a lagged LU is recomputed on the
            next solve instead of preconditioning with the LU of the old numbering.
        mass_history : list of (n_u,) float, optional
            Conservative form: M^n u^n (and M^{n−1} u^{n−1}) on the new DOFs.  Without it they
            are kept when the numbering is unchanged (the mesh moved: they belong to the times
            they were computed at) and recomputed with the new geometry's M otherwise.
        no_flux_dofs : (k,) int, optional
            Conservative form: the new ``no_flux_dofs`` (after a re-triangulation).
        """
        n_u = problem.space.n_u
        x = np.zeros(problem.space.n_dofs)
        x[:n_u] = u
        self.problem = problem
        self.state = FlowState(x, n_u, self.t)
        self._u_prev = None if u_prev is None else np.asarray(u_prev, dtype=float)
        self._u_prev2 = None  # order 3 continues at order 2 for one step
        self.mesh_velocity = mesh_velocity
        self._explicit_a0 = None  # the explicit scheme's LU belongs to the old matrix
        self._explicit_rhs = None
        self.__dict__.pop("_h_cache", None)
        self._refactorize = self._refactorize or renumbered
        if self.conservative:
            if no_flux_dofs is not None:
                self.no_flux_dofs = np.asarray(no_flux_dofs, dtype=np.int64)
            if mass_history is not None:
                self._mass_history = [np.asarray(m, dtype=float) for m in mass_history]
            elif renumbered or self._mass_history is None:
                self._mass_history = self._mass_weighted(problem.M)

    def _past(self) -> list:
        """[u^n, u^{n−1}, ...]: the velocities the next step's formulas use (at most ``order``)."""
        past = [self.state.u]
        for u in (self._u_prev, self._u_prev2)[: self.order - 1]:
            if u is None:
                break
            past.append(u)
        return past

    def _bdf(self):
        """Order-2 coefficients (a0, a1, a2) of (a0 u^{n+1} + a1 u^n + a2 u^{n-1}) / dt (BDF1 first)."""
        if self._u_prev is None:
            return 1.0, -1.0, 0.0
        return 1.5, -2.0, 0.5

    def _scheme(self) -> tuple[tuple, tuple]:
        """BDF coefficients and extrapolation weights of the next step (order ≤ past steps + 1)."""
        k = len(self._past())
        return BDF_COEFFICIENTS[k], EXTRAPOLATION[k]

    def _extrapolate(self, weights) -> np.ndarray:
        past = self._past()
        out = weights[0] * past[0]
        for w, u in zip(weights[1:], past[1:]):
            out = out + w * u
        return out

    def _history(self, a) -> np.ndarray:
        """M (a1 u^n + a2 u^{n−1} + ...) / dt for BDF coefficients ``a``, (n_u,); in the
        conservative form (a1 M^n u^n + a2 M^{n−1} u^{n−1}) / dt."""
        if self.conservative:
            out = a[1] * self._mass_history[0]
            if len(a) > 2 and a[2]:
                out = out + a[2] * self._mass_history[1]
            return out / self.dt
        return self.problem.M @ self._extrapolate(a[1:]) / self.dt

    def _convecting_velocity(self, weights=None):
        """Extrapolated convecting velocity EXT(u) (u^n on the first step), minus w on a moving mesh."""
        b = self._extrapolate(weights or self._scheme()[1])
        if self.mesh_velocity is not None:
            b = b - self.mesh_velocity
        if self.conservative and self.no_flux_dofs is not None:
            b = np.array(b, copy=True)
            b[self.no_flux_dofs] = 0.0
        return b

    def convection_data(self, b: np.ndarray) -> np.ndarray:
        """Pattern data of the convection operator for the convecting velocity ``b``: ((b·∇)u)·v,
        plus (div b) u·v in the conservative form (class docstring)."""
        pr = self.problem
        out = pr.convection_data(b)
        if self.conservative:
            out = out + pr.assembler.divergence_mass(b)
        return out

    def _full_matrix(self, uu_data: np.ndarray):
        """[[K_uu, Bᵀ], [B, 0]] on all DOFs (no conditions applied) for velocity-block data ``uu_data``."""
        pr = self.problem
        return sp.bmat([[pr.assembler.matrix(uu_data), pr.B.T], [pr.B, None]], format="csr")

    def residual(self, x: np.ndarray, a0: float, hist: np.ndarray, b: np.ndarray | None) -> np.ndarray:
        """Unsteady residual on all DOFs: M(a0 u)/dt + hist + A u + C(b)u + Bᵀp − f, and B u."""
        pr = self.problem
        n_u = pr.space.n_u
        r = pr.steady_residual(x, convection=False)
        u = x[:n_u]
        r[:n_u] += pr.M @ (a0 * u) / self.dt + hist
        if b is not None:
            r[:n_u] += pr.convection_vector(u, b)
            if self.conservative:
                r[:n_u] += pr.assembler.divergence_mass_vector(b, u)
        return r

    def step(self) -> FlowState:
        """Advance one time step; returns the new state."""
        pr = self.problem
        n_u = pr.space.n_u
        a, ext = self._scheme()
        a0 = a[0]
        t_new = self.t + self.dt
        tm = CostSplit()
        t0 = time.perf_counter()
        hist = self._history(a)
        x = self.state.x.copy()
        if self._u_prev is not None:
            x[:n_u] = self._extrapolate(ext)  # extrapolated guess
        d, v = pr.dirichlet_values(t_new)
        x[d] = v
        base = pr.A_data + pr.M_data * (a0 / self.dt)
        if self.convection == "semi-implicit":
            b = self._convecting_velocity(ext)
            K = base + self.convection_data(b)
            r = self.residual(x, a0, hist, b)
            tm.add("assembly", time.perf_counter() - t0)
            t0 = time.perf_counter()
            x -= _solve_free(pr, K, r, self.solver, self._refactorize)
            tm.add("solve", time.perf_counter() - t0)
            self.last_b = b
        elif self.convection == "explicit":
            ua = self._extrapolate(ext)  # EXT(u); convected with b = EXT(u) − w
            b = ua if self.mesh_velocity is None else ua - self.mesh_velocity
            bq = pr.assembler.values(b)  # b at the quadrature points, once for the CFL and the convection
            self.last_cfl = self._cfl(b, bq)
            self.max_cfl = max(self.max_cfl or 0.0, self.last_cfl)
            self._explicit_conv = pr.convection_vector(ua, b, b_values=bq)
            if self._explicit_a0 != a0:  # the matrix changes only with the order (BDF1, BDF2, BDF3)
                self._explicit_lu = pr.direct_solver().factorize(pr.condensed_matrix(base))
                self._explicit_full = self._full_matrix(base)
                self._explicit_a0 = a0
            rhs = np.concatenate([hist + self._explicit_conv - pr._f, np.zeros(pr.space.n_p)])
            r = self._explicit_full @ x + rhs  # the residual at the guess: one mat-vec
            tm.add("assembly", time.perf_counter() - t0)
            t0 = time.perf_counter()
            x -= pr.expand(self._explicit_lu.solve(pr.reduce(r)))
            tm.add("solve", time.perf_counter() - t0)
            self._explicit_rhs = rhs
            self.last_b = None
        else:
            for it in range(30):
                t0 = time.perf_counter()
                b = x[:n_u] if self.mesh_velocity is None else x[:n_u] - self.mesh_velocity
                r = self.residual(x, a0, hist, b)
                res = np.linalg.norm(pr.reduce(r))
                if res < self.newton_tol:
                    tm.add("assembly", time.perf_counter() - t0)
                    break
                # ALE: ((u − w)·∇)δu + (δu·∇)u, with b = u − w
                J = base + pr.newton_data(x[:n_u], b)
                tm.add("assembly", time.perf_counter() - t0)
                t0 = time.perf_counter()
                x -= _solve_free(pr, J, r, self.solver, self._refactorize)
                self._refactorize = False
                tm.add("solve", time.perf_counter() - t0)
            else:
                raise NewtonError(f"Newton did not converge in time step {self.n_steps + 1} (t = {t_new:g})", [res])
            self.last_b = b
        return self.accept(x, v, a0, hist, tm)

    # -- the parts of a step, for solvers that extend it (free bodies) ------------------------
    def bdf_coefficients(self) -> tuple[float, float, float]:
        """(a0, a1, a2) of the next step's derivative (a0 u^{n+1} + a1 u^n + a2 u^{n−1}) / dt (order 2 only)."""
        if self.order != 2:
            raise ValueError(f"bdf_coefficients() gives the order-2 formula; this stepper has order {self.order}")
        return self._bdf()

    def history_term(self, a1: float, a2: float) -> np.ndarray:
        """M (a1 u^n + a2 u^{n−1}) / dt, (n_u,), with M of the current geometry."""
        return self._history((None, a1, a2) if a2 else (None, a1))

    def convecting_velocity(self) -> np.ndarray:
        """The semi-implicit step's convecting velocity EXT(u) − w (2u^n − u^{n−1} − w at order 2), (n_u,)."""
        return self._convecting_velocity()

    def accept(self, x: np.ndarray, boundary_values: np.ndarray, a0: float, hist: np.ndarray,
               cost: CostSplit, b: np.ndarray | None = None) -> FlowState:
        """Make ``x`` (n_dofs,) the state at t + dt after a solve: checked to be finite, pressure
        normalised, u^n becomes u^{n−1}, the residual terms (a0, hist, and the convecting velocity
        ``b`` if given) kept for the loads."""
        pr = self.problem
        t_new = self.t + self.dt
        self._check_finite(x, t_new, boundary_values)
        pr.normalise_pressure(x)
        pr.timings += cost
        self.last_cost = cost
        self._refactorize = False
        self._last = (a0, hist)
        if b is not None:
            self.last_b = b
        if self.conservative:
            self._mass_history = [pr.M @ x[: pr.space.n_u], self._mass_history[0]]
        if self.order >= 3:
            self._u_prev2 = self._u_prev
        self._u_prev = self.state.u.copy()
        self.state = FlowState(x, pr.space.n_u, t_new)
        self.t = t_new
        self.n_steps += 1
        return self.state

    def get_state(self) -> dict:
        """Everything needed to continue the run bit for bit (for checkpoints): time, step count,
        u^n and p^n, u^{n−1}, and the terms of the last step's residual (for its forces)."""
        def cp(a):
            return None if a is None else np.array(a, copy=True)

        return {"t": self.t, "x": cp(self.state.x), "u_prev": cp(self._u_prev), "u_prev2": cp(self._u_prev2),
                "n_steps": self.n_steps,
                "last": getattr(self, "_last", None), "last_b": cp(self.last_b),
                "explicit_conv": cp(self._explicit_conv), "last_cfl": self.last_cfl,
                "mass_history": None if self._mass_history is None else [cp(m) for m in self._mass_history]}

    def set_state(self, state: dict) -> None:
        """Continue from a state of :meth:`get_state` (on the same mesh and element pair)."""
        self.t = float(state["t"])
        self.state = FlowState(np.array(state["x"], copy=True), self.problem.space.n_u, self.t)
        self._u_prev = None if state["u_prev"] is None else np.array(state["u_prev"], copy=True)
        u2 = state.get("u_prev2")
        self._u_prev2 = None if u2 is None else np.array(u2, copy=True)
        self.n_steps = int(state["n_steps"])
        if state.get("last") is not None:
            self._last = state["last"]
        self.last_b = state.get("last_b")
        self._explicit_conv = state.get("explicit_conv")
        self.last_cfl = state.get("last_cfl")
        if state.get("mass_history") is not None:
            self._mass_history = [np.array(m, copy=True) for m in state["mass_history"]]

    def solver_summary(self) -> dict:
        """Factorisations and Krylov iterations of the linear solver so far (if it counts them)."""
        s = self.solver
        return {"linear_solves": getattr(s, "solves", None), "factorizations": getattr(s, "factorizations", None),
                "krylov_iterations": getattr(s, "total_iterations", None)}

    def _check_finite(self, x: np.ndarray, t_new: float, boundary_values: np.ndarray) -> None:
        """Raise a clear error instead of carrying NaN/inf (a diverging run) any further.

        A velocity above 1e6 times the largest boundary speed seen so far counts as diverged.
        """
        bmax = np.abs(boundary_values).max(initial=0.0)
        self._blowup_speed = max(getattr(self, "_blowup_speed", 0.0), 1e6 * max(1.0, bmax))
        if not np.all(np.isfinite(x)) or np.abs(x[: self.problem.space.n_u]).max() > self._blowup_speed:
            raise FloatingPointError(
                f"the flow solution became non-finite in step {self.n_steps + 1} (t = {t_new:g}); "
                f"reduce dt = {self.dt:g}" + (f" (CFL was {self.last_cfl:.2f})" if self.last_cfl else ""))

    def _cfl(self, b: np.ndarray, b_values: np.ndarray | None = None) -> float:
        """Courant number max_e |b|_e Δt / h_e with h_e the element diameter (longest edge);
        ``b_values``: b at the quadrature points, if already evaluated."""
        bq = self.problem.assembler.values(b) if b_values is None else b_values
        speed = np.sqrt(bq[0] ** 2 + bq[1] ** 2).max(axis=1)
        return float((speed * self.dt / self._h_elements()).max())

    def _h_elements(self):
        if not hasattr(self, "_h_cache"):
            m = self.problem.space.mesh
            p, t = m.p, m.t
            e = [np.linalg.norm(p[:, t[i]] - p[:, t[(i + 1) % 3]], axis=0) for i in range(3)]
            self._h_cache = np.max(e, axis=0)
        return self._h_cache

    def last_residual(self) -> np.ndarray:
        """Residual of the last step's equations at the new state (for forces)."""
        a0, hist = self._last
        if self.convection == "explicit" and getattr(self, "_explicit_rhs", None) is not None:
            return self._explicit_full @ self.state.x + self._explicit_rhs  # one mat-vec
        r = self.residual(self.state.x, a0, hist, self.last_b)
        if self.convection == "explicit":
            r[: self.problem.space.n_u] += self._explicit_conv
        return r


#: The stepper under its former name (order 2 by default, as it always was).
BDF2Stepper = BDFStepper
