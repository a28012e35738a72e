"""Velocity/pressure finite element spaces on a mesh, boundary degrees of freedom, point values.

The unknown vector is ``x = [u, p]``: ``n_u`` velocity coefficients first (scikit-fem's
``ElementVector`` numbering), then ``n_p`` pressure coefficients.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Sequence

import numpy as np
import scipy.sparse as sp
from skfem import Basis, CellBasis, ElementVector, MeshTri2
from skfem.assembly.basis.abstract_basis import AbstractBasis

from .elements import ElementPair, element_pair

__all__ = ["FlowSpace", "VelocityBC", "RigidMotion"]


class MovedBasis(CellBasis):
    """A scikit-fem ``CellBasis`` on moved nodes whose basis values are computed on first use.

    The geometry map, the DOF locations and ``dx`` (``|det DF| w``, (n_elements, n_qp)) are
    computed at construction as ``CellBasis`` does; ``basis`` (the global basis values and
    gradients at the quadrature points, a list of ``Nbfun`` tuples) only when read.  The
    assembly of a moving mesh (:class:`fluidem.fluid.assembly.VectorAssembler`) takes the
    gradients from the affine map and reference values, so on most steps the list is never built.

    Parameters
    ----------
    mesh : skfem.MeshTri
    elem : skfem.Element
    quadrature : (X (2, n_qp), W (n_qp,))
        Reference points and weights.
    dofs : skfem.Dofs
        The DOF numbering (shared with the basis on the unmoved mesh).
    """

    def __init__(self, mesh, elem, quadrature, dofs):
        AbstractBasis.__init__(self, mesh, elem, None, None, quadrature, mesh.refdom, dofs, False)
        self.tind = None
        self.nelems = mesh.nelements
        # as CellBasis.__init__
        self.dx = np.abs(self.mapping.detDF(self.X)) * np.broadcast_to(self.W, (self.nelems, self.W.shape[-1]))

    @cached_property
    def basis(self):
        return [self.elem.gbasis(self.mapping, self.X, j) for j in range(self.Nbfun)]


@dataclass(frozen=True)
class RigidMotion:
    """Rigid-body velocity U + ω × (x − X) on an obstacle outline (no-slip on a moving body).

    ``velocity`` (2,) in length/time, ``omega`` in rad/time, ``center`` (2,) in length.
    Both may be callables of time ``t``.
    """

    velocity: Sequence[float] | Callable = (0.0, 0.0)
    omega: float | Callable = 0.0
    center: Sequence[float] = (0.0, 0.0)
    #: ``(L_x, L_y)`` periods (``None``: not periodic): the arm ``x − X`` is taken to the
    #: nearest image of X (a body across a periodic side, :mod:`fluidem.mesh.seam`)
    period: tuple = (None, None)

    def __call__(self, x, y, t):
        U = np.asarray(self.velocity(t) if callable(self.velocity) else self.velocity, dtype=float)
        om = float(self.omega(t) if callable(self.omega) else self.omega)
        cx, cy = self.center
        dx, dy = np.asarray(x, dtype=float) - cx, np.asarray(y, dtype=float) - cy
        Lx, Ly = self.period
        if Lx:
            dx = dx - Lx * np.round(dx / Lx)
        if Ly:
            dy = dy - Ly * np.round(dy / Ly)
        return np.array([U[0] - om * dy, U[1] + om * dx])


@dataclass(frozen=True)
class VelocityBC:
    """Dirichlet condition on the velocity of one or more named boundaries.

    Parameters
    ----------
    boundary : str or sequence of str
        Boundary names of the mesh (``mesh.boundaries``).
    value : (ux, uy), callable ``(x, y, t) -> (2, n)`` array, or :class:`RigidMotion`
        Prescribed velocity; ``(0, 0)`` is no-slip on a fixed wall.
    components : tuple of int
        Which velocity components are prescribed: ``(0, 1)`` both, ``(1,)`` only the normal
        component of a horizontal wall (free slip / symmetry), ``(0,)`` of a vertical one.
    """

    boundary: str | Sequence[str]
    value: object = (0.0, 0.0)
    components: tuple = (0, 1)

    @property
    def names(self) -> tuple:
        return (self.boundary,) if isinstance(self.boundary, str) else tuple(self.boundary)

    def evaluate(self, xy: np.ndarray, t: float) -> np.ndarray:
        """Velocity at points ``xy`` (2, n) and time ``t``, shape (2, n)."""
        if callable(self.value):
            out = np.asarray(self.value(xy[0], xy[1], t), dtype=float)
            return np.broadcast_to(out, (2, xy.shape[1]))
        return np.broadcast_to(np.asarray(self.value, dtype=float)[:, None], (2, xy.shape[1]))


class FlowSpace:
    """Bases and degree-of-freedom bookkeeping for one mesh and one element pair.

    Parameters
    ----------
    mesh : skfem.MeshTri or skfem.MeshTri2
        With named boundaries (``mesh.boundaries``).  A :class:`skfem.MeshTri2` gives
        isoparametric (curved) geometry.
    element : str
        Element pair name, see :mod:`fluidem.fluid.elements`.
    """

    def __init__(self, mesh, element: str = "p2b", intorder: int | None = None):
        self.pair: ElementPair = element_pair(element)
        self.mesh = mesh
        self.curved = isinstance(mesh, MeshTri2)
        order = intorder or self.pair.quadrature_order
        self.ub = Basis(mesh, ElementVector(self.pair.velocity()), intorder=order)
        self.pb = Basis(mesh, self.pair.pressure(), quadrature=self.ub.quadrature)
        self.n_u = self.ub.N
        self.n_p = self.pb.N
        self._boundary_cache: dict = {}

    def moved(self, mesh) -> "FlowSpace":
        """The same space on ``mesh``: the same triangles with moved nodes (ALE).

        Shares the DOF numbering (scikit-fem ``Dofs``), the quadrature and the boundary DOF
        lists of this space; only the geometry map, ``dx`` and the DOF locations are recomputed
        (no facet or DOF search), the basis values when first read (:class:`MovedBasis`).

        Parameters
        ----------
        mesh : skfem.MeshTri
            With ``mesh.t`` equal to ``self.mesh.t`` (straight elements).

        Raises
        ------
        ValueError
            If the triangles differ or the mesh is curved.
        """
        if isinstance(mesh, MeshTri2) or self.curved:
            raise ValueError("FlowSpace.moved supports straight (MeshTri) meshes only")
        if mesh.t.shape != self.mesh.t.shape or not np.array_equal(mesh.t, self.mesh.t):
            raise ValueError("FlowSpace.moved needs the same triangles; build a new FlowSpace after a "
                             "re-triangulation")
        new = object.__new__(FlowSpace)
        new.pair, new.mesh, new.curved = self.pair, mesh, False
        try:
            new.ub = MovedBasis(mesh, self.ub.elem, self.ub.quadrature, self.ub.dofs)
            new.pb = MovedBasis(mesh, self.pb.elem, self.ub.quadrature, self.pb.dofs)
        except TypeError:  # a scikit-fem whose AbstractBasis takes other arguments: the full bases
            new.ub = Basis(mesh, self.ub.elem, quadrature=self.ub.quadrature, dofs=self.ub.dofs)
            new.pb = Basis(mesh, self.pb.elem, quadrature=self.ub.quadrature, dofs=self.pb.dofs)
        new.n_u, new.n_p = self.n_u, self.n_p
        new._boundary_cache = self._boundary_cache  # DOF lists depend on the connectivity only
        return new

    @property
    def n_dofs(self) -> int:
        return self.n_u + self.n_p

    @property
    def element(self) -> str:
        return self.pair.name

    @property
    def boundary_names(self) -> list:
        return sorted((self.mesh.boundaries or {}).keys())

    def _check_boundary(self, name):
        if name not in (self.mesh.boundaries or {}):
            raise ValueError(f"unknown boundary {name!r}; the mesh has {self.boundary_names}")

    def velocity_dofs(self, boundary: str, component: int) -> np.ndarray:
        """Velocity DOF indices of one component (0 = x, 1 = y) on a named boundary."""
        key = (boundary, component)
        if key not in self._boundary_cache:
            self._check_boundary(boundary)
            self._boundary_cache[key] = self.ub.get_dofs(boundary).all(f"u^{component + 1}")
        return self._boundary_cache[key]

    def dof_locations(self, dofs: np.ndarray) -> np.ndarray:
        """Coordinates (2, k) of velocity DOFs (on curved meshes: the mapped positions)."""
        return self.ub.doflocs[:, dofs]

    def rigid_test_vector(self, boundary: str, mode: str, center=(0.0, 0.0)) -> np.ndarray:
        """Velocity coefficient vector equal to a rigid mode on ``boundary`` and zero elsewhere.

        ``mode`` is ``"x"``, ``"y"`` (unit translations) or ``"rot"`` (e_z × (x − center)).
        Used to evaluate forces and torques as volume integrals of the residual
        (John 2004, Sec. 3; exact for rigid modes since they lie in the velocity space).
        """
        v = np.zeros(self.n_u)
        dx, dy = self.velocity_dofs(boundary, 0), self.velocity_dofs(boundary, 1)
        if mode == "x":
            v[dx] = 1.0
        elif mode == "y":
            v[dy] = 1.0
        elif mode == "rot":
            px, py = self.dof_locations(dx), self.dof_locations(dy)
            v[dx] = -(px[1] - center[1])
            v[dy] = py[0] - center[0]
        else:
            raise ValueError(f"mode must be 'x', 'y' or 'rot', got {mode!r}")
        return v

    def probe_matrix(self, points, field: str = "pressure") -> sp.csr_matrix:
        """Sparse matrix mapping coefficients to values at ``points`` (m, 2).

        A point on an element boundary (a vertex, say) belongs to several elements; for a
        discontinuous field the values of all of them are averaged.  Raises ``ValueError``
        for a point outside the fluid domain.
        """
        from ..mesh.transfer import basis_values_matrix, locate_all

        basis = self.pb if field == "pressure" else self.ub
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        cells, refs, owners = locate_all(self.mesh, pts.T)
        weights = np.bincount(owners, minlength=len(pts)).astype(float)
        return basis_values_matrix(basis, cells, refs, owners, len(pts), divisor=weights[owners], point_major=True)
