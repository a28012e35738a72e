"""One implicit step of a fluid with free rigid bodies: BDF2 for both, one saddle-point solve.

The fluid is the BDF2 (BDF1 on the first step) semi-implicit Navier–Stokes step of
:class:`fluidem.fluid.navier_stokes.BDF2Stepper`; the bodies obey Newton–Euler with the same
BDF2 derivative,

    m_k D_t U_k = F_hyd,k + F_ext,k,     I_k D_t ω_k = T_hyd,k + T_ext,k,

with the hydrodynamic load by the volume integral of the fluid residual (John 2004) and the
outline velocity the rigid motion of the body, so both are solved together
(:class:`fluidem.coupling.rigid_system.RigidBodySystem`; Glowinski et al. 1999, Hu, Patankar &
Zhu 2001).  The fluid's inertia enters the body rows implicitly: the added mass is inside the
matrix, so the step is stable at density ratios near one, where a staggered step (forces
from the last solve) is not.  ``F_ext`` is the buoyant weight (ρ_s − ρ_f) A g plus any
contact loads: the fluid itself carries no gravity (its hydrostatic pressure is subtracted).
Units: masses per unit depth (mass/length), forces per unit depth; the matrix rows are
kinematic (divided by the fluid density ρ).
"""

from __future__ import annotations

import time

import numpy as np

from ..cost import CostSplit
from ..fluid.problem import FlowState
from ..fluid.solvers import AutoSolver, LaggedLUSolver
from .body_krylov import BodyBlockKrylovSolver

__all__ = ["AndersonMixing", "FreeBodyStepper", "carried_contact_load"]


class AndersonMixing:
    """Anderson acceleration of a fixed-point iteration ``F ← G(F)`` (Anderson 1965; Walker & Ni 2011,
    *SIAM J. Numer. Anal.* 49, 1715, Alg. AA with depth ``m``).

    With the residuals ``r_k = G(F_k) − F_k`` and the differences ``ΔR``, ``ΔG`` of the last ``m``
    residuals and images, the next iterate is ``G(F_k) − ΔG γ`` with ``γ`` the least-squares solution of
    ``ΔR γ ≈ r_k``.  ``m = 0`` is the plain iteration.  The contact load of bodies resting on each
    other contracts by only about 0.9 per plain iteration (the DEM's mass is far below the added mass of a
    body in a pile); the mixing extrapolates that slow mode.

    Examples
    --------
    A linear map contracting by 0.95: the plain iteration needs about 300 iterations to 1e-6, the mixed one 3.

    >>> A = np.diag([0.95, 0.5]); b = np.array([1.0, 1.0])
    >>> mix, F = AndersonMixing(2), np.zeros(2)
    >>> for k in range(4):
    ...     F = mix.next(F, A @ F + b)
    >>> bool(np.allclose(F, np.linalg.solve(np.eye(2) - A, b)))
    True
    """

    def __init__(self, memory: int = 3):
        self.memory = int(memory)
        self._F, self._G = [], []

    def next(self, F: np.ndarray, G: np.ndarray) -> np.ndarray:
        """The next iterate from the current ``F`` and its image ``G = G(F)`` (same shape)."""
        F, G = np.asarray(F, float), np.asarray(G, float)
        if self.memory <= 0:
            return G
        self._F.append(F.ravel().copy())
        self._G.append(G.ravel().copy())
        if len(self._F) > self.memory + 1:
            self._F.pop(0)
            self._G.pop(0)
        if len(self._F) < 2:
            return G
        Fs, Gs = np.array(self._F), np.array(self._G)
        R = Gs - Fs
        dR = np.diff(R, axis=0).T
        dG = np.diff(Gs, axis=0).T
        gamma = np.linalg.lstsq(dR, R[-1], rcond=1e-10)[0]
        return (G.ravel() - dG @ gamma).reshape(G.shape)


