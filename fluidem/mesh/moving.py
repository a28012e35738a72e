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
6. spring relaxation (:mod:`fluidem.mesh.relax`, eq. 1–3), then one clean-up pass: free
   nodes of elements still outside the angle bounds (outside narrow gaps) are removed, a
   node is added in such elements without free nodes, and steps 4–6 run once more.

Strategies (``strategy=``):

``"regenerate"``
    the older method: every step the background is reset (nodes snap back) and the whole
    pipeline runs, with ``relax_iterations`` sweeps (default 20).
``"drag"``
    mesh dragging (Sec. 4.2): each step the outline nodes move rigidly with their body;
    free nodes within ``drag_full · h`` of a body follow its rigid motion, with a weight
    falling to zero at ``drag_reach · h`` (the body drags the mesh around it); junction
    nodes keep their barycentric place between their three outline nodes; then
    ``relax_iterations`` relaxation sweeps (default 3; dragged nodes relax with a reduced
    step).  Nodes never snap back.  The current nodes are re-triangulated every
    ``retriangulate_every`` steps (K, default 30) or earlier when

    - an element is inverted by the rigid motion (``"inverted"``) or shrank below a tenth of
      its area (``"degenerate"``, typically a narrow-gap element whose anchor passes a
      corner),
    - bodies came within ``min_gap`` of each other, or a contact changed (``"contact"``),
    - an element outside narrow gaps crossed the angle bounds ``min_angle_trigger`` (15°)
      or 135° that it kept after the last triangulation (``"quality"``; an element that
      was already outside may lose 3° more).

    At re-triangulation nodes swallowed by (or closer than ``purge_clearance · h`` to) a
    body are purged, an independent set of nodes is removed where the incident edges are on
    average shorter than ``coarsen_ratio`` (0.7) of their target and nodes are added in triangles larger than ``refine_area`` (1.6) target
    areas (so
    vacated regions coarsen again, Fig. 6), and junction points are recomputed.
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
produced.  Outline nodes of the cluster bodies that lie on the closed outline are kept
(two closer than ``0.1 h`` are merged); vertices of the closed outline farther than
``0.3 h`` from every kept outline node (deep contact points, bridge corners) become
*contact nodes*, owned by and moving with the nearest body.  Where no contact node is
added, the outline cuts straight across the contact notch, which lies in the fluid: no
element overlaps a body, at the price of a fluid sliver below ``0.3 h`` at each contact.
Fluid enclosed by a ring of touching bodies (a hole of the closed union) is a *pore*: it is
meshed, detected and reported (``pore_areas``; it needs its own pressure reference).
Bodies must stay at least ``min_gap`` inside the box; a body outside raises ``ValueError``.

Narrow gaps: see :mod:`fluidem.mesh.quality`; an element counts as narrow-gap when the gap
at its centroid is narrower than ``h/2`` or when one of its edges joins two different
boundaries with one end closer than ``h/2`` to the other end's boundary.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import shapely
import triangle as tr
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..geometry import validate_polygon
from .background import GradedSize, SizeField, UniformSize, friedrichs_keller_grid, graded_background, subdivide_segment
from .adjacency import edges_from_neighbors, split_with_neighbors
from .junctions import junction_points
from .proximity import PolygonTable
from .quality import MeshQuality, OscillationDetector, mesh_quality
from .relax import MeshTopology, RelaxParams, relax, signed_areas
from .triangulate import SIDE_NAMES, BoxDomain, _facet_lookup

__all__ = ["MovingMesh", "MeshEvent", "STRATEGIES"]

#: mesh strategies by name
STRATEGIES = ("drag", "regenerate", "fixed")

# node kinds
FREE, SIDE, CORNER, OUTLINE, JUNCTION, CONTACT = 0, 1, 2, 3, 4, 5
_UID_OUTLINE = 1 << 40
_UID_NEW = 1 << 50
_FIRST_BODY_MARKER = 10


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
        element: the old mesh at the new positions is invalid), ``"regenerate"``.
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
    old_points: np.ndarray | None = field(default=None, repr=False)
    old_triangles: np.ndarray | None = field(default=None, repr=False)
    prev_points: np.ndarray | None = field(default=None, repr=False)
    seconds: float = 0.0


def _rot(angles):
    c, s = np.cos(angles), np.sin(angles)
    return c, s


