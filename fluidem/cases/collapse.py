"""Dry granular column collapse of DEM polygons, against Lube et al. (2005).

A column of random convex polygons of width L0 and height H0 = a L0 stands on a rough floor
against a wall at x = 0, held by a gate at x = L0.  The gate is removed and the grains spread
to the right along the floor; the normalised runout (L∞ − L0)/L0 is compared with the
two-dimensional (channel) experiments of Lube, Huppert, Sparks & Freundt (2005), "Collapses
of two-dimensional granular columns", *J. Fluid Mech.* 508, 175–199:
(L∞ − L0)/L0 ≈ 1.2 a for a ≲ 2.3 and ≈ 1.9 a^(2/3) above (:func:`lube`).

Material (SI units, 2D: masses per unit depth)
    Random convex polygons (:func:`grain`): 5–7 corners, size (diameter) 0.8 D–D with
    D = 1 cm, elongation 1–1.4, density ρ = 10 kg/m².  Contact law
    ``ContactModel(E=2000 N/m, mu=0.5, gamma=1)``, the same friction coefficient μ = 0.5 for
    grain–grain and grain–floor contacts (Coulomb, no rolling resistance).  γ = 1 gives a
    restitution of about 0.30 for flat faces.  Gravity (0, −9.81) m/s².

Floor (:func:`rough_floor`)
    One fixed grain (elongation 1) per grain size D along y = 0, from x = 0 to
    ``runout_room`` · L0, so that the deposit cannot slide on its base.

Initial packing (:func:`column`)
    Grains are placed on a loose square lattice of spacing 1.05 D inside the box
    x ∈ [0, L0] (floor(L0 / 1.05 D) grains per row, 9 for L0 = 10 D), rows added until the
    grain area reaches 0.8 a L0² (the packing fraction assumed for the settled column), with
    random sizes, shapes and orientations; the lattice falls and settles under gravity for
    1 s between the walls x = 0 and x = L0 (frictional walls, same μ).  The settled column is
    a random loose packing whose solid fraction φ is measured by :func:`packing_fraction`
    (0.81–0.87 for a = 0.5–4, seed 1: ``benchmarks/bench_dem_collapse.py`` writes it for
    each a), and whose aspect ratio a = H0/L0 is measured on it (it differs from the
    requested one by a few per cent).

The measured runouts are in ``benchmarks/results/column_collapse.md``.
"""

from __future__ import annotations

import numpy as np

from ..dem import Body, ContactModel, DEM

__all__ = ["D", "RHO", "E_SOFT", "GAMMA", "MU", "grain", "rough_floor", "frozen", "column", "collapse",
           "packing_fraction", "lube"]

#: Grain size (largest diameter of the largest grains), m.
D = 0.01
#: Grain density, kg/m² (2D).
RHO = 10.0
#: Contact stiffness E of the overlap-area law, N/m (soft on purpose: the number of steps
#: grows as √E; E/(ρ g D) = 2000, so static overlaps stay around 1 % of a grain's area).
E_SOFT = 2000.0
#: Damping coefficient γ of the contact law (restitution ≈ 0.30 for flat faces).
GAMMA = 1.0
#: Friction coefficient of the column collapse (grain–grain, grain–floor and grain–wall).
MU = 0.5


def grain(rng: np.random.Generator, position) -> Body:
    """One random grain: a convex polygon of 5–7 corners, size U(0.8 D, D) m, elongation
    U(1, 1.4), density :data:`RHO`, at ``position`` (m)."""
    return Body.random_convex(rng.uniform(0.8 * D, D), int(rng.integers(5, 8)), rng.uniform(1.0, 1.4),
                              rng=rng, density=RHO, position=position)


