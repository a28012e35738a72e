"""Small sparse-matrix helpers shared by the solvers (private)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _as_csr(K, name: str = "K") -> sp.csr_matrix:
    """``K`` as a square CSR matrix with sorted indices; ``TypeError``/``ValueError`` otherwise."""
    if not sp.issparse(K):
        raise TypeError(f"{name} must be a scipy sparse matrix, got {type(K).__name__}")
    K = sp.csr_matrix(K)
    if K.shape[0] != K.shape[1]:
        raise ValueError(f"{name} must be square, got shape {K.shape}")
    if not K.has_sorted_indices:
        K.sort_indices()
    return K


def _same_structure(a: sp.csr_matrix | None, b: sp.csr_matrix) -> bool:
    """Whether two CSR matrices have the same shape and sparsity pattern."""
    return (
        a is not None
        and a.shape == b.shape
        and a.nnz == b.nnz
        and np.array_equal(a.indptr, b.indptr)
        and np.array_equal(a.indices, b.indices)
    )


def _same_values(a: sp.csr_matrix | None, b: sp.csr_matrix) -> bool:
    """Whether two CSR matrices are equal entry by entry (same pattern and values)."""
    return _same_structure(a, b) and np.array_equal(a.data, b.data)


def _is_symmetric(A: sp.spmatrix, tol: float = 1e-12) -> bool:
    """Whether ``max |A - A^T| <= tol max |A|``."""
    d = abs(A - A.T)
    scale = abs(A).max() if A.nnz else 1.0
    return (d.max() if d.nnz else 0.0) <= tol * scale


def _relres(K, x, b) -> float:
    """True relative residual ``||b - K x||_2 / ||b||_2`` (absolute if ``b = 0``)."""
    nb = np.linalg.norm(b)
    r = np.linalg.norm(b - K @ x)
    return float(r / nb) if nb > 0 else float(r)


def _split(K: sp.csr_matrix, n_u: int):
    """Blocks ``(A, B^T, B, C)`` of ``K = [[A, B^T], [B, C]]``, velocity DOFs first."""
    n = K.shape[0]
    if not 0 < n_u < n:
        raise ValueError(f"n_u={n_u} must lie strictly between 0 and K.shape[0]={n}")
    A = K[:n_u, :n_u].tocsr()
    Bt = K[:n_u, n_u:].tocsr()
    B = K[n_u:, :n_u].tocsr()
    C = K[n_u:, n_u:].tocsr()
    return A, Bt, B, C


class _Counter:
    """Wrap a LinearOperator-like object and count applications."""

    def __init__(self, op):
        self.op = op
        self.count = 0

    def __call__(self, v):
        self.count += 1
        return self.op @ v
