"""Solvers by the names users type: :data:`SOLVERS` and the one factory :func:`make_solver`.

The names are those of kind ``"solver"`` in :mod:`fluidem.names` (``"auto"``, ``"direct"``,
``"iterative"``, ``"lagged"``; alias ``"lagged-lu"``), so a scene file, the command line and
Python mean the same by each; ``"auto"`` is the rule of :mod:`.choose`.

Given a flow problem, the factory reads from it (duck typing, nothing else):

* ``problem.free`` -- (n_free,) int, sorted free DOFs of the ``[u, p]`` numbering (velocity
  first), the rows and columns of the condensed saddle-point system;
* ``problem.space.n_u`` -- number of velocity DOFs before condensation;
* ``problem.space.pb`` -- the pressure basis, for the pressure mass matrix ``M_p``;
* ``problem.M`` -- (n_u, n_u) velocity mass matrix ``M_u``;
* ``problem.nu`` -- kinematic viscosity (coefficient of the viscous term);
* ``problem.direct_solver()`` -- the configured :class:`~.direct.DirectSolver` for its
  element pair.
"""

from __future__ import annotations

import numpy as np

from ... import names
from ...errors import InputError
from .block import BlockKrylovSolver
from .choose import AutoSolver
from .direct import DirectSolver
from .lagged import LaggedLUSolver

__all__ = ["SOLVERS", "make_solver", "flow_solver_options", "release_factors"]

#: Solvers by the names used in scene files and on the command line (the canonical names of
#: kind ``"solver"`` in :mod:`fluidem.names`, in its order).
SOLVERS = {
    "auto": AutoSolver,
    "direct": DirectSolver,
    "iterative": BlockKrylovSolver,
    "lagged": LaggedLUSolver,
}

_DIRECT_KEYS = ("backend", "permc_spec", "check_rtol", "symmetric_mode", "pivot_threshold", "ordering")
_LAGGED_KEYS = ("max_iterations_before_refactor",)


def flow_solver_options(problem) -> dict:
    """What the solvers need from a flow problem, condensed to its free DOFs.

    Parameters
    ----------
    problem : FlowProblem or alike
        Read: ``free``, ``space.n_u``, ``space.pb``, ``M``, ``nu``, ``direct_solver()``.

    Returns
    -------
    dict
        ``n_u`` (int, free velocity DOFs), ``pressure_mass`` ((n_p_free, n_p_free) CSR,
        ``M_p`` on the free pressure DOFs), ``velocity_mass`` ((n_u_free, n_u_free) CSR),
        ``nu`` (float), ``direct`` (dict of :class:`DirectSolver` keywords).
    """
    from skfem import asm

    from .. import forms

    n_u = problem.space.n_u
    free = np.asarray(problem.free)
    free_u = free[free < n_u]
    pf = free[free >= n_u] - n_u
    Mp = asm(forms.pressure_mass, problem.space.pb).tocsr()[pf][:, pf]
    Mu = problem.M[free_u][:, free_u]
    d = problem.direct_solver()
    direct = {"backend": "auto" if d.auto else d.backend, "permc_spec": d.permc_spec, "check_rtol": d.check_rtol,
              "symmetric_mode": d.symmetric_mode, "pivot_threshold": d.pivot_threshold, "ordering": d.ordering}
    return {"n_u": int(free_u.size), "pressure_mass": Mp, "velocity_mass": Mu,
            "nu": problem.nu, "direct": direct}


