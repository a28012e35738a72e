"""Forces and torques on obstacles, point values, and periodic-signal analysis.

Forces are volume integrals of the discrete residual (John & Matthies 2001; John 2004,
Sec. 3): with a test function v equal to a rigid mode on the obstacle outline DOFs and zero
on all other boundary DOFs, the force component on the body is F · e = −ρ R(u, p; v_e).  This
converges at twice the rate of a line integral of the stress and is exact for the discrete
solution's own momentum balance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .space import FlowSpace
from ..geometry import minimum_image

__all__ = ["BodyLoad", "body_loads", "RigidModes", "SideLoads", "side_loads", "PeriodicStats", "periodic_stats"]


@dataclass(frozen=True)
class BodyLoad:
    """Hydrodynamic load on one body: force (fx, fy) per unit depth and torque about ``center``."""

    fx: float
    fy: float
    torque: float


class _LoadVectors:
    """Rigid-mode test vectors for one boundary, cached per space."""

    def __init__(self, space: FlowSpace, boundary: str, center):
        self.ex = space.rigid_test_vector(boundary, "x")
        self.ey = space.rigid_test_vector(boundary, "y")
        self.rot = space.rigid_test_vector(boundary, "rot", center)



def body_loads(space: FlowSpace, residual: np.ndarray, boundary: str, rho: float = 1.0,
               center=(0.0, 0.0)) -> BodyLoad:
    """Force and torque on the body whose outline is ``boundary``.

    Parameters
    ----------
    residual : (n_dofs,) array
        Residual of the discrete momentum equations on all DOFs (no conditions applied),
        e.g. ``FlowProblem.steady_residual(x)`` or ``BDF2Stepper.last_residual()``.
    rho : float
        Fluid density; the residual is kinematic.
    center : (2,)
        Reference point of the torque.
    """
    cache = space.__dict__.setdefault("_load_vectors", {})
    key = (boundary, tuple(map(float, center)))
    if key not in cache:
        cache[key] = _LoadVectors(space, boundary, center)
    lv = cache[key]
    ru = residual[: space.n_u]
    return BodyLoad(-rho * float(lv.ex @ ru), -rho * float(lv.ey @ ru), -rho * float(lv.rot @ ru))


class RigidModes:
    """The rigid-mode operator R (3 n_bodies, n_u) of the body outlines of a space.

    Rows ``3k, 3k + 1, 3k + 2`` are the test vectors of body ``k`` (outline ``boundaries[k]``):
    unit x and y translation and the rotation e_z × (x − X_k) about its centre X_k, on the
    outline velocity DOFs and zero elsewhere (:meth:`FlowSpace.rigid_test_vector`).  Then

    * loads: ``(fx, fy, torque)_k = −ρ (R r_u)_k`` for the momentum residual ``r_u``
      (John 2004, Sec. 3; the same numbers as :func:`body_loads`, one mat-vec for all bodies);
    * prolongation: ``Rᵀ [U_k, V_k, ω_k]`` is the rigid velocity U_k + ω_k e_z × (x − X_k)
      on every outline DOF (the no-slip data of moving bodies, and of free bodies later).

    Parameters
    ----------
    space : FlowSpace
    boundaries : sequence of str
        Outline boundary names, one per body.
    centers : (n_bodies, 2) float
        Reference points of the torques, length units.
    period : (L_x, L_y)
        Periods of a periodic box (``None``: not periodic); a body across a periodic side
        has outline DOFs on both sides, each with its arm to the nearest image of the centre.

    Examples
    --------
    >>> import numpy as np
    >>> from fluidem.mesh.triangulate import Obstacle, to_skfem, triangulate_box
    >>> from fluidem.geometry import rectangle
    >>> from fluidem.fluid.space import FlowSpace
    >>> m = to_skfem(triangulate_box((0, 2, 0, 1), [Obstacle(rectangle(0.2, 0.2) + [1.0, 0.5], "sq")], 0.2))
    >>> R = RigidModes(FlowSpace(m, "th"), ["sq"], [[1.0, 0.5]])
    >>> R.matrix.shape[0], bool(np.allclose(R.prolong([[0.5, 0.0]], [0.0])[R.matrix[0].indices], 0.5))
    (3, True)
    """

    def __init__(self, space: FlowSpace, boundaries, centers, period=(None, None)):
        self.period = tuple(period)
        self.boundaries = list(boundaries)
        nb = len(self.boundaries)
        dx = [space.velocity_dofs(b, 0) for b in self.boundaries]  # one short list per body, once per mesh
        dy = [space.velocity_dofs(b, 1) for b in self.boundaries]
        body_x = np.concatenate([np.full(len(d), k) for k, d in enumerate(dx)]) if nb else np.zeros(0, int)
        body_y = np.concatenate([np.full(len(d), k) for k, d in enumerate(dy)]) if nb else np.zeros(0, int)
        self._dx = np.concatenate(dx) if nb else np.zeros(0, int)
        self._dy = np.concatenate(dy) if nb else np.zeros(0, int)
        self._bx, self._by = body_x, body_y
        rows = np.concatenate([3 * body_x, 3 * body_y + 1, 3 * body_x + 2, 3 * body_y + 2])
        cols = np.concatenate([self._dx, self._dy, self._dx, self._dy])
        self._order = np.lexsort((cols, rows))
        self._n_trans = len(self._dx) + len(self._dy)
        self.matrix = sp.csr_matrix((np.zeros(len(rows)), cols[self._order],
                                     np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=3 * nb))])),
                                    shape=(3 * nb, space.n_u))
        self.update(space, centers)

    def update(self, space: FlowSpace, centers) -> None:
        """Refill the torque rows for moved DOF locations (same connectivity) and ``centers`` (n_bodies, 2)."""
        self.centers = np.asarray(centers, dtype=float).reshape(len(self.boundaries), 2)
        c = self.centers
        px, py = space.dof_locations(self._dx), space.dof_locations(self._dy)
        # arms to the nearest image of the centre (a body across a periodic side)
        arm_y = minimum_image(np.column_stack([np.zeros(px.shape[1]), px[1] - c[self._bx, 1]]), self.period)[:, 1]
        arm_x = minimum_image(np.column_stack([py[0] - c[self._by, 0], np.zeros(py.shape[1])]), self.period)[:, 0]
        data = np.concatenate([np.ones(self._n_trans), -arm_y, arm_x])
        self.matrix.data[:] = data[self._order]

    def loads(self, residual: np.ndarray, rho: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Forces (n_bodies, 2) and torques (n_bodies,) from the residual (n_dofs,) (kinematic, times ``rho``)."""
        L = -rho * (self.matrix @ residual[: self.matrix.shape[1]]).reshape(-1, 3)
        return L[:, :2].copy(), L[:, 2].copy()

    def prolong(self, velocities, omegas) -> np.ndarray:
        """Velocity coefficients (n_u,) of the rigid motions (n_bodies, 2), (n_bodies,) on the outline DOFs."""
        v = np.column_stack([np.asarray(velocities, float).reshape(-1, 2), np.asarray(omegas, float)]).ravel()
        return self.matrix.T @ v


