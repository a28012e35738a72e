"""The saddle-point system of a fluid with free rigid bodies in it, one matrix for both.

Combined (fictitious-domain-free, body-fitted) formulation of Glowinski, Pan, Hesla & Joseph
(1999, Int. J. Multiphase Flow 25) and Hu, Patankar & Zhu (2001, J. Comput. Phys. 169): the
velocity on the outline of a free body k is its rigid motion U_k + ω_k e_z × (x − X_k), so
the outline velocity DOFs are not unknowns but the prolongation Π V of the body velocities
V = (U_x, U_y, ω)_k; the test functions are the free fluid DOFs and the rigid modes.  With the
fluid's discrete residual r(x) on all DOFs (kinematic, no conditions applied) and
x = S z_F + Π V + x_D (S: the free DOFs, x_D: the Dirichlet data of walls and prescribed
bodies, zero on free-body outlines), the equations are

    Sᵀ r(x) = 0                                    (fluid: momentum and continuity)
    Πᵀ r_u(x) + (m_k/ρ) D_t V − F_ext,k/ρ = 0       (bodies: Newton–Euler)

where Πᵀ = R is the rigid-mode operator (:class:`fluidem.fluid.forces.RigidModes`), so
Πᵀ r_u = −F_hyd/ρ is the hydrodynamic load by the volume-integral definition (John 2004), and
D_t the BDF2 derivative of the body velocity (the fluid's).  Linearised as the fluid is, the
system matrix is Tᵀ K T + blockdiag(0, M_b a0/(ρ Δt)) with T = [S | Π]: the condensed fluid
matrix bordered by 3 rows and columns per free body.  Its structure is fixed per
connectivity (refilled each step like :class:`fluidem.fluid.assembly.CondensedSystem`), so
a lagged LU serves the coupled system as it serves the fluid alone.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..fluid.assembly import coded_saddle_matrix

__all__ = ["RigidBodySystem"]


def _expand(indptr: np.ndarray, rows: np.ndarray):
    """For each of ``rows`` (m,), the positions of its entries in a CSR structure: (owner, position)."""
    cnt = indptr[rows + 1] - indptr[rows]
    owner = np.repeat(np.arange(len(rows)), cnt)
    start = np.repeat(indptr[rows] - (np.cumsum(cnt) - cnt), cnt)
    return owner, start + np.arange(int(cnt.sum()))


class RigidBodySystem:
    """Coupled fluid–body matrix ``Tᵀ K T + body mass`` on the unknowns z = [free fluid DOFs, V].

    Parameters
    ----------
    problem : FlowProblem
        The flow problem (its velocity-block pattern, divergence matrix and condensed unknowns,
        folded onto one unknown per periodic pair).  The outline DOFs of the free bodies are
        Dirichlet DOFs of the problem (so not among its free DOFs); their values are ignored.
    rigid : RigidModes
        Rigid-mode operator of *all* bodies of the problem (rows 3k, 3k+1, 3k+2), whose data
        it refills when the mesh moves.
    bodies : (n_bodies_free,) int
        Which bodies of ``rigid`` are free.

    Attributes
    ----------
    n_fluid, n_bodies, shape : sizes; ``z = [z_F (n_fluid), V (3 n_bodies)]``.
    """

    def __init__(self, problem, rigid, bodies):
        assembler, B = problem.assembler, problem.B
        self.problem = problem
        self.rigid = rigid
        self.bodies = np.asarray(bodies, dtype=np.int64)
        n_u, n_p = assembler.n, B.shape[0]
        n = n_u + n_p
        self.n_u = n_u
        fold = problem.condensed_index()
        self._fold_src = np.flatnonzero(fold >= 0)
        self._fold_dst = fold[self._fold_src]
        self.free = np.asarray(problem.free, dtype=np.int64)  # one representative per unknown
        self.n_fluid = len(self.free)
        self.n_bodies = len(self.bodies)
        nz = self.n_fluid + 3 * self.n_bodies
        self.shape = (nz, nz)
        # rows of R belonging to the free bodies, in the order of ``bodies``
        R = rigid.matrix
        self._rrows = (3 * self.bodies[:, None] + np.arange(3)[None, :]).ravel()
        # T (n, nz) with data = weight source: 0 -> 1.0, 1 + j -> R.data[j]
        rr, rpos = _expand(R.indptr, self._rrows)          # entries of R in the free bodies' rows
        t_rows = np.concatenate([self._fold_src, R.indices[rpos]])
        t_cols = np.concatenate([self._fold_dst, self.n_fluid + rr])
        t_src = np.concatenate([np.zeros(len(self._fold_src), np.int64), 1 + rpos])
        T = sp.csr_matrix((np.arange(1, len(t_rows) + 1, dtype=float), (t_rows, t_cols)), shape=(n, nz))
        T.sort_indices()
        t_src = t_src[T.data.astype(np.int64) - 1].astype(np.int32)
        # K coded: uu entry j -> +(j+1), B entry j -> −(j+1) (in B and Bᵀ)
        K, B = coded_saddle_matrix(assembler, B, "coo")
        self._B_indptr, self._B_indices = B.indptr.copy(), B.indices.copy()
        self._map_entries(K, T, t_src, nz)
        # the free bodies' rows of R as positions into its data (the structure is fixed per
        # connectivity, the data refilled as the mesh moves), and their outline DOFs
        self._r_pos = rpos
        self._r_cols = R.indices[rpos]
        self._r_rows = rr
        self._outline = np.unique(self._r_cols)

    #: K entries expanded at a time when the maps are built (bounds the temporaries: ~80 bytes an entry)
    CHUNK = 1 << 20

    def _map_entries(self, K, T, t_src, nz: int):
        """The structure of Tᵀ K T + body diagonal and where each of its entries comes from.

        Every entry (r, c) of ``K`` (coded COO) contributes to (T.col of row r, T.col of row c) for every
        pair of T entries in those rows, with the weight w[t_src] of each.  The structure is the pattern
        product Tᵀ |K| T (sparse, so only the result's entries are held); the contributions are expanded
        ``CHUNK`` K entries at a time into 4-byte maps, in their order, so that the sums of
        :meth:`matrix` are taken in the same order whatever the chunk size.  This keeps the peak of the
        construction near the maps kept (100 settling bodies, 159k DOFs: 305 MiB against 737 MiB when all
        contributions were expanded and sorted at once; the same matrix bit for bit).
        """
        pattern = sp.csr_matrix((np.ones(K.nnz), (K.row, K.col)), shape=K.shape)
        T_pattern = sp.csr_matrix((np.ones(T.nnz), T.indices, T.indptr), shape=T.shape)
        S = (T_pattern.T.tocsr() @ pattern @ T_pattern).tocsr()
        del pattern
        body = np.arange(self.n_fluid, nz)
        S = (S + sp.csr_matrix((np.ones(len(body)), (body, body)), shape=(nz, nz))).tocsr()
        S.sort_indices()
        self._indices = S.indices.astype(np.int32)
        self._indptr = S.indptr.astype(np.int32)
        self._nnz = S.nnz
        keys = np.repeat(np.arange(nz, dtype=np.int64), np.diff(S.indptr)) * nz + S.indices
        del S
        self._diag_pos = np.searchsorted(keys, body.astype(np.int64) * nz + body)
        cnt = np.diff(T.indptr)
        per_entry = cnt[K.row].astype(np.int64) * cnt[K.col]
        m = int(per_entry.sum())
        del per_entry
        small = np.int32 if max(self._nnz, K.nnz) < 2**31 else np.int64
        scatter = np.empty(m, small)                     # target of every contribution
        entry = np.empty(m, small)                       # the K entry it comes from
        weighted = np.empty(m, bool)                     # a body mode on either side
        w_pos, w_rc = [], []
        off = 0
        for s0 in range(0, K.nnz, self.CHUNK):
            rows, cols = K.row[s0:s0 + self.CHUNK], K.col[s0:s0 + self.CHUNK]
            e1, p1 = _expand(T.indptr, rows)
            e2, p2 = _expand(T.indptr, cols[e1])
            q1 = p1[e2]
            k = len(e2)
            scatter[off:off + k] = np.searchsorted(keys, T.indices[q1].astype(np.int64) * nz + T.indices[p2])
            entry[off:off + k] = s0 + e1[e2]
            wr, wc = t_src[q1], t_src[p2]
            wt = (wr != 0) | (wc != 0)
            weighted[off:off + k] = wt
            w_pos.append(off + np.flatnonzero(wt))
            w_rc.append(np.stack([wr[wt], wc[wt]]))
            off += k
        del keys
        code = K.data[entry].astype(np.int64)            # uu entry j -> j + 1, B entry j -> −(j + 1)
        del entry
        uu = code > 0
        src = (np.where(uu, code, -code) - 1).astype(small)  # position in the uu pattern data or B.data
        del code
        # entries alone on their target with weight 1 (fluid rows and columns, no body mode: most of
        # them) are copied; the others are weighted and summed in their order (the same sums)
        hits = np.bincount(scatter, minlength=self._nnz)
        direct = ~weighted & (hits[scatter] == 1)
        del hits
        # the maps kept index with intp (numpy converts other index types on every use: +30 % time)
        self._direct_uu = (scatter[direct & uu].astype(np.intp), src[direct & uu].astype(np.intp))
        self._direct_B = (scatter[direct & ~uu].astype(np.intp), src[direct & ~uu].astype(np.intp))
        rest = np.flatnonzero(~direct)
        del direct
        self._rest_scatter = scatter[rest].astype(np.intp)
        rest_uu = uu[rest]
        self._rest_uu = np.flatnonzero(rest_uu)
        self._rest_B = np.flatnonzero(~rest_uu)
        rest_src = src[rest].astype(np.intp)
        self._rest_src_uu, self._rest_src_B = rest_src[self._rest_uu], rest_src[self._rest_B]
        self._wr, self._wc = np.zeros((2, len(rest)), np.intp)    # weight sources, 0: weight 1
        if w_pos:
            at = np.searchsorted(rest, np.concatenate(w_pos))    # every weighted entry is in ``rest``
            self._wr[at], self._wc[at] = np.concatenate(w_rc, axis=1)

    # -- matrix -------------------------------------------------------------------------------
    def _weights(self) -> np.ndarray:
        return np.concatenate([[1.0], self.rigid.matrix.data])

    def matrix(self, uu_data: np.ndarray, body_diagonal: np.ndarray) -> sp.csr_matrix:
        """The coupled matrix for velocity-block data ``uu_data`` and the body rows' own diagonal
        ``body_diagonal`` (3 n_bodies,), e.g. m a0/(ρ Δt); the divergence is the problem's current one."""
        B = sp.csr_matrix(self.problem.B)
        B.sum_duplicates()
        if not (np.array_equal(B.indptr, self._B_indptr) and np.array_equal(B.indices, self._B_indices)):
            raise ValueError("RigidBodySystem.matrix: B's structure changed; build a new system")
        w = self._weights()
        vals = np.empty(len(self._rest_scatter))
        vals[self._rest_uu] = uu_data[self._rest_src_uu]
        vals[self._rest_B] = B.data[self._rest_src_B]
        vals *= w[self._wr] * w[self._wc]
        data = np.bincount(self._rest_scatter, weights=vals, minlength=self._nnz)
        for (dst, src), values in ((self._direct_uu, uu_data), (self._direct_B, B.data)):
            data[dst] = values[src]
        data[self._diag_pos] += body_diagonal
        return sp.csr_matrix((data, self._indices, self._indptr), shape=self.shape)

    # -- vectors ------------------------------------------------------------------------------
    def restrict(self, r: np.ndarray) -> np.ndarray:
        """Tᵀ r (nz,) of a full residual ``r`` (n_u + n_p,): condensed rows (periodic pairs summed),
        then Πᵀ r_u per free body."""
        rF = np.bincount(self._fold_dst, weights=r[self._fold_src], minlength=self.n_fluid)
        w = self.rigid.matrix.data[self._r_pos]
        rV = np.bincount(self._r_rows, weights=w * r[self._r_cols], minlength=3 * self.n_bodies)
        return np.concatenate([rF, rV])

    def split(self, z: np.ndarray):
        """(z_F, V (n_bodies, 3)) of a coupled vector."""
        return z[: self.n_fluid], z[self.n_fluid:].reshape(-1, 3)

    def prolong(self, z: np.ndarray, x_dirichlet: np.ndarray) -> np.ndarray:
        """Full ``x`` = S z_F + Π V + x_D for a coupled vector ``z`` and the Dirichlet part ``x_D`` (n,)."""
        x = np.array(x_dirichlet, dtype=float, copy=True)
        zF, V = self.split(z)
        x[self._fold_src] = zF[self._fold_dst]
        w = self.rigid.matrix.data[self._r_pos]
        u = np.bincount(self._r_cols, weights=w * V.ravel()[self._r_rows], minlength=self.n_u)
        x[self._outline] = u[self._outline]
        return x

    def gather(self, x: np.ndarray, V) -> np.ndarray:
        """The coupled vector of a full ``x`` and body velocities ``V`` (n_bodies, 3)."""
        return np.concatenate([x[self.free], np.asarray(V, float).ravel()])