def make_solver(method: str = "auto", problem=None, dt: float | None = None,
                kind: str | None = None, **options):
    """Build a solver by name, for bare matrices or for a flow problem.

    Parameters
    ----------
    method : {"auto", "direct", "iterative", "lagged"}
        A name of kind ``"solver"`` in :mod:`fluidem.names` (aliases accepted).
        ``"direct"``: a fresh sparse LU per matrix; ``"lagged"``: an LU reused as a GMRES
        preconditioner while it converges fast; ``"iterative"``: block-preconditioned
        GMRES (pyamg on the velocity block; Schur complement ν M_p⁻¹, plus the
        Cahouet--Chabard term when ``dt`` is given); ``"auto"``: chosen at ``factorize``
        by problem kind and size (:func:`~fluidem.fluid.solvers.choose.choose_solver`).
    problem : FlowProblem or alike, optional
        The flow problem whose condensed systems will be solved; supplies the free
        velocity DOFs, ``M_p``, ``M_u``, ``nu`` and the direct solver of its element pair
        (:func:`flow_solver_options` lists what is read).  Without it, the keywords below
        must give what the chosen solver needs (``n_u`` and ``pressure_mass`` for
        ``"iterative"``).
    dt : float, optional
        Time step of the systems to be solved (time units); ``None`` for steady problems.
        ``"auto"`` treats a given ``dt`` as a run of time steps.
    kind : {"steady", "stokes", "unsteady"}, optional
        Problem kind for ``"auto"``; default: ``"unsteady"`` with ``dt``, else decided at
        ``factorize`` from the symmetry of the velocity block.
    **options
        ``"direct"``: keywords of :class:`DirectSolver`.
        ``"iterative"``: keywords of :class:`BlockKrylovSolver` (``n_u`` is
        required without ``problem``).  ``"lagged"``: keywords of :class:`LaggedLUSolver`.
        ``"auto"``: ``n_u``, ``fallback``, the :class:`DirectSolver` keywords, the
        :class:`BlockKrylovSolver` keywords and ``max_iterations_before_refactor``,
        sorted to the three (``rtol`` goes to both Krylov paths).

    Returns
    -------
    solver
        An object with ``factorize(K)``, ``solve(b)``,
        ``as_preconditioner()`` and ``last_info``.

    Raises
    ------
    fluidem.errors.InputError
        For an unknown name (a ``ValueError``).

    Examples
    --------
    >>> make_solver("direct")  # doctest: +ELLIPSIS
    <...DirectSolver object at ...>
    >>> make_solver("lagged-lu").__class__.__name__
    'LaggedLUSolver'
    >>> make_solver("cholesky")
    Traceback (most recent call last):
    ...
    fluidem.errors.InputError: solver = 'cholesky': expected one of 'auto', 'direct', 'iterative', 'lagged' (solver)
    """
    method = names.lookup("solver", method, where="solver")
    if problem is not None:
        return _for_problem(method, problem, dt, kind, options)
    if dt is not None and method in ("auto", "iterative"):
        options["dt"] = dt
    if method == "auto":
        n_u = options.pop("n_u", None)
        fallback = options.pop("fallback", True)
        direct = {k: options.pop(k) for k in _DIRECT_KEYS if k in options}
        lagged = {k: options.pop(k) for k in _LAGGED_KEYS if k in options}
        if "rtol" in options:
            lagged["rtol"] = options["rtol"]
        return AutoSolver(n_u=n_u, direct_options=direct, iterative_options=options,
                          fallback=fallback, kind=kind, lagged_options=lagged)
    if method == "iterative":
        if "n_u" not in options:
            raise InputError("make_solver('iterative') needs n_u (number of velocity DOFs) or a "
                             "flow problem")
        return BlockKrylovSolver(options.pop("n_u"), **options)
    return SOLVERS[method](**options)


def _for_problem(method: str, problem, dt, kind, options: dict):
    """:func:`make_solver` for a flow problem: its direct solver, M_p, M_u and nu."""
    if method == "direct" and not options:
        return problem.direct_solver()
    if method == "lagged":
        return LaggedLUSolver(direct=problem.direct_solver(), **options)
    fo = flow_solver_options(problem)
    if method == "direct":
        return DirectSolver(**{**fo["direct"], **options})
    iterative = {"pressure_mass": fo["pressure_mass"], "nu": fo["nu"], "dt": dt,
                 "velocity_mass": fo["velocity_mass"]}
    if method == "iterative":
        return BlockKrylovSolver(fo["n_u"], **{**iterative, **options})
    fallback = options.pop("fallback", True)
    direct = {**fo["direct"], **{k: options.pop(k) for k in _DIRECT_KEYS if k in options}}
    lagged = {k: options.pop(k) for k in _LAGGED_KEYS if k in options}
    if "rtol" in options:
        lagged["rtol"] = options["rtol"]
    return AutoSolver(n_u=fo["n_u"], direct_options=direct, iterative_options={**iterative, **options},
                      fallback=fallback, kind=kind, lagged_options=lagged)


def release_factors(*solvers) -> None:
    """Drop the factors and matrices of each of ``solvers`` that holds any (its ``release``:
    :meth:`DirectSolver.release`, :meth:`LaggedLUSolver.release`, :meth:`AutoSolver.release`, the
    coupled block GMRES); ``None`` and solvers without them are skipped.  For the moment a
    re-triangulation makes them useless, before the new problem is built."""
    for s in solvers:
        release = getattr(s, "release", None)
        if release is not None:
            release()