class SideLoads:
    """The force of the fluid on each of some named boundaries (box sides), from the residual.

    The same volume-integral method as the bodies' loads (John 2004, Sec. 3): the force on
    side ``s`` along e is F_s · e = −ρ R(u, p; v_s e) with v_s the discrete function equal to
    1 on the velocity DOFs of ``s`` and 0 on every other DOF, i.e. the reaction on the
    Dirichlet DOFs of the side.  A DOF on two of the sides (the corner of two walls) counts
    half for each, so the test functions of the sides add up to one on every DOF they cover
    and the sides' forces add up to the force on their union.  On a periodic box the wall
    DOFs are Dirichlet and never identified (:func:`fluidem.fluid.periodic.representatives`):
    the corner of a wall and a periodic side is a DOF on each end of the wall, both in v_s.

    Parameters
    ----------
    space : FlowSpace
    sides : sequence of str
        Boundary names; each must carry a velocity condition (wall, moving wall, inflow), whose
        DOFs the solve does not balance.  On a natural (outflow) boundary the residual vanishes
        on every free DOF and the sum is not a force.

    Attributes
    ----------
    matrix : (2 n_sides, n_u) sparse
        Rows ``2k, 2k + 1``: v_s e_x and v_s e_y of side ``k``.

    Examples
    --------
    >>> import numpy as np
    >>> from skfem import MeshTri
    >>> from fluidem.fluid.space import FlowSpace, VelocityBC
    >>> from fluidem.fluid.problem import FlowProblem
    >>> from fluidem.fluid.navier_stokes import solve_stokes
    >>> m = MeshTri.init_tensor(np.linspace(0, 2, 9), np.linspace(0, 1, 5)).with_boundaries(
    ...     {"bottom": lambda x: np.isclose(x[1], 0), "top": lambda x: np.isclose(x[1], 1),
    ...      "left": lambda x: np.isclose(x[0], 0), "right": lambda x: np.isclose(x[0], 2)})
    >>> sp = FlowSpace(m, "th")
    >>> pr = FlowProblem(sp, 0.5, [VelocityBC("bottom"), VelocityBC("top", (1.0, 0.0))], periodic=("x",))
    >>> x = solve_stokes(pr).x
    >>> F = SideLoads(sp, ["bottom", "top"]).loads(pr.steady_residual(x, convection=False), rho=2.0)
    >>> (np.round(F, 12) + 0.0).tolist()  # mu U / H * L = (2 * 0.5) * 1 / 1 * 2: dragged along below, held back above
    [[2.0, 0.0], [-2.0, 0.0]]
    """

    def __init__(self, space: FlowSpace, sides):
        self.sides = list(sides)
        ns = len(self.sides)
        rows, cols = [], []
        for k, s in enumerate(self.sides):  # a few sides, each one vectorised over its DOFs
            for c in (0, 1):
                d = space.velocity_dofs(s, c)
                rows.append(np.full(len(d), 2 * k + c))
                cols.append(d)
        rows = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        cols = np.concatenate(cols) if cols else np.zeros(0, np.int64)
        share = np.bincount(cols, minlength=space.n_u)[cols] if len(cols) else np.zeros(0)
        self.matrix = sp.csr_matrix((1.0 / np.maximum(share, 1), (rows, cols)), shape=(2 * ns, space.n_u))

    def loads(self, residual: np.ndarray, rho: float = 1.0) -> np.ndarray:
        """Forces (n_sides, 2), force/depth, of the fluid on the sides, from the residual (n_dofs,)
        of the last solve's equations without conditions (kinematic, times ``rho``)."""
        return (-rho * (self.matrix @ residual[: self.matrix.shape[1]])).reshape(-1, 2)


