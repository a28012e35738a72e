"""Intel MKL PARDISO set up for saddle-point systems: :class:`PardisoLU` (optional ``pypardiso``).

PARDISO (Schenk & Gärtner, *Solving unsymmetric sparse systems of linear equations with
PARDISO*, FGCS 20, 2004) factorises with a nested-dissection ordering (METIS) and supernodes,
and replaces a pivot too small for its static pivoting by ``ε ‖A‖``.  The settings here
(``iparm``, 1-based as in the MKL manual) are chosen for the saddle-point systems of fluidem,
whose pressure block is zero:

==========  =====  ============================================================================
``iparm``   value  meaning
==========  =====  ============================================================================
1           1      the values below are set (not MKL's defaults)
2           2      METIS nested-dissection ordering
8           0      no refinement inside PARDISO: :class:`~.direct.DirectSolver` refines and
                   checks the true residual itself, a lagged LU runs GMRES around it
10          8      pivot perturbation ε = 1e-8 (MKL's default for unsymmetric matrices is 1e-13)
11, 13      0, 0   no scaling and weighted matching (MC64); ``matching=True``: 1, 1
18          -1     report the entries of the factors
==========  =====  ============================================================================

**Why no matching.**  The pressure block is zero, so without matching PARDISO's static pivoting
perturbs the pressure pivots (ε ‖K‖ in place of a zero): the factors are those of a slightly
regularised saddle-point matrix, a solve with them alone leaves a relative residual of 1e-3–1e-2,
and every use of them in fluidem refines or runs FGMRES around them (:class:`~.direct.DirectSolver`,
:class:`~.lagged.LaggedLUSolver`).  Weighted matching (MC64) permutes large entries onto the diagonal
instead, so few pivots are perturbed and the factors alone leave ~1e-7, but the permuted matrix
loses the symmetric pattern nested dissection orders, and the factors hold twice the entries.
Measured on the coupled systems of settling suspensions (``benchmarks/bench_pardiso_matching.py``,
medians, one MKL thread; analysis and factorisation / numerical factorisation / back-substitution,
entries of L + U, FGMRES iterations of the lagged LU to 1e-6 on the system five steps later):

=========  ============================================  ============================================
DOFs       with matching                                 without (the default)
=========  ============================================  ============================================
149 285    2.13 / 0.35 / 0.035 s, 19.6M, 9 iterations    0.77 / 0.16 / 0.017 s, 9.1M, 11 iterations
446 752    8.73 / 1.25 / 0.112 s, 64.5M, 9 iterations    2.56 / 0.56 / 0.051 s, 30.1M, 12 iterations
1 486 304  35.9 / 5.85 / 0.367 s, 238M, 9 iterations     10.5 / 2.33 / 0.176 s, 111M, 13 iterations
=========  ============================================  ============================================

The lagged solve took 0.68–0.86 of the time despite its two to four iterations more, and a new
analysis at a re-triangulation of 1 000 settling polygons costs 10.5 s instead of 35.9 s.

Why ε = 1e-8: with matching, on the coupled system of a settling suspension of 100 polygons
(149 285 DOFs, P2+bubble/P1dc, one thread), MKL's default ε = 1e-13 perturbed one pivot and the
solve left a relative residual of 4.9e-3 after MKL's two refinement steps (1.1 without them); with
ε = 1e-8 the same pivot left 7.8e-6, and GMRES preconditioned by the factors reached 5e-10 in 2
iterations.  Without matching 51 234 pivots are perturbed there (the pressure ones) and the
factors alone leave 6.0e-3.

Between re-triangulations the coupled matrix keeps its sparsity pattern and only its values
change: :meth:`PardisoLU.refactor` then repeats the numerical factorisation (phase 22) on the
ordering (and scaling and matching, if any) of the analysis (phase 11).  On the 149 285-DOF system
with matching: analysis and factorisation 5.9 s, the numerical factorisation alone 1.29 s (the
analysis 4.1 s of it), a solve 0.063 s; after a change of 1e-3 of every value the refactorised solve
leaves 3.3e-10 with no pivot perturbed (load 3.4 on 2 cores; without matching see the table above).

``pypardiso``'s own ``solve`` compares the matrix with the factorised one (a copy or a SHA-1
of its arrays) at every call, and its call into MKL converts the matrix's ``indptr`` and
``indices`` to 1-based 32-bit arrays each time; :class:`PardisoLU` calls MKL's ``pardiso``
itself with those arrays made once an analysis (the pattern is that of the analysis for every
later phase): a back-substitution of the coupled systems of 100 and 300 settling polygons (149k and
447k DOFs) takes 0.91 and 0.90 of the time of ``pypardiso``'s call on the same factors, with the same
solution bit for bit (``benchmarks/bench_pardiso_call.py``).  Right-hand sides are copied to float64
in Fortran order first: PARDISO reads the buffer as doubles whatever its type.

Examples
--------
>>> import numpy as np, scipy.sparse as sp
>>> K = sp.csr_matrix(np.array([[4.0, 1.0, 1.0], [1.0, 3.0, 0.0], [1.0, 0.0, 0.0]]))
>>> if pardiso_available():
...     lu = PardisoLU(K)
...     x = lu.solve(np.array([6.0, 4.0, 1.0]))
... else:
...     x = np.linalg.solve(K.toarray(), [6.0, 4.0, 1.0])
>>> np.round(x, 6).tolist()  # the pivot of the zero diagonal entry is perturbed
[1.0, 1.0, 1.0]
"""