def _body_vertices(b, i):
    v = getattr(b, "vertices", b)
    name = getattr(b, "name", None) or f"body{i}"
    return validate_polygon(v, f"body {i} ({name})"), name


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
    strategy : {"drag", "regenerate", "fixed"}
    retriangulate_every : int
        K, steps between re-triangulations when dragging (paper: 20–50).
    relax_iterations : int or None
        Relaxation sweeps per physical step (Sec. 3.3 iteration limit); default 3 for
        ``drag``, 20 for ``regenerate``.
    min_angle_trigger : float
        Re-triangulate early when the smallest angle outside narrow gaps falls below this
        (degrees).
    clearance : float
        Background nodes closer than ``clearance · h`` to a body are cut out.
    purge_clearance : float
        When dragging, nodes closer than ``purge_clearance · h`` to a body are purged at
        re-triangulation.
    min_gap : float or None
        Bodies closer than this are meshed as one outline (contact policy, module
        docstring); default ``1e-3 · h``.
    junctions : bool
        Insert Voronoi junction points (Sec. 3.2).
    background : {"fk", "delaunay"} or None
        Background nodes for a uniform size: the Friedrichs–Keller square grid (default) or
        a quality Delaunay point set; graded sizes always use the latter.
    relax_params : RelaxParams
    tow_width : float
        With grading: width (multiples of ``h``) of the zone of size ``h`` a body carries.
    drag_reach, drag_full : float
        Free nodes within ``drag_full · h`` of a body follow its rigid motion fully, with a
        weight falling linearly to zero at ``drag_reach · h``.
    retriangulate_iterations : int
        Relaxation sweeps after a re-triangulation.
    refine_area, coarsen_ratio : float
        Adaptation at re-triangulation: nodes are added in triangles larger than
        ``refine_area`` target areas and removed where incident edges average below
        ``coarsen_ratio`` of their target.

    Attributes
    ----------
    points : (n_nodes, 2) float
        Node positions, length units.
    triangles : (n_triangles, 3) int
        Counter-clockwise triangles.
    kind : (n_nodes,) int8
        0 free, 1 box side (slides along it), 2 box corner, 3 body outline, 4 junction,
        5 contact node.
    body_of : (n_nodes,) int
        Body of an outline or contact node, ``-1`` otherwise.
    h_node : (n_nodes,) float
        Target edge length carried by every node.
    contacts : (k, 2) int
        Body pairs meshed as one outline (closer than ``min_gap``).
    pore_areas : (k,) float
        Areas of fluid pores enclosed by touching bodies.

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
    """

    def __init__(self, domain, bodies, poses, h: float, grading=None, strategy: str = "drag",
                 retriangulate_every: int = 30, relax_iterations: int | None = None,
                 min_angle_trigger: float = 15.0, clearance: float = 0.5, purge_clearance: float = 0.3,
                 min_gap: float | None = None, junctions: bool = True, background: str | None = None,
                 relax_params: RelaxParams = RelaxParams(), initial_iterations: int = 60,
                 drag_reach: float = 3.0, drag_full: float = 1.0, drag_stiffness: float = 0.8,
                 gap_purge: float = 1.1, cleanup_passes: int = 1, retriangulate_iterations: int = 20,
                 tow_width: float = 2.0, refine_area: float = 1.6, coarsen_ratio: float = 0.7):
        self.domain = BoxDomain.from_any(domain)
        self.box = (self.domain.xmin, self.domain.xmax, self.domain.ymin, self.domain.ymax)
        if not (isinstance(h, (int, float, np.floating, np.integer)) and np.isfinite(h) and h > 0):
            raise ValueError(f"mesh size h must be a positive number, got {h!r}")
        self.h = float(h)
        if strategy not in STRATEGIES:
            raise ValueError(f"unknown mesh strategy {strategy!r}; allowed: {', '.join(map(repr, STRATEGIES))}")
        self.strategy = strategy
        if int(retriangulate_every) != retriangulate_every or retriangulate_every < 1:
            raise ValueError(f"retriangulate_every must be an integer >= 1, got {retriangulate_every!r}")
        self.retriangulate_every = int(retriangulate_every)
        if relax_iterations is None:
            relax_iterations = 20 if strategy == "regenerate" else 3
        if int(relax_iterations) != relax_iterations or relax_iterations < 0:
            raise ValueError(f"relax_iterations must be an integer >= 0, got {relax_iterations!r}")
        self.relax_iterations = int(relax_iterations)
        self.initial_iterations = int(initial_iterations)
        if not (np.isfinite(drag_reach) and drag_reach >= 0):
            raise ValueError(f"drag_reach must be a number >= 0 (multiple of h), got {drag_reach!r}")
        self.drag_reach = float(drag_reach)
        if not (np.isfinite(drag_full) and 0 <= drag_full < max(drag_reach, 1e-300)):
            raise ValueError(f"drag_full must be in [0, drag_reach) (multiple of h), got {drag_full!r}")
        self.drag_full = float(drag_full)
        if not (0 <= drag_stiffness <= 1):
            raise ValueError(f"drag_stiffness must be in [0, 1], got {drag_stiffness!r}")
        self.drag_stiffness = float(drag_stiffness)
        for name, val in (("clearance", clearance), ("purge_clearance", purge_clearance)):
            if not (np.isfinite(val) and 0 <= val < 2):
                raise ValueError(f"{name} must be in [0, 2) (multiples of h), got {val!r}")
        self.clearance = float(clearance)
        self.purge_clearance = float(purge_clearance)
        if not (np.isfinite(gap_purge) and gap_purge >= 0):
            raise ValueError(f"gap_purge must be a number >= 0 (multiple of h), got {gap_purge!r}")
        self.gap_purge = float(gap_purge)
        self.cleanup_passes = int(cleanup_passes)
        self.retriangulate_iterations = int(retriangulate_iterations)
        if not (np.isfinite(tow_width) and tow_width >= 0):
            raise ValueError(f"tow_width must be a number >= 0 (multiple of h), got {tow_width!r}")
        self.tow_width = float(tow_width)
        if not (np.isfinite(refine_area) and refine_area > 1):
            raise ValueError(f"refine_area must be a number > 1, got {refine_area!r}")
        self.refine_area = float(refine_area)
        if not (np.isfinite(coarsen_ratio) and 0 < coarsen_ratio < 1):
            raise ValueError(f"coarsen_ratio must be in (0, 1), got {coarsen_ratio!r}")
        self.coarsen_ratio = float(coarsen_ratio)
        self.min_angle_trigger = float(min_angle_trigger)
        self.min_gap = 1e-3 * self.h if min_gap is None else float(min_gap)
        if not (np.isfinite(self.min_gap) and self.min_gap > 0):
            raise ValueError(f"min_gap must be a positive number, got {min_gap!r}")
        self.use_junctions = bool(junctions)
        self.relax_params = relax_params

        # size field
        self._size, self._growth, self._graded = self._make_size(grading)
        if background is None:
            background = "delaunay" if self._graded else "fk"
        if background not in ("fk", "delaunay"):
            raise ValueError(f"background must be 'fk' or 'delaunay', got {background!r}")
        self.background_kind = background

        # bodies
        verts, names = [], []
        for i, b in enumerate(bodies):
            v, name = _body_vertices(b, i)
            verts.append(v)
            names.append(str(name))
        if len(set(names)) != len(names) or set(names) & set(SIDE_NAMES):
            names = [f"body{i}" for i in range(len(verts))]
        self.body_names = names
        self.n_bodies = len(verts)
        self._verts_local = verts
        self._nv = np.array([len(v) for v in verts], dtype=np.int64)
        self._vcat = np.vstack(verts) if verts else np.zeros((0, 2))
        self._vbody = np.repeat(np.arange(self.n_bodies), self._nv)
        self.poses = self._check_poses(poses)

        self._build_outline_table()
        self._build_background()
        self.step_count = 0
        self._steps_since = 0
        self._osc = OscillationDetector()
        self._damping = None
        self._next_uid = _UID_NEW
        self.pore_areas = np.zeros(0)
        self.contacts = np.zeros((0, 2), dtype=np.int64)
        self._prev_points = None
        self._prev_uid = None
        self._triangulate_from(self._bg_points, self._bg_kind, self._bg_uid, purge=self.clearance,
                               adapt=False, n_relax=self.initial_iterations)
        self._prev_points = self.points.copy()
        self._prev_uid = self.uid.copy()

    # ------------------------------------------------------------------ set-up
    def _make_size(self, grading):
        if grading is None:
            return UniformSize(self.h), 1.0, False
        if isinstance(grading, dict):
            allowed = {"region", "growth", "h_max"}
            bad = set(grading) - allowed
            if bad or "region" not in grading:
                raise ValueError(f"grading dict needs 'region' and may have 'growth', 'h_max'; got keys {sorted(grading)}")
            growth = float(grading.get("growth", 1.2))
            h_max = float(grading.get("h_max", 8 * self.h))
            return GradedSize(self.h, growth, h_max, grading["region"]), growth, True
        if isinstance(grading, UniformSize):
            return grading, 1.0, False
        if isinstance(grading, SizeField) or callable(grading):
            growth = float(getattr(grading, "growth", 1.2))
            return grading, growth, True
        raise ValueError(f"grading must be None, a dict, a SizeField or a callable, got {grading!r}")

    def _check_poses(self, poses) -> np.ndarray:
        try:
            p = np.asarray(poses, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"poses must be an (n_bodies, 3) array of numbers, got {poses!r}") from exc
        if self.n_bodies == 0 and p.size == 0:
            return np.zeros((0, 3))
        if p.shape != (self.n_bodies, 3) or not np.all(np.isfinite(p)):
            raise ValueError(f"poses must be a finite ({self.n_bodies}, 3) array of x, y, angle; got shape {p.shape}")
        w = self._world(self._vcat, self._vbody, p)
        xmin, xmax, ymin, ymax = self.box
        g = self.min_gap
        out = (w[:, 0] < xmin + g) | (w[:, 0] > xmax - g) | (w[:, 1] < ymin + g) | (w[:, 1] > ymax - g)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            b = int(self._vbody[k])
            raise ValueError(
                f"body {b} ({self.body_names[b]}) is not inside the domain {self.box} with the minimum gap "
                f"{g:.3g}: vertex {w[k].tolist()} at pose {p[b].tolist()}"
            )
        return p

    @staticmethod
    def _world(local, body, poses):
        c, s = _rot(poses[body, 2])
        x = c * local[:, 0] - s * local[:, 1] + poses[body, 0]
        y = s * local[:, 0] + c * local[:, 1] + poses[body, 1]
        return np.column_stack([x, y])

    def _target(self, pts, outline_world=None) -> np.ndarray:
        """Target edge length at ``pts`` (size field, and the zone the bodies carry)."""
        hs = np.asarray(self._size(pts), dtype=float)
        if self._graded and self.n_bodies:
            if outline_world is None:
                outline_world = self._world(self._ol_local, self._ol_body, self.poses)
            d, _ = cKDTree(outline_world).query(pts)
            hs = np.minimum(hs, self.h + (self._growth - 1.0) * np.maximum(d - self.tow_width * self.h, 0.0))
        return hs

    def _build_outline_table(self):
        """Outline nodes of every body in body coordinates, at the local target size."""
        loc, body, nxt = [], [], []
        off = 0
        for b, v in enumerate(self._verts_local):  # set-up only, once per body
            w = self._world(v, np.zeros(len(v), dtype=np.int64), self.poses[b:b + 1])
            size = lambda p: np.minimum(np.asarray(self._size(p), float), self.h)  # noqa: E731
            pieces = [subdivide_segment(w[i], w[(i + 1) % len(w)], size)[:-1] for i in range(len(w))]
            ring_w = np.vstack(pieces)
            c, s = np.cos(self.poses[b, 2]), np.sin(self.poses[b, 2])
            d = ring_w - self.poses[b, :2]
            ring = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
            # corners exactly as given
            k = 0
            for i, pc in enumerate(pieces):
                ring[k] = v[i]
                k += len(pc)
            n = len(ring)
            loc.append(ring)
            body.append(np.full(n, b))
            nxt.append(off + (np.arange(n) + 1) % n)
            off += n
        self._ol_local = np.vstack(loc) if loc else np.zeros((0, 2))
        self._ol_body = np.concatenate(body) if body else np.zeros(0, dtype=np.int64)
        self._ol_next = np.concatenate(nxt) if nxt else np.zeros(0, dtype=np.int64)

    def _build_background(self):
        if self.background_kind == "fk":
            pts, _ = friedrichs_keller_grid(self.box, self.h)
        else:
            pts = graded_background(self.box, self._size)
        kind, side = self._classify_box(pts)
        self._bg_points = pts
        self._bg_kind = kind
        self._bg_uid = np.arange(len(pts), dtype=np.int64)

    def _classify_box(self, pts):
        xmin, xmax, ymin, ymax = self.box
        tol = 1e-9 * max(xmax - xmin, ymax - ymin)
        on = np.column_stack([
            np.abs(pts[:, 1] - ymin) < tol, np.abs(pts[:, 0] - xmax) < tol,
            np.abs(pts[:, 1] - ymax) < tol, np.abs(pts[:, 0] - xmin) < tol,
        ])
        cnt = on.sum(axis=1)
        kind = np.where(cnt >= 2, CORNER, np.where(cnt == 1, SIDE, FREE)).astype(np.int8)
        side = np.where(cnt >= 1, np.argmax(on, axis=1), -1)
        return kind, side

    # ------------------------------------------------------------------ geometry helpers
    def _polygons(self, poses=None):
        poses = self.poses if poses is None else poses
        w = self._world(self._vcat, self._vbody, poses)
        rings = shapely.linearrings(w, indices=self._vbody)
        return shapely.polygons(rings)

    def _box_ring(self, pts, kind):
        """Segments of the box outline through the side/corner nodes, markers 1..4."""
        xmin, xmax, ymin, ymax = self.box
        W, H = xmax - xmin, ymax - ymin
        idx = np.flatnonzero((kind == SIDE) | (kind == CORNER))
        p = pts[idx]
        _, side = self._classify_box(p)
        s = np.select(
            [side == 0, side == 1, side == 2, side == 3],
            [p[:, 0] - xmin, W + p[:, 1] - ymin, W + H + xmax - p[:, 0], 2 * W + H + ymax - p[:, 1]],
        )
        # corners: the side that starts at them
        order = np.argsort(s, kind="stable")
        ring = idx[order]
        seg = np.column_stack([ring, np.roll(ring, -1)])
        mid = 0.5 * (pts[seg[:, 0]] + pts[seg[:, 1]])
        _, mside = self._classify_box(mid)
        return seg, mside + 1

    # ------------------------------------------------------------------ triangulation
    def _triangulate_from(self, cand, cand_kind, cand_uid, purge, adapt, n_relax, h_cand=None):
        """Cut-out + contacts + junctions + CDT + relaxation from candidate nodes (Sec. 2.1)."""
        info = {"n_purged": 0, "n_removed": 0, "n_inserted": 0}
        poses = self.poses
        olw = self._world(self._ol_local, self._ol_body, poses)
        polys = self._polygons(poses)
        tree = shapely.STRtree(polys) if self.n_bodies else None
        table = self._outline_table(poses)

        # contacts: bodies closer than min_gap are meshed as one closed outline
        ol_keep = np.ones(len(olw), dtype=bool)
        solids = list(polys)
        extra_pts, extra_body, seg_list, holes = [], [], [], []
        pore_list = []
        contacts = np.zeros((0, 2), dtype=np.int64)
        clustered = np.zeros(self.n_bodies, dtype=bool)
        if self.n_bodies > 1:
            a, b = tree.query(polys, predicate="dwithin", distance=self.min_gap)
            sel = a < b
            contacts = np.column_stack([a[sel], b[sel]])
        n_ol = len(olw)
        if len(contacts):
            g = coo_matrix((np.ones(len(contacts)), (contacts[:, 0], contacts[:, 1])),
                           shape=(self.n_bodies, self.n_bodies))
            _, lab = connected_components(g, directed=False)
            members_of = {}
            for k in np.unique(lab[np.concatenate([contacts[:, 0], contacts[:, 1]])]):
                members_of[k] = np.flatnonzero(lab == k)
            n_extra = 0
            tol = 1e-7 * self.h
            for k, mem in members_of.items():  # one per contact cluster (few)
                clustered[mem] = True
                r = 0.5 * self.min_gap
                closed = shapely.union_all(shapely.buffer(polys[mem], r, join_style="mitre", mitre_limit=20.0))
                closed = shapely.buffer(closed, -r, join_style="mitre", mitre_limit=20.0)
                # features below the gap scale (bridge steps) are noise: drop them
                closed = shapely.simplify(closed, self.min_gap, preserve_topology=True)
                comps = list(getattr(closed, "geoms", [closed]))
                rings = []
                for comp in comps:
                    solids.append(comp)
                    holes.append(np.array(shapely.get_coordinates(shapely.point_on_surface(comp))[0]))
                    rings.append(comp.exterior)
                    for ring in comp.interiors:
                        rings.append(ring)
                        pore_list.append(float(shapely.area(shapely.Polygon(ring))))
                in_mem = np.flatnonzero(np.isin(self._ol_body, mem))
                pts_m = shapely.points(olw[in_mem])
                dring = np.column_stack([shapely.distance(rg, pts_m) for rg in rings])
                on = dring.min(axis=1) < max(tol, 1.01 * self.min_gap)
                ol_keep[in_mem[~on]] = False
                which = np.argmin(dring, axis=1)
                for ri, ring in enumerate(rings):
                    rv = shapely.get_coordinates(ring)[:-1]
                    # ring vertices closer than 0.1 h to the previous kept one are dropped
                    if len(rv) > 3:
                        step = np.linalg.norm(np.diff(rv, axis=0, append=rv[:1]), axis=1)
                        rv = rv[np.concatenate([[True], step[:-1] >= 0.1 * self.h])]
                    kept = in_mem[on & (which == ri)]
                    if len(kept):
                        dk, _ = cKDTree(olw[kept]).query(rv)
                    else:
                        dk = np.full(len(rv), np.inf)
                    # ring vertices off the body outline nodes (contact points, bridge
                    # corners) become contact nodes unless an outline node is within 0.3 h:
                    # then the ring cuts straight across the contact notch, which lies in the
                    # fluid (the union is concave there), so no element overlaps a body
                    newp = rv[dk > 0.3 * self.h]
                    # owner of a contact node: nearest member body
                    if len(newp):
                        dmem = np.column_stack([shapely.distance(polys[m], shapely.points(newp)) for m in mem])
                        owner = mem[np.argmin(dmem, axis=1)]
                    else:
                        owner = np.zeros(0, dtype=np.int64)
                    # order the ring's nodes along it
                    allp = np.vstack([olw[kept], newp])
                    gid = np.concatenate([kept, n_ol + n_extra + np.arange(len(newp))])
                    pos = shapely.line_locate_point(ring, shapely.points(allp))
                    o = np.argsort(pos)
                    ringn = gid[o]
                    # outline nodes closer than 0.1 h to their predecessor on the ring
                    # (corners of two touching bodies) are merged into it
                    if len(ringn) > 3:
                        rp = allp[o]
                        step = np.linalg.norm(rp - np.roll(rp, 1, axis=0), axis=1)
                        drop = (step < 0.1 * self.h) & (ringn < n_ol)
                        drop[0] = False
                        ol_keep[ringn[drop]] = False
                        ringn = ringn[~drop]
                    if len(ringn) >= 3:
                        seg_list.append(np.column_stack([ringn, np.roll(ringn, -1)]))
                    extra_pts.append(newp)
                    extra_body.append(owner)
                    n_extra += len(newp)
        self.contacts = contacts
        self.pore_areas = np.array(pore_list)

        extra_pts = np.vstack(extra_pts) if extra_pts else np.zeros((0, 2))
        extra_body = np.concatenate(extra_body).astype(np.int64) if len(extra_pts) else np.zeros(0, dtype=np.int64)
        # outline segments of unclustered bodies
        free_ol = ~clustered[self._ol_body]
        seg_plain = np.column_stack([np.flatnonzero(free_ol), self._ol_next[free_ol]])
        hole_plain = (shapely.get_coordinates(shapely.point_on_surface(polys[~clustered]))
                      if self.n_bodies else np.zeros((0, 2)))

        # candidate nodes: cut out inside / near bodies
        cand = np.asarray(cand, dtype=float)
        box_nodes = (cand_kind == SIDE) | (cand_kind == CORNER)
        hc = self._target(cand, olw) if h_cand is None else h_cand
        keep = np.ones(len(cand), dtype=bool)
        if self.n_bodies:
            stree = shapely.STRtree(np.asarray(solids, dtype=object))
            # one query serves both tests (the closed contact outlines lie within min_gap
            # of the bodies, well inside the purge distance)
            qi = np.flatnonzero(cand_kind == FREE)
            ii, bb, dd = table.pairs_within(cand[qi], max(purge, self.gap_purge) * hc[qi], solid=True)
            close = dd < purge * hc[qi[ii]]
            keep[qi[ii[close]]] = False
            # no room in gaps narrower than gap_purge · h: the gap is spanned by one layer
            gap = self._gap_from_pairs(cand[qi], ii, dd)
            keep[qi[gap < self.gap_purge * hc[qi]]] = False
            # junction nodes from before are recomputed
        movable = (cand_kind == FREE) | box_nodes
        info["n_purged"] = int((~keep & (cand_kind == FREE)).sum())
        keep &= movable
        cpts, ckind, cuid, ch = cand[keep], cand_kind[keep], cand_uid[keep], hc[keep]

        if adapt:
            # adaptation works on the current mesh: the candidates are its nodes
            if len(cand) != len(self.points):
                raise RuntimeError("adaptation needs the current nodes as candidates")
            old_row = np.where(keep, np.cumsum(keep) - 1, -1)
            cpts, ckind, cuid, ch, nrem, nins = self._adapt(cpts, ckind, cuid, ch, olw,
                                                            stree if self.n_bodies else None, old_row)
            info["n_removed"], info["n_inserted"] = nrem, nins

        final_shape = None
        for attempt in range(self.cleanup_passes + 1):
            # assemble nodes: [candidates | outline | contact nodes | junctions]
            ol_idx = np.flatnonzero(ol_keep)
            nodes = np.vstack([cpts, olw[ol_keep], extra_pts])
            jp = np.zeros((0, 2))
            n_c = len(cpts)
            # map of outline table index -> node index
            ol_map = np.full(n_ol + len(extra_pts), -1, dtype=np.int64)
            ol_map[ol_idx] = n_c + np.arange(len(ol_idx))
            ol_map[n_ol:] = n_c + len(ol_idx) + np.arange(len(extra_pts))
            segs_b = [ol_map[seg_plain]] + [ol_map[s] for s in seg_list]
            segs_b = np.vstack(segs_b) if segs_b else np.zeros((0, 2), dtype=np.int64)
            if (segs_b < 0).any():
                raise RuntimeError("outline segment refers to a removed outline node")
            allpts = np.vstack([nodes, jp])
            kind = np.concatenate([ckind, np.full(len(ol_idx), OUTLINE, np.int8), np.full(len(extra_pts), CONTACT, np.int8),
                                   np.full(len(jp), JUNCTION, np.int8)])
            body_of = np.concatenate([np.full(n_c, -1), self._ol_body[ol_idx], extra_body, np.full(len(jp), -1)])
            ol_id = np.concatenate([np.full(n_c, -1), ol_idx, np.full(len(extra_pts) + len(jp), -1)])
            n_new = len(extra_pts) + len(jp)
            uid = np.concatenate([cuid, _UID_OUTLINE + ol_idx, self._next_uid + np.arange(n_new)])
            self._next_uid += n_new
            # contact nodes: body coordinates for rigid motion
            ex_local = np.zeros((len(extra_pts), 2))
            if len(extra_pts):
                pb = self.poses[extra_body]
                c, s = np.cos(pb[:, 2]), np.sin(pb[:, 2])
                d = extra_pts - pb[:, :2]
                ex_local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
            ring_seg, ring_mark = self._box_ring(allpts, kind)
            mid = 0.5 * (allpts[segs_b[:, 0]] + allpts[segs_b[:, 1]])
            if len(segs_b):
                owner = body_of[segs_b[:, 0]]
                same = owner == body_of[segs_b[:, 1]]
                if not same.all():
                    dd = shapely.distance(polys[None, :], shapely.points(mid[~same])[:, None])
                    owner = owner.copy()
                    owner[~same] = np.argmin(dd, axis=1)
                bmark = _FIRST_BODY_MARKER + owner
            else:
                bmark = np.zeros(0, dtype=np.int64)
            holes_all = np.vstack([hole_plain] + [h[None] for h in holes]) if (len(hole_plain) or holes) else None
            pslg = {
                "vertices": allpts,
                "segments": np.vstack([ring_seg, segs_b]).astype(np.int32),
                "segment_markers": np.concatenate([ring_mark, bmark]).astype(np.int32)[:, None],
            }
            if holes_all is not None and len(holes_all):
                pslg["holes"] = holes_all
            out = tr.triangulate(pslg, "pQn")
            t = out["triangles"].astype(np.int64)
            nbr = out["neighbors"].astype(np.int64)
            if len(out["vertices"]) != len(allpts):
                raise RuntimeError(
                    f"Triangle added {len(out['vertices']) - len(allpts)} points: outlines intersect "
                    "(bodies overlap by more than the contact policy handles)"
                )
            segs_out = out["segments"].astype(np.int64)
            marks_out = out["segment_markers"].ravel().astype(np.int64)
            # drop unused nodes (none expected; duplicates or points in holes)
            used = np.zeros(len(allpts), dtype=bool)
            used[t.ravel()] = True
            if not used.all():
                remap = np.cumsum(used) - 1
                t = remap[t]
                segs_out = remap[segs_out]
                allpts, kind, body_of, ol_id, uid = allpts[used], kind[used], body_of[used], ol_id[used], uid[used]
                ex_keep = used[n_c + len(ol_idx): n_c + len(ol_idx) + len(extra_pts)]
                ex_local = ex_local[ex_keep]
            # Triangle returns counter-clockwise triangles; make sure (swap vertices 1, 2 and
            # the neighbours opposite them together)
            cw = signed_areas(allpts, t) < 0
            if cw.any():
                t[cw] = t[cw][:, [0, 2, 1]]
                nbr[cw] = nbr[cw][:, [0, 2, 1]]
            if self.use_junctions and self.n_bodies >= 3:
                # Voronoi junction points (Sec. 3.2): split junction triangles at a new node
                owner = np.where((kind == OUTLINE) | (kind == CONTACT), body_of, -1)
                jt, jp = junction_points(allpts, t, owner, self.poses[:, :2], polys,
                                         lambda q: self._target(q, olw), clearance=0.3, tree=tree)
                if len(jp):
                    n0 = len(allpts)
                    # junction nodes follow their junction: fixed barycentric coordinates in
                    # the triangle of outline nodes they split
                    jv = t[jt]
                    P = allpts[jv]
                    e1, e2, r = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0], jp - P[:, 0]
                    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
                    l1 = (r[:, 0] * e2[:, 1] - r[:, 1] * e2[:, 0]) / det
                    l2 = (e1[:, 0] * r[:, 1] - e1[:, 1] * r[:, 0]) / det
                    jbary = np.column_stack([1 - l1 - l2, l1, l2])
                    t, nbr = split_with_neighbors(t, nbr, jt, n0 + np.arange(len(jp)))
                    allpts = np.vstack([allpts, jp])
                    kind = np.concatenate([kind, np.full(len(jp), JUNCTION, np.int8)])
                    body_of = np.concatenate([body_of, np.full(len(jp), -1)])
                    ol_id = np.concatenate([ol_id, np.full(len(jp), -1)])
                    uid = np.concatenate([uid, self._next_uid + np.arange(len(jp))])
                    self._next_uid += len(jp)
            self.points = allpts
            if self.use_junctions and self.n_bodies >= 3 and len(jp):
                self._junction_nodes = n0 + np.arange(len(jp))
                self._junction_verts = jv
                self._junction_bary = jbary
            else:
                self._junction_nodes = np.zeros(0, dtype=np.int64)
            self.kind = kind
            self.body_of = body_of.astype(np.int64)
            self.ol_id = ol_id.astype(np.int64)
            self.uid = uid.astype(np.int64)
            self._contact_local = ex_local
            self._contact_idx = np.flatnonzero(kind == CONTACT)
            self.triangles = t
            edges, edge_tris = edges_from_neighbors(t, nbr)
            self.topo = MeshTopology(t, edges, edge_tris, edge_tris[:, 0] != edge_tris[:, 1])
            self.boundary_segments = segs_out
            self.boundary_markers = marks_out
            self.h_node = self._target(allpts, olw)
            self.n_junctions = int(len(jp))
            self._mobility = self._make_mobility(kind)
            self._drag_mobility = self._mobility.copy()
            self._drag_mobility[kind == JUNCTION] = 1.0
            self._osc.reset()
            self._damping = None
            if n_relax:
                self.points, nb = relax(self.points, self.topo, self.h_node, self._mobility, n_relax, self.relax_params,
                                        bounds=self.box)
            if attempt == self.cleanup_passes:
                break
            # clean-up: bad elements outside narrow gaps lose their free nodes, or get one
            fix, shape = self._cleanup_points(table, tree, olw)
            if fix is None:
                final_shape = shape  # of the mesh kept
                break
            cpts, ckind, cuid = fix
        self._steps_since = 0
        if self.n_bodies > 1:
            a, b = tree.query(polys, predicate="dwithin", distance=self.h)
            sel = a < b
            self._near_pairs = np.column_stack([a[sel], b[sel]])
        else:
            self._near_pairs = np.zeros((0, 2), dtype=np.int64)
        self._drag_association(table)
        self._set_quality_baseline(final_shape)
        info["n_junctions"] = self.n_junctions
        return info

    def _cleanup_points(self, table, tree, olw):
        """New candidate nodes after removing free vertices of bad elements / adding nodes in them.

        Bad: an angle below ``min_angle_trigger`` or above 135° outside narrow gaps.  Returns
        ``(fix, shape)``: ``fix`` is ``None`` if there is nothing to fix, ``shape`` is
        ``_element_cosines(with_area=True)`` of the current mesh.
        """
        shape = self._element_cosines(with_area=True)
        cmax, cmin, _ = shape
        bad = np.flatnonzero((cmax > np.cos(np.radians(self.min_angle_trigger))) | (cmin < np.cos(np.radians(135.0))))
        if not len(bad):
            return None, shape
        t = self.triangles[bad]
        c = self.points[t].mean(axis=1)
        hh = 0.5 * self.h_node[t].mean(axis=1)
        bad = bad[~(self._gap_width(c, hh, table) < hh)]
        if not len(bad):
            return None, shape
        t = self.triangles[bad]
        free_v = self.kind[t] == FREE
        remove = np.zeros(len(self.points), dtype=bool)
        remove[t[free_v]] = True
        no_free = ~free_v.any(axis=1)
        newp = np.zeros((0, 2))
        if no_free.any():
            P = self.points[t[no_free]]
            cen = P.mean(axis=1)
            hq = self._target(cen, olw)
            if self.n_bodies:
                ix, dist = tree.query_nearest(shapely.points(cen), return_distance=True, all_matches=False)
                dn = np.zeros(len(cen))
                dn[ix[0]] = dist
            else:
                dn = np.full(len(cen), np.inf)
            newp = cen[dn >= 0.3 * hq]
        keep_kind = (self.kind == FREE) | (self.kind == SIDE) | (self.kind == CORNER)
        keep = keep_kind & ~remove
        cpts = np.vstack([self.points[keep], newp])
        ckind = np.concatenate([self.kind[keep], np.full(len(newp), FREE, np.int8)])
        cuid = np.concatenate([self.uid[keep], self._next_uid + np.arange(len(newp))])
        self._next_uid += len(newp)
        if not remove.any() and not len(newp):
            return None, shape
        return (cpts, ckind, cuid), shape

    def _drag_association(self, table):
        """Pairs (free node, body) within ``drag_reach · h`` and their drag weights."""
        free = np.flatnonzero((self._drag_mobility != 0.0).any(axis=1))
        if not self.n_bodies or not len(free) or self.drag_reach <= 0:
            self._drag_node = np.zeros(0, dtype=np.int64)
            self._drag_body = np.zeros(0, dtype=np.int64)
            self._drag_weight = np.zeros(0)
            self._relax_damping = np.ones(len(self.points))
            return
        reach = self.drag_reach * self.h_node[free]
        ii, bb, dist = table.pairs_within(self.points[free], reach)
        self._drag_node = free[ii]
        self._drag_body = bb
        full = self.drag_full * self.h_node[free][ii]
        self._drag_weight = np.clip((reach[ii] - dist) / np.maximum(reach[ii] - full, 1e-300), 0.0, 1.0)
        wmax = np.zeros(len(self.points))
        np.maximum.at(wmax, self._drag_node, self._drag_weight)
        self._relax_damping = 1.0 - self.drag_stiffness * wmax

    def _make_mobility(self, kind):
        mob = np.ones((len(kind), 2))
        # junction nodes sit where the junction has no room for a relaxed node: they are
        # placed (Sec. 3.2) and dragged, not relaxed
        mob[(kind == OUTLINE) | (kind == CONTACT) | (kind == CORNER) | (kind == JUNCTION)] = 0.0
        side_idx = np.flatnonzero(kind == SIDE)
        _, side = self._classify_box(self.points[side_idx] if hasattr(self, "points") and len(self.points) == len(kind)
                                     else np.zeros((0, 2)))
        if len(side_idx):
            horiz = (side == 0) | (side == 2)
            mob[side_idx[horiz], 1] = 0.0
            mob[side_idx[~horiz], 0] = 0.0
        return mob

    def _adapt(self, pts, kind, uid, h, olw, stree, old_row):
        """Coarsen where edges are much shorter than the target, refine where triangles are too big.

        ``pts, kind, uid, h``: the candidate nodes; ``old_row (n_nodes,)``: the candidate row of
        every current node, -1 where it was purged.
        """
        # coarsening: an independent set of free nodes whose incident edges are all short
        t = self.triangles
        e0, e1 = self.topo.e0, self.topo.e1
        old = self.points
        z = old[:, 0] + 1j * old[:, 1]
        L = np.abs(z[e1] - z[e0])
        L0 = 0.5 * (self.h_node[e0] + self.h_node[e1])
        n_old = len(old)
        # mean ratio of incident edge lengths to their targets
        ratio = L / L0
        deg = np.bincount(e0, minlength=n_old) + np.bincount(e1, minlength=n_old)
        mean_ratio = (np.bincount(e0, ratio, n_old) + np.bincount(e1, ratio, n_old)) / np.maximum(deg, 1)
        has_long = mean_ratio >= self.coarsen_ratio
        # candidate row of every old node (-1 if purged)
        row = old_row
        present = row >= 0
        cand = present & (self.kind == FREE) & ~has_long
        rng = np.random.default_rng(self.step_count)
        prio = np.where(cand, rng.random(n_old), -1.0)
        nb_max = np.full(n_old, -1.0)
        np.maximum.at(nb_max, e0, prio[e1])
        np.maximum.at(nb_max, e1, prio[e0])
        remove_old = cand & (prio > nb_max)
        keep = np.ones(len(pts), dtype=bool)
        keep[row[remove_old]] = False
        # refinement: centroids of triangles much larger than the target
        area = signed_areas(old, t)
        tp = self.topo
        ht = (self.h_node[tp.t0] + self.h_node[tp.t1] + self.h_node[tp.t2]) / 3.0
        big = area > self.refine_area * (np.sqrt(3) / 4) * ht**2
        newp = old[t[big]].mean(axis=1)
        if stree is not None and len(newp):
            hn = self._target(newp, olw)
            ii, _ = stree.query(shapely.points(newp), predicate="dwithin", distance=self.clearance * hn)
            ok = np.ones(len(newp), dtype=bool)
            ok[ii] = False
            newp = newp[ok]
        n_ins = len(newp)
        pts = np.vstack([pts[keep], newp])
        kind = np.concatenate([kind[keep], np.full(n_ins, FREE, np.int8)])
        uid = np.concatenate([uid[keep], self._next_uid + np.arange(n_ins)])
        self._next_uid += n_ins
        h = self._target(pts, olw)
        return pts, kind, uid, h, int((~keep).sum()), n_ins

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
        new = self._check_poses(poses)
        self.step_count += 1
        ev = MeshEvent(step=self.step_count)
        self._prev_points = self.points.copy()
        self._prev_uid = self.uid.copy()
        if self.strategy == "fixed":
            if not np.allclose(new, self.poses, rtol=0, atol=1e-12 * max(1.0, np.abs(self.poses).max(initial=0))):
                raise ValueError("strategy 'fixed' is for bodies that do not move; poses changed "
                                 f"(max change {np.abs(new - self.poses).max():.3g})")
        elif self.strategy == "regenerate":
            old_p, old_t = self.points, self.triangles
            self.poses = new
            info = self._triangulate_from(self._bg_points, self._bg_kind, self._bg_uid, purge=self.clearance,
                                          adapt=False, n_relax=self.relax_iterations)
            ev.retriangulated, ev.reason = True, "regenerate"
            ev.old_points, ev.old_triangles, ev.prev_points = old_p, old_t, old_p
            ev.n_purged, ev.n_junctions = info["n_purged"], info["n_junctions"]
        else:
            self._drag_step(new, ev)
        ev.contacts = self.contacts
        ev.pore_areas = self.pore_areas
        ev.n_nodes, ev.n_triangles = len(self.points), len(self.triangles)
        ev.seconds = time.perf_counter() - t0
        return ev

    def _drag_step(self, new, ev):
        x = self.points.copy()
        # 1. outline and contact nodes move rigidly with their body (Sec. 4.2)
        ol = np.flatnonzero(self.kind == OUTLINE)
        x[ol] = self._world(self._ol_local[self.ol_id[ol]], self._ol_body[self.ol_id[ol]], new)
        ci = self._contact_idx
        if len(ci):
            x[ci] = self._world(self._contact_local, self.body_of[ci], new)
        fixed = (self._drag_mobility == 0.0).all(axis=1)
        n = len(x)
        # 2. drag (Sec. 4.2): free nodes near a body follow its rigid motion with a weight
        #    of 1 up to drag_full · h from the outline, decaying linearly to 0 at drag_reach · h (weights of several
        #    bodies are averaged); relaxation then spreads the rest.
        d = np.zeros_like(x)
        if len(self._drag_node):
            xi = self.points[self._drag_node]
            pb_old, pb_new = self.poses[self._drag_body], new[self._drag_body]
            dth = pb_new[:, 2] - pb_old[:, 2]
            c, s_ = np.cos(dth), np.sin(dth)
            r = xi - pb_old[:, :2]
            rig = np.column_stack([c * r[:, 0] - s_ * r[:, 1], s_ * r[:, 0] + c * r[:, 1]]) + pb_new[:, :2] - xi
            w = self._drag_weight
            wsum = np.bincount(self._drag_node, w, n)
            dx = np.bincount(self._drag_node, w * rig[:, 0], n)
            dy = np.bincount(self._drag_node, w * rig[:, 1], n)
            norm = np.maximum(wsum, 1.0)
            d = np.column_stack([dx / norm, dy / norm]) * self._drag_mobility
        xd = x + np.where(fixed[:, None], 0.0, d)
        if len(self._junction_nodes):
            # junction nodes keep their barycentric place between their three outline nodes
            xd[self._junction_nodes] = np.einsum("kj,kjd->kd", self._junction_bary, x[self._junction_verts])
        # a dragged free node must not invert an element that rigid motion alone keeps valid
        a_rigid = signed_areas(x, self.triangles)
        bad = (signed_areas(xd, self.triangles) <= 0) & (a_rigid > 0)
        for _ in range(6):
            if not bad.any():
                break
            hit = np.zeros(n, dtype=bool)
            hit[self.triangles[bad].ravel()] = True
            hit &= ~fixed
            d[hit] *= 0.5
            xd = x + np.where(fixed[:, None], 0.0, d)
            bad = (signed_areas(xd, self.triangles) <= 0) & (a_rigid > 0)
        if bad.any():
            hit = np.zeros(n, dtype=bool)
            hit[self.triangles[bad].ravel()] = True
            xd[hit & ~fixed] = x[hit & ~fixed]
        self.poses = new
        # 3. relaxation with the per-step iteration limit (Sec. 3.3)
        damp = self._relax_damping if self._damping is None else self._relax_damping * self._damping
        xr, nb = relax(xd, self.topo, self.h_node, self._mobility, self.relax_iterations, self.relax_params,
                       bounds=self.box, damping=damp)
        ev.n_blocked = nb
        osc = self._osc.update(xr - xd, self.h_node)
        if len(osc):
            if self._damping is None:
                self._damping = np.ones(n)
            self._damping[osc] *= 0.5
        ev.oscillating = osc
        self.points = xr
        self._steps_since += 1
        # 4. re-triangulate?  (one pass over the elements gives areas and angle cosines)
        cmax, cmin, area = self._element_cosines(with_area=True)
        reason = ""
        if (area <= 0).any():
            reason = "inverted"
        elif (area < 0.1 * self._base_area).any():
            reason = "degenerate"  # an element (typically in a narrow gap) is collapsing
        elif self._contacts_changed():
            reason = "contact"
        elif self._steps_since >= self.retriangulate_every:
            reason = "periodic"
        elif self._quality_dropped(cmax, cmin):
            reason = "quality"
        if reason:
            ev.old_points, ev.old_triangles = xr.copy(), self.triangles.copy()
            ev.prev_points = self._prev_points
            info = self.retriangulate()
            ev.retriangulated, ev.reason = True, reason
            ev.n_purged, ev.n_removed, ev.n_inserted = info["n_purged"], info["n_removed"], info["n_inserted"]
            ev.n_junctions = info["n_junctions"]

    def retriangulate(self, n_relax: int | None = None) -> dict:
        """Constrained Delaunay triangulation of the current nodes (cut-out, adaptation, junctions).

        Returns a dict with ``n_purged``, ``n_removed``, ``n_inserted``, ``n_junctions``.
        """
        n_relax = self.retriangulate_iterations if n_relax is None else n_relax
        return self._triangulate_from(self.points, self.kind, self.uid, purge=self.purge_clearance,
                                      adapt=True, n_relax=n_relax, h_cand=self.h_node)

    def _outline_table(self, poses=None) -> PolygonTable:
        """The bodies' polygons in world coordinates, for vectorised point queries."""
        poses = self.poses if poses is None else poses
        key = poses.tobytes()
        cached = getattr(self, "_table_cache", None)
        if cached is None or cached[0] != key:
            cached = (key, PolygonTable(self._world(self._vcat, self._vbody, poses), self._nv))
            self._table_cache = cached
        return cached[1]

    def _point_body_distance(self, pts, body, table=None) -> np.ndarray:
        """Distance ``(k,)`` from points ``(k, 2)`` outside their body ``body (k,)`` to its outline."""
        table = self._outline_table() if table is None else table
        return table.distance(pts, body)

    def _box_distance(self, pts) -> np.ndarray:
        xmin, xmax, ymin, ymax = self.box
        return np.min(np.column_stack([pts[:, 1] - ymin, xmax - pts[:, 0], ymax - pts[:, 1], pts[:, 0] - xmin]), axis=1)

    def _owner_distance(self, pts, owner, table=None) -> np.ndarray:
        """Distance from ``pts`` to boundary ``owner`` (a body index, or -2 for the box)."""
        d = np.empty(len(pts))
        on = owner >= 0
        if on.any():
            d[on] = self._point_body_distance(pts[on], owner[on], table)
        if (~on).any():
            d[~on] = self._box_distance(pts[~on])
        return d

    def _anchored_across_gap(self, tri_idx, table=None) -> np.ndarray:
        """Elements with an edge joining two different boundaries one end of which lies closer
        than h/2 to the other end's boundary (they are anchored across a narrow gap)."""
        t = self.triangles[tri_idx]
        owner = np.where((self.kind == FREE) | (self.kind == JUNCTION), -3,
                         np.where(self.body_of >= 0, self.body_of, -2))
        # the three edges of every element, stacked: (a, b) = (t[:, i], t[:, j])
        a = np.concatenate([t[:, 0], t[:, 1], t[:, 2]])
        b = np.concatenate([t[:, 1], t[:, 2], t[:, 0]])
        oa, ob = owner[a], owner[b]
        span = np.flatnonzero((oa != -3) & (ob != -3) & (oa != ob))
        out = np.zeros(len(tri_idx), dtype=bool)
        if not len(span):
            return out
        a, b, oa, ob = a[span], b[span], oa[span], ob[span]
        lim = 0.25 * (self.h_node[a] + self.h_node[b])
        x = self.points
        d = self._owner_distance(np.vstack([x[a], x[b]]), np.concatenate([ob, oa]), table)
        d = np.minimum(d[:len(span)], d[len(span):])
        out[span[d < lim] % len(tri_idx)] = True
        return out

    def _contacts_changed(self) -> bool:
        """True when bodies came closer than ``min_gap`` or an outline node of a body in contact
        entered another body (the contact outlines must be rebuilt).

        Only pairs closer than ``h`` at the last triangulation are checked: bodies farther
        apart cannot touch before the elements between them invert.
        """
        pairs = self._near_pairs
        if not len(pairs):
            return False
        polys = self._polygons()
        d = shapely.distance(polys[pairs[:, 0]], polys[pairs[:, 1]])
        close = pairs[d <= self.min_gap]
        n = self.n_bodies
        now = close[:, 0] * n + close[:, 1]
        before = self.contacts[:, 0] * n + self.contacts[:, 1] if len(self.contacts) else now[:0]
        if len(np.setdiff1d(now, before)):
            return True
        if not len(now):
            return False
        inv = np.flatnonzero(np.isin(self.body_of, np.unique(close)))
        pi, bi = shapely.STRtree(polys).query(shapely.points(self.points[inv]), predicate="within")
        return bool((self.body_of[inv[pi]] != bi).any())

    def _element_cosines(self, with_area: bool = False):
        """Per element: largest and smallest cosine of its angles (no arccos: cheap per step),
        and with ``with_area`` its signed area (positive for counter-clockwise)."""
        x, y = self.points[:, 0], self.points[:, 1]
        t = self.topo
        ax, ay = x[t.t0], y[t.t0]
        ux, uy = x[t.t1] - ax, y[t.t1] - ay  # u = b − a
        wx, wy = ax - x[t.t2], ay - y[t.t2]  # w = a − c
        vx, vy = -(ux + wx), -(uy + wy)  # v = c − b
        lu2, lv2, lw2 = ux * ux + uy * uy, vx * vx + vy * vy, wx * wx + wy * wy
        # cos at a: (b − a)·(c − a)/(|b − a||c − a|) = −u·w/(|u||w|), and likewise at b, c
        ca = -(ux * wx + uy * wy) / np.sqrt(np.maximum(lu2 * lw2, 1e-300))
        cb = -(ux * vx + uy * vy) / np.sqrt(np.maximum(lu2 * lv2, 1e-300))
        cc = -(vx * wx + vy * wy) / np.sqrt(np.maximum(lv2 * lw2, 1e-300))
        cmax = np.maximum(np.maximum(ca, cb), cc)
        cmin = np.minimum(np.minimum(ca, cb), cc)
        if with_area:
            return cmax, cmin, 0.5 * (uy * wx - ux * wy)  # ½ (b − a) × (c − a)
        return cmax, cmin

    def _set_quality_baseline(self, shape=None):
        """Per-element thresholds for the quality trigger, set after each triangulation.

        Narrow-gap elements (the geometric flag of :meth:`quality` evaluated now, gaps change
        little between re-triangulations, or'ed with the structural one) are left out.
        ``shape``: ``_element_cosines(with_area=True)`` of the current mesh if the caller has it.
        """
        narrow = self._narrow_gap_owners() | self._structural_narrow()
        cmax, cmin, self._base_area = self._element_cosines(with_area=True) if shape is None else shape
        # an element may lose 3° from where it starts if it starts outside the bounds:
        # thresholds min(trigger, angle − 3°) and max(135°, angle + 3°); arccos only where
        # the angle is within 3° of a bound (the other elements get the bound itself)
        trig = float(self.min_angle_trigger)
        self._cos_lo = np.full(len(cmax), np.cos(np.radians(trig)))
        near = np.flatnonzero(cmax > np.cos(np.radians(trig + 3.0)))
        lo = np.minimum(trig, np.degrees(np.arccos(np.clip(cmax[near], -1, 1))) - 3.0)
        self._cos_lo[near] = np.cos(np.radians(np.clip(lo, 0, 180)))
        self._cos_hi = np.full(len(cmin), np.cos(np.radians(135.0)))
        near = np.flatnonzero(cmin < np.cos(np.radians(132.0)))
        hi = np.maximum(135.0, np.degrees(np.arccos(np.clip(cmin[near], -1, 1))) + 3.0)
        self._cos_hi[near] = np.cos(np.radians(np.clip(hi, 0, 180)))
        # narrow-gap elements are left out here, and watched by _quality_dropped instead
        self._cos_lo[narrow] = 2.0
        self._cos_hi[narrow] = -2.0
        self._base_narrow = narrow
        self._base_cos = (cmax, cmin)
        self._cos_bound = (np.cos(np.radians(self.min_angle_trigger)), np.cos(np.radians(135.0)))

    def _quality_dropped(self, cmax, cmin) -> bool:
        """True when an element outside narrow gaps got an angle below ``min_angle_trigger``
        or above 135° that it did not have after the last triangulation, or one that had
        such an angle lost another 3° on it.  ``cmax, cmin``: :meth:`_element_cosines` now."""
        if ((cmax > self._cos_lo) | (cmin < self._cos_hi)).any():
            return True
        # narrow-gap elements are watched too: once the gap has opened (the element is no
        # longer anchored across a gap narrower than h/2) it must meet the bounds
        looks_bad = self._base_narrow & ((cmax > self._cos_bound[0]) | (cmin < self._cos_bound[1]))
        # ... and got worse since the triangulation (the gap of an unchanged element did not open)
        looks_bad &= (cmax > self._base_cos[0] + 1e-3) | (cmin < self._base_cos[1] - 1e-3)
        idx = np.flatnonzero(looks_bad)
        if not len(idx):
            return False
        return bool((~self._anchored_across_gap(idx)).any())

    def _structural_narrow(self) -> np.ndarray:
        """Triangles whose three vertices are all on boundaries, not all of one owner."""
        tp = self.topo
        bnd = self.kind != FREE
        bnd &= self.kind != JUNCTION
        owner = np.where(self.body_of >= 0, self.body_of, -2)
        allb = bnd[tp.t0] & bnd[tp.t1] & bnd[tp.t2]
        o0, o1, o2 = owner[tp.t0], owner[tp.t1], owner[tp.t2]
        return allb & ((o0 != o1) | (o1 != o2))

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
        for b, name in enumerate(self.body_names):
            bnd[name] = look(self.boundary_segments[self.boundary_markers == _FIRST_BODY_MARKER + b])
        return m.with_boundaries(bnd)

    def node_velocity(self, dt: float) -> np.ndarray:
        """Mesh velocity ``w`` ``(n_nodes, 2)`` for ALE, length units per time unit.

        ``(x_now − x_prev) / dt`` per node for nodes that existed before the last
        :meth:`update`; a node created by a re-triangulation gets the mean velocity of its
        mesh neighbours that existed before (neighbours of neighbours if none did).
        """
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"time step dt must be a positive number, got {dt!r}")
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

    def _gap_width(self, pts, radius, table=None) -> np.ndarray:
        """Width ``d1 + d2`` of the gap at ``pts``: distances to the nearest and second-nearest
        distinct boundary (bodies; the box counts as one), ``inf`` if fewer than two lie within
        ``radius`` (array or float)."""
        pts = np.asarray(pts, dtype=float)
        if not len(pts):
            return np.zeros(0)
        pi = np.zeros(0, dtype=np.int64)
        d = np.zeros(0)
        if self.n_bodies:
            table = self._outline_table() if table is None else table
            pi, _, d = table.pairs_within(pts, radius, solid=True)
        return self._gap_from_pairs(pts, pi, d)

    def _gap_from_pairs(self, pts, pi, d) -> np.ndarray:
        """:meth:`_gap_width` from (point, body) pairs sorted by point and their distances."""
        k = len(pts)
        m1, m2 = np.full(k, np.inf), np.full(k, np.inf)
        if len(pi):
            # per point the smallest and second smallest body distance
            starts = np.flatnonzero(np.concatenate([[True], pi[1:] != pi[:-1]]))
            g = pi[starts]
            lo = np.minimum.reduceat(d, starts)
            is_min = d == np.repeat(lo, np.diff(np.append(starts, len(d))))
            second = np.minimum.reduceat(np.where(is_min, np.inf, d), starts)
            m1[g] = lo
            m2[g] = np.where(np.add.reduceat(is_min, starts) >= 2, lo, second)
        # ... and the box as one more boundary: the two smallest of {m1 ≤ m2, box}
        box = self._box_distance(pts)
        return np.minimum(m1, box) + np.minimum(np.maximum(m1, box), m2)

    def _non_free_count(self) -> np.ndarray:
        """Per triangle: how many of its vertices are not free nodes (0..3)."""
        nf = (self.kind != FREE).view(np.int8)
        tp = self.topo
        return nf[tp.t0] + nf[tp.t1] + nf[tp.t2]

    def _narrow_gap_owners(self) -> np.ndarray:
        """Cheap form of :meth:`_narrow_gap` for the re-triangulation trigger: the gap at the
        centroid is measured between the boundaries the element's own vertices lie on."""
        narrow = np.zeros(len(self.triangles), dtype=bool)
        cand = np.flatnonzero(self._non_free_count() >= 2)
        if not len(cand):
            return narrow
        tp, x, h = self.topo, self.points, self.h_node
        i0, i1, i2 = tp.t0[cand], tp.t1[cand], tp.t2[cand]
        c = (x[i0] + x[i1] + x[i2]) / 3.0
        hh = (h[i0] + h[i1] + h[i2]) / 6.0
        owner = np.where((self.kind == FREE) | (self.kind == JUNCTION), -3,
                         np.where(self.body_of >= 0, self.body_of, -2))
        o = np.column_stack([owner[i0], owner[i1], owner[i2]])
        # the distinct boundaries among the three vertices' owners
        ok = o != -3
        ok[:, 1] &= o[:, 1] != o[:, 0]
        ok[:, 2] &= (o[:, 2] != o[:, 0]) & (o[:, 2] != o[:, 1])
        rows, cols = np.nonzero(ok)
        d = np.full(o.shape, np.inf)
        table = self._outline_table()
        d[rows, cols] = self._owner_distance(c[rows], o[rows, cols], table)
        d.sort(axis=1)
        narrow[cand] = d[:, 0] + d[:, 1] < hh
        narrow[cand[self._anchored_across_gap(cand, table)]] = True
        return narrow

    def _narrow_gap(self) -> np.ndarray:
        """Narrow-gap triangles by the geometric definition of :mod:`fluidem.mesh.quality`."""
        t = self.triangles
        narrow = np.zeros(len(t), dtype=bool)
        # free nodes are purged from gaps narrower than gap_purge · h, so a triangle in a
        # narrow gap has at most one free vertex
        cand = np.flatnonzero(self._non_free_count() >= 2)
        if not len(cand):
            return narrow
        c = self.points[t[cand]].mean(axis=1)
        hh = 0.5 * self.h_node[t[cand]].mean(axis=1)
        narrow[cand] = self._gap_width(c, hh) < hh
        # ... or one of its edges joins two different boundaries and one end of it is closer
        # than h/2 to the other end's boundary (the element is anchored across the gap)
        narrow[cand[self._anchored_across_gap(cand)]] = True
        return narrow

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
        keys = set()
        key = np.sort(e, axis=1)
        k_mesh = key[:, 0] * n + key[:, 1]
        s = np.sort(self.boundary_segments, axis=1)
        k_seg = s[:, 0] * n + s[:, 1]
        if not np.isin(k_seg, k_mesh).all():
            return False
        del keys
        for b in range(self.n_bodies):
            if not (self.boundary_markers == _FIRST_BODY_MARKER + b).any():
                return False
        # every mesh edge with a triangle on one side only is a boundary segment
        bnd = key[~self.topo.interior]
        kb = bnd[:, 0] * n + bnd[:, 1]
        return bool(np.isin(kb, k_seg).all())
