"""A mesh that follows rigid polygonal bodies in a box (paper Sec. 2–4).

Pipeline of one *triangulation* (the "cut-out", Sec. 2.1):

1. candidate nodes: the background (Friedrichs–Keller square grid for a uniform size, a
   graded Delaunay point set for a graded one; Sec. 2.1, 2.3) or, when dragging, the
   current nodes;
2. nodes inside a body or closer than ``clearance · h`` to its outline are removed, and so
   are nodes in gaps narrower than ``gap_purge · h`` (such a gap is spanned by one layer
   of elements between the outline nodes);
3. outline nodes are added: every body carries a fixed set of outline nodes in body
   coordinates (its polygon edges subdivided at the target size around it);
4. Triangle's constrained Delaunay triangulation of all nodes, with the outlines and the
   box sides as segments and a hole point in every body: nothing is triangulated inside a
   body;
5. Voronoi junction points (Sec. 3.2, :mod:`fluidem.mesh.junctions`): triangles spanning
   three bodies are split at a junction node;
6. spring relaxation (:mod:`fluidem.mesh.relax`, eq. 1–3), then up to ``cleanup_passes``
   (2) clean-up passes: free nodes of elements still outside the angle bounds (outside
   narrow gaps) are removed, a node is added in such elements without free nodes, and
   steps 4–6 run once more.

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
    step).  Nodes never snap back.  The current nodes are re-triangulated every
    ``retriangulate_every`` steps (K, default 30) or earlier when

    - an element is inverted by the rigid motion (``"inverted"``) or shrank below a tenth of
      its area (``"degenerate"``, typically a narrow-gap element whose anchor passes a
      corner),
    - bodies came within ``min_gap`` of each other, or a contact changed (``"contact"``;
      a wall contact may breathe by ``contact_slack · h``, 0.02 h, first: a resting body
      whose overlap or gap changes by a little more than ``min_gap`` keeps its outline),
    - an element outside narrow gaps degraded ``angle_margin`` (10°) past 135°, or
      ``min_angle_margin`` (3°) below ``min_angle_trigger`` (15°), or as far past its own
      angles after the last triangulation if it was born outside them (``"quality"``, with
      hysteresis: an element born near a bound does not fire as soon as it crosses it,
      :func:`fluidem.mesh.triggers.quality_baseline`).

    At re-triangulation nodes swallowed by (or closer than ``purge_clearance · h`` to) a
    body are purged, an independent set of nodes is removed where the incident edges are on
    average shorter than ``coarsen_ratio`` (0.7) of their target and nodes are added in
    triangles larger than ``refine_area`` (1.6) target areas (at the midpoint of an edge on
    a box side, else at the centroid; so vacated regions coarsen again, Fig. 6), and
    junction points are recomputed.  The number of free and box nodes is held within
    ``node_count_tolerance`` (2 %) of a budget, the first mesh's count per unit of
    ``∫ h⁻² dA`` (``hold_node_count``): of two large neighbours only the larger is split, and
    above the budget the most compressed free nodes are removed as well (the harmonic drag
    compresses the whole region ahead of a body only mildly, below the coarsening
    threshold, while it stretches the region behind it beyond the refinement one).
``"fixed"``
    bodies do not move: the mesh is built once; :meth:`MovingMesh.update` checks that.

Oscillating nodes (Sec. 3.3) are detected from the relaxation displacements
(:class:`fluidem.mesh.quality.OscillationDetector`), reported, and their relaxation step is
halved each time they are flagged, on top of the per-step iteration limit.

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
as at a corner of a lid-driven cavity.  A body overlapping a side by more than
``max(wall_overlap · h, wall_overlap_fraction · its extent across the side)`` (0.1 h, a
quarter of its height) or lying outside the box raises :class:`~fluidem.errors.InputError`
(a ``ValueError``) naming the contact law's ``E``.

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
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.spatial import cKDTree

from .. import validate
from ..errors import InputError
from .adaptation import adapt as adapt_nodes
from .adaptation import cleanup_candidates
from .background import GradedSize, SizeField, UniformSize
from .contact_outline import contact_outline, contact_pairs, wall_depths
from .cutout import Triangulation, cut_out, triangulate
from .drag import DragAssociation, HarmonicDrag, drag_association, dragged_positions, harmonic_drag
from .gaps import (
    anchored_across_gap,
    boundary_owner,
    gap_width,
    narrow_gap,
    narrow_gap_owners,
    structural_narrow,
)
from .nodes import (
    CONTACT,
    CORNER,
    FIRST_BODY_MARKER,
    FREE,
    JUNCTION,
    OUTLINE,
    SIDE,
    UID_OUTLINE,
    BackgroundNodes,
    BodyOutlines,
    UidSource,
    background_nodes,
    body_vertices,
    mobility,
    outline_nodes,
    world,
)
from .periodic import match_side_nodes, periodic_axes, side_partners, slide_in_pairs
from .seam import (SEAM_BAND, SEAM_CODE, SEAM_MERGE, PeriodicImages, period_of, periodic_images, seam_nudge,
                   seam_positions)
from .params import PARAM_NAMES, STRATEGIES, MeshParams, mesh_params
from .proximity import PolygonTable
from .quality import MeshQuality, OscillationDetector, mesh_quality
from .relax import relax, signed_areas
from .triangulate import SIDE_NAMES, BoxDomain, _facet_lookup
from .triggers import (
    QualityBaseline,
    contacts_changed,
    element_shape,
    quality_baseline,
    quality_dropped,
    retriangulation_reason,
)

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
        self._size, self._growth, self._graded = self._make_size(grading)
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
        self._check_widths()
        self.body_poses = self._check_poses(poses)
        self._real_outlines: BodyOutlines = outline_nodes(verts, self.body_poses, self._size, self.h)
        self._set_images(self._image_set(self.body_poses))
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
        self._triangulate_from(bg.points, bg.kind, bg.uid, purge=p.clearance, adapt=False,
                               n_relax=p.initial_iterations)
        # free and box nodes per unit of ∫ h⁻² dA: the node budget of the re-triangulations
        self._node_density = self._movable_count() / self._size_integral()
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
        """Unpickle; a mesh pickled before the split by stage (checkpoints) is converted."""
        if "params" not in state:
            state = _state_before_split(state)
        state.setdefault("periodic", ())
        if "images" not in state:  # pickled before bodies could cross periodic sides
            n = state["n_bodies"]
            state.update(n_real=n, body_poses=state["poses"], _body_verts=state["_verts_local"],
                         _real_nv=state["_nv"], _real_vcat=state["_vcat"], _real_vbody=state["_vbody"],
                         _real_outlines=state["outlines"],
                         images=PeriodicImages(body=np.arange(n), cell=np.zeros((n, 2), dtype=np.int64),
                                               shift=np.zeros((n, 2))))
            nc = len(state.get("_contact_idx", ()))
            state.setdefault("_seam_outer_body", np.full(nc, -1, dtype=np.int64))
            state.setdefault("_seam_outer_local", np.zeros((nc, 2)))
        self.__dict__.update(state)

    # ------------------------------------------------------------------ set-up
    def _make_size(self, grading):
        if grading is None:
            return UniformSize(self.h), 1.0, False
        if isinstance(grading, dict):
            allowed = {"region", "growth", "h_max"}
            bad = set(grading) - allowed
            if bad or "region" not in grading:
                raise InputError(f"grading dict needs 'region' and may have 'growth', 'h_max'; "
                                 f"got keys {sorted(grading)}")
            growth = float(grading.get("growth", 1.2))
            h_max = float(grading.get("h_max", 8 * self.h))
            return GradedSize(self.h, growth, h_max, grading["region"]), growth, True
        if isinstance(grading, UniformSize):
            return grading, 1.0, False
        if isinstance(grading, SizeField) or callable(grading):
            growth = float(getattr(grading, "growth", 1.2))
            return grading, growth, True
        raise InputError(f"grading = {grading!r}: expected None, a dict, a SizeField or a callable")

    def _check_poses(self, poses) -> np.ndarray:
        try:
            p = np.asarray(poses, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"poses must be an (n_bodies, 3) array of numbers, got {poses!r}") from exc
        if self.n_real == 0 and p.size == 0:
            return np.zeros((0, 3))
        if p.shape != (self.n_real, 3) or not np.all(np.isfinite(p)):
            raise InputError(f"poses must be a finite ({self.n_real}, 3) array of x, y, angle; got shape {p.shape}")
        w = world(self._real_vcat, self._real_vbody, p)
        # a body may touch a wall or overlap it (the overlap is meshed as contact, the body with
        # the wall as one outline), as deep as allowed_wall_overlap; periodic sides are no walls
        depth = -wall_depths(w, self._real_vbody, self.n_real, self.box)  # (n_bodies, 4): > 0 outside
        depth[:, ~self._wall_sides] = -np.inf
        allowed = self.allowed_wall_overlap(p)
        bad = np.flatnonzero((depth > allowed).any(axis=1))
        if len(bad):
            b = int(bad[0])
            side = int(np.argmax(depth[b] - allowed[b]))
            if self._outside(p[b]):
                raise InputError(
                    f"body {b} ({self.body_names[b]}) at pose {p[b].tolist()} is not inside the domain "
                    f"{tuple(float(c) for c in self.box)}: it lies outside")
            raise InputError(
                f"body {b} ({self.body_names[b]}) at pose {p[b].tolist()} is not inside the domain "
                f"{tuple(float(c) for c in self.box)}: it overlaps the {SIDE_NAMES[side]} wall by "
                f"{depth[b, side]:.3g}; expected an overlap of at most {allowed[b, side]:.3g} = max(wall_overlap · h, "
                f"wall_overlap_fraction · its extent across the wall) (the overlap is meshed as contact): a "
                f"resting overlap this deep means a contact law too soft for the load (raise [contact] E) or a "
                f"pose outside the box")
        return p

    @property
    def _wall_sides(self) -> np.ndarray:
        """(4,) bool: which sides (bottom, right, top, left) are walls (not periodic)."""
        ax = self.__dict__.get("periodic", ())
        return np.array(["y" not in ax, "x" not in ax, "y" not in ax, "x" not in ax])

    def _check_widths(self) -> None:
        """Every vertex of a body lies less than half the period from its origin: the arm of a
        point of a body across a periodic side is then the one to the nearest image of its
        origin (:func:`fluidem.geometry.minimum_image`)."""
        L = period_of(self.box, self.periodic)
        for c, Lc in enumerate(L):
            if not Lc or not self.n_real:
                continue
            r = np.zeros(self.n_real)
            np.maximum.at(r, self._real_vbody, np.linalg.norm(self._real_vcat, axis=1))
            b = int(np.argmax(r))
            if r[b] >= 0.5 * Lc:
                raise InputError(f"body {b} ({self.body_names[b]}) has a vertex {r[b]:.4g} from its origin, across "
                                 f"periodic sides of period {Lc:.4g} in {'xy'[c]}: allowed: less than half the "
                                 f"period, {0.5 * Lc:.4g} (the arms of its rigid motion go to its nearest image)")

    # ------------------------------------------------------------------ periodic images
    def _extent(self, body_poses) -> np.ndarray:
        """Per real body ``(dx_min, dx_max, dy_min, dy_max)`` of its outline about its position."""
        w = world(self._real_vcat, self._real_vbody, body_poses) - body_poses[self._real_vbody, :2]
        ext = np.zeros((self.n_real, 4))
        ext[:, [0, 2]], ext[:, [1, 3]] = np.inf, -np.inf
        for c in range(2):
            np.minimum.at(ext[:, 2 * c], self._real_vbody, w[:, c])
            np.maximum.at(ext[:, 2 * c + 1], self._real_vbody, w[:, c])
        return ext

    def _image_set(self, body_poses, extent=None) -> PeriodicImages:
        """The periodic images to mesh at ``body_poses`` (:func:`fluidem.mesh.seam.periodic_images`;
        ``extent``: :meth:`_extent` at them, if the caller has it); without periodic sides every body once."""
        if not self.periodic or not self.n_real:
            n = self.n_real
            return PeriodicImages(body=np.arange(n), cell=np.zeros((n, 2), dtype=np.int64), shift=np.zeros((n, 2)))
        margin = (self.params.drag_reach + 1.0) * self.h
        ext = self._extent(body_poses) if extent is None else extent
        return periodic_images(body_poses, ext, self.box, self.periodic, margin)

    def _set_images(self, images: PeriodicImages, nudge: bool = False) -> None:
        """Make ``images`` the bodies the mesh holds: per image its outline, vertices and pose
        (``nudge``: bodies with an outline node on a periodic side line are held nudged off it,
        :func:`fluidem.mesh.seam.seam_nudge`)."""
        if nudge and self.periodic and self.n_real:
            ol = self._real_outlines
            pts = world(ol.local, ol.body, self.body_poses)
            shift = seam_nudge(pts, ol.body, self.n_real, self.box, self.periodic, SEAM_BAND * self.h)
            images = PeriodicImages(body=images.body, cell=images.cell, shift=images.shift + shift[images.body])
        self.images = images
        nb = len(images.body)
        self.n_bodies = nb
        self._verts_local = [self._body_verts[b] for b in images.body]
        self._nv = self._real_nv[images.body]
        self._vcat = np.vstack(self._verts_local) if nb else np.zeros((0, 2))
        self._vbody = np.repeat(np.arange(nb), self._nv)
        ol = self._real_outlines
        if nb == self.n_real and np.array_equal(images.body, np.arange(nb)) and not images.cell.any():
            self.outlines = ol
        else:
            # every image carries its body's outline rows; uids per (row, image cell)
            first = np.concatenate([[0], np.cumsum(np.bincount(ol.body, minlength=self.n_real))])
            counts = first[images.body + 1] - first[images.body]
            start = np.concatenate([[0], np.cumsum(counts)])[:-1]
            rows = np.concatenate([np.arange(first[b], first[b + 1]) for b in images.body]) if nb else \
                np.zeros(0, dtype=np.int64)
            img = np.repeat(np.arange(nb), counts)
            nxt = ol.next[rows] - np.repeat(first[images.body], counts) + np.repeat(start, counts)
            code = (images.cell[:, 0] + 512) * 1024 + (images.cell[:, 1] + 512)
            uid = UID_OUTLINE + rows + len(ol.body) * (np.repeat(code, counts) - (512 * 1024 + 512))
            self.outlines = BodyOutlines(local=ol.local[rows], body=img, next=nxt, uid=uid)
        self.poses = self._image_poses(self.body_poses)

    def _image_poses(self, body_poses, images: PeriodicImages | None = None) -> np.ndarray:
        """Poses ``(n_images, 3)`` of ``images`` (default: the images held), for real ``body_poses (n, 3)``."""
        im = self.images if images is None else images
        out = np.asarray(body_poses, dtype=float)[im.body].copy()
        out[:, :2] += im.shift
        return out

    def allowed_wall_overlap(self, poses=None) -> np.ndarray:
        """Deepest overlap ``(n_bodies, 4)`` of each body with each box side (bottom, right, top,
        left) that is meshed as contact, length units: ``max(wall_overlap · h,
        wall_overlap_fraction · e)``, ``e`` the body's extent across the side at ``poses``
        (default: the current ones; :class:`MeshParams`)."""
        poses = self.body_poses if poses is None else np.asarray(poses, dtype=float)
        p = self.params
        w = world(self._real_vcat, self._real_vbody, poses)
        ext = np.zeros((self.n_real, 2))
        for axis in range(2):
            hi = np.full(self.n_real, -np.inf)
            lo = np.full(self.n_real, np.inf)
            np.maximum.at(hi, self._real_vbody, w[:, axis])
            np.minimum.at(lo, self._real_vbody, w[:, axis])
            ext[:, axis] = hi - lo
        across = ext[:, [1, 0, 1, 0]]  # bottom/top: the height, right/left: the width
        return np.maximum(p.wall_overlap * self.h, p.wall_overlap_fraction * across)

    def _outside(self, pose) -> bool:
        """The reference point of a body at ``pose`` lies outside the box (across a wall)."""
        xmin, xmax, ymin, ymax = self.box
        ax = self.__dict__.get("periodic", ())
        return not (("x" in ax or xmin <= pose[0] <= xmax) and ("y" in ax or ymin <= pose[1] <= ymax))

    def _movable_count(self) -> int:
        """Free and box nodes of the current mesh (what the adaptation adds and removes)."""
        return int(((self.kind == FREE) | (self.kind == SIDE) | (self.kind == CORNER)).sum())

    def _size_integral(self) -> float:
        """``∫ h⁻² dA`` over the current mesh (elements, mean per-node target), dimensionless."""
        t = self.triangles
        h_t = self.h_node[t].mean(axis=1)
        return float((np.abs(signed_areas(self.points, t)) / h_t**2).sum())

    def _node_budget(self) -> float | None:
        """Free and box nodes the adaptation aims at (``hold_node_count``), ``None``: no aim."""
        density = self.__dict__.get("_node_density")
        if not self.params.hold_node_count or density is None:
            return None
        return density * self._size_integral()

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

    # ------------------------------------------------------------------ triangulation
    def _triangulate_from(self, cand, cand_kind, cand_uid, purge, adapt, n_relax, h_cand=None):
        """Contacts + cut-out (+ adaptation) + CDT + junctions + relaxation + clean-up from
        candidate nodes (Sec. 2.1); returns the counts of :class:`MeshEvent`."""
        p = self.params
        if self.periodic:
            self._set_images(self._image_set(self.body_poses), nudge=True)
        poses = self.poses
        outline_world = self.outlines.world(poses)
        polys = self._polygons(poses)
        tree = shapely.STRtree(polys) if self.n_bodies else None
        table = self._bodies_table(poses)

        def target(q):
            return self._target(q, outline_world)

        contact = contact_outline(polys, tree, outline_world, self.outlines, self.h, self.min_gap, p, box=self.box,
                                  wall_sides=self._wall_sides)
        self.contacts = contact.contacts
        self.walls = contact.walls
        self.pore_areas = contact.pore_areas

        cand = np.asarray(cand, dtype=float)
        h_candidates = target(cand) if h_cand is None else h_cand
        cut = cut_out(cand, cand_kind, h_candidates, table, purge, p.gap_purge, self.box)
        info = {"n_purged": cut.n_purged, "n_removed": 0, "n_inserted": 0}
        keep = cut.keep
        kept_points, kept_kind, kept_uid = cand[keep], cand_kind[keep], cand_uid[keep]
        if adapt:
            # adaptation works on the current mesh: the candidates are its nodes
            if len(cand) != len(self.points):
                raise RuntimeError("adaptation needs the current nodes as candidates")
            solid_tree = shapely.STRtree(np.asarray(contact.solids, dtype=object)) if self.n_bodies else None
            ad = adapt_nodes(kept_points, kept_kind, kept_uid, self.points, self.topo, self.h_node, self.kind,
                             np.where(keep, np.cumsum(keep) - 1, -1), solid_tree, target, self._uids,
                             self.step_count, p.refine_area, p.coarsen_ratio, p.clearance, box=self.box,
                             budget=self._node_budget(),
                             budget_tolerance=p.node_count_tolerance)
            kept_points, kept_kind, kept_uid = ad.points, ad.kind, ad.uid
            info["n_removed"], info["n_inserted"] = ad.n_removed, ad.n_inserted

        final_shape = None
        for attempt in range(p.cleanup_passes + 1):
            kept_points, kept_kind, kept_uid = match_side_nodes(kept_points, kept_kind, kept_uid, self.box,
                                                                self.periodic, self._uids, merge=0.25 * self.h)
            tri = triangulate(kept_points, kept_kind, kept_uid, outline_world, self.outlines, contact, poses, polys,
                              tree, self.box, self._uids, p.junctions, p.junction_clearance, target,
                              seams=(self.periodic, SEAM_MERGE * self.h) if self.periodic else None)
            self._install(tri, outline_world)
            if n_relax:
                self.points, _ = relax(self.points, self.topo, self.h_node, self._mobility, n_relax,
                                       p.relax_params, bounds=self.box)
                self.points = slide_in_pairs(self.points, self._side_pairs, self.box, lead=self.kind == CONTACT)
            if attempt == p.cleanup_passes:
                break
            # clean-up: bad elements outside narrow gaps lose their free nodes, or get one
            cleanup = cleanup_candidates(self.points, self.topo, self.kind, self.uid, self.h_node, table, tree,
                                         self.box, target, self._uids, p.min_angle_trigger, p.max_angle_trigger,
                                         p.cleanup_clearance)
            if cleanup.candidates is None:
                final_shape = cleanup.shape  # of the mesh kept
                break
            kept_points, kept_kind, kept_uid = cleanup.candidates
        self._steps_since = 0
        self._near_pairs = contact_pairs(polys, tree, self.h)
        self.drag: DragAssociation = drag_association(self.points, self.h_node, self._drag_mobility, table,
                                                      p.drag_reach, p.drag_full, p.drag_stiffness)
        self._harmonic = None  # built by the first drag step on this connectivity
        self._set_quality_baseline(final_shape)
        info["n_junctions"] = self.n_junctions
        return info

    def _install(self, tri: Triangulation, outline_world):
        """Make ``tri`` the current mesh (node data, topology, targets, mobility)."""
        self.points = tri.points
        self.kind = tri.kind
        self.body_of = tri.body_of
        self.outline_row = tri.outline_row
        self.uid = tri.uid
        self.triangles = tri.triangles
        self.topo = tri.topo
        self.boundary_segments = tri.boundary_segments
        self.boundary_markers = tri.boundary_markers
        self.junction_nodes = tri.junction_nodes
        self.junction_verts = tri.junction_verts
        self.junction_bary = tri.junction_bary
        self.n_junctions = int(len(tri.junction_nodes))
        self._contact_local = tri.contact_local
        self._contact_idx = np.flatnonzero(tri.kind == CONTACT)
        self._contact_wall = (np.full(len(self._contact_idx), -1, dtype=np.int64) if tri.contact_wall is None
                              else tri.contact_wall)
        nc = len(self._contact_idx)
        self._seam_outer_body = (np.full(nc, -1, dtype=np.int64) if tri.seam_outer_body is None
                                 else tri.seam_outer_body)
        self._seam_outer_local = np.zeros((nc, 2)) if tri.seam_outer_local is None else tri.seam_outer_local
        self.h_node = self._target(tri.points, outline_world)
        # periodic side nodes slide along their side in matched pairs (:func:`slide_in_pairs`)
        self._mobility = mobility(tri.kind, tri.points, self.box)
        self._side_pairs = side_partners(tri.points, tri.kind, self.box, self.periodic)
        # junction nodes are dragged (they are not relaxed)
        self._drag_mobility = self._mobility.copy()
        self._drag_mobility[tri.kind == JUNCTION] = 1.0
        self._osc.reset()
        self._damping = None

    def _set_quality_baseline(self, shape=None):
        """Thresholds of the quality trigger after a triangulation (:func:`quality_baseline`).

        Narrow-gap elements (the cheap geometric flag evaluated now, gaps change little
        between re-triangulations, or'ed with the structural one) are left out.
        ``shape``: :func:`element_shape` of the current mesh if the caller has it.
        """
        p = self.params
        narrow = self._narrow_gap_owners() | structural_narrow(self.topo, self.kind, self.body_of)
        shape = element_shape(self.points, self.topo) if shape is None else shape
        self.baseline: QualityBaseline = quality_baseline(shape, narrow, p.min_angle_trigger, p.max_angle_trigger,
                                                          p.angle_margin, p.min_angle_margin)

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
        real = self._check_poses(poses)
        hist = self.__dict__.get("_body_pose_history", (None, None))
        self._body_pose_history = (self.body_poses, hist[0])  # body poses at t^n, t^{n-1}
        self.body_poses = real
        new = self._image_poses(real)
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
            info = self._triangulate_from(bg.points, bg.kind, bg.uid, purge=self.params.clearance, adapt=False,
                                          n_relax=self.relax_iterations)
            ev.retriangulated, ev.reason = True, "regenerate"
            ev.old_points, ev.old_triangles, ev.prev_points = old_p, old_t, old_p
            ev.n_purged, ev.n_junctions = info["n_purged"], info["n_junctions"]
        else:
            self._drag_step(new, ev)
        self._carry_history(ev, *before)
        ev.contacts = self.contacts
        ev.walls = self.__dict__.get("walls", ev.walls)
        ev.pore_areas = self.pore_areas
        ev.n_nodes, ev.n_triangles = len(self.points), len(self.triangles)
        ev.seconds = time.perf_counter() - t0
        return ev

    def _drag_step(self, new, ev):
        """Drag (:mod:`fluidem.mesh.drag`), relax, and re-triangulate if a trigger fires."""
        p = self.params
        xd = dragged_positions(self.points, self.triangles, self.kind, self.outline_row, self.outlines.local,
                               self.outlines.body, self._contact_idx, self._contact_local, self.body_of,
                               self._drag_mobility, self.drag, self.junction_nodes, self.junction_verts,
                               self.junction_bary, self.poses, new, p.drag_halvings, self._harmonic_drag(),
                               wall_side=self.__dict__.get("_contact_wall"), box=self.box)
        self.poses = new
        if self.periodic:
            seam_broken = self._place_seam_nodes(xd, new)
            if seam_broken or self._needs_new_images():
                # an outline left its seam or a body reached a side without its image: the
                # clipped outlines change (:mod:`fluidem.mesh.seam`)
                self.points = xd
                self._steps_since += 1
                self._retriangulate_step(ev, "seam")
                return
        # nodes dragged out of the box: movable ones are put back on it; a fixed one (an outline
        # node of a body pressed into a wall) cannot be: no relaxation, re-triangulate now
        # (the outline is rebuilt with the wall, :mod:`fluidem.mesh.contact_outline`)
        xmin, xmax, ymin, ymax = self.box
        lo, hi = np.array([xmin, ymin]), np.array([xmax, ymax])
        outside = ((xd < lo) | (xd > hi)).any(axis=1)
        pressed = seam = False
        if outside.any():
            movable = outside & self._mobility.any(axis=1)
            xd[movable] = np.clip(xd[movable], lo, hi)
            over = np.flatnonzero(outside & ~movable)
            if len(over):
                # outline nodes of a body meshed with a wall, pressed past it by at most
                # contact_slack · h (a resting body's overlap breathing), are put back on it
                # per node and side (bottom, right, top, left) how far past it
                past = np.column_stack([ymin - xd[over, 1], xd[over, 0] - xmax, xd[over, 1] - ymax,
                                        xmin - xd[over, 0]])
                walls = self.__dict__.get("walls", np.zeros((0, 2), dtype=np.int64))
                meshed = np.zeros((self.n_bodies, 4), dtype=bool)
                meshed[walls[:, 0], walls[:, 1]] = True
                ok = np.where(past > 0, meshed[self.body_of[over]] & (past <= self._contact_slack()), True)
                if ok.all():
                    xd[over] = np.clip(xd[over], lo, hi)
                else:
                    pressed = True
                    if ((past > 0) & ~self._wall_sides[None, :]).any():
                        seam = True
        if pressed and seam:
            # an outline node passed a periodic side: the body is clipped anew there
            self.points = xd
            self._steps_since += 1
            self._retriangulate_step(ev, "seam")
            return
        if pressed:
            self.points = xd
            self._steps_since += 1
            shape = element_shape(xd, self.topo)
            reason = retriangulation_reason(shape, self.baseline, p.degenerate_area, 0, p.retriangulate_every,
                                            lambda: False, lambda: False)
            self._retriangulate_step(ev, reason if reason in ("inverted", "degenerate") else "contact")
            return
        # relaxation with the per-step iteration limit (Sec. 3.3)
        damp = self.drag.relax_damping if self._damping is None else self.drag.relax_damping * self._damping
        xd = slide_in_pairs(xd, self.__dict__.get("_side_pairs", np.zeros((0, 2), dtype=np.int64)), self.box,
                            lead=self.kind == CONTACT)
        xr, nb = relax(xd, self.topo, self.h_node, self._mobility, self.relax_iterations, p.relax_params,
                       bounds=self.box, damping=damp)
        ev.n_blocked = nb
        osc = self._osc.update(xr - xd, self.h_node)
        if len(osc):
            if self._damping is None:
                self._damping = np.ones(len(xd))
            self._damping[osc] *= 0.5
        ev.oscillating = osc
        self.points = slide_in_pairs(xr, self.__dict__.get("_side_pairs", np.zeros((0, 2), dtype=np.int64)), self.box,
                                     lead=self.kind == CONTACT)
        self._steps_since += 1
        # re-triangulate?  (one pass over the elements gives areas and angle cosines)
        shape = element_shape(xr, self.topo)
        reason = retriangulation_reason(
            shape, self.baseline, p.degenerate_area, self._steps_since, p.retriangulate_every,
            self._contacts_changed, lambda: quality_dropped(shape, self.baseline, self._anchored_across_gap))
        if reason:
            self._retriangulate_step(ev, reason)

    def _retriangulate_step(self, ev, reason):
        """Re-triangulate the current nodes in a drag step and record it in ``ev``."""
        ev.old_points, ev.old_triangles = self.points.copy(), self.triangles.copy()
        ev.prev_points = self._prev_points
        info = self.retriangulate()
        ev.retriangulated, ev.reason = True, reason
        ev.n_purged, ev.n_removed, ev.n_inserted = info["n_purged"], info["n_removed"], info["n_inserted"]
        ev.n_junctions = info["n_junctions"]

    def _place_seam_nodes(self, xd, poses) -> bool:
        """Put the seam nodes of ``xd (n, 2)`` at the crossings of their segments at ``poses``
        (:func:`fluidem.mesh.seam.seam_positions`); ``True`` if a segment no longer crosses its
        side (its inner end left the box or its outer end came in): re-triangulate."""
        wall = self.__dict__.get("_contact_wall")
        if wall is None:
            return False
        sel = wall >= SEAM_CODE
        if not sel.any():
            return False
        idx = self._contact_idx[sel]
        p_in = world(self._contact_local[sel], self.body_of[idx], poses)
        p_out = world(self._seam_outer_local[sel], self._seam_outer_body[sel], poses)
        side = wall[sel] - SEAM_CODE
        xd[idx] = seam_positions(p_in, p_out, side, self.box, xd[idx])
        xmin, xmax, ymin, ymax = self.box
        level = np.select([side == 0, side == 1, side == 2, side == 3], [ymin, xmax, ymax, xmin])
        c = np.where((side == 1) | (side == 3), 0, 1)
        k = np.arange(len(side))
        outward = np.where((side == 1) | (side == 2), 1.0, -1.0)
        inner_in = outward * (level - p_in[k, c]) > 0.0
        outer_out = outward * (p_out[k, c] - level) > 0.0
        return bool(not (inner_in & outer_out).all())

    def _needs_new_images(self) -> bool:
        """A body reaches into the box through a periodic side where the mesh holds no image of it."""
        ext = self._extent(self.body_poses)  # once per step: the image set and the test below
        need = self._image_set(self.body_poses, ext)
        p = self._image_poses(self.body_poses, need)
        xmin, xmax, ymin, ymax = self.box
        inside = ((p[:, 0] + ext[need.body, 1] > xmin) & (p[:, 0] + ext[need.body, 0] < xmax)
                  & (p[:, 1] + ext[need.body, 3] > ymin) & (p[:, 1] + ext[need.body, 2] < ymax))
        return bool(np.setdiff1d(need.key()[inside], self.images.key()).size)

    def _harmonic_drag(self) -> HarmonicDrag | None:
        """The harmonic extension of this connectivity (``drag_field="harmonic"``), factorised
        once per triangulation; ``None`` for the ramp."""
        if self.params.drag_field != "harmonic":
            return None
        if self.__dict__.get("_harmonic") is None:
            self._harmonic = harmonic_drag(self.topo, self.kind, self._mobility, self.drag)
        return self._harmonic

    def retriangulate(self, n_relax: int | None = None) -> dict:
        """Constrained Delaunay triangulation of the current nodes (cut-out, adaptation, junctions).

        Returns a dict with ``n_purged``, ``n_removed``, ``n_inserted``, ``n_junctions``.
        """
        n_relax = self.params.retriangulate_iterations if n_relax is None else n_relax
        return self._triangulate_from(self.points, self.kind, self.uid, purge=self.params.purge_clearance,
                                      adapt=True, n_relax=n_relax, h_cand=self.h_node)

    # ------------------------------------------------------------------ gaps and triggers on the current mesh
    def _contacts_changed(self) -> bool:
        """:func:`fluidem.mesh.triggers.contacts_changed` at the current poses, or a body
        came within ``min_gap`` of a wall, or one meshed with a wall left it by more than
        :meth:`_contact_slack` (hysteresis: a body resting on a wall whose gap breathes
        around ``min_gap`` does not re-trigger every step)."""
        if self.n_bodies:
            depth = wall_depths(world(self._vcat, self._vbody, self.poses), self._vbody, self.n_bodies, self.box)
            depth[:, ~self._wall_sides] = np.inf
            before = self.__dict__.get("walls", np.zeros((0, 2), dtype=np.int64))
            was = np.zeros(depth.shape, dtype=bool)
            was[before[:, 0], before[:, 1]] = True
            if ((depth < self.min_gap) & ~was).any() or (was & (depth > self._contact_slack())).any():
                return True
            # a wall node held on its side while its body lifted off there (a body rocking on
            # the wall): the closed outline no longer fits
            wall = self.__dict__.get("_contact_wall")
            if wall is not None and ((wall >= 0) & (wall < SEAM_CODE)).any():
                sel = (wall >= 0) & (wall < SEAM_CODE)
                idx = self._contact_idx[sel]
                rigid = world(self._contact_local[sel], self.body_of[idx], self.poses)
                if (np.abs(rigid - self.points[idx]).max() > self._contact_slack()):
                    return True
        return contacts_changed(self._polygons(), self._near_pairs, self.contacts, self.min_gap, self.points,
                                self.body_of)

    def _contact_slack(self) -> float:
        """How far (length units) a wall contact may breathe between re-triangulations:
        ``max(min_gap, contact_slack · h)`` (:class:`MeshParams`)."""
        return max(self.min_gap, self.params.contact_slack * self.h)

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
        """Positions at t^n and t^{n−1} of the trajectories of the nodes after :meth:`update`.

        ``x_n`` (positions before the update) and ``x_nm1`` (their own history) belong to the
        nodes before the update.  Without re-triangulation the nodes are the same.  After one
        the new nodes y lie in the old connectivity at the positions reached this step
        (``ev.old_points``, covering the new domain); the old mesh motion is affine on each
        old element, so the trajectory of y is that of its barycentric combination of old
        nodes: x^n(y) = Σ λ_k x_k^n, x^{n−1}(y) = Σ λ_k x_k^{n−1}.  If the old mesh is not valid
        there (``"inverted"``) or did not move (``"regenerate"``) the nodes are at rest this
        step (Eulerian).
        """
        if not ev.retriangulated:
            self._trajectory = (x_n, x_nm1)
            return
        if ev.reason in ("inverted", "regenerate") or ev.old_points is None:
            ev.history = "eulerian"
            self._trajectory = (self.points.copy(), self.points.copy())
            return
        from skfem import MeshTri

        from .transfer import locate_near

        old = MeshTri(np.asarray(ev.old_points, float).T.copy(), np.asarray(ev.old_triangles).T.copy())
        # a node that survived the re-triangulation moved little (relaxation): it is searched
        # first in the old elements around its old position
        hint = np.full(len(self.points), -1, dtype=np.int64)
        prev_uid = self._prev_uid
        if prev_uid is not None and len(prev_uid) == len(ev.old_points):
            order = np.argsort(prev_uid)
            pos = np.minimum(np.searchsorted(prev_uid[order], self.uid), len(order) - 1)
            match = prev_uid[order][pos] == self.uid
            hint[match] = order[pos[match]]
        cells, bary = locate_near(old, self.points.T, hint)
        tri = old.t[:, cells].T  # (n, 3), in the vertex order of the located cells

        def pull(x):
            return None if x is None else np.einsum("nk,nkd->nd", bary, x[tri])

        ev.history = "ale"
        self._trajectory = (pull(x_n), pull(x_nm1))
        if self.periodic:
            self._rigid_history()

    def _rigid_history(self) -> None:
        """Trajectories of the body nodes a re-triangulation created (nodes of an image entering
        the box, seam nodes): the rigid motion of their body (the crossing of their segment for
        seam nodes), not the old mesh's motion, which does not reach them (they lie beyond the
        old clipped outline)."""
        hist = self.__dict__.get("_body_pose_history", (None, None))
        prev = self._prev_uid
        new = np.ones(len(self.uid), dtype=bool)
        if prev is not None and len(prev):
            new = ~np.isin(self.uid, prev)
        traj = list(self._trajectory)
        for level, body_poses in enumerate(hist):
            if body_poses is None or traj[level] is None:
                continue
            poses = self._image_poses(body_poses)
            x = traj[level]
            ol = np.flatnonzero(new & (self.kind == OUTLINE))
            if len(ol):
                rows = self.outline_row[ol]
                x[ol] = world(self.outlines.local[rows], self.outlines.body[rows], poses)
            ci = self._contact_idx
            sel = new[ci]
            if sel.any():
                wall = self._contact_wall[sel]
                idx = ci[sel]
                x[idx] = world(self._contact_local[sel], self.body_of[idx], poses)
                seam = wall >= SEAM_CODE
                if seam.any():
                    p_out = world(self._seam_outer_local[sel][seam], self._seam_outer_body[sel][seam], poses)
                    x[idx[seam]] = seam_positions(x[idx[seam]], p_out, wall[seam] - SEAM_CODE, self.box,
                                                  self.points[idx[seam]])
        self._trajectory = tuple(traj)

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
            x_n, x_nm1 = self.node_history()
            if x_n is None:
                return np.zeros_like(self.points)
            if x_nm1 is None:
                return (self.points - x_n) / dt
            return (3.0 * (self.points - x_n) - (x_n - x_nm1)) / (2.0 * dt)  # differences first: round-off
        if order != 1:
            raise InputError(f"order = {order!r}: expected 1 or 2")
        order = np.argsort(self._prev_uid)
        pos = np.minimum(np.searchsorted(self._prev_uid[order], self.uid), len(order) - 1)
        match = self._prev_uid[order][pos] == self.uid
        w = np.zeros_like(self.points)
        j = order[pos[match]]
        w[match] = (self.points[match] - self._prev_points[j]) / dt
        # nodes created by the re-triangulation: mean velocity of their known mesh
        # neighbours, spreading outwards until every node has one (a few passes over the
        # edges; Qhull-based interpolation of all nodes cost seconds at 100k nodes)
        known = match.copy()
        e0, e1 = self.topo.e0, self.topo.e1
        n = len(w)
        while not known.all():
            k0, k1 = known[e0], known[e1]
            cnt = np.bincount(e0, k1, n) + np.bincount(e1, k0, n)
            sx = np.bincount(e0, k1 * w[e1, 0], n) + np.bincount(e1, k0 * w[e0, 0], n)
            sy = np.bincount(e0, k1 * w[e1, 1], n) + np.bincount(e1, k0 * w[e0, 1], n)
            new = ~known & (cnt > 0)
            if not new.any():  # a component without any known node (cannot happen in a mesh with bodies)
                break
            w[new, 0] = sx[new] / cnt[new]
            w[new, 1] = sy[new] / cnt[new]
            known |= new
        return w

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


#: keyword parameters stored as attributes by MovingMesh before the split by stage
_FORMER_PARAM_ATTRS = ("strategy", "retriangulate_every", "relax_iterations", "initial_iterations",
                       "retriangulate_iterations", "min_angle_trigger", "clearance", "purge_clearance", "gap_purge",
                       "cleanup_passes", "relax_params", "drag_reach", "drag_full", "drag_stiffness", "tow_width",
                       "refine_area", "coarsen_ratio")


def _state_before_split(old: dict) -> dict:
    """The pickled state of a MovingMesh from before the split by stage, in today's attributes."""
    s = dict(old)
    kw = {k: s.pop(k) for k in _FORMER_PARAM_ATTRS}
    s["params"] = MeshParams(min_gap=s.pop("min_gap"), junctions=s.pop("use_junctions"),
                             background=s["background_kind"], **kw)
    s["outlines"] = BodyOutlines(s.pop("_ol_local"), s.pop("_ol_body"), s.pop("_ol_next"))
    s["background_candidates"] = BackgroundNodes(s.pop("_bg_points"), s.pop("_bg_kind"), s.pop("_bg_uid"))
    s["_uids"] = UidSource(s.pop("_next_uid"))
    s["outline_row"] = s.pop("ol_id")
    s["junction_nodes"] = s.pop("_junction_nodes")
    s["junction_verts"] = s.pop("_junction_verts", np.zeros((0, 3), dtype=np.int64))
    s["junction_bary"] = s.pop("_junction_bary", np.zeros((0, 3)))
    s["drag"] = DragAssociation(s.pop("_drag_node"), s.pop("_drag_body"), s.pop("_drag_weight"),
                                s.pop("_relax_damping"))
    cos_max, cos_min = s.pop("_base_cos")
    bound_lo, bound_hi = s.pop("_cos_bound")
    s["baseline"] = QualityBaseline(cos_lo=s.pop("_cos_lo"), cos_hi=s.pop("_cos_hi"), area=s.pop("_base_area"),
                                    narrow=s.pop("_base_narrow"), cos_max=cos_max, cos_min=cos_min,
                                    cos_bound_lo=bound_lo, cos_bound_hi=bound_hi)
    return s