from __future__ import annotations

import ctypes
import functools
import weakref

import numpy as np
import scipy.sparse as sp

__all__ = ["PardisoLU", "pardiso_available", "PARDISO_IPARM", "PARDISO_MATCHING_IPARM"]

#: PARDISO's parameters for saddle-point systems (1-based ``iparm`` index -> value; module notes)
PARDISO_IPARM = {1: 1, 2: 2, 8: 0, 10: 8, 11: 0, 13: 0, 18: -1}
#: what ``PardisoLU(K, matching=True)`` sets on top: scaling and weighted matching (MC64)
PARDISO_MATCHING_IPARM = {11: 1, 13: 1}


@functools.cache
def pardiso_available() -> bool:
    """Whether the optional ``pypardiso`` (and its MKL runtime) imports; checked once a process (a failed
    import is not cached by Python, and ``"auto"`` asks at every factorisation of a large system)."""
    try:
        import pypardiso  # noqa: F401
    except Exception:  # ImportError, or mkl_rt missing
        return False
    return True


class PardisoLU:
    """PARDISO's factorisation of one real unsymmetric sparse matrix.

    Parameters
    ----------
    K : (n, n) sparse matrix
        Converted to CSR with sorted indices, float64.
    matching : bool
        Scaling and weighted matching (MC64) before the ordering: few perturbed pivots, so the
        factors alone solve to ~1e-7, at twice the entries and about three times the time
        (module notes).  Default ``False``: the pressure pivots are perturbed, and the factors
        are meant to be refined or wrapped in FGMRES, as every solver of fluidem does.

    Attributes
    ----------
    fill : int
        Entries of the factors L + U (``iparm(18)``).
    perturbed : int
        Pivots replaced by ε ‖K‖ (``iparm(14)``).
    peak_bytes : int
        PARDISO's peak memory of the analysis and factorisation (``iparm(15..17)``), bytes.
    numeric_refactorizations : int
        Numerical factorisations on the same analysis after the first (:meth:`refactor`).

    Raises
    ------
    RuntimeError
        PARDISO's error code, e.g. -2 (not enough memory) or -4 (zero pivot).
    """

    def __init__(self, K, matching: bool = False):
        import pypardiso

        K = sp.csr_matrix(K, dtype=np.float64)
        K.sort_indices()
        self.K = K
        _name_mkl_runtime(pypardiso)
        self._ps = pypardiso.PyPardisoSolver(mtype=11)
        # MKL's memory is outside Python's: released when this object goes, not only by free()
        # (a solver dropped without free() kept its factors until the process ended)
        self._release = weakref.finalize(self, _release, self._ps)
        self._ps.set_statistical_info_off()
        self.matching = bool(matching)
        for i, v in {**PARDISO_IPARM, **(PARDISO_MATCHING_IPARM if self.matching else {})}.items():
            self._ps.set_iparm(i, v)
        self._ps.set_iparm(12, 0)  # CSR, no transpose
        # 1-based 32-bit CSR indices, made once: every later phase reads this pattern (refactor checks it)
        self._ia = (K.indptr + 1).astype(np.int32)
        self._ja = (K.indices + 1).astype(np.int32)
        try:
            self._call(12, K.data, np.zeros((K.shape[0], 1), order="F"))  # analysis and factorisation
        except RuntimeError:
            self.free()
            raise
        it = self._ps.iparm
        self.fill = int(it[17])
        self.perturbed = int(it[13])
        self.peak_bytes = 1024 * int(max(it[14], it[15] + it[16]))
        #: numerical factorisations on this analysis after the first (:meth:`refactor`)
        self.numeric_refactorizations = 0

    def refactor(self, K) -> bool:
        """Factorise ``K`` numerically on the analysis of the matrix factorised first (PARDISO's
        phase 22), when ``K`` has its sparsity pattern (``indptr`` and ``indices`` equal);
        ``False``, and nothing done, otherwise.

        Raises
        ------
        RuntimeError
            PARDISO's error code (the previous factors are freed).
        """
        if self._ps is None:
            return False
        K = sp.csr_matrix(K, dtype=np.float64)
        K.sort_indices()
        if K.shape != self.K.shape or not (np.array_equal(K.indptr, self.K.indptr)
                                           and np.array_equal(K.indices, self.K.indices)):
            return False
        self._ps.set_iparm(12, 0)
        try:
            self._call(22, K.data, np.zeros((K.shape[0], 1), order="F"))
        except RuntimeError:
            self.free()
            raise
        self.K = K
        self.perturbed = int(self._ps.iparm[13])
        self.numeric_refactorizations += 1
        return True

    def solve(self, b, trans: str = "N") -> np.ndarray:
        """``K⁻¹ b`` (``trans="T"``: ``K⁻ᵀ b``) with the stored factors, ``b (n,)`` or ``(n, k)``;
        the result has the shape of ``b``."""
        if self._ps is None:
            raise RuntimeError("the factorisation was freed")
        b = np.asarray(b)
        rhs = np.asfortranarray(b, dtype=np.float64)
        if rhs is b:
            rhs = rhs.copy(order="F")
        self._ps.set_iparm(12, 2 if trans == "T" else 0)
        try:
            x = self._call(33, self.K.data, rhs)
        finally:
            self._ps.set_iparm(12, 0)
        return x.reshape(b.shape)

    def _call(self, phase: int, data, rhs) -> np.ndarray:
        """MKL's ``pardiso`` for ``phase`` (11 analysis, 12 analysis and factorisation, 22 numerical
        factorisation, 33 solve) with the stored 1-based pattern, the values ``data`` (float64, in the
        pattern's order) and the Fortran-ordered float64 right-hand side(s) ``rhs``; the solution in C
        order (as ``pypardiso``'s own call).

        Raises
        ------
        RuntimeError
            PARDISO's error code.
        """
        ps = self._ps
        x = np.zeros_like(rhs)
        error = ctypes.c_int32(0)
        int32_p = ctypes.POINTER(ctypes.c_int32)
        double_p = ctypes.POINTER(ctypes.c_double)
        ps._mkl_pardiso(ps.pt.ctypes.data_as(ctypes.POINTER(ps._pt_type[0])),
                        ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),  # maxfct, mnum
                        ctypes.byref(ctypes.c_int32(ps.mtype)), ctypes.byref(ctypes.c_int32(phase)),
                        ctypes.byref(ctypes.c_int32(self._ia.size - 1)),
                        data.ctypes.data_as(double_p), self._ia.ctypes.data_as(int32_p),
                        self._ja.ctypes.data_as(int32_p), ps.perm.ctypes.data_as(int32_p),
                        ctypes.byref(ctypes.c_int32(1 if rhs.ndim == 1 else rhs.shape[1])),  # nrhs
                        ps.iparm.ctypes.data_as(int32_p), ctypes.byref(ctypes.c_int32(ps.msglvl)),
                        rhs.ctypes.data_as(double_p), x.ctypes.data_as(double_p), ctypes.byref(error))
        if error.value != 0:
            from pypardiso.pardiso_wrapper import PyPardisoError

            raise RuntimeError(str(PyPardisoError(error.value)))
        return np.ascontiguousarray(x)

    def free(self) -> None:
        """Release PARDISO's memory of this factorisation (also done when the object is collected)."""
        if self._ps is not None:
            self._release()
            self._ps = None


@functools.cache
def _name_mkl_runtime(pypardiso) -> None:
    """Give ``pypardiso`` the MKL runtime it found at import (``PYPARDISO_MKL_RT``, its documented setting).

    Without it every new solver object searches for ``mkl_rt`` again, and where the library is not
    on the loader's path (a pip-installed MKL in a virtual environment) that is a recursive search
    of the environment's library folders: 0.2-0.4 s a factorisation with a new analysis (measured
    in a virtual environment with the development tools installed).  A path set by the user stays.
    """
    import os

    lib = getattr(getattr(pypardiso, "ps", None), "libmkl", None)
    if lib is not None and getattr(lib, "_name", None):
        os.environ.setdefault("PYPARDISO_MKL_RT", lib._name)


def _release(ps) -> None:
    """Free all of MKL's memory held for the PARDISO handle ``ps``."""
    ps.free_memory(everything=True)
