r"""Manufactured Stokes, Oseen and unsteady saddle-point systems on the unit square.

The test problem of the solver tests and benchmarks: the Stokes equations
:math:`-\nu \Delta u + \nabla p = f`, :math:`\operatorname{div} u = 0` on
:math:`\Omega = (0, 1)^2` with the manufactured solution ("curl of a quartic bubble")

.. math::

    u = \operatorname{curl} \psi = (\partial_y \psi, -\partial_x \psi), \quad
    \psi(x, y) = g(x)\, g(y), \quad g(s) = s^2 (1 - s)^2, \qquad
    p = x^3 + y^3 - \tfrac12,

and :math:`f = -\nu \Delta u + \nabla p` computed from it.  :math:`u` vanishes on the
whole boundary of the square, :math:`\operatorname{div} u = 0` exactly.

Boundary conditions: ``outflow=True`` puts :math:`u = 0` on three sides and the exact
traction :math:`\nu \partial_n u - p n` on :math:`x = 1` (natural boundary, ``K``
non-singular); ``outflow=False`` puts :math:`u = 0` on the whole boundary and pins one
pressure DOF.  Options add terms to the velocity block ``A`` (the load then no longer
belongs to the manufactured solution; the systems are for solver tests):

* ``peclet > 0``: Oseen convection :math:`(w \cdot \nabla) u` by ``peclet *``
  :func:`wind`, :math:`w = \operatorname{curl}(\sin^2 \pi x \sin^2 \pi y)`;
* ``newton=True``: also the Newton reaction term :math:`(u \cdot \nabla) w` (a
  Navier--Stokes Jacobian at the state ``peclet * wind``);
* ``dt``: :math:`(\alpha/\Delta t) M_u` (one backward-Euler/BDF step).

With the default pair "p2b" (P2+bubble / discontinuous P1) the system has about
:math:`18 m^2` DOFs on an ``m x m`` grid; the velocity L2 error is :math:`O(h^3)`, the
pressure error :math:`O(h^2)`.

Examples
--------
>>> P = saddle_point_problem(4)
>>> P.K.shape, P.n_u
((272, 272), 176)
>>> from fluidem.fluid.solvers import DirectSolver
>>> eu, ep = l2_errors(P, DirectSolver().factorize(P.K).solve(P.b))
>>> bool(eu < 1e-3 and ep < 5e-2)
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import (
    Basis,
    BilinearForm,
    ElementVector,
    FacetBasis,
    Functional,
    LinearForm,
    MeshTri,
)
from skfem.helpers import ddot, div, dot, grad, mul

from ..fluid.elements import element_pair

__all__ = ["SaddlePointProblem", "saddle_point_problem", "exact_velocity", "exact_pressure",
           "wind", "wind_gradient", "l2_errors"]


# --------------------------------------------------------------------- the solution
def _g(s):
    """g(s) = s^2 (1 - s)^2."""
    return s**2 * (1 - s) ** 2


def _g1(s):
    """g'(s)."""
    return 2 * s * (1 - s) * (1 - 2 * s)


def _g2(s):
    """g''(s)."""
    return 2 * (1 - 6 * s + 6 * s**2)


def _g3(s):
    """g'''(s)."""
    return 12 * (2 * s - 1)


def exact_velocity(x):
    """Manufactured velocity u = curl(g(x) g(y)) = (g(x) g'(y), -g'(x) g(y)).

    Parameters
    ----------
    x : (2, ...) float ndarray
        Points.

    Returns
    -------
    (2, ...) float ndarray
    """
    return np.array([_g(x[0]) * _g1(x[1]), -_g1(x[0]) * _g(x[1])])


def exact_pressure(x):
    """Manufactured pressure p = x^3 + y^3 - 1/2 (zero mean on the unit square).

    Parameters
    ----------
    x : (2, ...) float ndarray

    Returns
    -------
    (...) float ndarray
    """
    return x[0] ** 3 + x[1] ** 3 - 0.5


def wind(x):
    """Divergence-free convecting field curl(sin^2(pi x) sin^2(pi y)), (2, ...); zero on the
    boundary of the unit square."""
    sx, sy = np.sin(np.pi * x[0]), np.sin(np.pi * x[1])
    cx, cy = np.cos(np.pi * x[0]), np.cos(np.pi * x[1])
    return np.array([2 * np.pi * sx**2 * sy * cy, -2 * np.pi * sx * cx * sy**2])


