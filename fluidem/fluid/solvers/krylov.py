"""Krylov drivers that stop on the true residual: restarted FGMRES and MINRES.

Both take ``(K, b, M, x0, rtol, maxiter, ...)`` with ``M`` a preconditioner (anything with
``M @ v``) and return ``(x, iterations, residual history, reason)``; ``reason`` is ``""`` on
convergence, otherwise one line (maxiter reached, stagnation, non-finite residual) that the
calling solver puts into its :class:`~fluidem.fluid.solvers.results.LinearSolverError`.
``iterations`` counts preconditioner applications.

References
----------
.. [S93] Saad, Y. (1993). A flexible inner-outer preconditioned GMRES algorithm.
   *SIAM J. Sci. Comput.* 14, 461--469.
.. [GLR05] Giraud, L., Langou, J., Rozložník, M. (2005). The loss of orthogonality in the
   Gram-Schmidt orthogonalization process. *Comput. Math. Appl.* 50, 1069--1075.
.. [S03] Saad, Y. (2003). *Iterative Methods for Sparse Linear Systems*, 2nd ed. SIAM.
.. [PS75] Paige, C. C., Saunders, M. A. (1975). Solution of sparse indefinite systems of
   linear equations. *SIAM J. Numer. Anal.* 12, 617--629 (MINRES).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from ._sparse import _Counter

__all__ = ["fgmres_cycle", "run_fgmres", "run_minres"]


def _krylov_start(K, b, M, x0):
    """Common start of the Krylov drivers: size, ‖b‖, initial iterate, counted preconditioner
    (as a LinearOperator) and the residual history with the initial relative residual."""
    n = K.shape[0]
    nb = np.linalg.norm(b) or 1.0
    x = np.zeros(n) if x0 is None else np.array(x0, dtype=float)
    Mc = _Counter(M)
    Mop = spla.LinearOperator((n, n), matvec=Mc, dtype=float)
    return n, nb, x, Mc, Mop, [np.linalg.norm(b - K @ x) / nb]


def fgmres_cycle(K, b, x, M, atol: float, m: int):
    """One cycle of at most ``m`` iterations of right-preconditioned flexible GMRES ([S93]_,
    Algorithm 2.2) from ``x``, stopping early when the Krylov estimate of ‖b − K x‖₂ falls to
    ``atol`` (absolute).

    The Arnoldi basis is orthogonalised by classical Gram–Schmidt applied twice ([GLR05]_: as
    orthogonal as Householder reflections, with matrix–vector products over the basis), the
    Hessenberg matrix reduced by Givens rotations ([S03]_, Sec. 6.5.3).  The basis ``V`` and the
    preconditioned vectors ``Z`` are rows of arrays left uninitialised, so memory is touched
    only for the iterations made: a solve of 1.6 million unknowns in 5 iterations writes 11
    vectors, where a zeroed ``(n, m)`` store written by columns touches all of it.

    Parameters
    ----------
    K : (n, n) sparse matrix or operator
    b, x : (n,) float ndarray
        Right-hand side and start (``x`` is not changed).
    M : callable
        ``M(v)``: the preconditioner applied to ``v`` (may change between calls).
    atol : float
        Absolute residual at which the cycle stops.
    m : int
        Most iterations of the cycle, >= 1.

    Returns
    -------
    x : (n,) float ndarray
    estimates : list of float
        ‖r₀‖ and the Krylov estimate of the residual norm after each iteration.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> K = sp.diags([-1.0, 3.0, -1.0], [-1, 0, 1], shape=(20, 20)).tocsr()
    >>> x, est = fgmres_cycle(K, np.ones(20), np.zeros(20), lambda v: v, 1e-10, 30)
    >>> bool(np.linalg.norm(np.ones(20) - K @ x) <= 1e-10), len(est) <= 21
    (True, True)
    """
    r = b - K @ x
    beta = float(np.linalg.norm(r))
    estimates = [beta]
    if beta == 0.0 or beta <= atol:
        return x.copy(), estimates
    n = len(b)
    V = np.empty((m + 1, n))
    Z = np.empty((m, n))
    R = np.zeros((m + 1, m))  # the Hessenberg matrix, reduced to upper triangular as it grows
    cs, sn = np.zeros(m), np.zeros(m)
    g = np.zeros(m + 1)
    g[0] = beta
    V[0] = r / beta
    k = 0
    for j in range(m):
        Z[j] = M(V[j])
        w = K @ Z[j]
        h = V[: j + 1] @ w
        w -= h @ V[: j + 1]
        h2 = V[: j + 1] @ w  # the second Gram–Schmidt pass
        w -= h2 @ V[: j + 1]
        h += h2
        h_next = float(np.linalg.norm(w))
        col = np.append(h, h_next)
        for i in range(j):  # earlier rotations on the new column (i < m: the Krylov dimension)
            col[i], col[i + 1] = cs[i] * col[i] + sn[i] * col[i + 1], -sn[i] * col[i] + cs[i] * col[i + 1]
        rho = float(np.hypot(col[j], col[j + 1]))
        cs[j], sn[j] = (1.0, 0.0) if rho == 0.0 else (col[j] / rho, col[j + 1] / rho)
        col[j], col[j + 1] = rho, 0.0
        R[: j + 2, j] = col
        g[j], g[j + 1] = cs[j] * g[j], -sn[j] * g[j]
        k = j + 1
        estimates.append(abs(float(g[k])))
        if estimates[-1] <= atol or h_next == 0.0:  # converged, or the Krylov space is invariant
            break
        V[j + 1] = w / h_next
    # y = R⁻¹ g; least squares, so that a singular R (K singular) gives the minimum-norm step
    y = np.linalg.lstsq(R[:k, :k], g[:k], rcond=None)[0]
    return x + y @ Z[:k], estimates


def run_fgmres(K, b, M, x0, rtol, maxiter, restart, stagnation):
    """Restarted right-preconditioned flexible GMRES ([S93]_) stopped on the true residual.

    Runs :func:`fgmres_cycle` one restart cycle at a time so that the true
    residual is checked after each cycle and a cycle that does not reduce it
    by at least the factor ``stagnation`` ends the solve.

    Parameters
    ----------
    K : (n, n) sparse matrix
    b : (n,) float ndarray
    M : (n, n) operator
        Right preconditioner (anything with ``M @ v``); may change between
        applications (flexible GMRES).
    x0 : (n,) float ndarray or None
        Initial iterate (zero if ``None``).
    rtol : float
        Required true relative residual ``||b - K x||_2 / ||b||_2``.
    maxiter : int
        Maximum number of preconditioner applications.
    restart : int
        Restart length.
    stagnation : float
        A cycle must reduce the true residual below ``stagnation`` times its
        value at the cycle start.

    Returns
    -------
    x : (n,) float ndarray
    iterations : int
    history : (k,) float ndarray
        Relative residuals (Krylov estimates inside a cycle, true ones at cycle ends).
    reason : str
        ``""`` on convergence, else why the solve stopped.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> K = sp.diags([-1.0, 3.0, -1.0], [-1, 0, 1], shape=(20, 20)).tocsr()
    >>> x, it, hist, reason = run_fgmres(K, np.ones(20), sp.eye(20), None, 1e-10, 100, 30, 0.999)
    >>> reason, bool(hist[-1] <= 1e-10)
    ('', True)
    """
    n, nb, x, Mc, _, history = _krylov_start(K, b, M, x0)
    if history[-1] <= rtol:
        return x, 0, np.array(history), ""
    restart = max(1, min(restart, n - 1))
    reason = f"no convergence within maxiter={maxiter} iterations"
    while Mc.count < maxiter:
        inner = min(restart, maxiter - Mc.count)
        start, count = history[-1], Mc.count
        x, estimates = fgmres_cycle(K, b, x, Mc, rtol * nb, inner)
        if Mc.count == count:  # the cycle saw a converged start that our test did not
            reason = "stagnation: FGMRES made no iteration"
            history.append(np.linalg.norm(b - K @ x) / nb)
            break
        r_true = np.linalg.norm(b - K @ x) / nb
        history.extend(np.asarray(estimates[1:-1]) / nb)  # one entry per iteration: the last one true
        history.append(r_true)
        if not np.isfinite(r_true):
            reason = "residual is not finite (NaN/inf from the preconditioner?)"
            break
        if r_true <= rtol:
            return x, Mc.count, np.array(history), ""
        if r_true > stagnation * start:
            reason = (f"stagnation: a restart cycle of {inner} iterations reduced the residual "
                      f"only from {start:.2e} to {r_true:.2e}")
            break
    return x, Mc.count, np.array(history), reason


def run_minres(K, b, M, x0, rtol, maxiter, window, stagnation):
    """Preconditioned MINRES ([PS75]_, scipy) stopped on the true residual.

    Arguments and return values as for :func:`run_fgmres`, with ``M`` symmetric
    positive definite and ``window``: the number of iterations over which the
    residual must fall below ``stagnation`` times its earlier value.

    MINRES minimises the residual in the ``M`` norm, which for saddle-point
    systems can differ from the 2-norm by orders of magnitude, so the
    stopping test is done on the true 2-norm residual, computed in the
    callback (one extra product with ``K`` per iteration).  If scipy stops
    on its own test first, MINRES is restarted from the current iterate (at
    most three times).
    """
    n, nb, x, Mc, Mop, history = _krylov_start(K, b, M, x0)

    class _Stop(Exception):
        pass

    last = {"x": x}

    def cb(xk):
        last["x"] = xk.copy()
        history.append(np.linalg.norm(b - K @ xk) / nb)
        if history[-1] <= rtol:
            raise _Stop("")
        if not np.isfinite(history[-1]):
            raise _Stop("residual is not finite")
        if len(history) > window and history[-1] > stagnation * history[-1 - window]:
            raise _Stop(f"stagnation: {window} iterations reduced the residual only from "
                        f"{history[-1 - window]:.2e} to {history[-1]:.2e}")

    if history[-1] <= rtol:
        return x, 0, np.array(history), ""
    reason = f"no convergence within maxiter={maxiter} iterations"
    for _ in range(4):
        remaining = maxiter - Mc.count
        if remaining <= 0:
            break
        try:
            # ask for a little more than rtol: the built-in test is on the M-norm
            x, _ = spla.minres(K, b, x0=x, rtol=1e-3 * rtol, maxiter=remaining, M=Mop,
                               callback=cb)
        except _Stop as stop:
            x = last["x"]
            reason = str(stop)
            if not reason:
                return x, Mc.count, np.array(history), ""
            break
        r_true = np.linalg.norm(b - K @ x) / nb
        history.append(r_true)
        if r_true <= rtol:
            return x, Mc.count, np.array(history), ""
    return x, Mc.count, np.array(history), reason