def side_loads(space: FlowSpace, residual: np.ndarray, sides, rho: float = 1.0) -> np.ndarray:
    """Forces (n_sides, 2) of the fluid on the named ``sides`` (:class:`SideLoads`).

    The operator depends on the DOF numbering only and is kept with the space's boundary DOF
    lists, which a moved space (:meth:`FlowSpace.moved`) shares: built once per connectivity.
    """
    cache = space._boundary_cache
    key = ("side_loads", tuple(sides))
    if key not in cache:
        cache[key] = SideLoads(space, sides)
    return cache[key].loads(residual, rho)


@dataclass(frozen=True)
class PeriodicStats:
    """Statistics of a periodic signal over a settled window."""

    period: float
    frequency: float
    max: float
    min: float
    mean: float
    rms: float  # of the fluctuation about the mean
    n_periods: int


def _parabolic_extremum(t, y, i):
    """Vertex of the parabola through samples i−1, i, i+1 (sub-sample peak refinement)."""
    if i <= 0 or i >= len(y) - 1:
        return y[i]
    y0, y1, y2 = y[i - 1], y[i], y[i + 1]
    den = y0 - 2 * y1 + y2
    if den == 0:
        return y1
    s = 0.5 * (y0 - y2) / den
    return y1 - 0.25 * (y0 - y2) * s


def periodic_stats(t, y, t_start: float = 0.0, min_periods: int = 2) -> PeriodicStats:
    """Period, max, min, mean and rms of a periodic signal ``y(t)`` for ``t ≥ t_start``.

    The period is the mean spacing of upward mean-crossings (crossing times by cubic
    interpolation through the four samples around each crossing); extrema are refined by
    a parabola through the three samples around each sample extremum.  Raises
    ``ValueError`` if fewer than ``min_periods`` full periods lie in the window.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = t >= t_start
    t, y = t[keep], y[keep]
    if len(t) < 8:
        raise ValueError(f"too few samples ({len(t)}) after t_start = {t_start}")
    mean0 = y.mean()
    s = y - mean0
    up = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    crossings = []
    for i in up:  # a handful of crossings per signal
        lo, hi = max(i - 1, 0), min(i + 3, len(t))
        tt, ss = t[lo:hi], s[lo:hi]
        if len(tt) == 4:
            c = np.polyfit(tt - t[i], ss, 3)
            roots = np.roots(c)
            roots = roots[np.isreal(roots)].real + t[i]
            roots = roots[(roots >= t[i]) & (roots <= t[i + 1])]
            if len(roots):
                crossings.append(roots[0])
                continue
        crossings.append(t[i] - s[i] * (t[i + 1] - t[i]) / (s[i + 1] - s[i]))
    crossings = np.asarray(crossings)
    if len(crossings) < min_periods + 1:
        raise ValueError(
            f"signal has {max(len(crossings) - 1, 0)} full period(s) after t = {t_start:g}; "
            f"need at least {min_periods}: run longer or start the window earlier"
        )
    period = float(np.mean(np.diff(crossings)))
    win = (t >= crossings[0]) & (t <= crossings[-1])
    tw, yw = t[win], y[win]
    mean = float(np.trapezoid(yw, tw) / (tw[-1] - tw[0]))
    rms = float(np.sqrt(np.trapezoid((yw - mean) ** 2, tw) / (tw[-1] - tw[0])))
    imax, imin = int(np.argmax(y)), int(np.argmin(y))
    return PeriodicStats(period, 1.0 / period, float(_parabolic_extremum(t, y, imax)),
                         float(_parabolic_extremum(t, y, imin)), mean, rms, len(crossings) - 1)
