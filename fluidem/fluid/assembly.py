"""Fast re-assembly of the velocity-dependent terms and of the condensed saddle-point matrix.

Every time step needs the convection matrix for a new convecting velocity and the saddle-point
matrix restricted to the free DOFs.  scikit-fem assembles any form, but rebuilding the sparse
structure each step costs more than the arithmetic.  Here the element basis values at the
quadrature points are stored once, the sparsity pattern of the velocity block is fixed once
(with a scatter map from element entries to CSR data), and the free-DOF saddle-point matrix
keeps one structure whose data array is refilled in place.  Same quadrature, same numbers as
the scikit-fem forms in :mod:`fluidem.fluid.forms` (checked in the tests).

On a moving mesh whose connectivity is unchanged (nodes moved, no re-triangulation), the
pattern, the scatter maps and the condensed structure stay; only the basis values at the
quadrature points are refreshed (:meth:`VectorAssembler.update_geometry`) and the constant
forms (viscous, mass, divergence) are refilled from them (:meth:`VectorAssembler.viscous_data`,
:meth:`VectorAssembler.mass_data`, :class:`DivergencePattern`, :meth:`CondensedSystem.update_divergence`).

Vector basis functions of scikit-fem's ``ElementVector`` interleave components: local function
``k = 2 s + c`` is the scalar function ``s`` in component ``c``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["VectorAssembler", "CondensedSystem", "DivergencePattern", "coded_saddle_matrix"]


def csr_pattern(row_dofs: np.ndarray, col_dofs: np.ndarray, n_rows: int, n_cols: int):
    """CSR structure of an element matrix family and the map from element entries to it.

    Parameters
    ----------
    row_dofs : (n_row_local, n_elements) int
        Global row DOFs per element (scikit-fem's ``element_dofs`` layout).
    col_dofs : (n_col_local, n_elements) int
        Global column DOFs per element.
    n_rows, n_cols : int
        Matrix shape.

    Returns
    -------
    indptr : (n_rows + 1,) int32
    indices : (nnz,) int32
    scatter : (n_elements * n_row_local * n_col_local,) int
        Position in the CSR data of each element entry, element-major (``np.bincount(scatter,
        weights=local.ravel())`` sums element matrices ``local (n_elements, n_row_local,
        n_col_local)`` into the data array).
    """
    nr, nel = row_dofs.shape
    nc = col_dofs.shape[0]
    rows = np.broadcast_to(row_dofs.T[:, :, None], (nel, nr, nc)).ravel()
    cols = np.broadcast_to(col_dofs.T[:, None, :], (nel, nr, nc)).ravel()
    keys = rows.astype(np.int64) * n_cols + cols
    uniq, scatter = np.unique(keys, return_inverse=True)
    r, c = np.divmod(uniq, n_cols)
    indices = c.astype(np.int32)
    indptr = np.searchsorted(r, np.arange(n_rows + 1)).astype(np.int32)
    return indptr, indices, scatter


def affine_reference(basis, n: int | None = None):
    """Reference values of a scalar H1 element when ``basis`` maps every element affinely, else None.

    For an element whose global basis is the identity transformation of the reference one
    (scikit-fem's ``ElementH1.gbasis``: values φ̂(X̂), gradients DF⁻ᵀ ∇̂φ̂) on an affine map
    (``MappingAffine``, straight triangles) the values at the quadrature points are the same in
    every element and the gradients are the constant inverse Jacobian times the reference ones
    (:func:`affine_gradients`): no per-element basis evaluation is needed.

    Parameters
    ----------
    basis : skfem.CellBasis
        Of a scalar element or of ``ElementVector`` of one (then the scalar element's functions).
    n : int, optional
        Number of scalar functions (default: ``basis.Nbfun``, for a scalar basis).

    Returns
    -------
    (phi (n, n_qp), dphi (n, 2, n_qp)) or None
    """
    from skfem import ElementVector
    from skfem.element import ElementH1
    from skfem.mapping import MappingAffine

    elem = basis.elem.elem if isinstance(basis.elem, ElementVector) else basis.elem
    if not (isinstance(basis.mapping, MappingAffine) and basis.tind is None and isinstance(elem, ElementH1)
            and type(elem).gbasis is ElementH1.gbasis and basis.X.ndim == 2):
        return None
    n = basis.Nbfun if n is None else n
    vals = [elem.lbasis(basis.X, i) for i in range(n)]
    return np.array([v[0] for v in vals]), np.array([v[1] for v in vals])


def affine_gradients(invA: np.ndarray, dphi: np.ndarray) -> np.ndarray:
    """Global gradients (2, n_elements, n, n_qp) of reference gradients ``dphi`` (n, 2, n_qp) under
    affine maps with inverse Jacobians ``invA`` (2, 2, n_elements): ∂φ/∂x_d = Σ_i (DF⁻¹)_{id} ∂φ̂/∂X̂_i,
    the sum scikit-fem's ``ElementH1.gbasis`` forms, in the same order."""
    out = np.empty((2, invA.shape[2]) + dphi[:, 0].shape)
    tmp = np.empty(out.shape[1:])
    for d in range(2):  # in place: no temporaries of the full size beyond one
        np.multiply(invA[0, d][:, None, None], dphi[None, :, 0, :], out=out[d])
        np.multiply(invA[1, d][:, None, None], dphi[None, :, 1, :], out=tmp)
        out[d] += tmp
    return out


class VectorAssembler:
    """Element data of a vector basis and the CSR pattern of its velocity–velocity block.

    Parameters
    ----------
    ub : skfem.CellBasis
        Basis of ``ElementVector(e)`` with interleaved components.

    Attributes
    ----------
    indptr, indices : CSR structure of the (n_u, n_u) velocity block.
    nnz : int
    """

    def __init__(self, ub):
        nb = ub.Nbfun
        if nb % 2:
            raise ValueError("expected a 2D vector basis")
        self.n = ub.N
        self.ns = nb // 2
        self._set_geometry(ub)
        dofs = ub.element_dofs  # (nb, nel)
        self._element_dofs = dofs
        self.dofs_c = [dofs[c::2].T.copy() for c in range(2)]  # (nel, ns) per component
        self._gather = None  # scalar-entry sums (interleaved numbering only), see _interleaved_pattern
        if self.n % 2 == 0 and np.all(dofs[0::2] % 2 == 0) and np.array_equal(dofs[1::2], dofs[0::2] + 1):
            self._interleaved_pattern(dofs)
        else:
            self.indptr, self.indices, self._scatter = csr_pattern(dofs, dofs, self.n, self.n)
            self.nnz = len(self.indices)
        self._comp = np.arange(nb) % 2
        self._scal = np.arange(nb) // 2

    def _interleaved_pattern(self, dofs: np.ndarray) -> None:
        """The pattern from the scalar one when vector DOF 2k + c is component c of scalar DOF k.

        (scikit-fem's ``ElementVector`` numbering.)  The scalar pattern needs the distinct pairs of
        nel · ns² element entries instead of nel · (2 ns)²; each scalar entry (k, l) becomes the 2 × 2
        block (2k + c, 2l + d), and the CSR order is the one of the general construction.  Both the
        pattern and the grouping of element entries by scalar entry are counting sorts (scipy's COO to
        CSR conversion), not comparison sorts of all the keys: the whole assembler (pattern and element
        geometry) is built 1.5x and 1.7x faster on the systems of 100 and 300 settling polygons (149k and
        447k DOFs), the same arrays bit for bit (``benchmarks/bench_rebuild_setup.py``).
        """
        sd = (dofs[0::2] // 2).T  # (nel, ns) scalar DOFs
        nel, ns = sd.shape
        m = self.n // 2
        rows = np.broadcast_to(sd[:, :, None], (nel, ns, ns)).ravel()
        cols = np.broadcast_to(sd[:, None, :], (nel, ns, ns)).ravel()
        # the scalar pattern: the distinct (row, column) pairs in row-major order (a CSR built by a
        # counting sort over rows, each short row sorted alone: what np.unique of the keys row·m + column
        # gives, without sorting all nel·ns² keys), and the position of every element entry in it (a
        # search within its row)
        S = sp.csr_matrix((np.ones(len(rows), np.int32), (rows, cols)), shape=(m, m))  # summed, sorted
        sptr = S.indptr.astype(np.int64)
        n_uniq = S.nnz
        r = np.repeat(np.arange(m, dtype=np.int64), np.diff(sptr))
        q = S.indices.astype(np.int64)
        sinv = np.asarray(sp.csr_array((np.arange(n_uniq, dtype=np.int64), S.indices, S.indptr),
                                       shape=(m, m))[rows, cols])
        del S, rows, cols
        L = np.diff(sptr)[r]  # scalar row length of each scalar entry
        base = 4 * sptr[r] + 2 * (np.arange(n_uniq) - sptr[r])  # vector row 2k: 4 start + 2 offset
        self.nnz = 4 * n_uniq
        indptr = np.empty(self.n + 1, dtype=np.int64)
        indptr[0:-1:2] = 4 * sptr[:-1]
        indptr[1::2] = 4 * sptr[:-1] + 2 * np.diff(sptr)
        indptr[-1] = self.nnz
        indices = np.empty(self.nnz, dtype=np.int64)
        for c in range(2):
            for d in range(2):
                indices[base + 2 * c * L + d] = 2 * q + d
        self.indices = indices.astype(np.int32)
        self.indptr = indptr.astype(np.int32)
        b = base[sinv].reshape(nel, ns, 1, ns, 1)
        lj = 2 * L[sinv].reshape(nel, ns, 1, ns, 1)
        c = np.arange(2).reshape(1, 1, 2, 1, 1)
        d = np.arange(2).reshape(1, 1, 1, 1, 2)
        self._scatter = (b + c * lj + d).ravel()  # local entry (e, 2s + c, 2s' + d)
        # scalar element entries (e, s, s') summed per scalar entry by one sparse product whose rows
        # list their entries in element order (the order np.bincount sums them in: same numbers; the
        # conversion from COO is stable), and the vector entry of each scalar entry's block (row
        # component r, column component c)
        self._gather = sp.csr_matrix((np.ones(len(sinv)), (sinv, np.arange(len(sinv)))), shape=(n_uniq, len(sinv)))
        self._block_pos = {(r, c): base + 2 * r * L + c for r in range(2) for c in range(2)}

    def _set_geometry(self, ub) -> None:
        # scalar values/gradients in element-major layout: psi (nel, ns, nq), dpsi (2, nel, ns, nq)
        ref = affine_reference(ub, self.ns)
        if ref is None:
            self.psi = np.stack([np.asarray(ub.basis[2 * s][0])[0] for s in range(self.ns)], axis=1)
            self.dpsi = np.stack([ub.basis[2 * s][0].grad[0] for s in range(self.ns)], axis=2)
        else:
            phi, dphi = ref
            nel = ub.nelems
            if getattr(self, "psi", None) is None or self.psi.shape[0] != nel:
                self.psi = np.ascontiguousarray(np.broadcast_to(phi, (nel,) + phi.shape))
            self.dpsi = affine_gradients(ub.mapping.invA, dphi)
            if getattr(self, "_reference", None) is None:
                W = np.asarray(ub.W)
                self._reference = {
                    "phi": phi, "dphi": dphi, "W": W,
                    # ∫ φ̂_t φ̂_s and ∫ ∂_i φ̂_t ∂_j φ̂_s over the reference triangle (ns, ns), (2, 2, ns, ns)
                    "mass": np.einsum("q,tq,sq->ts", W, phi, phi),
                    "grad": np.einsum("q,tiq,sjq->ijts", W, dphi, dphi),
                }
            self._invA = np.asarray(ub.mapping.invA)  # (2, 2, nel)
            self._det = np.abs(np.asarray(ub.mapping.detA))  # (nel,)
        if ref is None:
            self._reference = None
        self.dx = np.asarray(ub.dx)  # (nel, nq)
        self.psi_dx = self.psi * self.dx[:, None, :]

    def update_geometry(self, ub) -> None:
        """Take the basis values of ``ub``: the same element DOFs on moved nodes.

        Keeps the pattern and the scatter maps; raises ``ValueError`` if the element DOFs of
        ``ub`` differ from those the pattern was built for (a re-triangulation needs a new
        assembler).
        """
        ed = ub.element_dofs
        if ed.shape != self._element_dofs.shape or ub.N != self.n or not np.array_equal(ed, self._element_dofs):
            raise ValueError("update_geometry needs the same element DOFs (same connectivity); "
                             "build a new VectorAssembler after a re-triangulation")
        self._set_geometry(ub)

    def _block_diagonal(self, S: np.ndarray) -> np.ndarray:
        """Pattern data of the vector operator with scalar element matrices ``S`` (nel, ns, ns) per component."""
        return self._from_blocks({(0, 0): S, (1, 1): S})

    def _from_blocks(self, blocks: dict) -> np.ndarray:
        """Pattern data (nnz,) of element matrices given by their component blocks.

        ``blocks[(r, c)]`` (nel, ns, ns) is the block of row component r and column component c
        (entry (e, s, s') couples test ψ_s e_r and trial ψ_s' e_c); absent blocks are zero.  With
        the interleaved numbering the blocks are summed on the scalar pattern (a quarter of the
        entries of the vector one, one sparse product for all blocks, the same block summed once)
        and placed in the vector data; the sums are those of :meth:`_scatter_local` on the full
        element matrices, bit for bit (same terms, same order).
        """
        if self._gather is None:
            nb = 2 * self.ns
            first = next(iter(blocks.values()))
            local = np.zeros((first.shape[0], nb, nb))
            for (r, c), X in blocks.items():
                local[:, r::2, c::2] = X
            return self._scatter_local(local)
        arrays, column = [], {}
        for key, X in blocks.items():
            j = next((k for k, A in enumerate(arrays) if A is X), None)
            if j is None:
                j = len(arrays)
                arrays.append(X)
            column[key] = j
        sums = self._gather @ np.stack([X.reshape(-1) for X in arrays], axis=1)  # (n_scalar_entries, k)
        data = np.zeros(self.nnz)
        for key, j in column.items():
            data[self._block_pos[key]] = sums[:, j]
        return data

    def _gradient_products(self, pairs) -> dict:
        """Element matrices P[(c, d)] (nel, ns, ns), entry (e, t, s) = ∫ ∂_c ψ_t ∂_d ψ_s, for ``pairs`` of (c, d).

        Straight triangles (affine map, constant inverse Jacobian J = DF⁻¹ and |det DF| per
        element): P_cd = |det DF| Σ_ij J_ic J_jd R_ij with the reference matrices
        R_ij = ∫ ∂_i φ̂_t ∂_j φ̂_s over the reference triangle (the same quadrature; the chain rule
        of :func:`affine_gradients` taken out of the sum over quadrature points), one small matrix
        product per pair.  Otherwise the quadrature sum on the element.
        """
        ref = self._reference
        out = {}
        for c, d in pairs:
            if ref is None:
                out[(c, d)] = np.matmul(self.dpsi[c] * self.dx[:, None, :], self.dpsi[d].transpose(0, 2, 1))
            else:
                J = self._invA
                coef = (self._det * J[:, c][:, None, :] * J[:, d][None, :, :]).reshape(4, -1).T  # (nel, (i, j))
                out[(c, d)] = (coef @ ref["grad"].reshape(4, -1)).reshape(-1, self.ns, self.ns)
        return out

    def mass_data(self) -> np.ndarray:
        """Pattern data of the velocity mass u · v (:func:`fluidem.fluid.forms.mass`), (nnz,).

        Straight triangles: |det DF| times the reference mass matrix (same quadrature)."""
        if self._reference is not None:
            return self._block_diagonal(self._det[:, None, None] * self._reference["mass"])
        return self._block_diagonal(np.matmul(self.psi_dx, self.psi.transpose(0, 2, 1)))

    def viscous_data(self) -> np.ndarray:
        """Pattern data of ∇u : ∇v (:func:`fluidem.fluid.forms.viscous`, multiply by ν), (nnz,)."""
        P = self._gradient_products([(0, 0), (1, 1)])
        return self._block_diagonal(P[(0, 0)] + P[(1, 1)])

    def stress_data(self) -> np.ndarray:
        """Pattern data of 2 ε(u) : ε(v) = ∇u : ∇v + ∇uᵀ : ∇v (:func:`fluidem.fluid.forms.viscous_stress`,
        multiply by ν), (nnz,): the Laplacian blocks plus, for test φ_t e_d and trial φ_s e_c,
        ∫ ∂_c φ_t ∂_d φ_s."""
        # P[(c, d)] (e, t, s) = ∫ ∂_c φ_t ∂_d φ_s; the Laplacian part S = P[(0, 0)] + P[(1, 1)]
        P = self._gradient_products([(c, d) for c in range(2) for d in range(2)])
        S = P[(0, 0)] + P[(1, 1)]
        # block (row d, column c): δ_cd S + P[(c, d)]
        return self._from_blocks({(0, 0): S + P[(0, 0)], (1, 1): S + P[(1, 1)], (1, 0): P[(0, 1)], (0, 1): P[(1, 0)]})

    # -- data arrays on the fixed pattern ----------------------------------------------
    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """CSR matrix of the velocity block from a data array on the pattern (no copy)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))

    def pattern_data(self, A) -> np.ndarray:
        """Values of a sparse matrix ``A`` (its pattern contained in ours) on our pattern."""
        A = sp.csr_matrix(A)
        A.sum_duplicates()
        out = np.zeros(self.nnz)
        rows = np.repeat(np.arange(self.n), np.diff(A.indptr))
        keys = rows.astype(np.int64) * self.n + A.indices
        pat_rows = np.repeat(np.arange(self.n), np.diff(self.indptr)).astype(np.int64)
        pat_keys = pat_rows * self.n + self.indices
        pos = np.searchsorted(pat_keys, keys)
        if np.any(pat_keys[np.minimum(pos, self.nnz - 1)] != keys):
            raise ValueError("matrix has entries outside the velocity pattern")
        out[pos] = A.data
        return out

    def _scatter_local(self, local: np.ndarray) -> np.ndarray:
        """Sum element matrices ``local`` (nel, nb, nb) into pattern data (nnz,)."""
        return np.bincount(self._scatter, weights=local.ravel(), minlength=self.nnz)

    # -- fields at quadrature points ----------------------------------------------------
    def values(self, u: np.ndarray) -> np.ndarray:
        """Velocity at quadrature points, (2, nel, nq), from coefficients ``u`` (n_u,)."""
        return np.stack([np.einsum("es,esq->eq", u[d], self.psi) for d in self.dofs_c])

    def gradients(self, u: np.ndarray) -> np.ndarray:
        """Velocity gradient ∂u_a/∂x_b at quadrature points, (2, 2, nel, nq)."""
        return np.stack([np.einsum("es,besq->beq", u[d], self.dpsi) for d in self.dofs_c])

    # -- forms ------------------------------------------------------------------------
    def convection(self, b: np.ndarray, a: np.ndarray | None = None) -> np.ndarray:
        """Pattern data of ((b·∇)u)·v, plus the Newton part ((u·∇)a)·v if ``a`` is given.

        ``b``, ``a`` are velocity coefficient vectors (n_u,).  Same integrand as
        :func:`fluidem.fluid.forms.convection` / ``convection_newton``.
        """
        bq = self.values(b)
        bgrad = np.einsum("cesq,ceq->esq", self.dpsi, bq)  # (b·∇)ψ_s
        S = np.matmul(self.psi_dx, bgrad.transpose(0, 2, 1))  # (nel, ns, ns): ∫ ψ_i (b·∇ψ_j)
        if a is None:
            return self._block_diagonal(S)
        G = self.gradients(a)  # (2, 2, nel, nq)
        blocks = {}
        for ca in range(2):
            for cb in range(2):
                # ∫ ψ_i ψ_j ∂a_ca/∂x_cb, row component ca, column component cb
                Mab = np.matmul(self.psi_dx * G[ca, cb][:, None, :], self.psi.transpose(0, 2, 1))
                blocks[(ca, cb)] = S + Mab if ca == cb else Mab
        return self._from_blocks(blocks)

    def divergence_mass(self, c: np.ndarray) -> np.ndarray:
        """Pattern data of (div c) u · v for velocity coefficients ``c`` (n_u,), (nnz,).

        Added to the convection ((c·∇)u)·v it makes the divergence form div(u ⊗ c) · v, whose
        integral against a constant v is the flux of c through the boundary (the conservative
        ALE form of :class:`fluidem.fluid.navier_stokes.BDF2Stepper`).
        """
        G = self.gradients(c)
        return self._block_diagonal(np.matmul(self.psi_dx * (G[0, 0] + G[1, 1])[:, None, :],
                                              self.psi.transpose(0, 2, 1)))

    def divergence_mass_vector(self, c: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Load vector (div c) a · v, (n_u,), for velocity coefficients ``c`` and ``a`` (n_u,)."""
        G = self.gradients(c)
        w = (G[0, 0] + G[1, 1]) * self.dx  # (nel, nq)
        aq = self.values(a)
        out = np.zeros(self.n)
        for k in range(2):
            loc = np.einsum("esq,eq->es", self.psi, w * aq[k])
            out += np.bincount(self.dofs_c[k].ravel(), weights=loc.ravel(), minlength=self.n)
        return out

    def convection_vector(self, a: np.ndarray, b: np.ndarray | None = None,
                          b_values: np.ndarray | None = None) -> np.ndarray:
        """Load vector ((b·∇)a)·v, shape (n_u,) (b = a if omitted); ``b_values`` (2, nel, nq), if
        given, is :meth:`values` of b, already evaluated (e.g. for a CFL number)."""
        G = self.gradients(a)
        bq = self.values(a if b is None else b) if b_values is None else b_values
        conv = np.einsum("abeq,beq->aeq", G, bq)  # ((b·∇)a)_a at quadrature points
        out = np.zeros(self.n)
        for c in range(2):
            loc = np.einsum("esq,eq->es", self.psi_dx, conv[c])
            out += np.bincount(self.dofs_c[c].ravel(), weights=loc.ravel(), minlength=self.n)
        return out


def coded_saddle_matrix(assembler: VectorAssembler, B, format: str = "csr"):
    """The saddle-point structure [[K_uu, Bᵀ], [B, 0]] with entry codes instead of values.

    Velocity-block entry j of the assembler's pattern carries the code j + 1, entry j of ``B``
    (summed CSR) the code −(j + 1) in both ``B`` and ``Bᵀ``: a condensed, folded or bordered
    system built from it knows where each of its entries comes from and is refilled per step
    by gathering (or summing) pattern data.

    Returns
    -------
    K : sparse matrix (n_u + n_p, n_u + n_p) in ``format``
    B : (n_p, n_u) csr_matrix
        ``B`` with duplicates summed (the numbering of the codes).
    """
    n_p = B.shape[0]
    B = sp.csr_matrix(B)
    B.sum_duplicates()
    code_uu = assembler.matrix(np.arange(1, assembler.nnz + 1, dtype=float))
    code_B = sp.csr_matrix((-np.arange(1, B.nnz + 1, dtype=float), B.indices, B.indptr), shape=B.shape)
    K = sp.bmat([[code_uu, code_B.T], [code_B, sp.csr_matrix((n_p, n_p))]], format=format)
    return K, B


class CondensedSystem:
    """The saddle-point matrix [[K_uu, Bᵀ], [B, 0]] restricted to free DOFs, refilled in place.

    Parameters
    ----------
    assembler : VectorAssembler
        Provides the velocity-block pattern.
    B : (n_p, n_u) sparse
        Divergence matrix (constant).
    free : (n_free,) int
        Free DOF indices into ``[u, p]``.

    ``matrix(uu_data)`` returns the free-DOF CSR matrix for velocity-block data on the pattern;
    its structure never changes, so factorisations and symbolic analyses can be reused.
    """

    def __init__(self, assembler: VectorAssembler, B, free: np.ndarray):
        K, B = coded_saddle_matrix(assembler, B, "csr")
        Kff = K[free][:, free].tocsr()
        Kff.sort_indices()
        codes = Kff.data
        self._uu_pos = np.flatnonzero(codes > 0)
        self._uu_src = codes[self._uu_pos].astype(np.int64) - 1
        b_pos = np.flatnonzero(codes < 0)
        const = np.zeros(len(codes))
        self._b_pos = b_pos
        self._b_src = (-codes[b_pos]).astype(np.int64) - 1
        const[b_pos] = B.data[self._b_src]
        self._const = const
        self._B_indptr, self._B_indices = B.indptr.copy(), B.indices.copy()
        self._indices = Kff.indices
        self._indptr = Kff.indptr
        self.shape = Kff.shape

    def matrix(self, uu_data: np.ndarray) -> sp.csr_matrix:
        data = self._const.copy()
        data[self._uu_pos] = uu_data[self._uu_src]
        return sp.csr_matrix((data, self._indices, self._indptr), shape=self.shape)

    def update_divergence(self, B) -> bool:
        """Take new values of the divergence matrix ``B`` (same structure as at construction).

        Returns ``False`` (and changes nothing) if the CSR structure of ``B`` differs; the
        caller then builds a new :class:`CondensedSystem`.
        """
        B = sp.csr_matrix(B)
        B.sum_duplicates()
        if not (np.array_equal(B.indptr, self._B_indptr) and np.array_equal(B.indices, self._B_indices)):
            return False
        self._const[self._b_pos] = B.data[self._b_src]
        return True


class DivergencePattern:
    """CSR structure and scatter map of the divergence matrix B (n_p, n_u), −∫ q div v.

    Parameters
    ----------
    assembler : VectorAssembler
        Velocity basis values (refreshed by its ``update_geometry``).
    pb : skfem.CellBasis
        Pressure basis on the same mesh and quadrature.

    ``matrix(pb)`` refills B from the current basis values (same numbers as
    ``asm(forms.divergence, ub, pb)`` to round-off); the structure is sorted CSR, fixed
    while the connectivity is.
    """

    def __init__(self, assembler: VectorAssembler, pb):
        self.va = assembler
        self.n_p = pb.N
        pd = pb.element_dofs  # (npl, nel)
        ud = assembler._element_dofs  # (nb, nel)
        self.indptr, self.indices, self._scatter = csr_pattern(pd, ud, self.n_p, assembler.n)
        self.nnz = len(self.indices)
        self._npl = pd.shape[0]
        self._reference = None  # reference divergence matrices on straight triangles (first matrix)

    def matrix(self, pb) -> sp.csr_matrix:
        """B on the current geometry: B[i, 2s+c] = −∫ q_i ∂ψ_s/∂x_c, (n_p, n_u) CSR."""
        va = self.va
        ref = affine_reference(pb, self._npl) if va._reference is not None else None
        nel = va.dx.shape[0]
        local = np.empty((nel, self._npl, 2 * va.ns))
        if ref is None:
            q = np.stack([np.asarray(pb.basis[i][0]) for i in range(self._npl)], axis=1)  # (nel, npl, nq)
            q_dx = q * va.dx[:, None, :]
            for c in range(2):
                local[:, :, c::2] = -np.matmul(q_dx, va.dpsi[c].transpose(0, 2, 1))
        else:
            # straight triangles: −|det DF| Σ_i J_ic D_i with D_i = ∫ q̂_p ∂_i φ̂_s on the reference
            # triangle (same quadrature), J = DF⁻¹ (see VectorAssembler._gradient_products)
            r = va._reference
            if self._reference is None:
                self._reference = np.einsum("q,pq,siq->ips", r["W"], ref[0], r["dphi"])  # (2, npl, ns)
            J = va._invA
            for c in range(2):
                coef = -(va._det * J[:, c]).T  # (nel, 2)
                local[:, :, c::2] = (coef @ self._reference.reshape(2, -1)).reshape(nel, self._npl, va.ns)
        data = np.bincount(self._scatter, weights=local.ravel(), minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_p, va.n))
