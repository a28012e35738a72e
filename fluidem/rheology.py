"""A Couette shear cell as a rheometer: shear rate, wall shear stress and effective viscosity.

A scene's box is a *shear cell* when one pair of opposite sides is periodic and the other
pair are walls (``wall`` or ``moving-wall``) parallel to each other: the bottom and top walls
of a box periodic in x, or the left and right walls of a box periodic in y.  With s the
coordinate along the walls (x or y), the low wall (bottom or left) at ``U_lo`` and the high
wall (top or right) at ``U_hi`` along s, and the gap H between them,

* shear rate γ̇ = (U_hi − U_lo) / H (signed; the normal components of the wall velocities do
  not shear);
* wall shear stress per recorded step τ = (F_lo,s − F_hi,s) / (2 L): the mean of the two
  walls' tangential forces per length L of wall, each with the sign that makes the stress of
  simple shear u_s = γ̇ n equal to μ γ̇ (the fluid drags the low wall along +s by μ γ̇ L and
  holds the high one back by as much).  The forces are those of ``sides.csv``
  (:class:`fluidem.fluid.forces.SideLoads`); a pressure-driven part (``fluid.body_force``)
  pushes both walls alike and cancels in τ;
* effective viscosity μ_eff / μ = ⟨τ⟩ / (μ γ̇), μ = ρ ν the fluid's dynamic viscosity, ⟨τ⟩
  the mean of the samples in the averaging window (every recorded step with t₀ ≤ t ≤ t₁).
  Default window: the second half of the run, [t_end / 2, t_end]; ``output.rheology_window``
  sets it.  For dilute disks μ_eff / μ = 1 + 2 φ (Einstein's 2D coefficient, φ the area
  fraction; Brady 1983); walls at a finite gap raise it by about 3.9 (a/H)² for one disk of radius a
  on the centre line of a square cell (``tests/test_rheology.py``).

The samples of a run are correlated in time, so their standard error is not σ/√n: it is
estimated by blocking (Flyvbjerg & Petersen 1989, J. Chem. Phys. 91, 461): the series is
averaged in pairs again and again, and at each level with n' blocks the variance of the
mean is estimated as c₀/(n' − 1), c₀ the blocks' variance; this rises with the block length
until the blocks are longer than the correlation time and then stays level within its own
error √(2/(n' − 1)).  The estimate reported is that of the first level on the plateau
(:func:`blocking_standard_error`), among the levels that keep at least :data:`MIN_BLOCKS`
blocks; ``blocks`` in run.json says how many blocks it rests on (correlations longer than
the window / ``blocks`` are not seen).

Examples
--------
>>> from fluidem.scene import Scene
>>> s = Scene.from_dict({"fluid": {"viscosity": 0.5, "density": 2.0, "model": "stokes"},
...     "domain": {"box": [0, 2, 0, 1], "left": "periodic", "right": "periodic",
...                "top": {"type": "moving-wall", "velocity": [3.0, 0.0]}},
...     "time": {"dt": 0.1, "t_end": 1.0}})
>>> cell, why = shear_cell(s)
>>> cell.sides, cell.shear_rate, cell.viscosity, window(s)
(('bottom', 'top'), 3.0, 1.0, (0.5, 1.0))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ShearCell", "shear_cell", "window", "wall_shear_stress", "blocking_standard_error", "rheology",
           "plan_note", "MIN_BLOCKS"]

#: fewest blocks a blocking level may have to count towards the standard error
MIN_BLOCKS = 16

#: (low wall, high wall, component along the walls, the periodic pair across)
_PAIRS = (("bottom", "top", 0, ("left", "right")), ("left", "right", 1, ("bottom", "top")))
_WALLS = ("wall", "moving-wall")


@dataclass(frozen=True)
class ShearCell:
    """The walls of a Couette cell and its shear rate.

    Attributes
    ----------
    sides : (str, str)
        Low and high wall: ``("bottom", "top")`` or ``("left", "right")``.
    axis : int
        Component along the walls: 0 (x) or 1 (y).
    gap : float
        Distance between the walls, length.
    length : float
        Length of each wall (the period), length.
    velocity_difference : float
        U_hi − U_lo along the walls, length/time.
    shear_rate : float
        γ̇ = velocity_difference / gap, 1/time (signed).
    viscosity : float
        The fluid's dynamic viscosity μ = ρ ν, mass/time per unit depth.
    """

    sides: tuple
    axis: int
    gap: float
    length: float
    velocity_difference: float
    shear_rate: float
    viscosity: float


def shear_cell(scene) -> tuple[ShearCell | None, str]:
    """The scene's shear cell, or ``(None, why)``.

    ``why`` is ``""`` when the box is not a periodic cell between two walls at all (nothing
    to say), and says what is missing when it is one whose walls do not shear the fluid.
    """
    if scene.fluid is None:
        return None, ""
    d = scene.domain
    x0, x1, y0, y1 = d.box
    for lo, hi, axis, across in _PAIRS:
        if not (d.side(lo).type in _WALLS and d.side(hi).type in _WALLS
                and all(d.side(s).type == "periodic" for s in across)):
            continue
        gap, length = (y1 - y0, x1 - x0) if axis == 0 else (x1 - x0, y1 - y0)
        dU = float(d.side(hi).velocity[axis]) - float(d.side(lo).velocity[axis])
        if dU == 0.0:
            xy = "xy"[axis]
            return None, (f"{lo} and {hi} are the walls of a cell periodic in {xy} but do not move relative to each "
                          f"other along {xy} (no shear rate); a Couette cell needs a 'moving-wall' with a velocity "
                          f"along {xy} different from the other wall's")
        mu = scene.fluid.density * scene.fluid.viscosity
        return ShearCell((lo, hi), axis, gap, length, dU, dU / gap, mu), ""
    return None, ""


def window(scene) -> tuple[float, float]:
    """The averaging window ``(t0, t1)``, time: ``output.rheology_window``, else the second half
    of the run ``(t_end / 2, t_end)``."""
    w = getattr(scene.output, "rheology_window", None)
    if w is not None:
        return float(w[0]), float(w[1])
    return 0.5 * scene.time.t_end, float(scene.time.t_end)


def wall_shear_stress(force_lo, force_hi, cell: ShearCell) -> np.ndarray:
    """Wall shear stress τ (n,), force/length², from the forces (n, 2) of the fluid on the low and
    high walls: (F_lo,s − F_hi,s) / (2 L), positive for a fluid that resists a positive shear rate."""
    a = cell.axis
    return (np.asarray(force_lo, float).reshape(-1, 2)[:, a] - np.asarray(force_hi, float).reshape(-1, 2)[:, a]) \
        / (2.0 * cell.length)


def blocking_standard_error(samples) -> tuple[float, int]:
    """Standard error of the mean of a correlated series by blocking (Flyvbjerg & Petersen 1989).

    Returns ``(standard error, blocks)``: the estimate c₀/(n' − 1) of the first blocking level
    (n' blocks) that no later level with at least :data:`MIN_BLOCKS` blocks exceeds by more
    than twice that later level's own error, √(2/(n'' − 1)) times its estimate (the plateau;
    the first level when the series is shorter), and the number of blocks of that level;
    ``(nan, n)`` for fewer than 2 samples.

    Examples
    --------
    >>> x = np.repeat(np.random.default_rng(1).choice([-1.0, 1.0], 128), 8)  # 128 coin tosses, each held 8 samples
    >>> se, blocks = blocking_standard_error(x)
    >>> round(float(se / np.sqrt(x.var() / 1023)), 2), blocks  # sqrt(1023/127) = 2.8 times the naive sigma/sqrt(n - 1)
    (2.84, 128)
    """
    x = np.asarray(samples, dtype=float).ravel()
    if len(x) < 2:
        return float("nan"), len(x)
    se, n = [np.sqrt(x.var() / (len(x) - 1))], [len(x)]
    while len(x) // 2 >= MIN_BLOCKS:
        m = 2 * (len(x) // 2)
        x = 0.5 * (x[0:m:2] + x[1:m:2])
        se.append(np.sqrt(x.var() / (len(x) - 1)))
        n.append(len(x))
    se, n = np.array(se), np.array(n)
    err = se / np.sqrt(2.0 * (n - 1))  # the estimate's own standard error (Flyvbjerg & Petersen 1989, eq. 28)
    for k in range(len(se)):  # the first level no later one rises above by more than twice its error
        if np.all(se[k + 1:] <= se[k] + 2.0 * err[k + 1:]):
            return float(se[k]), int(n[k])
    return float(se[-1]), int(n[-1])  # pragma: no cover - the last level always qualifies


def rheology(scene, sides: dict) -> dict | None:
    """The ``rheology`` section of run.json from a run's side loads (:func:`fluidem.io.read_sides`).

    Returns ``None`` when the scene is no shear cell; otherwise ``shear_rate`` (1/time),
    ``window`` [t0, t1] and whether it is the default, ``walls``, ``viscosity`` (μ),
    ``wall_shear_stress`` (the mean τ, force/length²), ``mu_eff_over_mu``, its
    ``standard_error``, ``samples`` and ``blocks`` (see the module docstring); the ratio is
    ``None`` when no recorded step lies in the window.
    """
    cell, _ = shear_cell(scene)
    if cell is None:
        return None
    t0, t1 = window(scene)
    lo, hi = cell.sides
    side, step, t = np.asarray(sides["side"]), np.asarray(sides["step"]), np.asarray(sides["t"])
    F = np.column_stack([sides["fx"], sides["fy"]]) if len(side) else np.zeros((0, 2))
    ilo, ihi = np.flatnonzero(side == lo), np.flatnonzero(side == hi)
    common, a, b = np.intersect1d(step[ilo], step[ihi], return_indices=True)
    ilo, ihi = ilo[a], ihi[b]
    tol = 1e-9 * max(scene.time.dt, abs(t1))
    inside = (t[ilo] >= t0 - tol) & (t[ilo] <= t1 + tol)
    tau = wall_shear_stress(F[ilo[inside]], F[ihi[inside]], cell)
    scale = cell.viscosity * cell.shear_rate
    out = {"shear_rate": cell.shear_rate, "window": [t0, t1],
           "window_from": "output.rheology_window" if getattr(scene.output, "rheology_window", None) is not None
           else "default: the second half of the run",
           "walls": list(cell.sides), "gap": cell.gap, "wall_length": cell.length, "viscosity": cell.viscosity,
           "samples": int(len(tau))}
    if len(tau) == 0:
        return {**out, "wall_shear_stress": None, "mu_eff_over_mu": None, "standard_error": None, "blocks": 0,
                "note": "no recorded step in the window (output.history_every sets the side loads' cadence)"}
    se, blocks = blocking_standard_error(tau)
    return {**out, "wall_shear_stress": float(tau.mean()), "mu_eff_over_mu": float(tau.mean() / scale),
            "standard_error": None if not np.isfinite(se) else se / abs(scale), "blocks": blocks,
            "method": "mu_eff/mu = mean of (F_lo - F_hi) along the walls / (2 L) over (mu shear_rate); standard "
                      "error by blocking (Flyvbjerg & Petersen 1989), the first level on the plateau, levels of at "
                      f"least {MIN_BLOCKS} blocks"}


def plan_note(scene) -> str | None:
    """The plan's note on the rheometer: the shear rate and the averaging window, or why there is none
    (``None`` when the box is no periodic cell between walls and no window is asked for)."""
    cell, why = shear_cell(scene)
    asked = getattr(scene.output, "rheology_window", None) is not None
    if cell is None:
        if why:
            return "no rheology: " + why
        if asked and scene.fluid is not None:
            return ("no rheology: output.rheology_window is set but the box is no shear cell (a pair of parallel "
                    "walls, one a 'moving-wall', with the other pair periodic)")
        return None
    t0, t1 = window(scene)
    lo, hi = cell.sides
    d = scene.domain
    xy = "xy"[cell.axis]
    u = {s: float(d.side(s).velocity[cell.axis]) for s in (lo, hi)}
    speed = "; ".join(f"{s} at rest" if u[s] == 0 else f"{s} at {u[s]:g}" for s in (lo, hi))
    return (f"rheometer: Couette cell between {lo} and {hi} ({speed} along {xy}), gap {cell.gap:g}: shear rate "
            f"{cell.shear_rate:g} (1/time); mu_eff/mu = mean wall shear stress / (mu shear rate) averaged over t in "
            f"[{t0:g}, {t1:g}] (" + ("output.rheology_window" if asked else "the second half of the run, by default; "
                                      "output.rheology_window sets it") + "), in run.json 'rheology'")
