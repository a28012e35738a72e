"""Gaps resolved by one to three elements: force, gap profile and condition per element pair.

The paper (Sec. 3.1) holds that elements of constant curvature (first and second order) cannot
represent the velocity across a gap between close surfaces moving in opposite directions, and that
P2+bubble ("quasi-third order") can.  Two Stokes problems (unit viscosity, a closed box with
no-slip walls, disks of radius ``a`` as polygons inscribed in the circle, a vertex facing the gap:
:func:`disk_outline`) put that to the test on meshes with ``n`` element layers across the gap:

``"sliding"``
    Two disks sliding past each other in opposite directions: centres (0, ±(a + δ/2)), the upper
    one moving at (+1, 0), the lower one at (−1, 0), neither turning, box [−6a, 6a] × [−6a, 6a].
    The gap is symmetric and the mean of the wall speeds is zero, so lubrication theory puts no
    pressure in the gap: the profile across it is linear (Couette) at leading order, with a slope
    that varies along the gap.  Loads: the force and torque on the upper disk.
``"rotating"``
    A disk turning at unit angular speed (counter-clockwise) at the gap δ above the floor of the
    box [−6a, 6a] × [0, 6a], not translating.  Its surface moves at ``a`` over a wall at rest, so
    the gap carries a pressure-driven (Poiseuille) flow on top of the shear: at the narrowest
    section the lubrication profile is the full parabola ``u = a y (2δ − y) / δ²``, the non-linear
    gap profile.  Loads: the force and torque on the disk.

The mesh (:func:`gap_mesh`): a constrained Delaunay triangulation (Triangle, 30° smallest angle)
whose size field is the local gap width (the sum of the distances to the two surfaces, which is the
width of the gap across a point in it) over ``max(n − ½, ¾)``, capped by ``h_body`` graded away from
the disks.  So the gap is meshed in ``n`` layers wherever it is narrower than about ``n · h_body``,
the rest of the mesh is the same for every ``n``, and the polygon is the same for every ``n`` and
refinement.  :func:`layers_across` counts the layers (the fewest mesh edges from one surface to the
other).

:func:`gap_case` solves one (element, n) and returns the loads, the velocity across the gap at two
sections (x = 0 and x = √(aδ), where the gap is about 2δ wide between the disks, 1.5δ under the
turning one) and the 1-norm condition estimate of the LU (:func:`fluidem.diagnostics.lu_condition`).
The reference is the same problem on a finer mesh (``refine``, ``gap_refine``) with P3/P2
(``benchmarks/bench_stability_curvature.py``, ``docs/stability.md``).  :func:`couette_case` is the
sanity check: plane Couette flow between plates moving at ±1, which every pair represents exactly.
"""

from __future__ import annotations

import time

import numpy as np

from .. import validate
from ..errors import InputError

__all__ = ["GEOMETRIES", "gap_mesh", "disk_outline", "layers_across", "gap_case", "couette_case",
           "lubrication_profile"]

#: The two set-ups of the module docstring.
GEOMETRIES = ("sliding", "rotating")

_BOX = 6.0  # half-width of the box in radii


def _layout(geometry: str, a: float, delta: float) -> dict:
    """Bodies (name, centre, velocity, omega), the box, and the walls of the gap."""
    L = _BOX * a
    if geometry == "sliding":
        c = a + 0.5 * delta
        return {"box": (-L, L, -L, L),
                "bodies": [("upper", (0.0, c), (1.0, 0.0), 0.0), ("lower", (0.0, -c), (-1.0, 0.0), 0.0)],
                "gap": (-0.5 * delta, 0.5 * delta), "surface_speed": 1.0}
    if geometry == "rotating":
        return {"box": (-L, L, 0.0, L), "bodies": [("disk", (0.0, a + delta), (0.0, 0.0), 1.0)],
                "gap": (0.0, delta), "surface_speed": a}
    raise InputError(f"geometry = {geometry!r}: expected one of {', '.join(map(repr, GEOMETRIES))}")


