"""Mesh size before the mesh: estimates of triangles, nodes, DOFs and memory, and the warnings
and refusals they call for (memory, a coarse box, coarse or thin bodies)."""

from __future__ import annotations

import numpy as np

from .effects import readable_bytes

__all__ = ["DOFS_PER_VERTEX", "TRIANGLES_PER_AREA", "TRIANGLES_PER_AREA_FK", "BYTES_PER_DOF", "BYTES_BASE",
           "BYTES_PER_DOF_ITERATIVE", "BYTES_PER_DOF_PARDISO", "BYTES_SETUP_PER_DOF", "planned_solver",
           "planned_lu_backend", "MIN_EDGES_PER_BODY", "MIN_THICKNESS_PER_H", "machine_memory", "moving_mesh_scene",
           "mesh_estimate", "mesh_warnings"]

#: DOFs per mesh vertex of each element pair on a triangle mesh (E ≈ 3V edges, T ≈ 2V triangles)
DOFS_PER_VERTEX = {"th": 9.0, "p2b": 18.0, "p3": 22.0, "mini": 7.0}
#: measured: triangles ≈ this × area / h² on meshes Triangle refines to the size (bodies that do not
#: move, graded meshes): an equilateral mesh has 2.31; the quality refinement adds the rest
TRIANGLES_PER_AREA = 3.6
#: the moving mesh on a uniform size starts from the Friedrichs–Keller grid of spacing h: two
#: right triangles per h² square (paper Sec. 2.1), whatever the number of bodies; measured 2.00 for
#: one disk at h = 0.05 and 0.025, 2.14 for the 20 disks of the sheared-suspension example and
#: 2.03 for the 105 polygons of the suspension example
TRIANGLES_PER_AREA_FK = 2.1
#: measured peak memory per DOF of a run (matrices, the LU factors, the moving mesh), bytes; plus a base
BYTES_PER_DOF, BYTES_BASE = 11e3, 150e6
#: the same where the run solves with block-preconditioned GMRES (``fluid.solver = "iterative"``, or
#: ``"auto"`` where the LU would not fit): memory linear in DOFs, the peak at a re-triangulation (the new
#: problem built beside the old one) or in a Krylov solve.  Measured on settling suspensions (P2+bubble,
#: ``benchmarks/bench_solver_scale.py`` scenes): a re-triangulation of 300 polygons peaked at 9.3 kB a DOF
#: (4 203 MiB at 474k DOFs; ordinary steps 7.5 kB); 2 000 polygons (3.15M DOFs, ordinary steps 7.0 kB,
#: 21 718 MiB) were killed at their first re-triangulation on a 24 GB machine (above 7.8 kB a DOF)
BYTES_PER_DOF_ITERATIVE = 9.0e3
#: the same where the run keeps a lagged PARDISO LU (``fluid.lu_backend`` ``"pardiso"``, or ``"auto"`` with
#: ``pypardiso`` installed): PARDISO's fill grows as n^1.1, about as the rest of a run's memory shrinks per
#: DOF.  Measured on the same suspensions, the peak at a re-triangulation (the old LU released first):
#: 7.6 kB a DOF at 1.57M DOFs (11 711 MiB) and 7.7 kB at 3.15M (23 152 MiB); an ordinary step 6.3 and 6.5
BYTES_PER_DOF_PARDISO = 7.8e3
#: resident memory of a run after its set-up, before the first LU, bytes per DOF (2 000 settling polygons,
#: 3.15M DOFs: 10 523 MiB): what the plan takes from the available memory before it asks whether the LU fits
BYTES_SETUP_PER_DOF = 3.5e3
#: smallest mesh edges along a body's outline, and smallest thickness / h, before a warning
MIN_EDGES_PER_BODY, MIN_THICKNESS_PER_H = 8, 0.1


