"""Flow splitting at a junction between four bodies, with and without a junction node (paper Sec. 3.2, Fig. 4).

Set-up: four fixed polygons fill a box except for two straight channels of width ``gap`` that
cross at a junction: a horizontal one and one at ``angle`` to it (90°: the blunt junction of
Fig. 4a; 45°: the sharp one of Fig. 4b, whose lower branch turns the flow by 135°).  The bodies
touch the box sides, so the fluid is the two channels alone (the moving mesh meshes each body
with its walls as one outline).  Stokes flow of unit viscosity enters the left end of the
horizontal channel with the Poiseuille profile of unit centre speed and leaves through the
other three ends (do-nothing, the same pressure at each); the *flux split* is the share of the
inflow leaving through each outlet, ``Q_k / Q_in`` by the boundary integral of ``u · n``.

With ``h`` about the gap every channel is one element wide (``gap_purge``): its straight parts
are exact for a quadratic velocity (Poiseuille), so what the coarse mesh gets wrong is the
junction, where two triangles span three bodies each.  The junction variants (:func:`junction_mesh`):

``"off"``
    ``MovingMesh(junctions=False)``;
``"library"``
    ``MovingMesh(junctions=True)``: :func:`fluidem.mesh.junctions.junction_points` as the
    mesh uses it, with its quality screen (the three triangles of the split keep their angles
    in [25°, 125°]);
``"voronoi"``
    the same candidate point (Voronoi vertex of the three body centres, else incentre or
    centroid) without the angle screen (clearance ``0.3 h`` kept);
``"centre"``
    one node where the diagonals of the quadrilateral of two junction triangles sharing an
    edge cross, splitting both (four triangles around one node).

The reference is the same fluid region on a fine body-fitted mesh of its own
(:func:`reference_mesh`, Triangle with a 30° quality bound), independent of the moving mesh.
"""

from __future__ import annotations

import numpy as np
import shapely

from ..errors import InputError

__all__ = ["VARIANTS", "OUTLETS", "junction_geometry", "junction_mesh", "reference_mesh", "flux_split",
           "junction_case"]

#: junction variants of :func:`junction_mesh`
VARIANTS = ("off", "library", "voronoi", "centre")
#: the outlets, in the order of the flux split
OUTLETS = ("right", "top", "bottom")


def junction_geometry(angle: float = 90.0, gap: float = 0.1, junction=(0.037, 0.021)) -> dict:
    """Four bodies around a junction of two channels (module docstring).

    Parameters
    ----------
    angle : float
        Angle between the channels, degrees, in [30, 90].
    gap : float
        Channel width, length, > 0.
    junction : (2,) float
        Where the channel centrelines cross, length (off the background grid's nodes, so that
        no background node lands in the junction).

    Returns
    -------
    dict
        ``box`` (xmin, xmax, ymin, ymax): [−0.5, 0.5]² at 90°, wider at smaller angles so that
        the inclined channel leaves through the top and the bottom; ``bodies`` (4,) arrays
        (n_i, 2) in body coordinates; ``poses`` (4, 3); ``fluid`` the fluid region (shapely);
        ``gap``, ``angle``, ``junction``.

    Examples
    --------
    >>> g = junction_geometry(90.0, 0.1)
    >>> len(g["bodies"]), round(g["fluid"].area, 4)           # two channels of 1 × 0.1 less their crossing
    (4, 0.19)
    """
    if not 30.0 <= float(angle) <= 90.0:
        raise InputError(f"junction_geometry(angle=...) = {angle!r}: expected degrees in [30, 90]")
    if not (np.isfinite(gap) and gap > 0):
        raise InputError(f"junction_geometry(gap=...) = {gap!r}: expected a length > 0")
    th = np.radians(angle)
    lx = 0.5 + 0.5 / np.tan(th) + 1e-12 if angle < 90 else 0.5
    ly = 0.5
    xj, yj = map(float, junction)
    a = 0.5 * gap
    box = shapely.box(-lx, -ly, lx, ly)
    d, n = np.array([np.cos(th), np.sin(th)]), np.array([-np.sin(th), np.cos(th)])
    c, r = np.array([xj, yj]), 10.0 * (lx + ly)
    horizontal = shapely.box(-r, yj - a, r, yj + a)
    inclined = shapely.Polygon([c - r * d - a * n, c + r * d - a * n, c + r * d + a * n, c - r * d + a * n])
    channels = horizontal.union(inclined)
    solids = box.difference(channels)
    parts = sorted(solids.geoms, key=lambda p: np.arctan2(p.centroid.y - yj, p.centroid.x - xj))
    bodies, poses = [], []
    for p in parts:
        p = shapely.geometry.polygon.orient(p.simplify(1e-12), 1.0)
        cc = np.array([p.centroid.x, p.centroid.y])
        bodies.append(np.asarray(p.exterior.coords)[:-1] - cc)
        poses.append([cc[0], cc[1], 0.0])
    return {"box": (-lx, lx, -ly, ly), "bodies": bodies, "poses": np.array(poses), "fluid": box.intersection(channels),
            "gap": float(gap), "angle": float(angle), "junction": (xj, yj)}