def _distances(layout: dict, a: float, points) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each point (m, 2) to the nearest disk, and the local gap width there (the sum of
    the distances to the two surfaces of the gap), lengths (m,)."""
    p = np.asarray(points, dtype=float)
    centres = np.array([b[1] for b in layout["bodies"]])
    d = np.maximum(np.linalg.norm(p[:, None, :] - centres[None, :, :], axis=2) - a, 0.0)  # (m, bodies)
    gap = d[:, 0] + (d[:, 1] if len(centres) == 2 else p[:, 1] - layout["box"][2])
    return d.min(axis=1), gap


def gap_mesh(geometry: str, n: int, delta: float, a: float = 1.0, h_body: float | None = None,
             growth: float = 1.25, refine: float = 1.0, gap_refine: float = 1.0):
    """The mesh of :func:`gap_case`: a :class:`skfem.MeshTri` with boundaries named by body and side.

    Parameters
    ----------
    geometry : {"sliding", "rotating"}
    n : int
        Element layers across the narrowest section, ≥ 1.  The size field in the gap is the local gap
        width over ``max(n − ½, ¾)``: Triangle's quality meshes (30° smallest angle) put ``n``
        layers across it so (measured by :func:`layers_across` for n = 1, 2, 3 and δ/a from 0.005
        to 0.1; a divisor ``n`` gives ``n + 1`` layers or more).
    delta : float
        Narrowest gap, length.
    a : float
        Disk circumradius, length.
    h_body : float
        Size at the disks away from the gap, length; ``a / 8`` by default.
    growth : float
        Size ratio of neighbouring cells away from the disks.
    refine : float
        Divides the whole size field (the reference meshes).
    gap_refine : float
        Divides the gap part of the size field once more.

    Returns
    -------
    (skfem.MeshTri, dict)
        The mesh and the layout (bodies as ``(name, centre, velocity, omega)``, ``box``, ``gap``:
        the y-interval of the narrowest section, ``surface_speed``).
    """
    from ..mesh.triangulate import Obstacle, to_skfem, triangulate_box

    n = validate.integer("gap_mesh(n=...)", n, lo=1)
    delta = validate.positive("gap_mesh(delta=...)", delta)
    a = validate.positive("gap_mesh(a=...)", a)
    layout = _layout(geometry, a, delta)
    h_body = a / 8.0 if h_body is None else validate.positive("gap_mesh(h_body=...)", h_body)
    across = max(n - 0.5, 0.75)

    def field(points, divisor):
        d, gap = _distances(layout, a, points)
        graded = np.minimum(8.0 * h_body, h_body + (growth - 1.0) * d)
        return np.minimum(graded, np.maximum(gap, 1e-12 * a) / divisor)

    def size(points):
        return field(points, across * gap_refine) / refine

    def outline(points):  # the polygon: vertices a gap width apart in the gap, the same for every n
        return field(points, 1.0)

    obstacles = [Obstacle(disk_outline(c, a, outline, (0.0, 0.5 * sum(layout["gap"]))), name)
                 for name, c, _, _ in layout["bodies"]]
    return to_skfem(triangulate_box(layout["box"], obstacles, size)), layout


def disk_outline(centre, a: float, size, towards) -> np.ndarray:
    """Polygon inscribed in a circle, its vertices spaced by a size field along the circle.

    Parameters
    ----------
    centre : (2,) float
        Centre of the circle, length.
    a : float
        Radius, length.
    size : callable ``points (m, 2) -> (m,)``
        Target vertex spacing, length.
    towards : (2,) float
        One vertex is the point of the circle nearest to it; the others are symmetric about that
        one for a size field symmetric about the line through it and the centre.

    Returns
    -------
    (k, 2) float
        Vertices, counter-clockwise, length.

    Examples
    --------
    >>> v = disk_outline((0.0, 0.0), 1.0, lambda p: np.full(len(p), 2 * np.pi / 8), (0.0, -5.0))
    >>> len(v), np.round(v[0], 12).tolist()
    (8, [0.0, -1.0])
    """
    c = np.asarray(centre, float)
    d = np.asarray(towards, float) - c
    theta0 = np.arctan2(d[1], d[0])
    phi = np.linspace(0.0, 2.0 * np.pi, 4001)
    pts = c + a * np.column_stack([np.cos(theta0 + phi), np.sin(theta0 + phi)])
    inv = a / np.asarray(size(pts), dtype=float)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(phi))])
    k = int(np.ceil(cum[-1] - 1e-9))
    t = theta0 + np.interp(np.linspace(0.0, cum[-1], k + 1)[:-1], cum, phi)
    return c + a * np.column_stack([np.cos(t), np.sin(t)])


def layers_across(mesh, lower: str, upper: str, x: float = 0.0, window: float = 0.0) -> int:
    """Element layers across a gap: the fewest mesh edges on a path from a node of boundary ``lower``
    to one of ``upper``, from the nodes of ``lower`` within ``window`` of the abscissa ``x`` (the
    nearest one if none).  One layer of triangles spanning the gap is 1; a structured gap of
    ``n`` rows of cells is ``n``.
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import shortest_path

    nodes_lo = np.unique(mesh.facets[:, mesh.boundaries[lower]])
    nodes_up = np.unique(mesh.facets[:, mesh.boundaries[upper]])
    # the halves of the two outlines that face each other
    y_up, y_lo = mesh.p[1, nodes_up].min(), mesh.p[1, nodes_lo].max()
    nodes_lo = nodes_lo[mesh.p[1, nodes_lo] >= 0.5 * (y_lo + mesh.p[1, nodes_lo].min())]
    nodes_up = nodes_up[mesh.p[1, nodes_up] <= 0.5 * (y_up + mesh.p[1, nodes_up].max())]
    near = nodes_lo[np.abs(mesh.p[0, nodes_lo] - x) <= window]
    if len(near) == 0:
        near = nodes_lo[[np.argmin(np.abs(mesh.p[0, nodes_lo] - x))]]
    f = mesh.facets
    nv = mesh.p.shape[1]
    G = sp.coo_matrix((np.ones(f.shape[1]), (f[0], f[1])), shape=(nv, nv)).tocsr()
    d = shortest_path(G, directed=False, unweighted=True, indices=near)
    return int(d[:, nodes_up].min())