def carried_contact_load(load, regions_then, regions_now):
    """The contact load a step starts its fixed-point iteration from (``contact_guess`` of
    :meth:`FreeBodyStepper.step`): the last step's ``load`` (n_bodies, 3), or ``None`` (start from no
    load) when the fluid's regions changed since it was found: ``regions_then`` and ``regions_now`` count the
    fluid regions of the two meshes (:attr:`fluidem.fluid.pockets.FluidComponents.n_components`;
    ``regions_then`` ``None``: unknown, the load is kept).

    A pore closed by grains touching each other and a wall is a fluid region of its own whose pressure holds
    the grains wherever their motion would change its area (:mod:`fluidem.fluid.pockets`). Grains pressed
    together there carry a contact load that only that pressure balances; a re-triangulation that opens the
    pore removes the pressure, and the load, used as the next step's guess, spins the grains up.
    ``column-collapse-fluid`` at dt = 0.01 s: two grains on the floor under contact loads of 36 N/m turned
    at −28 and +42 rad/s in the step after their 6.6 mm² pore opened, and one was pushed 3.7 mm into the
    floor a step later; with the guess dropped the same steps from the same state keep every grain below
    10 rad/s.

    >>> import numpy as np
    >>> F = np.ones((2, 3))
    >>> carried_contact_load(F, 2, 2) is F, carried_contact_load(F, 2, 1), carried_contact_load(F, None, 1) is F
    (True, None, True)
    """
    if regions_then is not None and regions_then != regions_now:
        return None
    return load


