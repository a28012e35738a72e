"""Drafting, kissing and tumbling of two disks settling in a channel (Glowinski et al. 2001).

Set-up (REFERENCES.md, "Resolved sedimentation in 2D"; CGS units: cm, g, s): a closed box
2 × 8 cm of fluid (ρ_f = 1 g/cm², ν = 0.01 cm²/s), g = 980 cm/s², two disks of diameter
d = 0.2 cm and density ρ_s = 1.01 released at rest with centres (1, 6.8) and (0.999, 7.2).
The trailing (upper) disk falls in the wake of the leading one, faster (drafting), closes the
gap until the squeeze film between them holds them together (kissing), and the pair, unstable
side by side, turns over (tumbling): the trailing disk passes the leading one.

Events (:func:`dkt_events`): ``t_kiss`` the first time the gap between the outlines falls
below the mesh size h (the contact range of earlier versions; the film is resolved down to a
fraction of h, :mod:`fluidem.coupling.contacts`); ``t_tumble`` the first time the line of
centres is horizontal (the trailing disk level with the leading one); ``t_draft`` the first
time the trailing disk falls 5 % faster than the leading one.  Glowinski et al. (2001) and
Wan & Turek (2006) show these phases in figures; no tabulated event times were found
(REFERENCES.md), so the numbers here are this code's, with the set-up stated.

The density ratio 1.01 makes explicit (staggered) coupling unstable: the fluid's added mass
(≈ ρ_f A) exceeds the body's inertia minus its buoyancy by far, ``fluid.coupling = "explicit"``
diverges within a few steps (:mod:`fluidem.coupling.free_flow`).
"""

from __future__ import annotations

import time

import numpy as np

from ..geometry import regular_polygon
from ..scene import Scene
from .base import CaseResult, register_case

__all__ = ["dkt_scene", "dkt_events", "dkt", "uhlmann_dkt_scene", "UHLMANN"]

D = 0.2  # disk diameter, cm

#: The accuracy variant of Uhlmann (2005, J. Comput. Phys. 209, Sec. 5.2; also Koblitz et al. 2017,
#: J. Comput. Phys. 343, Fig. 10), CGS: disks d = 0.25 cm, ρ_s/ρ_f = 1.5, ν = 0.01 cm²/s,
#: g = 981 cm/s², a closed channel 8d wide and 24d high, centres 4d (trailing) and 6d (leading) below
#: the top wall with lateral offsets +d/250 and −d/250.  u_ref = √(π d (ρ_s/ρ_f − 1) g / 2)
#: = 13.88 cm/s, t_ref = d/u_ref = 0.01801 s, Re_ref = u_ref d/ν = 347.
UHLMANN = {"d": 0.25, "density": 1.5, "viscosity": 0.01, "g": 981.0, "width": 8 * 0.25, "height": 24 * 0.25}
UHLMANN["u_ref"] = float(np.sqrt(np.pi * UHLMANN["d"] * (UHLMANN["density"] - 1.0) * UHLMANN["g"] / 2.0))
UHLMANN["t_ref"] = UHLMANN["d"] / UHLMANN["u_ref"]


def dkt_scene(h: float = 0.02, dt: float = 0.005, t_end: float = 6.0, density: float = 1.01, segments: int = 64,
              element: str = "p2b", coupling: str = "implicit") -> Scene:
    """The Glowinski DKT scene (module docstring); ``h`` the mesh size at the disks (cm), graded by
    1.2 to 8 h, the default contact model (:mod:`fluidem.coupling.contacts`); disks as regular
    ``segments``-gons."""
    disk = regular_polygon(D / 2, segments).tolist()
    return Scene.from_dict({
        "name": "dkt-glowinski",
        "gravity": [0.0, -980.0],
        "fluid": {"density": 1.0, "viscosity": 0.01, "model": "navier-stokes", "element": element,
                  "coupling": coupling},
        "domain": {"box": [0.0, 2.0, 0.0, 8.0]},
        "bodies": [{"name": "leading", "shape": "polygon", "vertices": disk, "position": [1.0, 6.8],
                    "density": density},
                   {"name": "trailing", "shape": "polygon", "vertices": disk, "position": [0.999, 7.2],
                    "density": density}],
        "contact": {"E": 1e5, "mu": 0.0, "gamma": 0.3},
        "mesh": {"h": h, "grading": {"growth": 1.2, "h_max": 8 * h}},
        "time": {"dt": dt, "t_end": t_end}})


def uhlmann_dkt_scene(h: float = 0.01, dt: float = 5e-4, t_end: float = 0.3, segments: int = 96,
                      element: str = "p2b", growth: float = 1.2, coarse: float = 8.0) -> Scene:
    """The DKT of Uhlmann (2005), :data:`UHLMANN`: ``h`` the mesh size at the disks (cm), graded by
    ``growth`` to ``coarse`` × h, the default contact model; disks as regular ``segments``-gons.
    Bodies ``leading`` (first) and ``trailing``; the channel is x ∈ [0, 8d], y ∈ [0, 24d], gravity −y.

    >>> s = uhlmann_dkt_scene()
    >>> [b.name for b in s.bodies], s.domain.box
    (['leading', 'trailing'], (0.0, 2.0, 0.0, 6.0))
    """
    u = UHLMANN
    d, W, H = u["d"], u["width"], u["height"]
    disk = regular_polygon(d / 2, segments).tolist()
    return Scene.from_dict({
        "name": "dkt-uhlmann",
        "gravity": [0.0, -u["g"]],
        "fluid": {"density": 1.0, "viscosity": u["viscosity"], "model": "navier-stokes", "element": element},
        "domain": {"box": [0.0, W, 0.0, H]},
        "bodies": [{"name": "leading", "shape": "polygon", "vertices": disk,
                    "position": [W / 2 - d / 250, H - 6 * d], "density": u["density"]},
                   {"name": "trailing", "shape": "polygon", "vertices": disk,
                    "position": [W / 2 + d / 250, H - 4 * d], "density": u["density"]}],
        "contact": {"E": 1e5, "mu": 0.0, "gamma": 0.3},
        "mesh": {"h": h, "grading": {"growth": growth, "h_max": coarse * h}},
        "time": {"dt": dt, "t_end": t_end}})