def _with_boundaries(points, triangles, segments, markers):
    """scikit-fem mesh of ``points`` (n, 2), ``triangles`` (m, 3) with the box sides named from
    ``segments`` (k, 2) and their ``markers`` (1–4: bottom, right, top, left; others: ``walls``)."""
    from skfem import MeshTri

    from ..mesh.triangulate import SIDE_NAMES, _facet_lookup

    m = MeshTri(np.asarray(points, float).T.copy(), np.asarray(triangles).T.copy())
    look = _facet_lookup(m)
    bnd = {name: look(segments[markers == k + 1]) for k, name in enumerate(SIDE_NAMES)}
    bnd["walls"] = look(segments[markers > len(SIDE_NAMES)])
    return m.with_boundaries(bnd)


def _centre_split(points, triangles, jt):
    """Split every pair of junction triangles ``jt`` sharing an edge at the crossing of the
    diagonals of their quadrilateral (four triangles around one node, orientation kept)."""
    t = np.asarray(triangles).copy()
    p = np.asarray(points, float)
    new, extra, used = [], [], set()
    for a in jt:  # a handful of junction triangles: a loop over pairs is cheap
        for b in jt:
            if b <= a or a in used or b in used:
                continue
            shared = set(t[a]) & set(t[b])
            if len(shared) != 2:
                continue
            ta = list(t[a])
            k = (set(ta) - shared).pop()
            r = ta.index(k)
            i, j = ta[(r + 1) % 3], ta[(r + 2) % 3]  # t[a] = (k, i, j), t[b] holds (l, j, i)
            lv = (set(t[b]) - shared).pop()
            s = np.linalg.solve(np.column_stack([p[j] - p[i], p[k] - p[lv]]), p[k] - p[i])[0]
            if not 0.0 < s < 1.0:  # the quadrilateral is not convex: no crossing on the shared edge
                continue
            c = len(p) + len(new)
            new.append(p[i] + s * (p[j] - p[i]))
            t[a], t[b] = [k, i, c], [lv, j, c]
            extra += [[k, c, j], [lv, c, i]]
            used |= {a, b}
    pts = np.vstack([p] + ([np.array(new)] if new else []))
    return pts, np.vstack([t] + ([np.array(extra)] if extra else [])), len(new)


def junction_mesh(geometry: dict, h: float, variant: str = "off"):
    """The moving mesh of ``geometry`` at size ``h`` (``strategy="fixed"``) with a junction variant.

    Parameters
    ----------
    geometry : dict
        :func:`junction_geometry`.
    h : float
        Mesh size, length.
    variant : {"off", "library", "voronoi", "centre"}
        Module docstring.

    Returns
    -------
    mesh : skfem.MeshTri
        Boundaries ``left`` (inlet), ``right``, ``top``, ``bottom`` (outlets) and ``walls``.
    n_points : int
        Junction nodes the variant added.
    """
    from ..mesh import MovingMesh
    from ..mesh.junctions import junction_points, junction_triangles, split_triangles
    from ..mesh.nodes import CONTACT, OUTLINE

    if variant not in VARIANTS:
        raise InputError(f"junction variant {variant!r}: expected one of {', '.join(VARIANTS)}")
    g = geometry
    mm = MovingMesh(g["box"], g["bodies"], g["poses"], h=h, strategy="fixed", junctions=variant == "library")
    pts, tri, n_new = mm.points, mm.triangles, mm.n_junctions
    owner = np.where((mm.kind == OUTLINE) | (mm.kind == CONTACT), mm.body_of, -1)
    if variant == "voronoi":
        jt, q = junction_points(pts, tri, owner, mm.poses[:, :2], np.asarray(mm._polygons()), h,
                                clearance=mm.params.junction_clearance, min_angle=0.0, max_angle=180.0)
        tri = split_triangles(tri, jt, len(pts) + np.arange(len(q)))
        pts, n_new = np.vstack([pts, q]), len(q)
    elif variant == "centre":
        pts, tri, n_new = _centre_split(pts, tri, junction_triangles(tri, owner))
    return _with_boundaries(pts, tri, mm.boundary_segments, mm.boundary_markers), int(n_new)


