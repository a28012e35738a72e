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

from .space import FlowSpace

__all__ = ["BodyLoad", "body_loads", "PeriodicStats", "periodic_stats"]


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