def dkt_events(t: np.ndarray, leading: np.ndarray, trailing: np.ndarray, v_leading: np.ndarray,
               v_trailing: np.ndarray, contact_range: float) -> dict:
    """Event times of a DKT run (module docstring).

    Parameters
    ----------
    t : (n,) float
        Times, s.
    leading, trailing : (n, 2) float
        Centres, cm.
    v_leading, v_trailing : (n,) float
        Vertical velocities, cm/s (negative: falling).
    contact_range : float
        The gap that counts as kissing (the mesh size h in :func:`dkt`), cm.

    Returns
    -------
    dict
        ``t_draft``, ``t_kiss``, ``t_tumble`` (s, NaN if not reached), ``min_gap`` (cm) and the
        centres at the kiss (``kiss_leading``, ``kiss_trailing``).

    Examples
    --------
    >>> t = np.array([0.0, 1.0, 2.0, 3.0])
    >>> lead = np.array([[1.0, 6.0], [1.0, 5.0], [1.0, 4.0], [1.05, 3.0]])
    >>> trail = np.array([[1.0, 6.5], [1.0, 5.3], [1.0, 4.21], [0.9, 2.9]])
    >>> e = dkt_events(t, lead, trail, np.array([-1, -1, -1, -1.0]), np.array([-1, -1.2, -1.1, -1.0]), 0.02)
    >>> e["t_draft"], e["t_kiss"], e["t_tumble"]
    (1.0, 2.0, 3.0)
    """
    sep = trailing - leading
    gap = np.hypot(sep[:, 0], sep[:, 1]) - D

    def first(mask):
        k = np.flatnonzero(mask)
        return (float(t[k[0]]), int(k[0])) if len(k) else (float("nan"), -1)

    t_draft, _ = first(v_trailing < 1.05 * v_leading)
    t_kiss, kk = first(gap < contact_range)
    t_tumble, _ = first(np.abs(sep[:, 1]) <= np.abs(sep[:, 0]))
    out = {"t_draft": t_draft, "t_kiss": t_kiss, "t_tumble": t_tumble, "min_gap": float(gap.min())}
    if kk >= 0:
        out["kiss_leading"] = leading[kk].tolist()
        out["kiss_trailing"] = trailing[kk].tolist()
    return out


@register_case("dkt")
def dkt(element: str = "p2b", h: float = 0.02, dt: float = 0.005, t_end: float = 6.0, progress=None,
        record=None) -> CaseResult:
    """Drafting, kissing and tumbling of two disks (Glowinski et al. 2001): event times of a run.

    ``record(row)`` receives ``(t, x_lead, y_lead, x_trail, y_trail, v_lead, v_trail, gap)``
    after every step (e.g. to keep the trajectories).  Quantities: ``t_draft``, ``t_kiss``,
    ``t_tumble`` (s), ``min_gap`` (cm), ``y_lead_end``, ``y_trail_end`` (cm).  No published
    reference numbers (figures only).
    """
    from ..simulation import Simulation

    t0 = time.perf_counter()
    sim = Simulation(dkt_scene(h=h, dt=dt, t_end=t_end, element=element))
    t_build = time.perf_counter() - t0
    fl = sim.flow
    rows = []
    cost_sum = {}

    def step_done(k, n, t, cost):
        P, V = fl.poses, fl.body_velocities
        rows.append((fl.t, *P[0, :2], *P[1, :2], V[0, 1], V[1, 1], np.hypot(*(P[1, :2] - P[0, :2])) - D))
        for part, s in cost.parts.items():
            cost_sum[part] = cost_sum.get(part, 0.0) + s
        if record is not None:
            record(rows[-1])
        if progress and k % max(1, n // 50) == 0:
            progress(k, n, t)

    t0 = time.perf_counter()
    sim.run(out_dir=None, progress=step_done)
    t_run = time.perf_counter() - t0
    R = np.array(rows)
    ev = dkt_events(R[:, 0], R[:, 1:3], R[:, 3:5], R[:, 5], R[:, 6], h)
    q = {k: v for k, v in ev.items() if not isinstance(v, list)}
    q.update({"y_lead_end": float(R[-1, 2]), "y_trail_end": float(R[-1, 4])})
    n = len(R)
    return CaseResult("dkt", element, 0, fl.dofs, q, {}, {"build": t_build, "run": t_run}, "polygonal", dt,
                      extra={"steps": n, "triangulations": sim.counters["triangulations"],
                             "cost_per_step": {k: v / max(n, 1) for k, v in cost_sum.items()},
                             "contact_substeps": fl.contacts.substeps, "contact_passes": fl.contacts.dem_calls,
                             **{k: v for k, v in ev.items() if isinstance(v, list)}})