def rough_floor(rng: np.random.Generator, half_width: float = 0.4) -> list[Body]:
    """Fixed grains along y = 0 from x = −``half_width`` to ``half_width`` (m), one per grain
    size D (5–7 corners, size U(0.8 D, D), elongation 1), so that a deposit cannot slide on
    its base."""
    xs = np.arange(-half_width, half_width + 1e-9, D)
    return [Body.random_convex(rng.uniform(0.8 * D, D), int(rng.integers(5, 8)), 1.0, rng=rng,
                               density=RHO, position=(x, 0.0), motion="fixed") for x in xs]


def frozen(sim: DEM, window: float = 0.05, tol: float = 0.01) -> bool:
    """Run ``window`` seconds and measure how much the free grains move meanwhile.

    Parameters
    ----------
    sim : DEM
        The simulation, advanced in place by ``window`` s.
    window : float
        Duration of the measurement, s.
    tol : float
        Threshold on the displacement, in grain sizes D.

    Returns
    -------
    bool
        True if 99 % of the free grains moved less than ``tol`` · D.  The 99th percentile of
        the displacements (m) is stored as ``sim.last_move``: a small value means the
        deposit's shape no longer changes, while a few single grains may still roll at the toe
        or rock on a corner (a weakly damped mode of the overlap law, whose damping scales with
        the contact length).
    """
    x0 = sim.positions[sim.free].copy()
    sim.run(sim.time + window, sim.dt_max)
    move = np.sqrt(((sim.positions[sim.free] - x0) ** 2).sum(axis=1))
    sim.last_move = float(np.percentile(move, 99))
    return sim.last_move < tol * D


def column(aspect: float, width_grains: int = 10, seed: int = 1, mu: float = MU,
           runout_room: float = 12.0) -> tuple[DEM, float]:
    """Settled column of width L0 = ``width_grains`` · D and height ≈ ``aspect`` · L0.

    Parameters
    ----------
    aspect : float
        Requested aspect ratio H0/L0 (the settled one is measured by :func:`collapse`).
    width_grains : int
        Column width L0 in grain sizes D.
    seed : int
        Seed of the random grains (floor first, then the column, row by row).
    mu : float
        Friction coefficient of every contact.
    runout_room : float
        Length of the rough floor (fixed grains along y = 0 from x = 0), in units of L0.

    Returns
    -------
    sim : DEM
        The column after 1 s of settling in the box x ∈ [0, L0] (grains first, then the
        fixed floor grains), at t = 1 s.
    L0 : float
        Column width, m.

    Notes
    -----
    The grains start on a loose square lattice of spacing 1.05 D (floor(L0 / 1.05 D) per
    row); rows are added until the grain area reaches 0.8 ``aspect`` L0², 0.8 being the
    packing fraction assumed for the settled column (the measured one: :func:`packing_fraction`).
    """
    rng = np.random.default_rng(seed)
    L0 = width_grains * D
    floor = rough_floor(rng, half_width=0.5 * runout_room * L0)
    for f in floor:
        f.position = f.position + (0.5 * runout_room * L0, 0.0)
    h = 1.05 * D
    ncol = int(np.floor(L0 / h))
    grains, k = [], 0
    # lattice rows until the settled column reaches aspect · L0 (packing fraction ~ 0.8)
    area_needed = aspect * L0 * L0 * 0.8
    area = 0.0
    while area < area_needed:
        iy, ix = divmod(k, ncol)
        g = grain(rng, ((ix + 0.5) * L0 / ncol, D + (iy + 0.5) * h))
        grains.append(g)
        area += g.area
        k += 1
    model = ContactModel(E=E_SOFT, mu=mu, gamma=GAMMA)
    sim = DEM(grains + floor, walls=(0.0, L0, -np.inf, np.inf), contact=model)
    sim.run(1.0, sim.dt_max)
    return sim, L0


def _floor_top(sim: DEM) -> float:
    """Highest point of the fixed floor grains, m."""
    return max(o[:, 1].max() for o, f in zip(sim.outlines(), sim.free) if not f)


