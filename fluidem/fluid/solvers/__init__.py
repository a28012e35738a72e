r"""Linear solvers for the saddle-point systems of incompressible flow.

Every fluid step ends in one linear system

.. math::

    K \begin{bmatrix} u \\ p \end{bmatrix}
    = \begin{bmatrix} A & B^T \\ B & -C \end{bmatrix}
      \begin{bmatrix} u \\ p \end{bmatrix}
    = \begin{bmatrix} f \\ g \end{bmatrix},

assembled after Dirichlet condensation, velocity DOFs first (``n_u`` of them),
then pressure DOFs (``n_p``).  ``A`` is the velocity block (viscous term, plus
``(alpha/dt) M_u`` for unsteady flow, plus convection for Oseen/Newton systems,
so possibly non-symmetric), ``B`` the (negative) discrete divergence and ``C``
an optional pressure stabilisation (usually zero).

Solvers here share one shape, borrowed from pyamg: an object is configured in
its constructor, ``factorize(K)`` does the setup (LU, AMG hierarchies) and
returns the object, ``solve(b)`` returns ``x`` and records a :class:`SolveInfo`
in ``last_info``, ``as_preconditioner()`` gives a
:class:`scipy.sparse.linalg.LinearOperator`.

The package, one job per module:

* :mod:`.results` -- :class:`SolveInfo` and :class:`LinearSolverError` (also
  ``SolverError``; a :class:`fluidem.errors.SolverError`).
* :mod:`.direct` -- :class:`DirectSolver`: sparse LU (SuperLU through scipy;
  PARDISO through the optional ``pypardiso`` package).
* :mod:`.ordering` -- :class:`~.ordering.OrderingChoice`: SuperLU's symmetric-mode
  ordering or COLAMD for a run's continuous-pressure systems, by the fill each gives.
* :mod:`.krylov` -- the FGMRES and MINRES drivers that stop on the true residual.
* :mod:`.block` -- :class:`BlockKrylovSolver`: GMRES with a block upper-triangular
  preconditioner, or MINRES with a block-diagonal one (symmetric Stokes); pyamg
  smoothed aggregation on the velocity block and the Schur-complement
  approximations ``"mass"``, ``"cahouet-chabard"`` and ``"lsc"``.
* :mod:`.lagged` -- :class:`LaggedLUSolver`: keeps the LU of an earlier matrix and
  solves the current one by GMRES preconditioned with it; refactorises when the
  iteration count exceeds a threshold.
* :mod:`.choose` -- what ``"auto"`` means: :func:`choose_solver` (by problem kind
  and size, from the measurements in ``benchmarks/bench_solvers.py``),
  :func:`choose_method` and :class:`AutoSolver`.
* :mod:`.factory` -- :data:`SOLVERS` and :func:`make_solver`, solvers by the names
  of kind ``"solver"`` in :mod:`fluidem.names` (``"auto"``, ``"direct"``,
  ``"iterative"``, ``"lagged"``), for bare matrices or for a flow problem.

No solver returns an unconverged field: the true relative residual
``||b - K x||_2 / ||b||_2`` is checked after every solve and
:class:`SolverError` is raised, with a summary of the residual history, when
it misses the tolerance, when a Krylov method stagnates or when the LU is
singular.

Singular systems.  With velocity Dirichlet conditions on the whole boundary
the pressure is determined only up to a constant and ``K`` is singular.  The
caller removes the null space by *pinning* one pressure DOF: treat it like a
Dirichlet DOF (condense it out with value 0) before handing ``K`` over, and
shift the pressure afterwards if a zero mean is wanted.  With an outflow
(natural) boundary nothing needs to be done.  Both the direct and the
iterative path assume a non-singular ``K``.

Examples
--------
>>> import numpy as np, scipy.sparse as sp
>>> from fluidem.fluid.solvers import make_solver
>>> K = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 0.0]]))
>>> s = make_solver("direct").factorize(K)
>>> s.solve(np.array([3.0, 1.0])).round(12), s.last_info.iterations
(array([1., 1.]), 0)
"""

from __future__ import annotations

from ._sparse import (  # noqa: F401  (private helpers, importable from here as before)
    _as_csr,
    _Counter,
    _is_symmetric,
    _relres,
    _same_structure,
    _same_values,
    _split,
)
from .block import _SCHUR, BlockKrylovSolver  # noqa: F401
from .choose import (
    DIRECT_MAX_DOFS,
    DIRECT_MAX_DOFS_CONVECTIVE,
    DIRECT_MAX_DOFS_UNSTEADY,
    LAGGED_MAX_DOFS,
    PROBLEM_KINDS,
    AutoSolver,
    choose_method,
    choose_solver,
)
from .direct import DirectSolver, _pardiso_available, default_direct_backend  # noqa: F401
from .factory import _DIRECT_KEYS, SOLVERS, flow_solver_options, make_solver, release_factors  # noqa: F401
from .krylov import _krylov_start, run_fgmres, run_minres  # noqa: F401
from .lagged import LaggedLUSolver
from .results import LinearSolverError, SolveInfo, SolverError, _history_summary  # noqa: F401

_fgmres = run_fgmres
_minres = run_minres

__all__ = [
    "SolveInfo",
    "SolverError",
    "LinearSolverError",
    "DirectSolver",
    "BlockKrylovSolver",
    "LaggedLUSolver",
    "AutoSolver",
    "SOLVERS",
    "make_solver",
    "flow_solver_options",
    "choose_method",
    "choose_solver",
    "default_direct_backend",
    "run_fgmres",
    "run_minres",
    "PROBLEM_KINDS",
    "DIRECT_MAX_DOFS",
    "DIRECT_MAX_DOFS_UNSTEADY",
    "DIRECT_MAX_DOFS_CONVECTIVE",
    "LAGGED_MAX_DOFS",
]
