"""A mesh that follows rigid polygonal bodies in a box (paper Sec. 2–4).

One *triangulation* (the "cut-out", Sec. 2.1: candidate nodes cut out around the bodies,
outline nodes added, Triangle's constrained Delaunay triangulation, junction points,
relaxation and clean-up) is :func:`fluidem.mesh.moving_triangulation.triangulate_from`, whose
module docstring has the pipeline step by step.

Strategies (``strategy=``):

``"regenerate"``
    the older method: every step the background is reset (nodes snap back) and the whole
    pipeline runs, with ``relax_iterations`` sweeps (default 20).
``"drag"``
    mesh dragging (Sec. 4.2): each step the outline nodes move rigidly with their body;
    free nodes within ``drag_full · h`` of a body follow its rigid motion, and the other
    free nodes the harmonic extension of these displacements over the mesh, the box sides
    sliding (``drag_field="harmonic"``; ``"ramp"``: a weight falling to zero at
    ``drag_reach · h``; :mod:`fluidem.mesh.drag`); junction nodes keep their barycentric
    place between their three outline nodes; then
    ``relax_iterations`` relaxation sweeps (default 3; dragged nodes relax with a reduced
    step, oscillating ones, Sec. 3.3, a halved one).  Nodes never snap back.  The current
    nodes are re-triangulated every ``retriangulate_every`` steps (K, default 30) or earlier
    when a trigger fires (inverted or degenerate elements, contacts, quality:
    :mod:`fluidem.mesh.drag_step`); then the nodes are adapted to the target size, the node
    count held to a budget (:mod:`fluidem.mesh.moving_triangulation`), and junction points are
    recomputed.
``"fixed"``
    bodies do not move: the mesh is built once; :meth:`MovingMesh.update` checks that.

Target size: the user's size field (``h`` and ``grading``); with grading, the bodies carry
a fine zone with them, ``h_body(x) = h + (growth − 1) max(d(x) − w, 0)``, ``d`` the
distance to the nearest body and ``w = tow_width · h``, and the target is
``min(size(x), h_body(x))``.  Between re-triangulations the target size is attached to the
nodes, so a body moving into the coarse region tows its nodes (Fig. 6); at
re-triangulation it is re-evaluated at the new positions.

Contact policy ("closed union outline"): bodies closer than ``min_gap`` (default
``1e-3 · h``; touching or overlapping, as the DEM allows small overlaps) are merged for
meshing.  The fluid region is the box minus the morphological closing (mitre buffer by
``min_gap/2`` out and back in, then simplified at ``min_gap``) of the union of the cluster,
so gaps narrower than ``min_gap`` are filled and no element thinner than ``min_gap`` is
produced.  Outline nodes of the cluster bodies that lie on the closed outline and outside
the other bodies of the cluster are kept (two closer than ``0.1 h`` are merged); vertices
of the closed outline farther than ``0.3 h`` from every kept outline node (deep contact
points, bridge corners) become *contact nodes*, owned by and moving with the nearest body.  Where no contact node is
added, the outline cuts straight across the contact notch, which lies in the fluid: no
element overlaps a body, at the price of a fluid sliver below ``0.3 h`` at each contact.
Fluid enclosed by a ring of touching bodies (a hole of the closed union) is a *pore*: it is
meshed, detected and reported (``pore_areas``; it needs its own pressure reference).
Walls join the contact policy: a body closer than ``min_gap`` to a box side (touching it,
or overlapping it as the DEM's soft wall contact allows at rest, up to
:meth:`MovingMesh.allowed_wall_overlap`: the overlap is meshed as contact) is meshed
with that wall as one closed outline; the fluid between them narrower than
``min_gap`` is filled, the box sides under the body are no boundary (the ``bottom``/...
facets end where the body's facets begin), and *wall nodes* where the outline leaves the
side slide along it with the body (:mod:`fluidem.mesh.contact_outline`).  Fluid conditions
on the merged outline: every facet keeps its owner, the body facets get the body's rigid
motion and the wall facets the wall's condition; the node where they meet is a body (wall)
node, so it moves with the body: the body condition applied after the wall one wins there,
as at a corner of a lid-driven cavity.  A body overlapping a side deeper than allowed or
lying outside the box raises :class:`~fluidem.errors.InputError` (:mod:`fluidem.mesh.moving_input`).

Narrow gaps: see :mod:`fluidem.mesh.quality`; an element counts as narrow-gap when the gap
at its centroid is narrower than ``h/2`` or when one of its edges joins two different
boundaries with one end closer than ``h/2`` to the other end's boundary.

Stages (pure functions over arrays, each returning a small dataclass; the class below
composes them and keeps the state between steps):

* :mod:`fluidem.mesh.nodes` — node kinds, uids, outline table, background, box ring;
* :mod:`fluidem.mesh.contact_outline` — the contact policy (closed outlines, pores);
* :mod:`fluidem.mesh.cutout` — cut-out, Triangle, junction points (steps 2–5);
* :mod:`fluidem.mesh.adaptation` — coarsening/refinement and the clean-up pass (step 6);
* :mod:`fluidem.mesh.drag` — drag association and the dragged displacement;
* :mod:`fluidem.mesh.gaps` — gap widths and narrow-gap elements;
* :mod:`fluidem.mesh.triggers` — when to re-triangulate;
* :mod:`fluidem.mesh.params` — every parameter, validated (:class:`MeshParams`).

The class keeps its state in its own attributes; functions over it, by concern:
:mod:`fluidem.mesh.moving_triangulation` (one triangulation), :mod:`fluidem.mesh.drag_step`
(a drag step and its triggers), :mod:`fluidem.mesh.moving_images` (periodic images, seam
nodes), :mod:`fluidem.mesh.moving_history` (node trajectories, ALE mesh velocity),
:mod:`fluidem.mesh.moving_input` (pose and width checks), :mod:`fluidem.mesh.moving_state`
(the pickled state of earlier versions).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.spatial import cKDTree

from .. import validate
from ..errors import InputError
from .background import size_from_grading
from .drag_step import drag_step
from .gaps import anchored_across_gap, boundary_owner, gap_width, narrow_gap, narrow_gap_owners
from .moving_history import carry_history, velocity_from_history, velocity_from_last_step
from .moving_images import image_poses, image_set, set_images, unbend_seams
from .moving_input import allowed_wall_overlap, check_poses, check_widths
from .moving_state import restored_state
from .moving_triangulation import movable_count, size_integral, triangulate_from
from .nodes import (FIRST_BODY_MARKER, BodyOutlines, UidSource, background_nodes,
                    body_vertices, outline_nodes, world)
from .params import PARAM_NAMES, STRATEGIES, MeshParams, mesh_params
from .periodic import bends_seams, periodic_axes
from .proximity import PolygonTable
from .quality import MeshQuality, OscillationDetector, mesh_quality
from .triangulate import SIDE_NAMES, BoxDomain, _facet_lookup

__all__ = ["MovingMesh", "MeshEvent", "MeshParams", "STRATEGIES"]


@dataclass
class MeshEvent:
    """What :meth:`MovingMesh.update` did in one step.

    Attributes
    ----------
    step : int
        Step counter after the update.
    retriangulated : bool
        The connectivity changed: fields must be transferred (:mod:`fluidem.mesh.transfer`)
        from ``old_points``/``old_triangles`` to the new mesh.
    reason : str
        ``""`` (none), ``"periodic"`` (every K steps), ``"quality"`` (an angle crossed the
        bounds), ``"degenerate"`` (an element shrank below a tenth of its area), ``"contact"``
        (bodies touched or their contact changed), ``"inverted"`` (the rigid motion inverted an
        element: the old mesh at the new positions is invalid), ``"regenerate"``
        (:mod:`fluidem.mesh.triggers`).
    n_nodes, n_triangles : int
    n_purged, n_removed, n_inserted, n_junctions : int
        Nodes purged inside/near bodies, removed by coarsening, inserted by refinement, and
        junction points in the new mesh (re-triangulation only).
    oscillating : (k,) int
        Nodes that flipped between two positions in the last steps (Sec. 3.3).
    n_blocked : int
        Relaxation moves dropped because they would have inverted an element.
    n_repaired : int
        Nodes moved to repair elements that fired the quality trigger or shrank below
        ``degenerate_area`` instead of re-triangulating (:mod:`fluidem.mesh.repair`); 0 if
        none.  ``len(repaired_nodes)`` (read only).
    repair_declined : str
        Why the repair did not avert this ``"quality"`` or ``"degenerate"`` re-triangulation
        (e.g. ``"a narrow-gap element fired too"``); ``""`` if it was not tried.
    fired_at : (k, 2) float
        Where the trigger fired: the centroids of the elements that did (length units, at the
        node positions of this step before a re-triangulation; reasons ``"inverted"``,
        ``"degenerate"`` and ``"quality"``, :func:`fluidem.mesh.triggers.fired_elements`);
        empty for the others and without re-triangulation.
    repaired_nodes : (k,) int
        Those nodes; their jump from ``repaired_from`` (n_nodes, 2), the positions before the
        repair, is a transfer (:func:`fluidem.mesh.transfer.move_with_nodes`), not mesh motion.
    contacts : (k, 2) int
        Body pairs closer than ``min_gap`` (meshed as one outline).
    walls : (k, 2) int
        ``(body, side)`` pairs closer than ``min_gap`` (side 0 bottom, 1 right, 2 top, 3 left),
        meshed with the wall as one outline.
    pore_areas : (k,) float
        Areas of fluid pores fully enclosed by touching bodies, units².
    old_points, old_triangles : arrays or None
        The previous connectivity at the positions the nodes reached this step before the
        re-triangulation (a valid mesh for transfer unless ``reason == "inverted"``).
    prev_points : array or None
        Positions of the previous connectivity before this update (always a valid mesh;
        use it with ``old_triangles`` when ``reason == "inverted"``).
    seconds : float
        Wall-clock time of the update.
    history : str
        How the node trajectories continue through a re-triangulation
        (:meth:`MovingMesh.node_history`): ``"ale"`` (pulled back through the old mesh motion),
        ``"eulerian"`` (nodes at rest this step: ``reason`` ``"inverted"`` or ``"regenerate"``),
        ``""`` without re-triangulation.
    transfer_change, force_change : float or None
        Filled by the flow on the moving mesh at a re-triangulation: the relative L2 change
        the field transfer made to u^n (interpolation noise, paper Fig. 5) and the relative
        change of the body forces in this step.
    """

    step: int
    retriangulated: bool = False
    reason: str = ""
    n_nodes: int = 0
    n_triangles: int = 0
    n_purged: int = 0
    n_removed: int = 0
    n_inserted: int = 0
    n_junctions: int = 0
    oscillating: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    n_blocked: int = 0
    repair_declined: str = ""
    fired_at: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    repaired_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    repaired_from: np.ndarray | None = field(default=None, repr=False)
    contacts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    pore_areas: np.ndarray = field(default_factory=lambda: np.zeros(0))
    walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    old_points: np.ndarray | None = field(default=None, repr=False)
    old_triangles: np.ndarray | None = field(default=None, repr=False)
    prev_points: np.ndarray | None = field(default=None, repr=False)
    seconds: float = 0.0
    history: str = ""
    transfer_change: float | None = None
    force_change: float | None = None

    @property
    def n_repaired(self) -> int:
        return len(self.repaired_nodes)


class MovingMesh:
    """A triangle mesh of a box minus moving rigid polygons.

    Parameters
    ----------
    domain : (xmin, xmax, ymin, ymax) or BoxDomain
        The box, length units; walls on all sides.
    bodies : sequence of (n_i, 2) arrays or objects with ``.vertices``
        Outlines in body coordinates (counter-clockwise; the pose rotates them about the
        body origin, normally the centre of mass).  Clockwise or self-intersecting outlines
        raise ``ValueError``.
    poses : (n_bodies, 3) float
        Initial ``x, y, angle`` (length units, radians).
    h : float
        Target edge length near the bodies and in the region of interest, > 0.
    grading : None, dict, SizeField or callable
        ``None``: uniform ``h``.  A dict ``{"region": (xmin, xmax, ymin, ymax) or polygons,
        "growth": g, "h_max": H}``: fine (``h``) in the region, growing by the factor ``g``
        per cell away from it up to ``H`` (paper Fig. 3).  A :class:`SizeField` or a callable
        ``points (m, 2) -> h (m,)`` is used as is (its ``growth`` attribute, if any, sets
        the zone towed by the bodies; else 1.2).
    strategy : {"drag", "regenerate", "fixed"} or None
        Overrides ``params.strategy`` (default ``"drag"``).
    periodic : sequence of {"x", "y"}
        Periodic axes (``"x"``: the sides ``left`` and ``right`` are one; ``"y"``: ``bottom``
        and ``top``; :mod:`fluidem.mesh.periodic`).  Their nodes match in every
        triangulation and slide in matched pairs; bodies may cross them (their periodic
        images are meshed, clipped at the box, :mod:`fluidem.mesh.seam`; ``poses`` may lie
        outside the box along a periodic axis).  A body with a vertex half a period or more
        from its origin raises ``InputError``.
    params : MeshParams or None
        Every other parameter (:class:`fluidem.mesh.params.MeshParams`, which documents
        them: ``retriangulate_every``, ``relax_iterations``, ``min_angle_trigger``,
        ``clearance``, ``purge_clearance``, ``min_gap``, ``junctions``, ``background``,
        ``relax_params``, ``initial_iterations``, ``drag_reach``, ``drag_full``,
        ``drag_field``, ``drag_stiffness``, ``gap_purge``, ``cleanup_passes``,
        ``retriangulate_iterations``, ``tow_width``, ``refine_area``, ``coarsen_ratio``, and the
        named constants).
    **keywords
        Any :class:`MeshParams` field, overriding ``params``.

    Attributes
    ----------
    params : MeshParams
        The parameters in use (its fields also read as attributes: ``mm.drag_reach``).
    points : (n_nodes, 2) float
        Node positions, length units.
    triangles : (n_triangles, 3) int
        Counter-clockwise triangles.
    kind : (n_nodes,) int8
        0 free, 1 box side (slides along it), 2 box corner, 3 body outline, 4 junction,
        5 contact node (:mod:`fluidem.mesh.nodes`).
    body_of : (n_nodes,) int
        Body of an outline or contact node, ``-1`` otherwise.
    outline_row : (n_nodes,) int
        Row of an outline node in the outline table (``outlines``), ``-1`` otherwise.
    uid : (n_nodes,) int
        Node ids that survive re-triangulations.
    h_node : (n_nodes,) float
        Target edge length carried by every node.
    contacts : (k, 2) int
        Body pairs meshed as one outline (closer than ``min_gap``).
    walls : (k, 2) int
        ``(body, side)`` pairs meshed as one outline with the wall (closer than ``min_gap``).
    pore_areas : (k,) float
        Areas of fluid pores enclosed by touching bodies.
    outlines : BodyOutlines
        The outline nodes of every body in body coordinates.
    background_candidates : BackgroundNodes
        The background nodes (candidates of every ``"regenerate"`` triangulation).
    drag : DragAssociation
        Nodes dragged by each body and their weights (:mod:`fluidem.mesh.drag`).
    baseline : QualityBaseline
        Thresholds of the quality trigger (:mod:`fluidem.mesh.triggers`).

    Raises
    ------
    InputError
        A parameter, pose or outline is not allowed (also a ``ValueError``).
    MeshError
        The geometry cannot be meshed (also a ``RuntimeError``).

    Examples
    --------
    >>> import numpy as np
    >>> from fluidem.geometry import rectangle
    >>> mm = MovingMesh((0, 2, 0, 1), [rectangle(0.3, 0.2)], [[0.6, 0.5, 0.0]], h=0.1)
    >>> ev = mm.update([[0.62, 0.5, 0.05]])
    >>> q = mm.quality()
    >>> q.n_inverted, q.n_nodes_inside_bodies, q.min_angle > 15
    (0, 0, True)
    >>> w = mm.node_velocity(0.01)   # ALE mesh velocity, (n_nodes, 2)
    >>> MovingMesh((0, 2, 0, 1), [rectangle(0.3, 0.2)], [[0.6, 0.5, 0.0]], h=0.1,
    ...            params=MeshParams(retriangulate_every=10)).retriangulate_every
    10
    """

    def __init__(self, domain, bodies, poses, h: float, grading=None, strategy: str | None = None, *,
                 params: MeshParams | None = None, periodic=(), **keywords):
        if strategy is not None:
            keywords["strategy"] = strategy
        self.params = p = mesh_params(params, **keywords)
        self.domain = BoxDomain.from_any(domain)
        self.box = (self.domain.xmin, self.domain.xmax, self.domain.ymin, self.domain.ymax)
        self.h = validate.positive("mesh size h", h)
        self.periodic = periodic_axes(periodic)

        # size field
        self._size, self._growth, self._graded = size_from_grading(grading, self.h)
        self.background_kind = p.background_for(self._graded)

        # bodies
        verts, names = [], []
        for i, b in enumerate(bodies):
            v, name = body_vertices(b, i)
            verts.append(v)
            names.append(str(name))
        if len(set(names)) != len(names) or set(names) & set(SIDE_NAMES):
            names = [f"body{i}" for i in range(len(verts))]
        self.body_names = names
        self.n_real = len(verts)
        self._body_verts = verts
        self._real_nv = np.array([len(v) for v in verts], dtype=np.int64)
        self._real_vcat = np.vstack(verts) if verts else np.zeros((0, 2))
        self._real_vbody = np.repeat(np.arange(self.n_real), self._real_nv)
        check_widths(self)
        self.body_poses = check_poses(self, poses)
        self._real_outlines: BodyOutlines = outline_nodes(verts, self.body_poses, self._size, self.h)
        set_images(self, image_set(self, self.body_poses))
        self.background_candidates = background_nodes(self.box, self.h, self._size, self.background_kind,
                                                     periodic=self.periodic)
        self.step_count = 0
        self._steps_since = 0
        self._osc = OscillationDetector()
        self._damping = None
        self._uids = UidSource()
        self.pore_areas = np.zeros(0)
        self.contacts = np.zeros((0, 2), dtype=np.int64)
        self.walls = np.zeros((0, 2), dtype=np.int64)
        self._prev_points = None
        self._prev_uid = None
        bg = self.background_candidates
        triangulate_from(self, bg.points, bg.kind, bg.uid, purge=p.clearance, adapt=False,
                         n_relax=p.initial_iterations)
        # free and box nodes per unit of ∫ h⁻² dA: the node budget of the re-triangulations
        self._node_density = movable_count(self) / size_integral(self)
        self._prev_points = self.points.copy()
        self._prev_uid = self.uid.copy()
        self._trajectory = (None, None)  # node_history(): positions at t^n, t^{n-1} of the current nodes

    # ------------------------------------------------------------------ parameters as attributes
    def __getattr__(self, name):
        # called only for names not found otherwise: the MeshParams fields
        params = self.__dict__.get("params")
        if params is not None and name in PARAM_NAMES:
            return getattr(params, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __setattr__(self, name, value):
        if name in PARAM_NAMES:  # a parameter set here would be ignored: the stages read self.params
            raise AttributeError(f"MovingMesh.{name} is a parameter: give it as MovingMesh({name}=...) or in params=")
        object.__setattr__(self, name, value)

    @property
    def min_gap(self) -> float:
        """Contact distance in use, length units (``params.min_gap`` or ``default_min_gap · h``)."""
        return self.params.min_gap_for(self.h)

    @property
    def relax_iterations(self) -> int:
        """Relaxation sweeps per physical step (the strategy's default if not given)."""
        return self.params.step_iterations

    @property
    def use_junctions(self) -> bool:
        """Voronoi junction points are inserted (``params.junctions``)."""
        return self.params.junctions

    @property
    def ol_id(self) -> np.ndarray:
        """Former name of :attr:`outline_row`."""
        return self.outline_row

    # the drag association under its former names
    _drag_node = property(lambda self: self.drag.node)
    _drag_body = property(lambda self: self.drag.body)
    _drag_weight = property(lambda self: self.drag.weight)
    _relax_damping = property(lambda self: self.drag.relax_damping)

    def __getstate__(self):
        # the factorised harmonic extension (SuperLU) is rebuilt on the next drag step
        state = dict(self.__dict__)
        state["_harmonic"] = None
        return state

    def __setstate__(self, state):
        """Unpickle; a mesh pickled by an earlier version (checkpoints) is converted
        (:func:`fluidem.mesh.moving_state.restored_state`)."""
        self.__dict__.update(restored_state(state))
    # ------------------------------------------------------------------ set-up
    @property
    def _wall_sides(self) -> np.ndarray:
        """(4,) bool: which sides (bottom, right, top, left) are walls (not periodic)."""
        ax = self.__dict__.get("periodic", ())
        return np.array(["y" not in ax, "x" not in ax, "y" not in ax, "x" not in ax])

    def allowed_wall_overlap(self, poses=None) -> np.ndarray:
        """Deepest overlap ``(n_bodies, 4)`` of each body with each box side (bottom, right, top,
        left) that is meshed as contact, length units: ``max(wall_overlap · h,
        wall_overlap_fraction · e)``, ``e`` the body's extent across the side at ``poses``
        (default: the current ones; :class:`MeshParams`)."""
        poses = self.body_poses if poses is None else np.asarray(poses, dtype=float)
        return allowed_wall_overlap(self, poses)
    def _target(self, pts, outline_world=None) -> np.ndarray:
        """Target edge length at ``pts`` (size field, and the zone the bodies carry)."""
        hs = np.asarray(self._size(pts), dtype=float)
        if self._graded and self.n_bodies:
            if outline_world is None:
                outline_world = self.outlines.world(self.poses)
            d, _ = cKDTree(outline_world).query(pts)
            hs = np.minimum(hs, self.h + (self._growth - 1.0) * np.maximum(d - self.tow_width * self.h, 0.0))
        return hs

    # ------------------------------------------------------------------ geometry helpers
    def _polygons(self, poses=None):
        poses = self.poses if poses is None else poses
        w = world(self._vcat, self._vbody, poses)
        rings = shapely.linearrings(w, indices=self._vbody)
        return shapely.polygons(rings)

    def _outline_table(self, poses=None) -> PolygonTable:
        """The bodies' polygons in world coordinates, for vectorised point queries."""
        poses = self.poses if poses is None else poses
        key = poses.tobytes()
        cached = getattr(self, "_table_cache", None)
        if cached is None or cached[0] != key:
            cached = (key, PolygonTable(world(self._vcat, self._vbody, poses), self._nv))
            self._table_cache = cached
        return cached[1]

    def _bodies_table(self, poses=None) -> PolygonTable | None:
        """:meth:`_outline_table`, or ``None`` without bodies."""
        return self._outline_table(poses) if self.n_bodies else None

    # ------------------------------------------------------------------ stepping
    def update(self, poses) -> MeshEvent:
        """Move the bodies to ``poses`` ``(n_bodies, 3)`` (x, y, angle) and follow with the mesh.

        Returns
        -------
        MeshEvent
            What happened (re-triangulation and why, purged/inserted nodes, oscillating
            nodes, contacts, pores, timing).
        """
        t0 = time.perf_counter()
        real = check_poses(self, poses)
        hist = self.__dict__.get("_body_pose_history", (None, None))
        self._body_pose_history = (self.body_poses, hist[0])  # body poses at t^n, t^{n-1}
        self.body_poses = real
        new = image_poses(real, self.images)
        self.step_count += 1
        ev = MeshEvent(step=self.step_count)
        self._prev_points = self.points.copy()
        self._prev_uid = self.uid.copy()
        before = (self._prev_points, self.__dict__.get("_trajectory", (None, None))[0])
        if self.strategy == "fixed":
            if not np.allclose(new, self.poses, rtol=0, atol=1e-12 * max(1.0, np.abs(self.poses).max(initial=0))):
                raise InputError("strategy 'fixed' is for bodies that do not move; poses changed "
                                 f"(max change {np.abs(new - self.poses).max():.3g})")
        elif self.strategy == "regenerate":
            old_p, old_t = self.points, self.triangles
            self.poses = new
            bg = self.background_candidates
            info = triangulate_from(self, bg.points, bg.kind, bg.uid, purge=self.params.clearance, adapt=False,
                                    n_relax=self.relax_iterations)
            ev.retriangulated, ev.reason = True, "regenerate"
            ev.old_points, ev.old_triangles, ev.prev_points = old_p, old_t, old_p
            ev.n_purged, ev.n_junctions = info["n_purged"], info["n_junctions"]
        else:
            drag_step(self, new, ev)
        self._carry_history(ev, *before)
        ev.contacts = self.contacts
        ev.walls = self.__dict__.get("walls", ev.walls)
        ev.pore_areas = self.pore_areas
        ev.n_nodes, ev.n_triangles = len(self.points), len(self.triangles)
        ev.seconds = time.perf_counter() - t0
        return ev

    def retriangulate(self, n_relax: int | None = None) -> dict:
        """Constrained Delaunay triangulation of the current nodes (cut-out, adaptation, junctions).

        Returns a dict with ``n_purged``, ``n_removed``, ``n_inserted``, ``n_junctions``.
        """
        n_relax = self.params.retriangulate_iterations if n_relax is None else n_relax
        cand = unbend_seams(self) if bends_seams(self) else self.points
        return triangulate_from(self, cand, self.kind, self.uid, purge=self.params.purge_clearance,
                                adapt=True, n_relax=n_relax, h_cand=self.h_node)

    # ------------------------------------------------------------------ gaps on the current mesh
    def _anchored_across_gap(self, tri_idx, table=None) -> np.ndarray:
        """:func:`fluidem.mesh.gaps.anchored_across_gap` of triangles ``tri_idx``."""
        table = self._bodies_table() if table is None else table
        return anchored_across_gap(tri_idx, self.triangles, self.points, boundary_owner(self.kind, self.body_of),
                                   self.h_node, table, self.box)

    def _gap_width(self, pts, radius, table=None) -> np.ndarray:
        """:func:`fluidem.mesh.gaps.gap_width` at ``pts (k, 2)`` within ``radius``."""
        table = self._bodies_table() if table is None else table
        return gap_width(pts, radius, table, self.box)

    def _narrow_gap_owners(self) -> np.ndarray:
        """:func:`fluidem.mesh.gaps.narrow_gap_owners` of the current mesh."""
        return narrow_gap_owners(self.points, self.triangles, self.topo, self.kind, self.body_of, self.h_node,
                                 self._bodies_table(), self.box)

    def _narrow_gap(self) -> np.ndarray:
        """Narrow-gap triangles (:func:`fluidem.mesh.gaps.narrow_gap`)."""
        return narrow_gap(self.points, self.triangles, self.topo, self.kind, self.body_of, self.h_node,
                          self._bodies_table(), self.box)

    # ------------------------------------------------------------------ outputs
    def skfem_mesh(self):
        """scikit-fem :class:`skfem.MeshTri` of the current mesh.

        Boundaries ``"bottom"``, ``"right"``, ``"top"``, ``"left"`` and one per body (its
        name, ``body<i>`` by default) are facet index arrays in ``mesh.boundaries``.
        """
        from skfem import MeshTri

        m = MeshTri(self.points.T.copy(), self.triangles.T.copy())
        look = _facet_lookup(m)
        bnd = {}
        for k, name in enumerate(SIDE_NAMES):
            bnd[name] = look(self.boundary_segments[self.boundary_markers == k + 1])
        real = self.images.body  # an image's outline is its body's
        owner = np.where(self.boundary_markers >= FIRST_BODY_MARKER,
                         real[np.clip(self.boundary_markers - FIRST_BODY_MARKER, 0, max(len(real) - 1, 0))]
                         if len(real) else -1, -1)
        for b, name in enumerate(self.body_names):
            bnd[name] = look(self.boundary_segments[owner == b])
        return m.with_boundaries(bnd)

    # ------------------------------------------------------------------ node trajectories (ALE)
    def _carry_history(self, ev: MeshEvent, x_n: np.ndarray, x_nm1: np.ndarray | None) -> None:
        """The trajectories of the nodes after :meth:`update` (``x_n``, ``x_nm1``: of the nodes
        before it; :func:`fluidem.mesh.moving_history.carry_history`)."""
        carry_history(self, ev, x_n, x_nm1)
    def node_history(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Positions ``(x_n, x_nm1)``, each ``(n_nodes, 2)`` or None, of the current nodes' trajectories
        one and two :meth:`update` calls ago (length units).

        Through a re-triangulation the new nodes follow the old mesh motion
        (:class:`MeshEvent` ``history``).  ``x_nm1`` is None after the first update, both before it.
        """
        return self.__dict__.get("_trajectory", (None, None))

    def node_velocity(self, dt: float, order: int = 1) -> np.ndarray:
        """Mesh velocity ``w`` ``(n_nodes, 2)`` for ALE, length units per time unit.

        ``order = 1``: ``(x_now − x_prev) / dt`` per node for nodes that existed before the
        last :meth:`update`; a node created by a re-triangulation gets the mean velocity of its
        mesh neighbours that existed before (neighbours of neighbours if none did).

        ``order = 2``: the derivative at the current time of the node trajectories
        (:meth:`node_history`) by BDF2, w = (3x^{n+1} − 4x^n + x^{n−1}) / (2 dt) (BDF1 when
        x^{n−1} is not known yet), the mesh velocity of a second-order ALE BDF2 step
        (Formaggia & Nobile 2004, CMAME 193, 4097–4116).  Constant ``dt`` between updates.
        """
        if not (np.isfinite(dt) and dt > 0):
            raise InputError(f"time step dt must be a positive number, got {dt!r}")
        if order == 2:
            return velocity_from_history(self.points, *self.node_history(), dt)
        if order != 1:
            raise InputError(f"order = {order!r}: expected 1 or 2")
        return velocity_from_last_step(self.points, self.uid, self._prev_points, self._prev_uid, self.topo, dt)

    def nodes_inside_bodies(self) -> np.ndarray:
        """Indices of nodes strictly inside a body (other than on their own outline)."""
        if not self.n_bodies:
            return np.zeros(0, dtype=np.int64)
        polys = self._polygons()
        tree = shapely.STRtree(polys)
        pi, bi = tree.query(shapely.points(self.points), predicate="within")
        sel = self.body_of[pi] != bi
        pi, bi = pi[sel], bi[sel]
        if len(pi):
            d = shapely.distance(shapely.boundary(polys[bi]), shapely.points(self.points[pi]))
            pi = pi[d > 1e-9 * self.h]
        return np.unique(pi)

    def quality(self) -> MeshQuality:
        """Quality statistics of the current mesh (:class:`fluidem.mesh.quality.MeshQuality`)."""
        return mesh_quality(self.points, self.triangles, narrow=self._narrow_gap(),
                            n_inside=len(self.nodes_inside_bodies()))

    def outline_facets_present(self) -> bool:
        """True when every body outline is closed by boundary segments of the mesh.

        Checks that each body has boundary segments and that the edges between consecutive
        outline nodes of unclustered bodies are edges of the mesh.
        """
        e = self.topo.edges
        n = len(self.points)
        key = np.sort(e, axis=1)
        k_mesh = key[:, 0] * n + key[:, 1]
        s = np.sort(self.boundary_segments, axis=1)
        k_seg = s[:, 0] * n + s[:, 1]
        if not np.isin(k_seg, k_mesh).all():
            return False
        for b in range(self.n_bodies):
            if not (self.boundary_markers == FIRST_BODY_MARKER + b).any():
                return False
        # every mesh edge with a triangle on one side only is a boundary segment
        bnd = key[~self.topo.interior]
        kb = bnd[:, 0] * n + bnd[:, 1]
        return bool(np.isin(kb, k_seg).all())