def _gap_sides(layout: dict) -> tuple[str, str]:
    """Boundary names below and above the gap."""
    names = [b[0] for b in layout["bodies"]]
    return (names[1], names[0]) if len(names) == 2 else ("bottom", names[0])


def lubrication_profile(geometry: str, eta, a: float = 1.0) -> np.ndarray:
    """Leading-order (lubrication) u_x across the narrowest section at ``eta`` ∈ [0, 1] (bottom to top).

    ``"sliding"``: the linear Couette profile from −1 to +1; ``"rotating"``: the parabola
    ``a η (2 − η)`` (the wall at rest, the disk's surface at speed ``a``, zero shear at the disk).
    """
    eta = np.asarray(eta, dtype=float)
    if geometry == "sliding":
        return 2.0 * eta - 1.0
    if geometry == "rotating":
        return a * eta * (2.0 - eta)
    raise InputError(f"geometry = {geometry!r}: expected one of {', '.join(map(repr, GEOMETRIES))}")


def _section(mesh, layout: dict, x: float) -> tuple[float, float]:
    """y-interval of the gap at abscissa x: between the boundary edges of the mesh above and below
    the centre of the narrowest section."""
    y_mid = 0.5 * sum(layout["gap"])
    below, above = [layout["box"][2]], []
    for name, _, _, _ in layout["bodies"]:
        e = mesh.p[:, mesh.facets[:, mesh.boundaries[name]]]  # (2, 2 ends, k)
        x0, x1 = e[0, 0], e[0, 1]
        hit = (np.minimum(x0, x1) <= x) & (x <= np.maximum(x0, x1)) & (x0 != x1)
        s = (x - x0[hit]) / (x1[hit] - x0[hit])
        y = e[1, 0, hit] + s * (e[1, 1, hit] - e[1, 0, hit])
        below += [v for v in y if v < y_mid]
        above += [v for v in y if v > y_mid]
    return max(below), min(above)