def reference_mesh(geometry: dict, h: float):
    """A body-fitted mesh of the fluid region of ``geometry``, size ``h`` (Triangle, 30° quality bound).

    Returns a :class:`skfem.MeshTri` with the boundaries of :func:`junction_mesh`.
    """
    import triangle as tr

    fluid = shapely.geometry.polygon.orient(shapely.segmentize(geometry["fluid"], h), 1.0)
    v = np.asarray(fluid.exterior.coords)[:-1]
    seg = np.column_stack([np.arange(len(v)), (np.arange(len(v)) + 1) % len(v)])
    out = tr.triangulate({"vertices": v, "segments": seg}, f"pq30a{np.sqrt(3) / 4 * h * h:.12f}Q")
    p, s = out["vertices"], out["segments"]
    xmin, xmax, ymin, ymax = geometry["box"]
    mid = 0.5 * (p[s[:, 0]] + p[s[:, 1]])
    tol = 1e-9 * (xmax - xmin)
    marker = np.full(len(s), 10)
    for k, on in enumerate((np.abs(mid[:, 1] - ymin), np.abs(mid[:, 0] - xmax), np.abs(mid[:, 1] - ymax),
                            np.abs(mid[:, 0] - xmin))):
        marker[on < tol] = k + 1
    return _with_boundaries(p, out["triangles"], s, marker)


def flux_split(mesh, geometry: dict, element: str = "p2b") -> dict:
    """Stokes flow through the junction of ``geometry`` on ``mesh`` and its flux split.

    Parameters
    ----------
    mesh : skfem.MeshTri
        :func:`junction_mesh` or :func:`reference_mesh`.
    geometry : dict
        :func:`junction_geometry`.
    element : str
        Element pair (:mod:`fluidem.fluid.elements`).

    Returns
    -------
    dict
        ``split`` (3,) ``Q_k / Q_in`` for :data:`OUTLETS`; ``inflow`` ``Q_in`` (length²/time;
        ``2/3 · gap`` exactly); ``mass_defect`` ``|ΣQ_out − Q_in| / Q_in``; ``condition`` the 1-norm
        condition estimate of the Stokes LU (:func:`fluidem.diagnostics.lu_condition`);
        ``dofs``.
    """
    from skfem import FacetBasis, Functional

    from ..diagnostics import lu_condition
    from ..fluid import FlowProblem, FlowSpace, VelocityBC
    from ..fluid.navier_stokes import solve_stokes

    yj, a = geometry["junction"][1], 0.5 * geometry["gap"]
    space = FlowSpace(mesh, element)
    bcs = [VelocityBC("walls", (0.0, 0.0)),
           VelocityBC("left", lambda x, y, t: np.array([np.clip(1.0 - ((y - yj) / a) ** 2, 0.0, None), 0.0 * y]))]
    problem = FlowProblem(space, 1.0, bcs)
    solver = problem.direct_solver()
    x = solve_stokes(problem, solver=solver).x

    @Functional
    def normal_flux(w):
        return w["u"][0] * w.n[0] + w["u"][1] * w.n[1]

    q = {}
    for name in ("left",) + OUTLETS:
        fb = FacetBasis(mesh, space.ub.elem, facets=mesh.boundaries[name], intorder=6)
        q[name] = float(normal_flux.assemble(fb, u=fb.interpolate(x[: space.n_u])))
    q_in = -q["left"]
    out = np.array([q[k] for k in OUTLETS])
    return {"split": out / q_in, "inflow": q_in, "mass_defect": abs(out.sum() - q_in) / q_in,
            "condition": lu_condition(solver), "dofs": int(space.n_dofs)}


def junction_case(angle: float, h: float, variant: str, element: str = "p2b", reference: dict | None = None,
                  h_reference: float | None = None, gap: float = 0.1) -> dict:
    """One row of the comparison: the flux split of a junction variant against the fine reference.

    Parameters
    ----------
    angle, gap : float
        :func:`junction_geometry`.
    h : float
        Mesh size, length.
    variant : str
        :data:`VARIANTS`.
    element : str
        Element pair.
    reference : dict or None
        :func:`flux_split` on the reference mesh, if computed already; else computed on
        :func:`reference_mesh` at ``h_reference`` (default ``gap / 4``).

    Returns
    -------
    dict
        :func:`flux_split` plus ``n_points`` (junction nodes added), ``reference`` (its split),
        ``error`` ``max_k |split_k − reference_k|`` (a share of the inflow) and the inputs.

    Examples
    --------
    >>> r = junction_case(90.0, 0.1, "off")
    >>> r["n_points"], bool(r["error"] > 0.05)                # a one-element junction: 8 % of the inflow
    (0, True)
    """
    geo = junction_geometry(angle, gap)
    if reference is None:
        reference = flux_split(reference_mesh(geo, h_reference or gap / 4), geo, element)
    mesh, n_points = junction_mesh(geo, h, variant)
    r = flux_split(mesh, geo, element)
    r.update(angle=float(angle), h=float(h), gap=float(gap), variant=variant, element=element, n_points=n_points,
             reference=reference["split"], error=float(np.abs(r["split"] - reference["split"]).max()))
    return r
