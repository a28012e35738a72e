"""A disk approaching a plane wall in Stokes flow: how much of the squeeze film a mesh resolves.

Set-up: a regular ``segments``-gon of radius ``a`` (a vertex facing the wall) whose closest
vertex is ``δ`` above the floor of a closed box [−20a, 20a] × [0, 20a], moving towards it at unit
speed without turning, in Stokes flow of unit viscosity; the moving mesh of
:class:`fluidem.mesh.MovingMesh` (size ``h`` at the disk, graded ×1.2 to 2a), as in every
free-body run.  The force on the disk by the volume integral of the residual
(:class:`fluidem.fluid.forces.RigidModes`) is compared with the exact solution for a cylinder
approaching a plane (bipolar coordinates, Jeffery 1922; Jeffrey & Onishi 1981; REFERENCES.md)::

    F⊥ / (μ V) = 4π / (α − tanh α),   cosh α = 1 + δ/a,

of which the lubrication law ``3√2π (a/δ)^(3/2)`` is the δ ≪ a limit.  The polygon's radius is
that of the equal-area disk (:func:`fluidem.dem.lubrication.equal_area_radius`).  The box makes
the resolved force 0.3–0.9 % larger than the exact half-plane value where the film is resolved
(δ = h on the finer meshes), which bounds what the comparison can tell.

:func:`resolved_film_length` inverts the exact law: the gap ``δ_e`` at which it gives the
resolved force, and ``δ_r = √(δ_e² − δ²)`` (0 where the resolved force is at least the exact
one), the quantity :mod:`fluidem.dem.lubrication` uses.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..dem.lubrication import equal_area_radius
from ..geometry import polygon_area, regular_polygon

__all__ = ["bipolar_force", "wall_approach_mesh", "approach_load", "wall_approach_force", "resolved_film_length"]


def bipolar_force(delta, a):
    """Exact F⊥/(μV) of a cylinder of radius ``a`` approaching a plane wall at gap ``delta`` (lengths).

    >>> law = 3 * 2**0.5 * np.pi * 100**1.5                # the lubrication limit at δ/a = 0.01
    >>> round(float(bipolar_force(0.01, 1.0)) / law, 4)
    1.0105
    """
    alpha = np.arccosh(1.0 + np.asarray(delta, float) / a)
    return 4.0 * np.pi / (alpha - np.tanh(alpha))


def wall_approach_mesh(h: float, delta: float, a: float = 0.1, segments: int = 96, x: float = 0.0):
    """The moving mesh of the module docstring with the disk's closest vertex ``delta`` above the floor.

    Parameters
    ----------
    h, delta, a : float
        Mesh size at the disk, gap, circumradius of the polygon (lengths).
    segments : int
        Vertices of the polygon (a multiple of 4 puts a vertex at the bottom).
    x : float
        Abscissa of the disk's centre, length (another triangulation of the same gap).

    Returns
    -------
    (MovingMesh, ndarray)
        The mesh and the disk's centre ``(x, y)``, shape (2,).
    """
    from ..mesh import MovingMesh

    disk = regular_polygon(a, segments)
    y = delta - disk[:, 1].min()
    L = 20.0 * a
    mm = MovingMesh((-L, L, 0.0, L), [disk], [[x, y, 0.0]], h=h,
                    grading={"region": (x - 3 * a, x + 3 * a, 0.0, 3 * a), "growth": 1.2, "h_max": 2 * a})
    return mm, np.array([x, y])


def approach_load(mm, element: str, centre) -> tuple[float, int]:
    """Resolved F⊥/(μV) (the force's y component) on the disk ``body0`` of ``mm`` at ``centre``, shape (2,),
    moving down at unit speed in Stokes flow of unit viscosity, walls at rest; and the DOFs."""
    from ..fluid import FlowProblem, FlowSpace, RigidMotion, VelocityBC, solve_stokes
    from ..fluid.forces import RigidModes

    centre = (float(centre[0]), float(centre[1]))
    space = FlowSpace(mm.skfem_mesh(), element)
    bcs = [VelocityBC(["left", "right", "bottom", "top"], (0.0, 0.0)),
           VelocityBC("body0", RigidMotion((0.0, -1.0), 0.0, centre))]
    problem = FlowProblem(space, 1.0, bcs)
    state = solve_stokes(problem)
    F, _ = RigidModes(space, ["body0"], [centre]).loads(problem.steady_residual(state.x, convection=False))
    return float(F[0, 1]), int(problem.B.shape[0] + problem.B.shape[1])


def wall_approach_force(element: str, h: float, delta: float, a: float = 0.1, segments: int = 96,
                        x: float = 0.0) -> dict:
    """Resolved force F⊥/(μV) on the disk of the module docstring.

    Parameters
    ----------
    element : str
        Element pair (``th``, ``p2b``, ``p3``, ``mini``).
    h : float
        Mesh size at the disk, length.
    delta : float
        Gap between the closest vertex and the wall, length, > 0.
    a : float
        Circumradius of the polygon, length.
    segments : int
        Vertices of the polygon (a multiple of 4 puts a vertex at the bottom).
    x : float
        Abscissa of the disk's centre, length (:func:`wall_approach_mesh`).

    Returns
    -------
    dict
        ``force`` (resolved F⊥/(μV)), ``exact`` (:func:`bipolar_force` with the equal-area radius),
        ``radius`` (that radius), ``dofs``.
    """
    mm, centre = wall_approach_mesh(h, delta, a, segments, x)
    force, dofs = approach_load(mm, element, centre)
    r = float(equal_area_radius(polygon_area(regular_polygon(a, segments))))
    return {"force": force, "exact": float(bipolar_force(delta, r)), "radius": r, "dofs": dofs}


def resolved_film_length(force: float, delta: float, a: float) -> float:
    """δ_r = √(δ_e² − δ²) with ``bipolar_force(δ_e, a) = force`` (length); 0 where ``force`` is at
    least the exact value at ``delta``.

    >>> round(resolved_film_length(float(bipolar_force(0.05, 1.0)), 0.03, 1.0), 6)
    0.04
    """
    if force >= bipolar_force(delta, a):
        return 0.0
    d_e = brentq(lambda d: bipolar_force(d, a) - force, delta, 100.0 * a)
    return float(np.sqrt(max(d_e * d_e - delta * delta, 0.0)))
