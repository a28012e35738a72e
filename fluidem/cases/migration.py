"""Inertial migration of a neutrally buoyant disk in plane Couette flow (Feng, Hu & Joseph 1994).

Set-up (Feng, Hu & Joseph 1994, J. Fluid Mech. 277, 271–301, the Couette case; REFERENCES.md,
"Inertial migration in plane Couette"): walls a distance W apart move at ∓ΔU/2, Re = ΔU W/ν = 40;
a disk of radius W/8 and the fluid's density, free to translate and rotate, released at rest with
its centre W/4 from the bottom wall.  Fluid inertia pushes it across the streamlines to the centre
line, where the two walls' lifts balance.  Lengths in W, times in W/ΔU: W = ΔU = 1, ν = 1/40.

The channel is periodic along the walls with period :data:`PERIOD` W (the disk is carried along
its streamline at about ΔU/4 and crosses the periodic sides every 16 time units, as in an
unbounded channel); the mesh is uniform, size ``h``, and follows the disk (bent periodic sides,
:mod:`fluidem.mesh.seam`).

Reference: :data:`FENG_HU_JOSEPH`, the distance of the centre from the bottom wall read from their
figure of the migration (to about ±0.01 W).
"""

from __future__ import annotations

import numpy as np

from ..diagnostics import recently_retriangulated
from ..scene import Scene

__all__ = ["FENG_HU_JOSEPH", "PERIOD", "RADIUS", "START", "crossing_kinks", "migration_scene", "wall_distance"]

#: Feng, Hu & Joseph (1994): distance of the disk's centre from the wall it started near (in W) at
#: t (in W/ΔU), read from their figure (REFERENCES.md).
FENG_HU_JOSEPH = {10.0: 0.30, 20.0: 0.34, 40.0: 0.42, 60.0: 0.46, 100.0: 0.49}

#: Disk radius and starting distance from the bottom wall (W).
RADIUS, START = 0.125, 0.25

#: Period of the channel along the walls (W).
PERIOD = 4.0


def migration_scene(h: float = 0.04, dt: float = 0.05, t_end: float = 60.0, reynolds: float = 40.0,
                    period: float = PERIOD, element: str = "p2b") -> Scene:
    """The Couette migration scene of the module docstring.

    Parameters
    ----------
    h : float
        Mesh size (W), uniform.
    dt : float
        Time step (W/ΔU).
    t_end : float
        End time (W/ΔU).
    reynolds : float
        Re = ΔU W/ν; the viscosity is 1/Re (density 1).
    period : float
        Length of the periodic channel (W).
    element : str
        Velocity–pressure pair.

    Returns
    -------
    Scene
        Channel [0, period] × [0, 1], bottom wall at velocity (−1/2, 0), top at (1/2, 0); the disk
        ``disk`` free, density 1, at (period/2, :data:`START`), no gravity.

    Examples
    --------
    >>> s = migration_scene(t_end=1.0)
    >>> s.domain.box, s.fluid.viscosity, s.bodies[0].position
    ((0.0, 4.0, 0.0, 1.0), 0.025, (2.0, 0.25))
    """
    return Scene.from_dict({
        "name": "inertial-migration",
        "gravity": [0.0, 0.0],
        "fluid": {"density": 1.0, "viscosity": 1.0 / reynolds, "model": "navier-stokes", "element": element},
        "domain": {"box": [0.0, period, 0.0, 1.0], "left": "periodic", "right": "periodic",
                   "bottom": {"type": "moving-wall", "velocity": [-0.5, 0.0]},
                   "top": {"type": "moving-wall", "velocity": [0.5, 0.0]}},
        "bodies": [{"name": "disk", "shape": "disk", "radius": RADIUS, "position": [period / 2, START],
                    "motion": "free", "density": 1.0}],
        "mesh": {"h": h},
        "time": {"dt": dt, "t_end": t_end}})


def wall_distance(t: np.ndarray, y: np.ndarray, at) -> np.ndarray:
    """Distance of the centre from the bottom wall (W) at the times ``at``, linearly interpolated.

    Parameters
    ----------
    t : (n,) float
        Times of the run, increasing (W/ΔU).
    y : (n,) float
        The centre's height above the bottom wall at ``t`` (W).
    at : (m,) float
        Times to read (W/ΔU), within ``[t[0], t[-1]]`` (to 1e-9 relative).

    Returns
    -------
    (m,) float

    Examples
    --------
    >>> wall_distance(np.array([0.0, 10.0, 20.0]), np.array([0.25, 0.3, 0.34]), [5.0, 20.0])
    array([0.275, 0.34 ])
    """
    at = np.asarray(at, dtype=float)
    slack = 1e-9 * max(1.0, abs(t[-1]))           # the run's clock is a sum of dt
    if at.min() < t[0] - slack or at.max() > t[-1] + slack:
        raise ValueError(f"times {at.min():g}..{at.max():g} outside the run's {t[0]:g}..{t[-1]:g}")
    return np.interp(at, t, y)


def crossing_kinks(t: np.ndarray, x: np.ndarray, velocities: np.ndarray, retriangulated: np.ndarray,
                   after: float = 5.0, quiet_steps: int = 4, period: float = PERIOD, radius: float = RADIUS) -> dict:
    """How smooth the disk's motion is through the periodic sides: the largest kink of its velocities.

    The kink at step k is |(V_k − V_k−1) − (V_k−1 − V_k−2)| per component (the second difference of
    the series); steps are grouped by whether the outline straddles a periodic side (its centre within
    ``radius`` of x = 0 or ``period``) and whether the mesh was re-triangulated in the step or the
    ``quiet_steps − 1`` before.

    Parameters
    ----------
    t : (n,) float
        Times of the steps (W/ΔU).
    x : (n,) float
        The centre's x in the box [0, period) (W).
    velocities : (n, m) float
        The disk's velocities per step (e.g. u, v, ω).
    retriangulated : (n,) bool
        Whether the step re-triangulated the mesh.
    after : float
        Only steps after this time (past the start from rest).

    Returns
    -------
    dict
        ``"crossing"``, ``"away"``, ``"re-triangulated crossing"``, ``"re-triangulated away"``: the
        largest kink per component, (m,) float, or None for a group without steps; ``"crossings"``: how
        many times the outline came onto a side.

    Examples
    --------
    >>> t = np.arange(10.0)
    >>> x = np.array([0.5, 0.4, 0.3, 0.2, 0.1, 0.0, 3.9, 3.8, 3.7, 3.6])
    >>> v = np.c_[np.r_[0.0, 0, 0, 0, 0, 1, 0, 0, 0, 0]]
    >>> k = crossing_kinks(t, x, v, np.zeros(10, bool), after=1.0)
    >>> k["crossings"], k["crossing"], k["away"]
    (1, [2.0], [1.0])
    """
    straddle = np.minimum(x, period - x) < radius
    recent = recently_retriangulated(retriangulated, quiet_steps)
    kink = np.abs(np.diff(velocities, n=2, axis=0))
    k = np.arange(2, len(t))
    late = t[k] > after
    groups = {"crossing": straddle[k] & ~recent[k], "away": ~straddle[k] & ~recent[k],
              "re-triangulated crossing": straddle[k] & recent[k], "re-triangulated away": ~straddle[k] & recent[k]}
    out = {g: (kink[m & late].max(axis=0).tolist() if (m & late).any() else None) for g, m in groups.items()}
    out["crossings"] = int(np.count_nonzero(np.diff(straddle.astype(int)) == 1))
    return out
