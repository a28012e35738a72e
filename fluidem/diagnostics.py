r"""Numerical health of a run: conditioning, Krylov effort, interpolation noise, mesh oscillation.

Everything here is read from what the run computes anyway; nothing dense is ever formed.

* **Condition estimate** of every LU the solvers compute (fresh, lagged, inside the automatic
  choice, of the fluid or of the coupled fluid–body system): the 1-norm condition number

  .. math::

      \kappa_1(K) = \|K\|_1 \, \|K^{-1}\|_1 ,

  with ``‖K‖₁`` the largest column sum of ``|K|`` (exact, from the sparse matrix) and ``‖K⁻¹‖₁``
  by the block 1-norm estimator of Higham & Tisseur (2000), the block form of Hager (1984) and
  Higham (1988) (:func:`scipy.sparse.linalg.onenormest`), applied to the factors the solver
  already holds: a handful of solves with ``K`` and ``Kᵀ`` (:meth:`DirectSolver.inverse_operator`).
  The estimate is a lower bound of ``‖K⁻¹‖₁``, usually exact and rarely low by more than a factor
  3 (Higham & Tisseur 2000, Sec. 4).  Measured (``tests/test_diagnostics.py``): equal to
  ``numpy.linalg.cond(K, 1)`` to 1e-12 on 94 of 100 random sparse matrices (the others low by at most
  20 %), on Taylor–Hood Stokes systems and a Navier–Stokes channel step (2514 DOFs); low by 4.6 % on
  one P2-bubble/P1dc system (624 DOFs).  The estimator's random start columns are seeded, so a
  run's estimates are reproducible.  It is computed only when an LU is computed, and of the
  numerical refactorisations of a PARDISO LU on an unchanged pattern only every
  :data:`CONDITION_REFACTOR_STRIDE`-th (cost below).
* **Krylov effort**: the iterations and the true relative residual of every solve.
* **Interpolation noise**: the relative L2 change of u a field transfer makes at a
  re-triangulation (:func:`fluidem.coupling.moving_flow.transfer_change`, paper Sec. 3.3, Fig. 5),
  per re-triangulation and accumulated.
* **Discrete inf-sup constant** of the current mesh, on request (one extra LU):
  :func:`inf_sup_constant`, :func:`flow_inf_sup` (``flow_inf_sup(sim.flow.problem)``).
* **Oscillation of the mesh relaxation**: nodes whose relaxation move reversed the previous one
  three steps in a row (:class:`fluidem.mesh.quality.OscillationDetector`; paper Sec. 3.3); the
  relaxation halves their step.  Reported as how many, which share of the nodes, and the largest
  swing as a fraction of the node's target size ``h``; a swing ``s h`` every step is a spurious
  mesh velocity ``s h / Δt`` in the ALE convection ``(u − w)·∇u``.

:class:`RunDiagnostics` gathers these into one :class:`StepHealth` per step, a short text for the
``--verbose`` line, a ``diagnostics`` section of ``run.json`` (extremes, where they happened and a
decimated series) and warnings when a threshold below is crossed, each naming the likely mechanism
and its remedy.

Cost: one estimate took 8 solves with the factors on each Stokes test system (``t = 2`` columns, 2 iterations of the
estimator, each a solve with ``K`` and one with ``Kᵀ`` per column) on every system measured, against
a factorisation that costs 40-60 solves (``fluidem.fluid.solvers.lagged``).  In whole runs
(``benchmarks/bench_diagnostics.py``, one thread): 2.5 % of the step time for the settling-disk
example (12.8k DOFs, 2 LUs in 40 steps), 3.7 % for ten settling disks (51.7k DOFs, 3 LUs in 30
steps), 2.1 % for the first 24 steps of the suspension example (162k DOFs, 2 LUs, 1.4 s an estimate
against 5.6 s a step); a run that re-triangulates every 3-4 steps would pay about 7 %.  A PARDISO
refactorisation costs only 7-9 solves: estimating every one took 10.3 % of a settling pile of 100
polygons (sampled over 50 steps of ``bench_pile_resolution.py``, 27 LUs in its first 83 steps), hence
the stride.

Examples
--------
>>> import numpy as np, scipy.sparse as sp
>>> from fluidem.fluid.solvers import DirectSolver
>>> K = sp.csr_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]))
>>> s = DirectSolver().factorize(K)
>>> est = condition_estimate(K, s.inverse_operator())
>>> bool(abs(est / np.linalg.cond(K.toarray(), 1) - 1) < 1e-12)
True
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["condition_estimate", "lu_condition", "inf_sup_constant", "flow_inf_sup", "oscillation_text",
           "recently_retriangulated", "gap_elements", "GAP_LOCKING_ELEMENTS",
           "StepHealth", "RunDiagnostics", "CONDITION_GROWTH", "CONDITION_REFACTOR_STRIDE", "KRYLOV_RISE",
           "KRYLOV_MIN_ITERATIONS", "KRYLOV_WINDOW", "NOISE_WINDOW", "NOISE_BOUND", "NOISE_MIN_TRANSFERS",
           "SERIES_POINTS", "MECHANISMS"]

#: Warn when the condition estimate has grown by this factor since the run's first factorisation.
#: The viscous block of a mesh with smallest element size h_min has κ ∝ h_min⁻² (κ of the whole
#: saddle-point matrix grows at least as fast), so 1e3 is a smallest element about 30 times smaller
#: than at the start: a near-contact gap meshed by a few tiny elements, or a pocket of fluid closed by
#: touching bodies, whose volume cannot change while they move (paper Sec. 3 and 5).
CONDITION_GROWTH = 1e3

#: Of the numerical refactorisations on the pattern of the previous LU (a PARDISO LU refactorised on the
#: same mesh, :attr:`DirectSolver.numeric_only`), estimate every this many; every other LU (a new
#: analysis: the first on each mesh) is estimated.  A refactorisation costs 7-9 solves with the factors
#: (``fluidem.fluid.solvers.pardiso``), an estimate up to 20 (its 2 columns, with ``Kᵀ`` too): estimating
#: them all was 10 % of a settling pile of 100 polygons (27 LUs in 83 steps; module docstring, Cost).
CONDITION_REFACTOR_STRIDE = 4

#: Warn when the mean Krylov iterations per solve over the last :data:`KRYLOV_WINDOW` steps exceeds
#: this factor times their mean over the first such window.  Consecutive matrices of a run differ a
#: little, so a preconditioner (a lagged LU, an AMG hierarchy with a Schur approximation) that
#: needed n iterations at the start needs about n later (the lagged LU refactorises above 25; the
#: block preconditioner took 40-50 from 10k to 500k DOFs, ``fluidem.fluid.solvers.choose``); a
#: threefold rise says the matrices moved away from what it models.
KRYLOV_RISE = 3.0
#: ... and only when that mean is at least this many iterations (a rise from 1 to 3 is no sign).
KRYLOV_MIN_ITERATIONS = 10.0
#: Steps of the windows of :data:`KRYLOV_RISE`.
KRYLOV_WINDOW = 10

#: Warn when the interpolation noise of the last :data:`NOISE_WINDOW` re-triangulations sums above
#: this (relative L2 change of u).  Between re-triangulations the fields are not interpolated (ALE),
#: so the transfers are the only source of this error, and it accumulates when the transfers come
#: faster than viscosity damps grid-scale perturbations (paper Sec. 3.3, Fig. 5).  10 % over 20
#: transfers is 0.5 % each on average; measured: 0.044 % per transfer for the settling-disk example,
#: 1.1 % for the first transfer of the suspension example (its flow still starting from rest).
NOISE_BOUND = 0.1
#: Re-triangulations summed for :data:`NOISE_BOUND`.
NOISE_WINDOW = 20
#: ... and only once this many have been summed: the noise of one transfer is in the record, not yet an
#: accumulation.  The transfer at step 1 is left out of the sum: it carries the initial field (at rest
#: with moving outlines, not a discrete solution), whose relative change measured 18 % on the restart
#: tests' moving-mesh scene, its own roughness rather than noise.
NOISE_MIN_TRANSFERS = 5

#: The likely mechanism and its remedy, by warning.
MECHANISMS = {
    "condition": "likely a near-contact gap meshed with too few elements, or a fluid pocket closed by touching "
                 "bodies; refine mesh.h near the bodies (mesh.grading), check the contacts (the repulsion's "
                 "contact.repulsion_range) and the mesh quality in events.log",
    "krylov": "the preconditioner no longer fits the matrices, likely a growing condition number (a narrowing "
              "gap) or a stale lagged LU / AMG hierarchy; refactorise more often (fluid.solver = \"direct\") or "
              "refine the mesh near the bodies",
    "pocket": "fluid enclosed by touching bodies, with no way out; its pressure is fixed by its own reference "
              "(zero mean over the pocket), its velocity follows the bodies around it, and the run stops with a "
              "message if their prescribed motion would change the pocket's area; for the flow through the gap, "
              "keep the bodies apart by more than the mesh's contact gap (contact.repulsion_range)",
    "gap": "wrong element curvature (paper Sec. 3.1): a gap spanned by one element carries only a linear velocity "
           "profile with MINI's P1 velocity, too stiff between surfaces moving relative to each other (measured "
           "+13 % sliding and +227 % turning at gap/a = 0.005; Taylor-Hood +0.1-0.5 %, P2+bubble +0.2-2.3 %, "
           "docs/stability.md); use fluid.element = 'th' or 'p2b', or refine mesh.h near the bodies",
    "noise": "the fields are transferred too often or onto a mesh too coarse for them; re-triangulate less often "
             "(mesh.retriangulate_every), loosen the quality triggers, or refine mesh.h (the transfer error falls "
             "with the element order)",
}

#: Points of each series kept in ``run.json`` (every step up to 2x this, then every 2nd, 4th ... step).
SERIES_POINTS = 200


def condition_estimate(K, inverse, t: int = 2) -> float:
    """Estimate of the 1-norm condition number ``κ₁(K) = ‖K‖₁ ‖K⁻¹‖₁`` from a solver's factors.

    Parameters
    ----------
    K : (n, n) sparse matrix
        The matrix factorised.
    inverse : LinearOperator, shape (n, n)
        ``v ↦ K⁻¹ v`` with ``rmatvec`` ``v ↦ K⁻ᵀ v`` (:meth:`DirectSolver.inverse_operator`).
    t : int
        Columns of the block estimator (Higham & Tisseur 2000); 2 is scipy's default.

    Returns
    -------
    float
        ``‖K‖₁ · est ‖K⁻¹‖₁``, dimensionless (in the units of K's rows and columns); the estimate
        is a lower bound of the true value, usually equal to it.  For ``n ≤ 4`` the norm of the
        inverse is computed exactly (scipy does so below ``4 t`` columns).
    """
    from scipy.sparse.linalg import onenormest

    from .fluid.solvers.seeded import seeded

    norm_k = float(abs(K).sum(axis=0).max())
    # scipy draws the random ±1 start columns from numpy's global generator
    with seeded():
        return norm_k * float(onenormest(inverse, t=t))


def lu_condition(solver) -> float | None:
    """:func:`condition_estimate` of the LU a :class:`~fluidem.fluid.solvers.DirectSolver` holds, or
    None when it holds none or cannot solve with the transpose (PARDISO)."""
    if getattr(solver, "_lu", None) is None or getattr(solver, "K", None) is None:
        return None
    inv = solver.inverse_operator()
    return None if inv is None else condition_estimate(solver.K, inv)


def inf_sup_constant(A, B, Mp) -> float:
    r"""The discrete inf-sup constant β_h of a velocity–pressure pair on a mesh (on request: one extra LU).

    .. math::

        \beta_h^2 = \min_{q} \frac{q^T B A^{-1} B^T q}{q^T M_p q},

    the smallest eigenvalue of the pressure Schur complement against the pressure mass matrix
    (Brezzi & Fortin 1991; the numerical inf-sup test of Chapelle & Bathe 1993).  Found as the
    eigenvalue of the pencil ``([[A, Bᵀ], [B, 0]], [[0, 0], [0, M_p]])`` nearest to zero (it is
    ``−β_h²``), by ARPACK in shift-invert mode about 0 on one sparse LU of the saddle-point matrix:
    no dense matrix.  β_h bounded away from 0 under refinement is what a stable pair guarantees; a
    mesh with a pressure mode the velocities cannot see (a pocket closed by bodies, a locked
    element patch) has β_h ≈ 0.

    Parameters
    ----------
    A : (n_u, n_u) sparse matrix
        The velocity norm: the stiffness (vector Laplacian, or the symmetric-gradient form) on the
        free velocity DOFs, symmetric positive definite (no ν, mass or convection).
    B : (n_p, n_u) sparse matrix
        The discrete divergence on the free DOFs.
    Mp : (n_p, n_p) sparse matrix
        The pressure mass matrix on the free pressure DOFs.

    Returns
    -------
    float
        β_h, dimensionless; 0 for a singular saddle-point matrix.

    Examples
    --------
    >>> from fluidem.cases.manufactured import saddle_point_problem
    >>> P = saddle_point_problem(4, pair="th")                  # Stokes, ν = 1: K[:n_u, :n_u] is the stiffness
    >>> n = P.n_u
    >>> round(inf_sup_constant(P.K[:n, :n], P.K[n:, :n], P.Mp), 3)
    0.359
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from .fluid.solvers.seeded import seeded

    A, B, Mp = sp.csr_matrix(A), sp.csr_matrix(B), sp.csr_matrix(Mp)
    n_u, n_p = A.shape[0], Mp.shape[0]
    K = sp.bmat([[A, B.T], [B, None]], format="csc")
    try:
        lu = spla.splu(K)
    except RuntimeError:  # exactly singular: a pressure mode with no velocity to see it
        return 0.0

    def apply(v):  # (K − 0 N)⁻¹ N v
        w = np.zeros(n_u + n_p)
        w[n_u:] = Mp @ v[n_u:]
        return lu.solve(w)

    op = spla.LinearOperator((n_u + n_p, n_u + n_p), matvec=apply, dtype=float)
    with seeded():  # ARPACK's start vector: the same in every run
        mu = spla.eigs(op, k=1, which="LM", v0=np.r_[np.zeros(n_u), np.random.rand(n_p)],
                       return_eigenvectors=False)[0]
    lam = 1.0 / mu.real  # the eigenvalue of the pencil nearest to 0: −β_h²
    return float(np.sqrt(max(-lam, 0.0)))


def flow_inf_sup(problem) -> float:
    """:func:`inf_sup_constant` of a flow problem's current mesh (``problem.A / problem.nu`` on the free
    velocity DOFs, ``problem.B``, the pressure mass matrix); one extra sparse LU, so on request only."""
    from skfem import asm

    from .fluid import forms

    n_u = problem.space.n_u
    free = np.asarray(problem.free)
    fu, fp = free[free < n_u], free[free >= n_u] - n_u
    A = (problem.A / problem.nu).tocsr()[fu][:, fu]
    B = problem.B.tocsr()[fp][:, fu]
    Mp = asm(forms.pressure_mass, problem.space.pb).tocsr()[fp][:, fp]
    return inf_sup_constant(A, B, Mp)


def recently_retriangulated(retriangulated, steps: int) -> np.ndarray:
    """Per step, whether the mesh was re-triangulated in it or in the ``steps − 1`` before
    (``retriangulated (n,)`` bool): the steps that still carry a transfer's noise, to be left out when
    the smoothness of a series of velocities or loads is judged.

    >>> recently_retriangulated([False, True, False, False, False], 3).tolist()
    [False, True, True, True, False]
    """
    flags = np.asarray(retriangulated, dtype=float)
    return np.convolve(flags, np.ones(steps))[:len(flags)] > 0


def oscillation_text(n: int, n_nodes: int, swing: float | None) -> str:
    """What the oscillation count means, in one line (for ``events.log``).

    >>> print(oscillation_text(3, 1200, 0.004))  # doctest: +NORMALIZE_WHITESPACE
    3 of 1200 mesh nodes (0.25 %) flip back and forth between two positions in the relaxation
    (3 steps in a row; largest swing 0.4 % of the local mesh size h a step); their relaxation step is halved
    """
    share = 100.0 * n / max(n_nodes, 1)
    s = (f"{n} of {n_nodes} mesh nodes ({share:.2g} %) flip back and forth between two positions in the relaxation "
         "(3 steps in a row")
    if swing is not None:
        s += f"; largest swing {100 * swing:.2g} % of the local mesh size h a step"
    return s + "); their relaxation step is halved"


@dataclass
class StepHealth:
    """The numerical health of one step.

    Attributes
    ----------
    step : int
    t : float
        Time.
    factorizations : int
        LU factorisations in the step.
    condition : float or None
        Largest condition estimate ``κ₁`` of the LUs of the step (None: no LU this step).
    growth : float or None
        ``condition`` over the run's first estimate.
    solves : int
        Linear solves in the step (direct and Krylov).
    iterations : int
        Most Krylov iterations of one solve in the step (0: direct solves only).
    krylov_iterations : int
        Krylov iterations summed over the step's solves.
    residual : float or None
        Largest true relative residual ``‖b − K x‖₂ / ‖b‖₂`` of the step's solves.
    noise : float or None
        Interpolation noise of this step's re-triangulation (None: none).
    oscillating : int
        Nodes oscillating in the relaxation this step.
    oscillating_share : float
        ``oscillating`` over the mesh nodes.
    swing : float or None
        Largest relaxation move of an oscillating node over its target size h.
    pockets : int
        Fluid pockets enclosed by touching bodies in the step's mesh, each with its own pressure
        reference (:mod:`fluidem.fluid.pockets`).
    gap_elements : int
        Triangles of the step's moving mesh that span a gap with one element: their three vertices on
        the outlines of at least two bodies, or of a body and a wall (:func:`gap_elements`).
    repaired : int
        Mesh nodes moved this step to bring elements past the angle bounds or the area floor back
        within them instead of re-triangulating (:mod:`fluidem.mesh.repair`).
    repair_declined : str
        Why the repair did not avert this step's quality or degenerate re-triangulation (``""``:
        not tried).
    """

    step: int
    t: float
    factorizations: int = 0
    condition: float | None = None
    growth: float | None = None
    solves: int = 0
    iterations: int = 0
    krylov_iterations: int = 0
    residual: float | None = None
    noise: float | None = None
    oscillating: int = 0
    oscillating_share: float = 0.0
    swing: float | None = None
    pockets: int = 0
    gap_elements: int = 0
    repaired: int = 0
    repair_declined: str = ""

    def text(self) -> str:
        """The compact health part of a ``--verbose`` line: ``cond1 <κ> (x<growth>)`` at an LU,
        ``noise <n> %`` at a re-triangulation, ``osc <k> nodes`` when nodes oscillate, ``pockets <k>``
        when the mesh holds enclosed fluid pockets; ``""`` if none."""
        parts = []
        if self.condition is not None:
            parts.append(f"cond1 {self.condition:.2e}" + (f" (x{self.growth:.3g})" if self.growth is not None else ""))
        if self.noise is not None:
            parts.append(f"noise {100 * self.noise:.2g} %")
        if self.oscillating:
            parts.append(f"osc {self.oscillating} nodes")
        if self.pockets:
            parts.append(f"pockets {self.pockets}")
        return "  ".join(parts)


class RunDiagnostics:
    """Gathers one :class:`StepHealth` per step and the run's extremes (module docstring).

    Usage: wrap the flow step in :meth:`watching` (the solvers report each LU and each solve to
    it), then call :meth:`finish_step` with the step's mesh event; :meth:`record` is the
    ``diagnostics`` section of ``run.json``.

    Parameters
    ----------
    enabled : bool
        False: nothing is estimated or recorded.

    Attributes
    ----------
    last : StepHealth or None
        The last finished step.
    first_condition : float or None
        The run's first condition estimate (the reference of ``growth``).
    seconds : float
        Wall seconds spent on the estimates.
    warnings : list of str
        Warnings issued so far (each mechanism once a run).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from fluidem.fluid.solvers import DirectSolver
    >>> d = RunDiagnostics()
    >>> K = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(20, 20)).tocsr()
    >>> with d.watching():
    ...     x = DirectSolver().factorize(K).solve(np.ones(20))
    >>> h = d.finish_step(1, 0.1)
    >>> round(h.condition), h.solves, h.iterations     # κ₁ = ‖K‖₁ max_j j(n+1−j)/2 = 4 · 55
    (220, 1, 0)
    """

    def __init__(self, enabled: bool = True):
        self.enabled = bool(enabled)
        self.last: StepHealth | None = None
        self.first_condition: float | None = None
        self.seconds = 0.0
        self.warnings: list[str] = []
        self._warned: set = set()
        self._conditions: list[float] = []
        self._refactors_since_estimate = 0
        self._infos: list = []
        self._steps = 0
        self._stride = 1
        self._series: dict[str, list] = {k: [] for k in ("step", "condition", "iterations", "residual", "noise",
                                                         "oscillating")}
        self._ext: dict[str, tuple] = {}
        self._noise: list[float] = []
        self._noise_total = 0.0
        self._iter_per_step: list[float] = []
        self._counts = {"factorizations": 0, "estimates": 0, "solves": 0, "krylov_solves": 0,
                        "krylov_iterations": 0, "retriangulations": 0, "oscillation_steps": 0,
                        "pocket_steps": 0, "repair_steps": 0, "repaired_nodes": 0}
        self._pocket_text = ""
        self._declined: dict[str, int] = {}  # quality re-triangulations the repair did not avert, by why
        self._element = None  # the element pair of the last step's problem (the gap warning's condition)

    # -- the solvers' reports ------------------------------------------------------------------
    def factorized(self, solver) -> None:
        """An LU was just computed by ``solver`` (a DirectSolver): estimate its condition (of a numerical
        refactorisation on the previous pattern, every :data:`CONDITION_REFACTOR_STRIDE`-th only)."""
        self._counts["factorizations"] += 1
        if getattr(solver, "numeric_only", False):
            self._refactors_since_estimate += 1
            if self._refactors_since_estimate < CONDITION_REFACTOR_STRIDE:
                return
        self._refactors_since_estimate = 0
        t0 = time.perf_counter()
        try:
            c = lu_condition(solver)
        except Exception:  # an estimate must never stop a run (a singular LU raises in its solve)
            c = None
        if c is not None and np.isfinite(c):
            self._conditions.append(c)
        self.seconds += time.perf_counter() - t0

    def solved(self, info) -> None:
        """A solve finished (its :class:`~fluidem.fluid.solvers.SolveInfo`)."""
        self._infos.append(info)

    def watching(self):
        """Context manager: the solvers of this thread report to this object inside it."""
        from contextlib import contextmanager

        from .fluid.solvers.results import add_observer, remove_observer

        @contextmanager
        def cm():
            if not self.enabled:
                yield self
                return
            add_observer(self)
            try:
                yield self
            finally:
                remove_observer(self)

        return cm()

    # -- per step ----------------------------------------------------------------------------
    def finish_step(self, step: int, t: float, event=None, mesh=None, problem=None) -> StepHealth:
        """Close the step: its :class:`StepHealth` from what the solvers reported and the mesh event.

        Parameters
        ----------
        step : int
        t : float
            Time.
        event : MeshEvent, optional
            The moving mesh's event of the step (``retriangulated``, ``transfer_change``,
            ``oscillating``).
        mesh : MovingMesh, optional
            For the node count and the swing of the oscillating nodes.
        problem : FlowProblem, optional
            For the enclosed fluid pockets of its mesh (``problem.components``; reported when the
            problem gives each its own pressure reference, ``pin_pockets``).
        """
        h = StepHealth(step=int(step), t=float(t))
        infos, self._infos = self._infos, []
        conds, self._conditions = self._conditions, []
        h.factorizations, self._counts["factorizations"] = self._counts["factorizations"], 0
        if conds:
            h.condition = max(conds)
            if self.first_condition is None:
                self.first_condition = conds[0]
            h.growth = h.condition / self.first_condition
        h.solves = len(infos)
        its = [int(i.iterations) for i in infos]
        h.iterations = max(its, default=0)
        h.krylov_iterations = sum(its)
        res = [float(i.relative_residual) for i in infos if np.isfinite(i.relative_residual)]
        h.residual = max(res) if res else None
        if event is not None:
            if getattr(event, "retriangulated", False) and getattr(event, "transfer_change", None) is not None:
                h.noise = float(event.transfer_change)
            h.repaired = int(getattr(event, "n_repaired", 0) or 0)
            h.repair_declined = str(getattr(event, "repair_declined", "") or "")
            osc = np.asarray(getattr(event, "oscillating", ()), dtype=np.int64)
            h.oscillating = int(osc.size)
            if osc.size and mesh is not None:
                n_nodes = len(getattr(mesh, "points", ())) or 1
                h.oscillating_share = osc.size / n_nodes
                h.swing = _swing(mesh, osc)
        if mesh is not None and hasattr(mesh, "body_of"):
            h.gap_elements = gap_elements(mesh)
            pair = getattr(getattr(getattr(problem, "space", None), "pair", None), "name", None)
            if pair is not None:
                self._element = pair
        comp = getattr(problem, "components", None)
        if comp is not None and getattr(problem, "pin_pockets", False):  # free bodies: the coupling holds them
            h.pockets = int(len(comp.pockets))
            self._pocket_text = comp.text()
        if self.enabled:
            self._add(h, n_krylov=sum(1 for i in its if i > 0))
        self.last = h
        return h

    def _add(self, h: StepHealth, n_krylov: int) -> None:
        c = self._counts
        c["estimates"] += h.condition is not None
        c["solves"] += h.solves
        c["krylov_solves"] += n_krylov
        c["krylov_iterations"] += h.krylov_iterations
        c["retriangulations"] += h.noise is not None
        self._noise_total += h.noise or 0.0
        c["oscillation_steps"] += h.oscillating > 0
        c["pocket_steps"] += h.pockets > 0
        c["repair_steps"] += h.repaired > 0
        c["repaired_nodes"] += h.repaired
        if h.repair_declined:
            self._declined[h.repair_declined] = self._declined.get(h.repair_declined, 0) + 1
        for key, value in (("condition", h.condition), ("iterations", h.iterations if h.solves else None),
                           ("residual", h.residual), ("noise", h.noise),
                           ("oscillating", h.oscillating or None), ("swing", h.swing),
                           ("pockets", h.pockets or None), ("gap_elements", h.gap_elements or None)):
            if value is None:
                continue
            old = self._ext.get(key)
            self._ext[key] = (value, h.step) if old is None or value > old[0] else old
            self._ext["last_" + key] = (value, h.step)
        if h.noise is not None and h.step > 1:
            self._noise = [*self._noise[-(NOISE_WINDOW - 1):], h.noise]  # the window only: long runs stay small
        if n_krylov:
            its = self._iter_per_step  # the first window and the last one
            its.append(h.krylov_iterations / n_krylov)
            if len(its) > 2 * KRYLOV_WINDOW:
                del its[KRYLOV_WINDOW]
        self._steps += 1
        if (self._steps - 1) % self._stride == 0:
            s = self._series
            for key in s:
                s[key].append(getattr(h, key))
            if len(s["step"]) >= 2 * SERIES_POINTS:
                for key in s:
                    s[key] = s[key][::2]
                self._stride *= 2

    # -- warnings --------------------------------------------------------------------------------
    def check(self) -> list[str]:
        """Warnings newly due after the last finished step, each naming the likely mechanism and its
        remedy (each mechanism once a run; also kept in :attr:`warnings`)."""
        h, new = self.last, []
        if h is None or not self.enabled:
            return new
        if h.growth is not None and h.growth > CONDITION_GROWTH and "condition" not in self._warned:
            new.append(("condition",
                        f"step {h.step}: the condition estimate of the linear system grew {h.growth:.3g}-fold "
                        f"since the first factorisation (to {h.condition:.3g}; warned above "
                        f"{CONDITION_GROWTH:g}x): " + MECHANISMS["condition"]))
        w = KRYLOV_WINDOW
        its = self._iter_per_step
        if len(its) >= 2 * w and "krylov" not in self._warned:
            first, recent = float(np.mean(its[:w])), float(np.mean(its[-w:]))
            if recent > KRYLOV_RISE * max(first, 1.0) and recent >= KRYLOV_MIN_ITERATIONS:
                new.append(("krylov",
                            f"step {h.step}: Krylov iterations per solve rose from {first:.3g} (first {w} "
                            f"steps) to {recent:.3g} (last {w}; warned above {KRYLOV_RISE:g}x and "
                            f"{KRYLOV_MIN_ITERATIONS:g}): " + MECHANISMS["krylov"]))
        noise = self._noise[-NOISE_WINDOW:]
        if h.noise is not None and len(noise) >= NOISE_MIN_TRANSFERS and sum(noise) > NOISE_BOUND and \
                "noise" not in self._warned:
            new.append(("noise",
                        f"step {h.step}: the interpolation noise of the last {len(noise)} re-triangulations "
                        f"sums to {100 * sum(noise):.3g} % of the velocity (warned above "
                        f"{100 * NOISE_BOUND:g} % over {NOISE_WINDOW}): " + MECHANISMS["noise"]))
        element = getattr(self, "_element", None)  # a run checkpointed before the count holds none
        if h.gap_elements and element in GAP_LOCKING_ELEMENTS and "gap" not in self._warned:
            new.append(("gap", f"step {h.step}: {h.gap_elements} triangles span a gap between bodies (or a body and "
                               f"a wall) with one element across, with element {element!r}: "
                               + MECHANISMS["gap"]))
        if h.pockets and "pocket" not in self._warned:
            new.append(("pocket", f"step {h.step}: {self._pocket_text}: " + MECHANISMS["pocket"]))
        for key, msg in new:
            self._warned.add(key)
            self.warnings.append(msg)
        return [msg for _, msg in new]

    # -- the record ------------------------------------------------------------------------------
    def record(self) -> dict:
        """The ``diagnostics`` section of ``run.json``: counts, extremes (``max`` and the step
        where, ``last`` and its step) per quantity, the decimated series and the warnings.  Plain
        JSON data; non-finite values as None."""
        e = self._ext

        def ext(key):
            if key not in e:
                return None
            return {"max": _num(e[key][0]), "max_step": e[key][1],
                    "last": _num(e["last_" + key][0]), "last_step": e["last_" + key][1]}

        c = self._counts
        cond = ext("condition")
        if cond is not None:
            cond.update(first=_num(self.first_condition), growth=_num(e["condition"][0] / self.first_condition),
                        estimates=c["estimates"])
        noise = ext("noise")
        if noise is not None:
            noise.update(retriangulations=c["retriangulations"], total=_num(self._noise_total))
        osc = ext("oscillating")
        if osc is not None:
            osc.update(steps=c["oscillation_steps"], swing_max=_num(e["swing"][0]) if "swing" in e else None)
        s = self._series
        return {
            "note": "condition: 1-norm condition estimate of each LU (Higham-Tisseur estimator on the solver's "
                    "factors); iterations: most Krylov iterations of a solve in a step; residual: largest true "
                    "relative residual of a step's solves; noise: relative L2 change of u by the field transfer at a "
                    "re-triangulation; oscillating: mesh nodes flipping between two positions in the relaxation, "
                    "swing_max their largest move over the local h; gap_elements: triangles spanning a gap "
                    "between two bodies (or a body and a wall) with one element; mesh_repairs: steps in which "
                    "mesh nodes were moved to bring elements past the angle bounds or the area floor back within "
                    "them instead of re-triangulating, the nodes moved, and the quality and degenerate "
                    "re-triangulations it did not avert by why (declined); series: "
                    + ("every step" if self._stride == 1 else f"one step in {self._stride}") + " of this run",
            "seconds": self.seconds, "steps": self._steps,
            "condition": cond,
            "krylov": {"solves": c["solves"], "krylov_solves": c["krylov_solves"],
                       "iterations_total": c["krylov_iterations"], "iterations": ext("iterations"),
                       "residual": ext("residual")},
            "interpolation_noise": noise,
            "oscillation": osc,
            "mesh_repairs": {"steps": c["repair_steps"], "nodes": c["repaired_nodes"],
                             "declined": dict(self._declined)},
            "pockets": None if "pockets" not in e else {"max": int(e["pockets"][0]), "max_step": e["pockets"][1],
                                                        "steps": c["pocket_steps"]},
            "gap_elements": ext("gap_elements"),
            "series": {k: [_num(v) for v in vals] for k, vals in s.items()},
            "warnings": list(self.warnings),
        }


#: Element pairs whose velocity is linear across a one-element gap and so locks between surfaces moving
#: relative to each other (paper Sec. 3.1): measured in ``benchmarks/results/stability_curvature.md``
#: (MINI +13.5 % sliding, +227 % turning at gap/a = 0.005 with one layer); the quadratic pairs were off by
#: at most 2.3 % there, so a one-layer gap with them is counted (``gap_elements``) but not warned about.
GAP_LOCKING_ELEMENTS = ("mini",)


def gap_elements(mesh) -> int:
    """Triangles of a moving ``mesh`` (``triangles``, ``kind``, ``body_of``) whose three vertices lie on
    boundaries of at least two owners, one of them a body: a gap between two bodies, or a body and a
    wall, spanned by one element (:func:`fluidem.mesh.gaps.boundary_owner`; vectorised, one pass).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from fluidem.mesh.kinds import FREE, OUTLINE
    >>> m = SimpleNamespace(triangles=np.array([[0, 1, 2], [1, 2, 3]]),
    ...                     kind=np.array([OUTLINE, OUTLINE, OUTLINE, FREE]), body_of=np.array([0, 0, 1, -1]))
    >>> gap_elements(m)
    1
    """
    from .mesh.gaps import NOT_ON_BOUNDARY, boundary_owner

    tri = np.asarray(mesh.triangles)
    if not len(tri):
        return 0
    own = boundary_owner(np.asarray(mesh.kind), np.asarray(mesh.body_of))[tri]
    spans = (own != NOT_ON_BOUNDARY).all(axis=1) & (own.min(axis=1) != own.max(axis=1)) & (own >= 0).any(axis=1)
    return int(spans.sum())


def _swing(mesh, osc: np.ndarray) -> float | None:
    """Largest last relaxation move of the nodes ``osc`` over their target size h (from the moving
    mesh's oscillation detector), or None when the mesh does not keep it."""
    det = getattr(mesh, "_osc", None)
    d = getattr(det, "_prev", None)
    hn = getattr(mesh, "h_node", None)
    if d is None or hn is None or len(d) != len(hn) or osc.max() >= len(d):
        return None
    return float((np.hypot(d[osc, 0], d[osc, 1]) / hn[osc]).max())


def _num(v):
    """A JSON number: float/int as is, non-finite or None as None."""
    if v is None:
        return None
    if isinstance(v, (int, np.integer)):
        return int(v)
    v = float(v)
    return v if np.isfinite(v) else None


def health_dict(h: StepHealth) -> dict:
    """``StepHealth`` as a plain dict (JSON values)."""
    return {k: _num(v) for k, v in asdict(h).items()}