def gap_case(geometry: str, element: str, n: int, delta: float, a: float = 1.0, h_body: float | None = None,
             refine: float = 1.0, gap_refine: float = 1.0, profile_points: int = 41) -> dict:
    """Solve one set-up of the module docstring (Stokes, μ = 1) and measure it.

    Parameters
    ----------
    geometry : {"sliding", "rotating"}
    element : str
        Element pair (``mini``, ``th``, ``p2b``, ``p3``).
    n, delta, a, h_body, refine, gap_refine
        As :func:`gap_mesh`.
    profile_points : int
        Points across the gap at each section (the surfaces included).

    Returns
    -------
    dict
        ``fx``, ``fy``, ``torque`` (on the upper disk or the rotating one, about its centre, per
        unit depth, μ = 1), ``sections`` (x of each section), ``profiles`` (u_x at the points,
        one list per section, ``profile_points`` each from the lower surface up), ``condition`` (the
        1-norm condition estimate of the LU, dimensionless), ``dofs``, ``cells``, ``layers``
        (element layers across the narrowest section, :func:`layers_across`), ``h_min`` (shortest
        edge, length), ``seconds`` (wall time).
    """
    from ..diagnostics import lu_condition
    from ..fluid import FlowProblem, FlowSpace, RigidMotion, VelocityBC, solve_stokes
    from ..fluid.forces import RigidModes
    from ..fluid.solvers import DirectSolver

    t0 = time.perf_counter()
    mesh, layout = gap_mesh(geometry, n, delta, a=a, h_body=h_body, refine=refine,
                            gap_refine=gap_refine)
    space = FlowSpace(mesh, element)
    bcs = [VelocityBC(["left", "right", "bottom", "top"], (0.0, 0.0))]
    bcs += [VelocityBC(name, RigidMotion(v, om, c)) for name, c, v, om in layout["bodies"]]
    problem = FlowProblem(space, 1.0, bcs, viscous="stress")  # exact torques (fluidem.fluid.problem)
    solver = DirectSolver()  # COLAMD, partial pivoting: the same LU for every pair
    state = solve_stokes(problem, solver=solver)
    condition = lu_condition(solver)
    name, centre = layout["bodies"][0][:2]
    F, T = RigidModes(space, [name], [centre]).loads(problem.steady_residual(state.x, convection=False))
    sections = [0.0, float(np.sqrt(a * delta))]
    profiles = []
    for x in sections:
        y0, y1 = _section(mesh, layout, x)
        eta = np.linspace(0.0, 1.0, profile_points)
        pad = 1e-9 * a  # a hair inside the fluid
        ys = y0 + pad + eta * (y1 - y0 - 2 * pad)
        P = space.probe_matrix(np.column_stack([np.full_like(ys, x), ys]), field="velocity")
        profiles.append((P @ state.u)[0::2].tolist())
    edges = mesh.p[:, mesh.facets]
    return {"fx": float(F[0, 0]), "fy": float(F[0, 1]), "torque": float(T[0]), "sections": sections,
            "profiles": profiles, "condition": None if condition is None else float(condition),
            "dofs": int(space.n_dofs),
            "cells": int(mesh.t.shape[1]), "layers": layers_across(mesh, *_gap_sides(layout), window=delta),
            "h_min": float(np.linalg.norm(edges[:, 0] - edges[:, 1], axis=0).min()),
            "seconds": time.perf_counter() - t0}


def couette_case(element: str, n: int, width: float = 1.0, gap: float = 0.1) -> dict:
    """Plane Couette flow between plates moving at ±1, ``n`` elements across the gap (periodic in x).

    A structured mesh of right triangles of legs ``gap / n``.  Every pair holds the linear profile
    exactly: the force per unit length on the upper plate is −2μ/δ (μ = 1).

    Parameters
    ----------
    element : str
        Element pair (``mini``, ``th``, ``p2b``, ``p3``).
    n : int
        Rows of cells across the gap.
    width : float
        Period in x, length.
    gap : float
        Distance between the plates, length.

    Returns
    -------
    dict
        ``fx`` (force on the upper plate per unit length), ``exact`` (−2/δ), ``profile_error``
        (largest |u − exact| over 101 × 11 points of the gap, velocity units), ``condition``.

    Examples
    --------
    >>> r = couette_case("th", 1)
    >>> round(r["fx"], 9), r["exact"], r["profile_error"] < 1e-12
    (-20.0, -20.0, True)
    """
    from skfem import MeshTri

    from ..diagnostics import lu_condition
    from ..fluid import FlowProblem, FlowSpace, VelocityBC, solve_stokes
    from ..fluid.forces import side_loads

    nx = max(1, int(round(width / (gap / n))))
    m = MeshTri.init_tensor(np.linspace(0.0, width, nx + 1), np.linspace(-0.5 * gap, 0.5 * gap, n + 1))
    m = m.with_boundaries({"bottom": lambda x: np.isclose(x[1], -0.5 * gap),
                           "top": lambda x: np.isclose(x[1], 0.5 * gap),
                           "left": lambda x: np.isclose(x[0], 0.0),
                           "right": lambda x: np.isclose(x[0], width)})
    space = FlowSpace(m, element)
    problem = FlowProblem(space, 1.0, [VelocityBC("top", (1.0, 0.0)), VelocityBC("bottom", (-1.0, 0.0))],
                          periodic=("x",), viscous="stress")
    solver = problem.direct_solver()
    state = solve_stokes(problem, solver=solver)
    f = side_loads(space, problem.steady_residual(state.x, convection=False), ["top"])
    X, Y = np.meshgrid(np.linspace(0.0, width, 101), np.linspace(-0.5 * gap, 0.5 * gap, 11))
    u = (space.probe_matrix(np.column_stack([X.ravel(), Y.ravel()]), field="velocity") @ state.u).reshape(-1, 2)
    err = np.abs(u - np.column_stack([2.0 * Y.ravel() / gap, np.zeros(Y.size)])).max()
    return {"fx": float(f[0, 0]) / width, "exact": -2.0 / gap, "profile_error": float(err),
            "condition": lu_condition(solver)}
