"""The automatic choice of a solver: what ``"auto"`` means, everywhere.

The rule (:func:`choose_solver`), by problem kind and system size ``n = n_u + n_p``, with
the limits measured by ``benchmarks/bench_solvers.py`` (P2-bubble/P1-discontinuous systems
of 10k, 50k and 200k DOFs, one thread; the table is in that file's docstring):

* ``"steady"`` (Oseen, Newton): ``"direct"`` below ``DIRECT_MAX_DOFS_CONVECTIVE``
  (SuperLU 300k, PARDISO 2M DOFs), ``"lagged"`` above (one LU kept over the Newton
  iterations while GMRES converges fast with it);
* ``"stokes"``: ``"direct"`` below ``DIRECT_MAX_DOFS`` (SuperLU 20k, PARDISO 2M),
  ``"iterative"`` above;
* ``"unsteady"`` (a run of time steps): ``"lagged"`` below ``LAGGED_MAX_DOFS``
  (SuperLU 300k; PARDISO: no size limit), ``"iterative"`` above;
* ``"stokes"`` and ``"unsteady"``: ``"iterative"`` also where the LU would not fit in the memory
  available (:func:`fluidem.fluid.solvers.memory.lu_fits`).

Why:

* Steady Newton/Oseen systems stay on an LU: the block preconditioners need iteration counts
  that grow with refinement and Reynolds number (Newton: 385 iterations at 10k DOFs, 898 at
  50k, no convergence in 1000 at 200k).  Above the limit the LU of the first Newton matrix
  preconditions GMRES for the next ones (refactorised when it needs many iterations): DFG
  2D-1 with P2-bubble/P1dc at 361k DOFs in 101 s (5 Newton iterations, 4.8 GB peak), where
  block GMRES had not converged after 44 minutes.
* Stokes: block-preconditioned GMRES (pressure-mass Schur approximation) was 2x faster than
  SuperLU at 10k DOFs and 5-10x at 50k-200k; with PARDISO the LU was faster at every size
  measured, up to memory (1.5 GB at 500k DOFs, ~7 GB extrapolated at 2M).
* Time stepping: a sequence of nearby matrices.  The LU of an earlier step as a GMRES
  preconditioner (:class:`~fluidem.fluid.solvers.lagged.LaggedLUSolver`) took 0.05 / 0.21 /
  1.39 s per step at 10k / 50k / 200k DOFs against 0.36 / 1.46 / 6.93 s for block GMRES with
  the Cahouet--Chabard Schur approximation; a refactorisation (SuperLU 42.9 s at 200k) pays
  for itself within 8 steps, so the lagged LU is used up to the memory limit of the LU.
  With PARDISO that limit is memory alone: on the coupled systems of 2 000 settling polygons
  (3.15M DOFs) the lagged PARDISO LU took 27.5 s a step against 379 s for block GMRES, and less
  memory in an ordinary step (19.5 against 21.7 GB peak; ``benchmarks/results/solver_scale.md``),
  but a re-triangulation peaked at 23.2 GB: the memory rule's headroom is for that.

:func:`choose_method` is the crossover for *one* system (direct or iterative), also used by
:class:`AutoSolver` for the steady kinds; its unsteady limit ``DIRECT_MAX_DOFS_UNSTEADY``
compares a fresh LU with block GMRES for a single unsteady system.  All limits are
module-level dicts keyed by the direct backend and can be changed at run time.

Examples
--------
>>> choose_solver(50_000, "steady", "superlu")[0], choose_solver(50_000, "stokes", "superlu")[0]
('direct', 'iterative')
>>> choose_solver(50_000, "unsteady")[0], choose_solver(10**7, "unsteady")[0]
('lagged', 'iterative')
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ... import validate
from ._sparse import _as_csr, _is_symmetric
from .block import BlockKrylovSolver
from .direct import DirectSolver, default_direct_backend
from .lagged import LaggedLUSolver
from .memory import lu_fits
from .results import SolveInfo, SolverError

__all__ = ["choose_solver", "choose_method", "AutoSolver", "PROBLEM_KINDS", "DIRECT_MAX_DOFS",
           "DIRECT_MAX_DOFS_UNSTEADY", "DIRECT_MAX_DOFS_CONVECTIVE", "LAGGED_MAX_DOFS"]

# --------------------------------------------------------------------------
# Crossover of the automatic choice.  Measured with benchmarks/bench_solvers.py
# (P2-bubble/P1-discontinuous pair on a unit square, one thread, wall clock on a
# shared machine; the table is in that file's docstring).
# --------------------------------------------------------------------------
#: Steady Stokes: LU below this many DOFs, block-preconditioned GMRES above; by
#: direct backend.  SuperLU: GMRES was 2x faster at 10k DOFs and 5-10x at 50k-200k.
#: PARDISO: LU was faster at every size measured (2.8x at 500k DOFs, 1.5 GB peak),
#: because the AMG iteration counts grow with refinement; the limit is memory
#: (extrapolated ~7 GB at 2M DOFs).
DIRECT_MAX_DOFS = {"superlu": 20_000, "pardiso": 2_000_000}
#: One unsteady system with the Cahouet--Chabard preconditioner, whose iteration count
#: stayed at 40-50 from 10k to 500k DOFs.  SuperLU: equal at 10k, GMRES 2x faster at
#: 50k.  PARDISO: LU faster up to 200k, GMRES faster at 500k.
DIRECT_MAX_DOFS_UNSTEADY = {"superlu": 20_000, "pardiso": 400_000}
#: Steady convective systems (Oseen, Newton): the Schur approximations need iteration
#: counts that grow with refinement and Reynolds number (Newton at 200k DOFs: no
#: convergence in 1000 iterations), so LU up to its memory limit (SuperLU needed
#: 5x the memory of PARDISO at 50k DOFs).
DIRECT_MAX_DOFS_CONVECTIVE = {"superlu": 300_000, "pardiso": 2_000_000}
#: Time stepping: the lagged LU (5-7x cheaper per step than block GMRES at 10k-200k DOFs)
#: up to the memory limit of the LU: for SuperLU the size of :data:`DIRECT_MAX_DOFS_CONVECTIVE`;
#: for PARDISO no size limit (``None``), only :func:`~fluidem.fluid.solvers.memory.lu_fits` — the
#: lagged PARDISO LU was 14x faster per step than block GMRES at 3.15M DOFs (27.5 against 379 s, one
#: thread) and peaked lower in an ordinary step (19.5 against 21.7 GB).
LAGGED_MAX_DOFS = {"superlu": 300_000, "pardiso": None}

#: Problem kinds of the automatic choice: steady Oseen/Newton systems, Stokes systems
#: (symmetric velocity block, no time derivative), time stepping.
PROBLEM_KINDS = ("steady", "stokes", "unsteady")


def choose_method(n_dofs: int, convective: bool = False, dt: float | None = None,
                  backend: str | None = None) -> tuple[str, str]:
    """Choose ``"direct"`` or ``"iterative"`` for one system from the measured crossover.

    Parameters
    ----------
    n_dofs : int
        System size ``n_u + n_p``.
    convective : bool
        Whether the velocity block is non-symmetric (Oseen, Newton).
    dt : float, optional
        Time step, s; ``None`` for steady problems.
    backend : {"superlu", "pardiso"}, optional
        Direct backend the choice is for; default :func:`default_direct_backend`.

    Returns
    -------
    method : str
        ``"direct"`` or ``"iterative"``.
    reason : str
        One line saying why.

    Notes
    -----
    Steady Stokes systems switch to the iterative path at
    ``DIRECT_MAX_DOFS[backend]``, unsteady ones (Cahouet--Chabard
    preconditioner) at ``DIRECT_MAX_DOFS_UNSTEADY[backend]``, steady
    convective ones at ``DIRECT_MAX_DOFS_CONVECTIVE[backend]``.  All are
    module-level dicts and can be changed at run time.  Timings behind them:
    ``benchmarks/bench_solvers.py``.  For a sequence of time steps the rule of
    ``"auto"`` is :func:`choose_solver` (the lagged LU).

    Examples
    --------
    >>> choose_method(5_000)[0]
    'direct'
    >>> choose_method(10**8)[0]
    'iterative'
    """
    backend = backend or default_direct_backend(n_dofs)
    if dt is not None:
        limit, kind = DIRECT_MAX_DOFS_UNSTEADY[backend], "unsteady"
    elif convective:
        limit, kind = DIRECT_MAX_DOFS_CONVECTIVE[backend], "steady convective"
    else:
        limit, kind = DIRECT_MAX_DOFS[backend], "Stokes"
    where = f"(measured {backend} LU / AMG-GMRES crossover)"
    if n_dofs < limit:
        return "direct", f"{kind}: {n_dofs} DOFs < {limit} {where}"
    return "iterative", f"{kind}: {n_dofs} DOFs >= {limit} {where}"


def choose_solver(n_dofs: int, kind: str = "steady", backend: str | None = None,
                  freed_bytes: float = 0.0, available_bytes: float | None = None) -> tuple[str, str]:
    """The solver name ``"auto"`` stands for, by problem kind and size (the module's table).

    Parameters
    ----------
    n_dofs : int
        System size ``n_u + n_p`` (free DOFs).
    kind : {"steady", "stokes", "unsteady"}
        ``"steady"``: Oseen or Newton systems (non-symmetric velocity block, no time
        derivative); ``"stokes"``: Stokes systems; ``"unsteady"``: the systems of a run of
        time steps.
    backend : {"superlu", "pardiso"}, optional
        Direct backend; default :func:`default_direct_backend`.
    freed_bytes : float
        Memory released before the factorisation (the PARDISO LU the caller holds), bytes: counted
        as available by :func:`~fluidem.fluid.solvers.memory.lu_fits`.
    available_bytes : float, optional
        The memory available, bytes (default: what the machine says now).

    Returns
    -------
    name : str
        ``"direct"``, ``"iterative"`` or ``"lagged"`` (names of kind ``"solver"`` in
        :mod:`fluidem.names`).
    reason : str
        One line saying why.

    Examples
    --------
    >>> choose_solver(12_000, "unsteady")
    ('lagged', 'unsteady: 12000 DOFs < 300000 (lagged superlu LU up to its memory limit)')
    >>> choose_solver(400_000, "steady", backend="superlu")[0]
    'lagged'
    >>> choose_solver(12_000, "newton")
    Traceback (most recent call last):
    ...
    fluidem.errors.InputError: kind = 'newton': expected one of 'steady', 'stokes', 'unsteady'
    """
    kind = validate.choice("kind", kind, PROBLEM_KINDS)
    backend = backend or default_direct_backend(n_dofs)
    if kind == "steady" and n_dofs >= DIRECT_MAX_DOFS_CONVECTIVE[backend]:
        limit = DIRECT_MAX_DOFS_CONVECTIVE[backend]
        return "lagged", (f"steady convective: {n_dofs} DOFs >= {limit}: one {backend} LU kept over the "
                          "Newton iterations (block GMRES does not converge for Newton systems this large)")
    if kind == "unsteady":
        limit = LAGGED_MAX_DOFS[backend]
        where = f"(lagged {backend} LU up to its memory limit)"
        if limit is not None and n_dofs >= limit:
            return "iterative", f"unsteady: {n_dofs} DOFs >= {limit} {where}"
        name, reason = "lagged", f"unsteady: {n_dofs} DOFs < {limit} {where}"
    else:
        name, reason = choose_method(n_dofs, convective=kind == "steady", backend=backend)
    if name != "iterative" and kind != "steady":
        # block GMRES, whose memory grows linearly, where the LU would not fit (Stokes, time steps)
        fits, why = lu_fits(n_dofs, backend, available_bytes=available_bytes, freed_bytes=freed_bytes)
        if not fits:
            return "iterative", f"{kind}: {why}"
        if kind == "unsteady" and LAGGED_MAX_DOFS[backend] is None:
            reason = f"unsteady: the lagged {backend} LU fits ({why})"
    return name, reason


class AutoSolver:
    """The solver chosen at ``factorize`` by :func:`choose_solver` (the meaning of ``"auto"``).

    Parameters
    ----------
    n_u : int, optional
        Velocity DOFs; needed if the iterative path may be chosen, and to tell Stokes
        from convective systems.
    direct_options, iterative_options : dict, optional
        Keyword arguments for :class:`DirectSolver` and
        :class:`BlockKrylovSolver` (``pressure_mass``, ``nu``, ``dt`` ...).
    fallback : bool
        If the iterative path raises :class:`SolverError`, factorise ``K``
        and solve directly (noted in ``last_info.note``) instead of raising.
    kind : {"steady", "stokes", "unsteady"}, optional
        Problem kind for :func:`choose_solver`.  Default: ``"unsteady"`` if
        ``iterative_options`` holds a time step ``dt``, else ``"stokes"`` when the
        velocity block ``K[:n_u, :n_u]`` is symmetric and ``"steady"`` otherwise (or
        when ``n_u`` is not given), decided at every ``factorize``.
    lagged_options : dict, optional
        Keyword arguments for :class:`LaggedLUSolver` (its LU is a :class:`DirectSolver`
        with ``direct_options``).

    Attributes
    ----------
    chosen : str
        ``"direct"``, ``"iterative"`` or ``"lagged"`` after ``factorize``.
    reason : str
        Why.
    solver : DirectSolver, BlockKrylovSolver or LaggedLUSolver
        The solver in use.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> K = sp.diags([-1.0, 4.0, -1.0], [-1, 0, 1], shape=(30, 30)).tocsr()
    >>> s = AutoSolver(iterative_options={"dt": 0.01}).factorize(K)
    >>> s.chosen
    'lagged'
    >>> x = s.solve(np.ones(30))
    >>> AutoSolver().factorize(K).chosen
    'direct'
    """

    def __init__(self, n_u: int | None = None, direct_options: dict | None = None,
                 iterative_options: dict | None = None, fallback: bool = True,
                 kind: str | None = None, lagged_options: dict | None = None):
        self.n_u = n_u
        self.fallback = fallback
        self.kind = None if kind is None else validate.choice("kind", kind, PROBLEM_KINDS)
        self.K: sp.csr_matrix | None = None
        self.direct_options = dict(direct_options or {})
        self.iterative_options = dict(iterative_options or {})
        self.lagged_options = dict(lagged_options or {})
        self.chosen: str | None = None
        self.reason = ""
        self.solver = None

    def _kind(self, K: sp.csr_matrix) -> str:
        if self.kind is not None:
            return self.kind
        if self.iterative_options.get("dt") is not None:
            return "unsteady"
        if self.n_u is not None and _is_symmetric(K[: self.n_u, : self.n_u]):
            return "stokes"
        return "steady"

    def _build(self, method: str):
        if method == "direct":
            return DirectSolver(**self.direct_options)
        if method == "lagged":
            return LaggedLUSolver(direct=DirectSolver(**self.direct_options), **self.lagged_options)
        return BlockKrylovSolver(self.n_u, **self.iterative_options)

    def _held_lu_bytes(self) -> float:
        """:attr:`DirectSolver.held_lu_bytes` of the LU in use (0 for block GMRES): released before a new
        one is computed, so the memory rule counts them as available, or a run whose LU fitted would
        leave it at the next step."""
        return float(getattr(getattr(self.solver, "direct", self.solver), "held_lu_bytes", 0.0))

    def factorize(self, K, force: bool = False) -> "AutoSolver":
        """Choose a method for ``K`` (shape (n, n)) and set it up; returns self.

        ``force``: a lagged LU factorises ``K`` now (e.g. after a renumbering of the DOFs,
        which keeps the shape but makes the old LU a poor preconditioner).
        """
        K = _as_csr(K)
        opts = self.iterative_options
        kind = self._kind(K)
        backend = self.direct_options.get("backend", "auto")
        backend = default_direct_backend(K.shape[0]) if backend == "auto" else backend
        method, reason = choose_solver(K.shape[0], kind, backend=backend, freed_bytes=self._held_lu_bytes())
        if method == "iterative" and (self.n_u is None or (
                opts.get("pressure_mass") is None and opts.get("schur") != "lsc")):
            instead = "lagged" if kind == "unsteady" else "direct"
            method, reason = instead, reason + f"; but no n_u/pressure_mass given, so {instead}"
        if method != self.chosen or self.solver is None:
            self.solver = self._build(method)
            self.chosen = method
        self.reason = reason
        self.K = K
        if method == "direct":
            self.solver.refactorize_if_changed(K)
        elif method == "lagged":
            self.solver.factorize(K, force=force)
        else:
            self.solver.factorize(K)
        return self

    def release(self) -> None:
        """Drop the factors of the chosen LU (:meth:`LaggedLUSolver.release`), if it has any."""
        release = getattr(self.solver, "release", None)
        if release is not None:
            release()
        self.K = None

    def solve(self, b: np.ndarray, rtol: float | None = None) -> np.ndarray:
        """Solve with the chosen solver; ``b`` shape (n,), returns ``x`` shape (n,).  ``rtol``: the
        relative residual of this solve for a lagged LU (:meth:`LaggedLUSolver.solve`); other
        solvers keep their own."""
        try:
            if rtol is not None and isinstance(self.solver, LaggedLUSolver):
                return self.solver.solve(b, rtol=rtol)
            return self.solver.solve(b)
        except SolverError as err:
            if not (self.fallback and self.chosen == "iterative"):
                raise
            first_line = str(err).splitlines()[0]
            self.solver = DirectSolver(**self.direct_options).factorize(self.K)
            self.chosen = "direct"
            self.reason += f"; iterative path failed ({first_line}), fell back to LU"
            x = self.solver.solve(b)
            self.solver.last_info.note = f"fallback after: {first_line}"
            return x

    @property
    def last_info(self) -> SolveInfo | None:
        """:class:`SolveInfo` of the last solve."""
        return None if self.solver is None else self.solver.last_info

    @property
    def factorizations(self) -> int | None:
        """LU factorisations of the solver in use (``None`` if it does not count them)."""
        return getattr(self.solver, "factorizations", None)

    @property
    def solves(self) -> int | None:
        """Solves of the solver in use (``None`` if it does not count them)."""
        return getattr(self.solver, "solves", None)

    @property
    def total_iterations(self) -> int | None:
        """Krylov iterations of the solver in use (``None`` if it does not count them)."""
        return getattr(self.solver, "total_iterations", None)

    def as_preconditioner(self) -> spla.LinearOperator:
        """The chosen solver's preconditioner, shape (n, n)."""
        return self.solver.as_preconditioner()