def wind_gradient(x):
    """Gradient of :func:`wind`, ``G[i, j] = d wind_i / d x_j``, (2, 2, ...)."""
    s2x, s2y = np.sin(2 * np.pi * x[0]), np.sin(2 * np.pi * x[1])
    sx, sy = np.sin(np.pi * x[0]), np.sin(np.pi * x[1])
    p2 = np.pi**2
    return np.array([
        [p2 * s2x * s2y, 2 * p2 * sx**2 * np.cos(2 * np.pi * x[1])],
        [-2 * p2 * np.cos(2 * np.pi * x[0]) * sy**2, -p2 * s2x * s2y],
    ])


# --------------------------------------------------------------------- the system
@dataclass(frozen=True)
class SaddlePointProblem:
    """A condensed saddle-point system ``K x = b`` and what built it.

    Attributes
    ----------
    K : (n, n) CSR matrix
        ``[[A, B^T], [B, 0]]`` on the free DOFs, velocity first (``n = n_u + n_p``).
    b : (n,) float ndarray
        Right-hand side on the free DOFs.
    n_u : int
        Free velocity DOFs.
    Mp : (n_p, n_p) CSR matrix
        Pressure mass matrix on the free pressure DOFs.
    Mu : (n_u, n_u) CSR matrix
        Velocity mass matrix on the free velocity DOFs.
    ub, pb : skfem.Basis
        Velocity and pressure bases (all DOFs).
    iu, ip : int ndarray
        Free velocity / pressure DOFs in the numbering of ``ub`` / ``pb``.
    Mp_full : (pb.N, pb.N) CSR matrix
        Pressure mass matrix on all pressure DOFs.
    h : float
        Grid spacing ``1 / m``.
    """

    K: sp.csr_matrix
    b: np.ndarray
    n_u: int
    Mp: sp.csr_matrix
    Mu: sp.csr_matrix
    ub: Basis
    pb: Basis
    iu: np.ndarray
    ip: np.ndarray
    Mp_full: sp.csr_matrix
    h: float

    @property
    def n(self) -> int:
        """System size ``n_u + n_p``."""
        return self.K.shape[0]

    def __repr__(self) -> str:
        return (f"SaddlePointProblem(n={self.n}, n_u={self.n_u}, n_p={self.n - self.n_u}, "
                f"h={self.h:.4g})")