def packing_fraction(sim: DEM, L0: float, margin: float = 1.0) -> float:
    """Solid area fraction of the settled column.

    Parameters
    ----------
    sim : DEM
        A settled column (:func:`column`), gate still closed.
    L0 : float
        Column width, m.
    margin : float
        Band left out below the column top, in grain sizes D.

    Returns
    -------
    float
        Area of all grain outlines (free grains and the floor grains' tips) inside the
        rectangle x ∈ [0, L0], y ∈ [floor top, column top − ``margin`` D], divided by the
        rectangle's area.  The column top is the mean of the 3 highest free-grain centres
        + D/2 (as in :func:`collapse`); the rough top surface is left out by ``margin``.
        Overlaps of the contacts (≲ 1 % of a grain) are counted twice.
    """
    import shapely

    y0 = _floor_top(sim)
    y = np.sort(sim.positions[sim.free, 1])
    y1 = float(np.mean(y[-3:]) + 0.5 * D) - margin * D
    box = shapely.box(0.0, y0, L0, y1)
    area = sum(shapely.Polygon(o).intersection(box).area for o in sim.outlines())
    return float(area / box.area)


def collapse(aspect: float, **kw) -> tuple[float, float, DEM, float]:
    """Release the settled column and measure its runout.

    The wall x = L0 is removed and the grains flow for 3 s (the front stops within ~1 s; a
    few single grains roll on for longer and are not counted).

    Parameters
    ----------
    aspect : float
        Requested aspect ratio H0/L0.
    **kw
        Passed to :func:`column` (``width_grains``, ``seed``, ``mu``, ``runout_room``).

    Returns
    -------
    a : float
        Aspect ratio H0/L0 measured on the settled column (H0: mean top of the 3 highest
        grains, i.e. their centres + D/2, above the floor surface).
    runout : float
        (L∞ − L0)/L0, with L∞ the front of the deposit: the rightmost outline point of a free
        grain touching another free grain (a grain that bounced away alone does not count).
    sim : DEM
        The simulation at the end; ``sim.last_move`` is the 99th-percentile displacement
        (m) of the free grains in the last 0.05 s (:func:`frozen`), and ``sim.column`` a dict
        with the settled column's ``L0`` (m), ``H0`` (m), ``packing_fraction`` and
        ``grains``.
    t_flow : float
        Flow time after opening the gate, s.
    """
    sim, L0 = column(aspect, **kw)
    free = sim.free
    floor_top = _floor_top(sim)
    y = np.sort(sim.positions[free, 1])
    H0 = float(np.mean(y[-3:]) + 0.5 * D - floor_top)
    a = H0 / L0
    sim.column = {"L0": L0, "H0": H0, "packing_fraction": packing_fraction(sim, L0), "grains": int(free.sum())}
    sim.walls = (0.0, np.inf, -np.inf, np.inf)      # open the gate at x = L0
    t_open = sim.time
    sim.run(sim.time + 2.95, sim.dt_max)
    frozen(sim)                                     # the last 0.05 s: measure the motion
    # runout: front of the deposit = rightmost outline point of a free grain touching
    # another free grain (a grain that bounced away alone does not count)
    c = sim.contacts
    both = (c.j >= 0) & free[c.i] & free[np.maximum(c.j, 0)]
    touching = np.zeros(sim.n, bool)
    touching[c.i[both]] = True
    touching[c.j[both]] = True
    front = max(o[:, 0].max() for k, o in enumerate(sim.outlines()) if touching[k])
    return a, (front - L0) / L0, sim, sim.time - t_open


def lube(a: float) -> float:
    """Normalised runout (L∞ − L0)/L0 of a dry 2D column collapse of aspect ratio ``a``.

    Lube et al. (2005), *J. Fluid Mech.* 508, 175–199: 1.2 a for a ≤ 2.3, 1.9 a^(2/3) above.

    Examples
    --------
    >>> from fluidem.cases.collapse import lube
    >>> round(lube(1.0), 3), round(lube(4.0), 3)
    (1.2, 4.788)
    """
    return 1.2 * a if a <= 2.3 else 1.9 * a ** (2.0 / 3.0)
