"""Periodic degrees of freedom: DOFs on paired box sides identified in the condensed system.

On a box periodic in ``x`` (sides ``left`` and ``right`` one, :mod:`fluidem.mesh.periodic`)
every velocity DOF on the right side equals its partner on the left side, and so does every
continuous pressure DOF; a discontinuous pressure (P1dc) lives in the elements and needs no
identification (the weak form couples the two sides through the velocity).  The mesh stays
the full mesh (every node once, both sides present): the identification is a sparse
prolongation ``P`` from the periodic unknowns to the full DOFs, ``x = P y`` (a slave DOF takes
its master's value), and the condensed saddle-point system is ``Pᵀ K P`` on the free masters
(the standard treatment of periodic constraints by master/slave elimination, e.g. Zienkiewicz,
Taylor & Zhu, *The Finite Element Method: Its Basis and Fundamentals*, 7th ed., Sec. 9.7).
Assembly, boundary DOF lists, forces, transfer and outputs keep working on the full mesh
(outputs show the duplicated values on both sides).

scikit-fem builds periodic meshes the other way, in the topology (``MeshTri1DG.periodic``:
nodes repeated per element, the periodic nodes identified in ``t``, so the periodic sides are
no boundary at all).  That changes ``mesh.p``/``mesh.t`` and the boundary facets that the
moving mesh, the field transfer, the probes and the plots rely on, and a moved mesh would need
per-element geometry; the prolongation in the condensed structure keeps all of them.

Each DOF maps to its representative (``rep``, the smallest index of its class of identified
DOFs: corners of a doubly periodic box are one class of four), and each full DOF to its row in
the condensed system (``fold``; −1 for Dirichlet and pinned DOFs).  Per step this costs one
``bincount`` over the nonzeros of the condensed matrix and one per vector (no Python loop).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import MeshError
from .assembly import coded_saddle_matrix
from ..mesh.periodic import SIDE_PAIRS

__all__ = ["periodic_pairs", "representatives", "FoldedSystem"]


def _side_pairs(basis, names, lo_name, hi_name, along: int, tol: float):
    """(slave, master) DOF pairs of one side pair and one field (DOF names ``names``)."""
    lo_f, hi_f = basis.mesh.boundaries[lo_name], basis.mesh.boundaries[hi_name]
    out = []
    for name in names:
        dl = basis.get_dofs(lo_f).all(name) if name else basis.get_dofs(lo_f).all()
        dh = basis.get_dofs(hi_f).all(name) if name else basis.get_dofs(hi_f).all()
        sl, sh = basis.doflocs[along, dl], basis.doflocs[along, dh]
        ol, oh = np.argsort(sl, kind="stable"), np.argsort(sh, kind="stable")
        if len(dl) != len(dh) or np.any(np.abs(sl[ol] - sh[oh]) > tol):
            raise MeshError(f"periodic sides {lo_name!r} and {hi_name!r} do not match: {len(dl)} and {len(dh)} "
                            "DOFs at different places; the mesh needs matching nodes on both sides "
                            "(fluidem.mesh.periodic)")
        out.append(np.column_stack([dh[oh], dl[ol]]))
    return out


def periodic_pairs(space, axes) -> np.ndarray:
    """(slave, master) pairs ``(k, 2)`` of the ``[u, p]`` DOFs of ``space`` on the periodic sides.

    Parameters
    ----------
    space : FlowSpace
        On a straight mesh with the boundaries ``left``, ``right``, ``bottom``, ``top``.
    axes : tuple of {"x", "y"}
        Periodic axes (:func:`fluidem.mesh.periodic.periodic_axes`).

    Raises
    ------
    MeshError
        If the DOFs of a side pair do not match in position.
    """
    p = space.mesh.p
    tol = 1e-8 * float(max(np.ptp(p[0]), np.ptp(p[1])))
    parts = []
    for a in axes:
        lo, hi = SIDE_PAIRS[a]
        along = 1 if a == "x" else 0
        parts += _side_pairs(space.ub, ("u^1", "u^2"), lo, hi, along, tol)
        if not space.pair.pressure_discontinuous:
            parts += [space.n_u + q for q in _side_pairs(space.pb, (None,), lo, hi, along, tol)]
    return np.vstack(parts) if parts else np.zeros((0, 2), dtype=np.int64)


def representatives(n: int, pairs: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Representative ``(n,)`` of every DOF: the smallest index among the DOFs identified with it.

    Pairs with a ``fixed`` (Dirichlet) DOF are left out: a Dirichlet DOF keeps its own value
    (the corners of a wall between periodic sides carry the same value on both sides).
    """
    isfixed = np.zeros(n, dtype=bool)
    isfixed[fixed] = True
    keep = ~(isfixed[pairs[:, 0]] | isfixed[pairs[:, 1]])
    pr = pairs[keep]
    g = sp.coo_matrix((np.ones(len(pr)), (pr[:, 0], pr[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    return first[label]


class FoldedSystem:
    """The condensed saddle-point matrix ``Pᵀ K P`` on the free periodic unknowns, refilled per step.

    Same interface as :class:`fluidem.fluid.assembly.CondensedSystem`: ``matrix(uu_data)``
    returns the CSR matrix for velocity-block data on the assembler's pattern (structure
    fixed, so factorisations and symbolic analyses are reused) and ``update_divergence(B)``
    takes new divergence values.

    Parameters
    ----------
    assembler : VectorAssembler
    B : (n_p, n_u) sparse
        Divergence matrix.
    fold : (n_u + n_p,) int
        Row of every full DOF in the condensed system (that of its representative), −1 for
        fixed DOFs.
    n_free : int
        Size of the condensed system.
    """

    def __init__(self, assembler, B, fold: np.ndarray, n_free: int):
        K, B = coded_saddle_matrix(assembler, B, "coo")
        r, c, code = fold[K.row], fold[K.col], K.data
        keep = (r >= 0) & (c >= 0)
        r, c, code = r[keep], c[keep], code[keep]
        key = r.astype(np.int64) * n_free + c
        uniq, scatter = np.unique(key, return_inverse=True)
        rows, cols = np.divmod(uniq, n_free)
        self._indices = cols.astype(np.int32)
        self._indptr = np.searchsorted(rows, np.arange(n_free + 1)).astype(np.int32)
        self.shape = (n_free, n_free)
        self._nnz = len(uniq)
        uu = code > 0
        self._uu_dst, self._uu_src = scatter[uu], code[uu].astype(np.int64) - 1
        self._b_dst, self._b_src = scatter[~uu], (-code[~uu]).astype(np.int64) - 1
        self._B_indptr, self._B_indices = B.indptr.copy(), B.indices.copy()
        self._const = np.bincount(self._b_dst, weights=B.data[self._b_src], minlength=self._nnz)

    def matrix(self, uu_data: np.ndarray) -> sp.csr_matrix:
        data = self._const + np.bincount(self._uu_dst, weights=uu_data[self._uu_src], minlength=self._nnz)
        return sp.csr_matrix((data, self._indices, self._indptr), shape=self.shape)

    def update_divergence(self, B) -> bool:
        """Take new values of ``B`` (same structure); ``False`` if the structure differs."""
        B = sp.csr_matrix(B)
        B.sum_duplicates()
        if not (np.array_equal(B.indptr, self._B_indptr) and np.array_equal(B.indices, self._B_indices)):
            return False
        self._const = np.bincount(self._b_dst, weights=B.data[self._b_src], minlength=self._nnz)
        return True