class FreeBodyStepper:
    """Implicit fluid–body BDF2 steps on the mesh of a :class:`~fluidem.fluid.navier_stokes.BDF2Stepper`.

    Parameters
    ----------
    fluid : BDF2Stepper
        The fluid stepper (its problem, time step, state and history); its ``step`` is not
        used, this class advances it.
    system : RigidBodySystem
        The coupled matrix of ``fluid.problem`` with the free bodies.
    mass : (n_bodies,) float
        Body masses per unit depth, mass/length.
    inertia : (n_bodies,) float
        Moments of inertia about the centres of mass per unit depth, mass·length.
    rho : float
        Fluid density, mass/length² (2D).
    velocities : (n_bodies, 3) float, optional
        Initial (U_x, U_y, ω) of the bodies; zero by default.
    solver : object with ``factorize(K)`` and ``solve(b)``, optional
        Linear solver of the coupled system; the problem's direct solver by default.

    Attributes
    ----------
    V : (n_bodies, 3) float
        Body velocities at the current time.
    last_cost : CostSplit
        ``assembly`` and ``solve`` seconds of the last step.
    """

    def __init__(self, fluid, system, mass, inertia, rho: float, velocities=None, solver=None):
        self.fluid = fluid
        self.system = system
        nb = system.n_bodies
        self.mass = np.asarray(mass, float).reshape(nb)
        self.inertia = np.asarray(inertia, float).reshape(nb)
        self.rho = float(rho)
        self.V = np.zeros((nb, 3)) if velocities is None else np.array(velocities, float).reshape(nb, 3)
        self.V_prev = None
        #: contact load iteration (see :meth:`step`): relative tolerance and most iterations
        self.contact_tolerance = 1e-3
        self.contact_iterations = 8
        #: iterates the Anderson mixing of the contact load remembers (0: the plain fixed point)
        self.contact_memory = 3
        #: the iteration stops, unsettled, once a pass leaves more than this fraction of the change two passes
        #: before (a stalled iteration; 0 turns the rule off; see :meth:`step`)
        self.contact_stall = 0.7
        self.last_contact_iterations = 0
        #: whether the last step's contact load settled within ``contact_iterations`` (else the last iterate is used)
        self.last_contact_converged = True
        self.last_contact_load = np.zeros((nb, 3))
        self._step_rhs_norm = 0.0
        self.solver = solver or fluid.problem.direct_solver()
        #: the next factorisation must not reuse an LU of another numbering (a re-triangulation)
        self.refactorize = False
        self.last_cost = CostSplit()

    @property
    def t(self) -> float:
        return self.fluid.t

    def _inertia_diagonal(self) -> np.ndarray:
        """(3 n_bodies,) kinematic body inertia m, m, I over ρ."""
        return (np.column_stack([self.mass, self.mass, self.inertia]) / self.rho).ravel()

    def step(self, external, contact=None, contact_guess=None) -> FlowState:
        """Advance fluid and bodies by one step.

        Parameters
        ----------
        external : (n_bodies, 3) float
            External force (x, y) and torque on each body at the new time (buoyant weight),
            per unit depth.
        contact : callable or None
            ``contact(V, F) -> F_new or None``: the mean contact load (n_bodies, 3) over the
            step that the bodies' contacts give when the solve yields the body velocities ``V``
            with the contact load ``F`` in it (:meth:`fluidem.coupling.contacts.FluidContacts.mean_load`);
            None when no body is within reach.  The load is found by fixed-point iteration, each
            iterate corrected by one back-substitution with the solver's stored LU (only the body
            rows of the right-hand side change), until it changes by less than
            ``contact_tolerance`` × the largest |external| (at most ``contact_iterations``, and no more
            once a correction leaves more than ``contact_stall`` of the change two corrections before:
            the contact load of grains flowing as a dense layer in ``column-collapse-fluid`` stalls 60–300
            tolerances off, and the passes after the stall, 40 % of them, moved its front at t = 1 s
            by 0.6 %); one
            solve to full accuracy then makes fluid and bodies agree on the body velocities.
            ``last_contact_iterations`` counts the corrections.
        contact_guess : (n_bodies, 3) float or None
            A first guess of the contact load (e.g. the last step's), solved with from the start;
            when the contacts confirm it to the tolerance no correction solve is needed (bodies
            resting on each other or a wall).  ``last_contact_load`` holds the load found.

        Returns
        -------
        FlowState
            The new fluid state (``self.V`` holds the new body velocities).
        """
        st, sysm = self.fluid, self.system
        pr = st.problem
        n_u = pr.space.n_u
        dt = st.dt
        tm = CostSplit()
        t0 = time.perf_counter()
        a0, a1, a2 = st.bdf_coefficients()
        hist = st.history_term(a1, a2)
        b = st.convecting_velocity()
        t_new = st.t + dt
        x = st.state.x.copy()
        if st.previous_velocity is not None:
            x[:n_u] = 2.0 * st.state.u - st.previous_velocity
        d, v = pr.dirichlet_values(t_new)
        x[d] = v
        V_guess = self.V if self.V_prev is None else 2.0 * self.V - self.V_prev
        z = sysm.gather(x, V_guess)
        x = sysm.prolong(z, x)
        r = st.residual(x, a0, hist, b)
        # body rows: (m/ρ) D_t V − F_ext/ρ, plus Πᵀ r_u (= −F_hyd/ρ) from the fluid residual
        Vp = self.V if self.V_prev is None else self.V_prev
        D_t = (a0 * V_guess + a1 * self.V + (a2 * Vp if a2 else 0.0)) / dt
        minv = self._inertia_diagonal()
        rz = sysm.restrict(r)
        guess = np.zeros((sysm.n_bodies, 3)) if contact is None or contact_guess is None else \
            np.asarray(contact_guess, float).reshape(sysm.n_bodies, 3)
        rz[sysm.n_fluid:] += minv * D_t.ravel() - (np.asarray(external, float) + guess).ravel() / self.rho
        K = sysm.matrix(pr.A_data + pr.M_data * (a0 / dt) + st.convection_data(b), minv * (a0 / dt))
        tm.add("assembly", time.perf_counter() - t0)
        t0 = time.perf_counter()
        if self.refactorize and isinstance(self.solver, (LaggedLUSolver, AutoSolver, BodyBlockKrylovSolver)):
            self.solver.factorize(K, force=True)
        else:
            self.solver.factorize(K)
        self.refactorize = False
        z -= self.solver.solve(rz)
        self._step_rhs_norm = float(np.linalg.norm(rz))
        tm.add("solve", time.perf_counter() - t0)
        self.last_contact_iterations = 0
        self.last_contact_load = np.zeros((sysm.n_bodies, 3))
        if contact is not None:
            self.last_contact_load = self._iterate_contacts(z, contact, guess,
                                                            np.abs(np.asarray(external, float)).max(), tm)
        x = sysm.prolong(z, x)
        self.V_prev = self.V
        self.V = sysm.split(z)[1].copy()
        self.last_cost = tm
        return st.accept(x, v, a0, hist, tm, b=b)  # the fluid stepper's loads and next step read it

    def _iterate_contacts(self, z, contact, guess, scale, tm):
        """Fixed point of the contact load in place on ``z``, which was solved with the load
        ``guess`` (see :meth:`step`); returns the load found.

        The iterates correct ``z`` with the solver's preconditioner alone (the stored, possibly
        lagged LU: one back-substitution each); once the load has settled, one solve to full
        accuracy of the change from ``guess`` makes ``z`` exact for it (skipped when the first
        iterate confirms ``guess``)."""
        sysm = self.system
        F = guess.copy()
        z0 = z.copy()
        e = np.zeros_like(z)
        tol = self.contact_tolerance * max(scale, 1e-300)
        approx = None
        self.last_contact_converged = False
        mixing = AndersonMixing(self.contact_memory)
        changes = []
        for _ in range(self.contact_iterations):
            F_new = contact(sysm.split(z)[1], F)
            if F_new is None:
                F_new = np.zeros_like(F)
            changes.append(float(np.abs(F_new - F).max()))
            if changes[-1] <= tol:
                F = F_new
                self.last_contact_converged = True
                break
            F_next = mixing.next(F, F_new)
            dF = F_next - F
            F = F_next
            t0 = time.perf_counter()
            if approx is None:
                approx = self.solver.as_preconditioner()
            e[sysm.n_fluid:] = dF.ravel() / self.rho  # an external load enters the body rows as −F/ρ
            z += approx.matvec(e)
            tm.add("solve", time.perf_counter() - t0)
            self.last_contact_iterations += 1
            if self.contact_stall > 0 and len(changes) >= 3 and changes[-1] > self.contact_stall * changes[-3]:
                break  # stalled: further passes buy little (see the class's contact_stall)
        if self.last_contact_iterations:
            t0 = time.perf_counter()
            e[sysm.n_fluid:] = (F - guess).ravel() / self.rho
            z[:] = z0 + self._correction_solve(e)
            tm.add("solve", time.perf_counter() - t0)
        return F

    def _correction_solve(self, e):
        """``K⁻¹ e`` for the contact load's change ``e`` (body rows only), to the absolute residual
        ``rtol/2 · ‖rz‖`` of the step's own solve (``rz`` its right-hand side, ``rtol`` the lagged
        LU's): the step's residual then stays within 1.5 ``rtol ‖rz‖``.  The change is small
        (``‖e‖/‖rz‖`` = 0.006–0.03 over the first steps of 100 settling polygons), so its relative
        residual may be 1e-4–1e-5 instead of 1e-6: 2–3 GMRES iterations fewer, each a
        back-substitution with the lagged LU.  Solvers that are not a lagged LU solve as usual."""
        inner = self.solver.solver if isinstance(self.solver, AutoSolver) else self.solver
        if not isinstance(inner, LaggedLUSolver):
            return self.solver.solve(e)
        norm_e = float(np.linalg.norm(e))
        rtol = 0.5 * inner.rtol * self._step_rhs_norm / max(norm_e, 1e-300)
        return self.solver.solve(e, rtol=min(max(rtol, inner.rtol), 1e-2))
