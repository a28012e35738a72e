"""Weak forms of the incompressible Navier–Stokes equations, one small function per term.

Gradient (not symmetric-gradient) form of the viscous term by default, so that the natural
boundary condition is the "do-nothing" outflow ν ∂u/∂n − p n = 0 of the DFG benchmark
(Schäfer & Turek 1996; Heywood, Rannacher & Turek 1996).  Its boundary term is the
pseudo-traction ν ∂u/∂n, which misses ν (∇u)ᵀ n: on a body at rest or in translation that
part integrates to zero against the rigid modes (u is constant along the outline), on a
rotating body it does not (a spinning disk would feel half its torque), so flows with rotating
bodies use the stress form :func:`viscous_stress`, 2 ε(u) : ε(v), whose boundary term is the
true viscous traction (natural condition: traction-free).  Forms are in kinematic units
(divided by the density ρ); ``grad(u)[i, j] = ∂u_i/∂x_j``.
"""

from skfem import BilinearForm, LinearForm
from skfem.helpers import ddot, div, dot, grad, mul

__all__ = [
    "viscous", "viscous_stress", "divergence", "mass", "pressure_mass", "convection",
    "convection_newton", "convection_jacobian", "convection_residual", "body_force",
]


@BilinearForm
def viscous(u, v, w):
    """Viscous term ∇u : ∇v (multiply by ν)."""
    return ddot(grad(u), grad(v))


@BilinearForm
def viscous_stress(u, v, w):
    """Viscous term in stress form 2 ε(u) : ε(v) = ∇u : ∇v + ∇uᵀ : ∇v (multiply by ν)."""
    return ddot(grad(u), grad(v)) + ddot(grad(u).transpose((1, 0, 2, 3)), grad(v))


@BilinearForm
def divergence(u, q, w):
    """Continuity / pressure coupling −q div u (its transpose gives −p div v)."""
    return -div(u) * q


@BilinearForm
def mass(u, v, w):
    """Velocity mass u · v."""
    return dot(u, v)


@BilinearForm
def pressure_mass(p, q, w):
    """Pressure mass p q (Schur-complement approximation, pressure normalisation)."""
    return p * q


@BilinearForm
def convection(u, v, w):
    """Convection ((b · ∇) u) · v with the convecting velocity b = ``w.b``.

    On a moving mesh b = u − w_mesh (ALE form, Donea & Huerta 2003, eq. 7.26); on a fixed
    mesh b is the extrapolated velocity (semi-implicit) or the Newton iterate.
    """
    return dot(mul(grad(u), w.b), v)


@BilinearForm
def convection_newton(u, v, w):
    """Newton part of the linearised convection ((u · ∇) a) · v about the iterate a = ``w.a``."""
    return dot(mul(grad(w.a), u), v)


@BilinearForm
def convection_jacobian(u, v, w):
    """Jacobian of the convection (a·∇)a at a = ``w.a``: ((a·∇)u + (u·∇)a) · v (Newton)."""
    return dot(mul(grad(u), w.a) + mul(grad(w.a), u), v)


@LinearForm
def convection_residual(v, w):
    """Convection of the iterate ((b · ∇) a) · v with b = ``w.b`` and a = ``w.a``."""
    return dot(mul(grad(w.a), w.b), v)


@LinearForm
def body_force(v, w):
    """Body force per unit mass f · v with f = ``w.f`` (a constant 2-vector or a field)."""
    return dot(w.f, v)