def machine_memory() -> tuple[float, float]:
    """(total, available) physical memory of this machine, bytes (``inf`` when unknown)."""
    import os

    try:
        page = os.sysconf("SC_PAGE_SIZE")
        return float(page * os.sysconf("SC_PHYS_PAGES")), float(page * os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not a POSIX system
        return float("inf"), float("inf")


def _outline_stats(scene):
    """(areas (n,), perimeters (n,)) of the bodies' initial outlines, length² and length."""
    outlines = scene.world_outlines()
    area = np.array([0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
                     for p in outlines])  # once per plan
    perim = np.array([np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum() for p in outlines])
    return area, perim


def _graded_cells(scene, fluid_area: float) -> float:
    """∫ dA / h(x)² over the fluid for the graded size h = min(h_max, h + (growth − 1) d)
    (:class:`fluidem.mesh.background.GradedSize`), d the distance to the grading region (the
    bodies' bounding circles, or a box), by the midpoint rule on a grid of ~40k cells scaled to
    the fluid area."""
    from scipy.spatial import cKDTree

    x0, x1, y0, y1 = scene.domain.box
    g, h = scene.mesh.grading, scene.mesh.h
    n = 200
    nx = max(8, int(round(n * np.sqrt((x1 - x0) / (y1 - y0)))))
    ny = max(8, int(round(n * n / nx)))
    X, Y = np.meshgrid(x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx, y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny)
    P = np.column_stack([X.ravel(), Y.ravel()])
    reg = g["region"]
    if reg == "bodies":
        if not scene.bodies:
            return fluid_area / h / h
        C = np.array([b.position for b in scene.bodies], float)
        R = np.array([b.bounding_radius for b in scene.bodies])
        k = min(8, len(C))
        dist, idx = cKDTree(C).query(P, k=k)
        dist, idx = dist.reshape(len(P), k), idx.reshape(len(P), k)
        d = np.maximum((dist - R[idx]).min(axis=1), 0.0)
    else:
        dx = np.maximum(np.maximum(reg[0] - P[:, 0], P[:, 0] - reg[1]), 0.0)
        dy = np.maximum(np.maximum(reg[2] - P[:, 1], P[:, 1] - reg[3]), 0.0)
        d = np.hypot(dx, dy)
    size = np.minimum(g["h_max"], h + (g["growth"] - 1.0) * d)
    box_area = (x1 - x0) * (y1 - y0)
    with np.errstate(over="ignore"):  # an absurdly small h: inf, which the plan refuses
        return float(np.mean((1.0 / size) / size)) * fluid_area if box_area > 0 else 0.0


def moving_mesh_scene(scene) -> bool:
    """Whether ``scene``'s flow is solved on the moving mesh (:mod:`fluidem.mesh.moving`): it has
    free bodies, or bodies whose outlines move over more than one quasi-static Stokes step;
    otherwise Triangle meshes the fluid once (:mod:`fluidem.mesh.triangulate`)."""
    if any(b.motion == "free" for b in scene.bodies):
        return True
    once = scene.fluid is not None and scene.fluid.model == "stokes" and scene.time.n_steps == 1
    return any(b.outline_moves for b in scene.bodies) and not once


def mesh_estimate(scene, memory: tuple[float, float] | None = None) -> dict:
    """Rough size of a fluid scene's mesh and solve, before anything is built.

    Triangles ≈ :data:`TRIANGLES_PER_AREA_FK` × (fluid area) / h² on the uniform moving mesh
    (:func:`moving_mesh_scene`, the Friedrichs–Keller background), else
    :data:`TRIANGLES_PER_AREA` × (fluid area) / h² (graded: × the mean of
    (h/h(x))² over the box for the graded size h(x)); nodes ≈ triangles / 2; DOFs by
    :data:`DOFS_PER_VERTEX`; peak memory ≈ :data:`BYTES_BASE` + :data:`BYTES_PER_DOF` × DOFs
    (measured for a Taylor–Hood channel with the default solver), or :data:`BYTES_PER_DOF_ITERATIVE` × DOFs
    where the run will solve without an LU (:func:`planned_solver`).  Within a factor of ~2.

    Parameters
    ----------
    scene : fluidem.scene.Scene
        A validated scene with a fluid.
    memory : (float, float), optional
        (total, available) memory of the machine, bytes; :func:`machine_memory` when not given.

    Returns
    -------
    dict
        ``triangles``, ``nodes``, ``dofs``, ``peak_bytes``, ``machine_bytes``,
        ``available_bytes`` (floats) and ``solver`` (:func:`planned_solver`).
    """
    x0, x1, y0, y1 = scene.domain.box
    area_b, _ = _outline_stats(scene) if scene.bodies else (np.zeros(0), None)
    A = max((x1 - x0) * (y1 - y0) - float(area_b.sum()), 0.0)
    h = scene.mesh.h
    g = scene.mesh.grading
    if g is None:  # in ratios to h: inf, not an error, for an absurdly small h (the plan refuses it)
        with np.errstate(over="ignore"):
            per_area = TRIANGLES_PER_AREA_FK if moving_mesh_scene(scene) else TRIANGLES_PER_AREA
            tri = per_area * max(((x1 - x0) / h) * ((y1 - y0) / h) - float(area_b.sum() / h / h), 0.0)
    else:
        tri = TRIANGLES_PER_AREA * _graded_cells(scene, A)
    n_boundary = 2.0 * ((x1 - x0) + (y1 - y0)) / h + sum(scene.default_segments(b) for b in scene.bodies)
    tri = max(tri, n_boundary)  # at least the outline nodes, however coarse h is
    nodes = max(tri / 2.0, n_boundary)
    dofs = DOFS_PER_VERTEX.get(scene.fluid.element, 9.0) * nodes
    total, avail = machine_memory() if memory is None else memory
    solver = planned_solver(scene, dofs, avail)
    backend = planned_lu_backend(scene, dofs)
    per_dof = (BYTES_PER_DOF_ITERATIVE if solver == "iterative" else
               BYTES_PER_DOF_PARDISO if backend == "pardiso" else BYTES_PER_DOF)
    return {"triangles": tri, "nodes": nodes, "dofs": dofs, "peak_bytes": BYTES_BASE + per_dof * dofs,
            "machine_bytes": total, "available_bytes": avail, "solver": solver, "lu_backend": backend}


def _dofs_int(dofs: float) -> int:
    """An estimate of DOFs as an integer (beyond 1e308 or 2⁶²: 2⁶², huge)."""
    return int(min(max(dofs, 1.0), 2.0**62)) if np.isfinite(dofs) else 2**62


def planned_lu_backend(scene, dofs: float) -> str:
    """The sparse LU a fluid scene of about ``dofs`` DOFs will factorise with: ``fluid.lu_backend``, or
    for ``"auto"`` PARDISO from its threshold when ``pypardiso`` is installed, SuperLU otherwise
    (:func:`fluidem.fluid.solvers.direct.default_direct_backend`)."""
    from ..fluid.solvers.direct import default_direct_backend

    b = scene.fluid.lu_backend
    return b if b != "auto" else default_direct_backend(_dofs_int(dofs))


def planned_solver(scene, dofs: float, available_bytes: float | None = None) -> str:
    """The linear solver a fluid scene of about ``dofs`` DOFs will run with: ``fluid.solver``, or for
    ``"auto"`` the choice of :func:`fluidem.fluid.solvers.choose.choose_solver` at that size (``"iterative"``
    above the LU's size limit or where its LU would not fit in ``available_bytes`` less the set-up's
    :data:`BYTES_SETUP_PER_DOF`).

    >>> from fluidem.scene import Scene
    >>> sc = Scene.from_dict({"domain": {"box": [0, 1, 0, 1]}, "fluid": {"viscosity": 1.0},
    ...                       "time": {"dt": 0.1, "t_end": 1.0}})
    >>> planned_solver(sc, 1e4), planned_solver(sc, 1e8)
    ('lagged', 'iterative')
    """
    from ..fluid.solvers.choose import choose_solver

    fl = scene.fluid
    if fl.solver != "auto":
        return fl.solver
    n = _dofs_int(dofs)
    kind = "stokes" if fl.model == "stokes" else "unsteady"
    if available_bytes is None or not np.isfinite(available_bytes):
        return choose_solver(n, kind, planned_lu_backend(scene, dofs))[0]
    # the run asks once its problem is set up: what is available then
    left = max(available_bytes - BYTES_SETUP_PER_DOF * n, 0.0)
    return choose_solver(n, kind, planned_lu_backend(scene, dofs), available_bytes=left)[0]


def mesh_warnings(scene, est) -> tuple[list, list]:
    """(warnings, refusals) about a fluid scene's mesh: memory, a coarse box, coarse or thin bodies."""
    warn, refuse = [], []
    h = scene.mesh.h
    x0, x1, y0, y1 = scene.domain.box
    L = min(x1 - x0, y1 - y0)
    lu = f" with the {est['lu_backend']} LU" if est.get("solver") != "iterative" and "lu_backend" in est else ""
    size = (f"mesh.h = {h:g}: about {est['nodes']:.2g} nodes, {est['dofs']:.2g} DOFs, peak memory "
            f"{readable_bytes(est['peak_bytes'])} (solver {est.get('solver', 'auto')!r}{lu})")
    if not np.isfinite(est["peak_bytes"]):
        refuse.append(f"mesh.h = {h:g} in the box {x1 - x0:g} × {y1 - y0:g}: more than 1e308 nodes (the estimate "
                      f"overflows), far beyond this machine's {readable_bytes(est['machine_bytes'])}: raise mesh.h "
                      "(or grade the mesh with mesh.grading)")
    elif est["peak_bytes"] > est["machine_bytes"]:
        refuse.append(f"{size}, more than this machine's {readable_bytes(est['machine_bytes'])}: raise mesh.h (or "
                      "grade the mesh with mesh.grading)")
    elif est["peak_bytes"] > 0.5 * est["available_bytes"]:
        warn.append(f"{size}, more than half the memory available now ({readable_bytes(est['available_bytes'])})")
    if h > L / 4:
        warn.append(f"mesh.h = {h:g} is coarse for the box ({x1 - x0:g} × {y1 - y0:g}): about {est['triangles']:.0f} "
                    f"triangles; results will be far off (the default is min(box / 20, body / 4) = "
                    f"{scene.default_mesh_size():g})")
    if scene.bodies:
        area, perim = _outline_stats(scene)
        nodes = np.array([scene.default_segments(b) if b.shape in ("disk", "ellipse") else len(b.local_vertices())
                          for b in scene.bodies])  # the outline's own vertices stay in the mesh
        edges = np.maximum(perim / h, nodes)
        thick = 2.0 * area / np.maximum(perim, 1e-300)
        for k in np.flatnonzero(edges < MIN_EDGES_PER_BODY)[:3]:
            b = scene.bodies[k]
            warn.append(f"body {b.name!r}: about {edges[k]:.0f} mesh edges along its outline (perimeter "
                        f"{perim[k]:.3g}, mesh.h = {h:g}); at least {MIN_EDGES_PER_BODY} resolve it (mesh.h <= "
                        f"{perim[k] / MIN_EDGES_PER_BODY:.3g})")
        for k in np.flatnonzero(thick / h < MIN_THICKNESS_PER_H)[:3]:
            b = scene.bodies[k]
            warn.append(f"body {b.name!r} is about {thick[k]:.3g} thick, {h / thick[k]:.0f} times thinner than "
                        f"mesh.h = {h:g}: expect degenerate triangles (angles of a fraction of a degree) around it; "
                        "a thicker body or a finer mesh near it (mesh.grading)")
    return warn, refuse