def saddle_point_problem(m: int, pair: str = "p2b", nu: float = 1.0, dt: float | None = None,
                         peclet: float = 0.0, alpha: float = 1.0, outflow: bool = True,
                         newton: bool = False, intorder: int = 4) -> SaddlePointProblem:
    """The manufactured Stokes system (module docstring) on an ``m x m`` grid, condensed.

    Parameters
    ----------
    m : int
        Cells per side of the structured grid (two triangles per cell); ``h = 1/m``.
    pair : str
        Element pair name of :mod:`fluidem.fluid.elements` (``"p2b"``, ``"th"``, ...).
    nu : float
        Viscosity (non-dimensional).
    dt : float, optional
        Adds ``(alpha/dt) M_u`` to the velocity block.
    peclet : float
        Strength of the Oseen convection by :func:`wind`.
    alpha : float
        Coefficient of the mass term with ``dt`` (1 backward Euler, 3/2 BDF2).
    outflow : bool
        Traction (natural) condition on ``x = 1``; otherwise walls all round and one
        pressure DOF pinned.
    newton : bool
        Add the Newton reaction term ``(u . grad) wind`` (with ``peclet``).
    intorder : int
        Quadrature order of the volume forms.

    Returns
    -------
    SaddlePointProblem

    Examples
    --------
    >>> saddle_point_problem(3, pair="th", dt=0.01, peclet=1.0)
    SaddlePointProblem(n=76, n_u=60, n_p=16, h=0.3333)
    """
    el = element_pair(pair)
    mesh = MeshTri.init_tensor(np.linspace(0, 1, m + 1), np.linspace(0, 1, m + 1))
    eu = ElementVector(el.velocity())
    ub = Basis(mesh, eu, intorder=intorder)
    pb = ub.with_element(el.pressure())

    @BilinearForm
    def viscous(u, v, w):
        return nu * ddot(grad(u), grad(v))

    @BilinearForm
    def convection(u, v, w):
        return peclet * dot(mul(grad(u), wind(w.x)), v)

    @BilinearForm
    def reaction(u, v, w):
        return peclet * dot(mul(wind_gradient(w.x), u), v)

    @BilinearForm
    def mass(u, v, w):
        return dot(u, v)

    @BilinearForm
    def divergence(u, q, w):
        return -div(u) * q

    @BilinearForm
    def pmass(p, q, w):
        return p * q

    @LinearForm
    def load(v, w):
        # f = -nu Laplace u + grad p
        x, y = w.x
        f1 = -nu * (_g2(x) * _g1(y) + _g(x) * _g3(y)) + 3 * x**2
        f2 = nu * (_g3(x) * _g(y) + _g1(x) * _g2(y)) + 3 * y**2
        return f1 * v[0] + f2 * v[1]

    @LinearForm
    def traction(v, w):
        # nu du/dn - p n on x = 1, n = (1, 0): (nu du_1/dx - p, nu du_2/dx)
        y = w.x[1]
        return -(0.5 + y**3) * v[0] - 2 * nu * _g(y) * v[1]

    A = viscous.assemble(ub)
    Mu = mass.assemble(ub)
    if peclet:
        A = A + convection.assemble(ub)
    if newton:
        A = A + reaction.assemble(ub)
    if dt is not None:
        A = A + (Mu / dt if alpha == 1.0 else (alpha / dt) * Mu)
    B = divergence.assemble(ub, pb)
    Mp = pmass.assemble(pb)
    K = sp.bmat([[A, B.T], [B, None]], format="csr")
    b = np.concatenate([load.assemble(ub), np.zeros(pb.N)])
    if outflow:
        right = mesh.facets_satisfying(lambda x: np.isclose(x[0], 1.0), boundaries_only=True)
        b[: ub.N] += traction.assemble(FacetBasis(mesh, eu, facets=right, intorder=6))
        walls = mesh.facets_satisfying(lambda x: ~np.isclose(x[0], 1.0), boundaries_only=True)
        D = ub.get_dofs(walls).all()
    else:
        D = np.concatenate([ub.get_dofs().all(), [ub.N]])  # walls + pinned pressure DOF
    interior = np.setdiff1d(np.arange(K.shape[0]), D)
    iu = interior[interior < ub.N]
    ip = interior[interior >= ub.N] - ub.N
    return SaddlePointProblem(
        K=K[interior][:, interior].tocsr(), b=b[interior], n_u=int(iu.size),
        Mp=Mp[ip][:, ip].tocsr(), Mu=Mu[iu][:, iu].tocsr(), ub=ub, pb=pb, iu=iu, ip=ip,
        Mp_full=Mp, h=1.0 / m)


def l2_errors(problem: SaddlePointProblem, x: np.ndarray) -> tuple[float, float]:
    """L2 errors of a solution against the manufactured one.

    Parameters
    ----------
    problem : SaddlePointProblem
    x : (n,) float ndarray
        Solution on the free DOFs (velocity first).

    Returns
    -------
    error_u : float
        ``||u_h - u||_{L2}``.
    error_p : float
        ``||p_h - mean(p_h) - p||_{L2}`` (the exact pressure has zero mean).
    """
    ub, pb = problem.ub, problem.pb
    u = np.zeros(ub.N)
    u[problem.iu] = x[: problem.n_u]
    p = np.zeros(pb.N)
    p[problem.ip] = x[problem.n_u:]

    @Functional
    def eu(w):
        e = w["uh"] - exact_velocity(w.x)
        return dot(e, e)

    @Functional
    def mean_p(w):
        return w["ph"]

    @Functional
    def ep(w):
        e = w["ph"] - w["c"] - exact_pressure(w.x)
        return e * e

    ph = pb.interpolate(p)
    c = mean_p.assemble(pb, ph=ph)  # unit square: mean = integral
    return (float(np.sqrt(eu.assemble(ub, uh=ub.interpolate(u)))),
            float(np.sqrt(ep.assemble(pb, ph=ph, c=c))))
