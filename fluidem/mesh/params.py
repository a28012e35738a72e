"""Parameters of the moving mesh (:class:`fluidem.mesh.MovingMesh`), validated once.

Every length is a multiple of the local target edge length ``h`` unless said otherwise;
every angle is in degrees.  The defaults are the values the hard cases were tuned with
(``tests/mesh/test_mesh_hard_cases.py``).

Examples
--------
>>> from fluidem.mesh.params import MeshParams
>>> p = MeshParams(strategy="regenerate")
>>> p.step_iterations           # relax_iterations=None: the default of the strategy
20
>>> p.min_gap_for(0.1)          # default contact distance: 1e-3 h
0.0001
>>> MeshParams(coarsen_ratio=1.5)
Traceback (most recent call last):
...
fluidem.errors.InputError: MovingMesh(coarsen_ratio=...) = 1.5: expected a number in (0, 1)
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from .. import names
from .. import validate as v
from ..errors import InputError
from .relax import RelaxParams

__all__ = ["MeshParams", "STRATEGIES", "PARAM_NAMES", "REPAIR_SWEEPS", "check_strategy", "mesh_params"]

#: mesh strategies by name (:data:`fluidem.names.REGISTRY` ``"strategy"``)
STRATEGIES = names.choices("strategy")
#: Gauss–Seidel sweeps of the node repair when a scene asks for it (``[mesh] repair = true``)
REPAIR_SWEEPS = 2


def _key(name: str) -> str:
    return f"MovingMesh({name}=...)"


def check_strategy(value) -> str:
    """The canonical strategy name for ``value`` (aliases of :mod:`fluidem.names` accepted)."""
    try:
        return names.lookup("strategy", value, where=_key("strategy"))
    except InputError:
        allowed = ", ".join(repr(s) for s in STRATEGIES)
        raise InputError(f"unknown mesh strategy {value!r}: expected one of {allowed}") from None


def _count(name, value, lo):
    """An integer >= ``lo``; integral floats (``30.0``) are accepted as before."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    return v.integer(_key(name), value, lo=lo)


@dataclass(frozen=True)
class MeshParams:
    """Parameters of :class:`fluidem.mesh.MovingMesh` (module docstring of
    :mod:`fluidem.mesh.moving` for the pipeline they steer).

    Parameters
    ----------
    strategy : {"drag", "regenerate", "fixed"}
        How the mesh follows the bodies.
    retriangulate_every : int
        K, steps between re-triangulations when dragging (paper Sec. 4.2: 20–50), >= 1.
    relax_iterations : int or None
        Relaxation sweeps per physical step (Sec. 3.3 iteration limit), >= 0; ``None``:
        3 for ``drag``, 20 for ``regenerate`` (:attr:`step_iterations`).
    initial_iterations : int
        Relaxation sweeps after the first triangulation.
    retriangulate_iterations : int
        Relaxation sweeps after a re-triangulation.
    min_angle_trigger, max_angle_trigger : float
        Angle bounds (degrees) outside narrow gaps: crossing them triggers a
        re-triangulation (``"quality"``) and elements outside them are fixed by the
        clean-up pass.
    angle_margin : float
        Degrees the largest angle of an element may grow past ``max_angle_trigger`` (or past
        its angle after the last triangulation if that was larger) before it triggers a
        re-triangulation (:func:`fluidem.mesh.triggers.quality_baseline`), >= 0.
    min_angle_margin : float
        Degrees the smallest angle may fall below ``min_angle_trigger`` (or below its angle
        after the last triangulation if that was smaller) before it triggers, >= 0.  Default 0:
        the smallest angle stays at least ``min_angle_trigger`` between re-triangulations (the
        hard cases assert 15°); a margin of 3° halved the re-triangulations of some dense scenes
        but let elements of 12° stand.
    repair_sweeps : int
        Before a ``"quality"`` or ``"degenerate"`` re-triangulation, sweeps of the node repair
        (:mod:`fluidem.mesh.repair`): the nodes around the elements that fired are moved to
        bring them back within their thresholds and above ``degenerate_area`` of their area, and
        the mesh is re-triangulated only if that fails; 0 (the default): no repair, >= 0;
        :data:`REPAIR_SWEEPS` (2) is the measured setting, the scene key ``[mesh] repair =
        true``.  The moved nodes' fields are transferred from the mesh before the move
        (:func:`fluidem.mesh.transfer.move_with_nodes`), like a re-triangulation on a few
        elements.
    degenerate_area : float
        An element that shrank below this fraction of its area at the last triangulation
        triggers a re-triangulation (``"degenerate"``).
    clearance : float
        Background nodes closer than ``clearance · h`` to a body are cut out; in [0, 2).
    purge_clearance : float
        When dragging, nodes closer than ``purge_clearance · h`` to a body are purged at
        re-triangulation; in [0, 2).
    gap_purge : float
        Free nodes in gaps narrower than ``gap_purge · h`` are removed (the gap is spanned
        by one layer of elements); >= 0.
    min_gap : float or None
        Bodies closer than this (length units) are meshed as one outline; ``None``:
        ``default_min_gap · h`` (:meth:`min_gap_for`).
    default_min_gap : float
        ``min_gap`` as a multiple of ``h`` when ``min_gap`` is ``None``.
    on_outline_factor : float
        A body outline node belongs to the closed contact outline when it lies within
        ``on_outline_factor · min_gap`` of it.
    contact_merge : float
        Vertices of a closed contact outline, and outline nodes along it, closer than
        ``contact_merge · h`` to their predecessor are merged into it.
    contact_node_spacing : float
        A vertex of a closed contact outline farther than ``contact_node_spacing · h``
        from every kept outline node becomes a contact node.
    wall_overlap, wall_overlap_fraction : float
        A body may overlap a box side by up to ``max(wall_overlap · h, wall_overlap_fraction ·
        e)``, ``e`` the body's extent across that side (its height for the floor and the lid,
        its width for the side walls): the overlap is meshed as contact, the body and the
        wall as one closed outline (:mod:`fluidem.mesh.contact_outline`), which holds at any
        depth that leaves most of the body in the box (measured to half its extent).  So the
        resting overlap of the DEM's soft wall contact, which grows with the load and falls
        with the contact law's ``E``, is meshable whatever the mesh size; a deeper overlap
        raises ``InputError`` naming the contact law.  ``wall_overlap >= 0``,
        ``wall_overlap_fraction`` in [0, 0.5].
    contact_slack : float
        Hysteresis of a wall contact, a multiple of ``h``: between re-triangulations the
        outline of a body meshed with a wall may stay on the wall while the body lifts off it
        by up to ``contact_slack · h``, and its outline nodes pressed past the wall by up to
        that much are put back on it, instead of a re-triangulation (``"contact"``) each time
        a resting body moves by more than ``min_gap``; a body lifted farther leaves the
        contact; >= 0.
    mitre_limit : float
        Mitre limit of the closing buffer of a contact cluster (shapely ``buffer``).
    junctions : bool
        Insert Voronoi junction points (Sec. 3.2).
    junction_clearance : float
        A junction point must stay ``junction_clearance · h`` away from the bodies
        (:func:`fluidem.mesh.junctions.junction_points`).
    cleanup_passes : int
        Clean-up passes after a triangulation (remove free nodes of bad elements, add a
        node in bad elements without any), >= 0; a pass runs only while bad elements are
        left (one pass left a 14° element in the collapsing-step hard case).
    cleanup_clearance : float
        A node added by the clean-up must be ``cleanup_clearance · h`` away from the bodies.
    background : {"fk", "delaunay"} or None
        Background nodes for a uniform size: Friedrichs–Keller grid or a quality Delaunay
        point set; ``None``: ``"fk"`` for a uniform size, ``"delaunay"`` for a graded one.
    relax_params : RelaxParams
        Spring relaxation (:mod:`fluidem.mesh.relax`).
    drag_reach, drag_full : float
        Free nodes within ``drag_full · h`` of a body follow its rigid motion fully, with a
        weight falling linearly to zero at ``drag_reach · h``; ``0 <= drag_full < drag_reach``.
    drag_field : {"harmonic", "ramp"}
        How the free nodes not fully dragged follow (:mod:`fluidem.mesh.drag`): the harmonic
        extension of the displacements of the outline and fully dragged nodes over the
        whole mesh (box sides slide), or the linear ramp of the drag weight between
        ``drag_full`` and ``drag_reach``.
    seams : {"bend", "clip"}
        Between re-triangulations of a box with periodic sides (:mod:`fluidem.mesh.seam`):
        ``"bend"`` drags the periodic side nodes in matched pairs like free nodes and holds
        the seam nodes fixed on their bodies, so the sides bend around the bodies crossing
        them and an outline node passing a side changes nothing; ``"clip"`` keeps the sides
        straight, the seam nodes sliding along them, and re-triangulates whenever an
        outline node passes a side (``"seam"``).
    drag_stiffness : float
        Dragged nodes relax with the step reduced by ``1 − drag_stiffness · weight``; in [0, 1].
    drag_halvings : int
        How often the drag displacement of nodes of an element it would invert is halved
        before those nodes only move rigidly.
    tow_width : float
        With grading: width of the zone of size ``h`` a body carries; >= 0.
    refine_area : float
        Re-triangulation adds a node in triangles larger than ``refine_area`` target areas; > 1.
    coarsen_ratio : float
        Re-triangulation removes free nodes whose incident edges average below
        ``coarsen_ratio`` of their target; in (0, 1).
    hold_node_count : bool
        Re-triangulation keeps the number of free and box nodes within
        ``node_count_tolerance`` of its budget, the count of the first triangulation per
        unit of ``∫ h⁻² dA`` over the fluid (so it changes only with the geometry and the
        size field): above it the most compressed free nodes are removed, below it the
        largest elements are split (:func:`fluidem.mesh.adaptation.adapt`).  Without it the
        harmonic drag's gentle compression ahead of a body is never coarsened while the
        stretched region behind it is refined, and the count drifts up (+25 % in 300 steps
        of the plate case).
    node_count_tolerance : float
        Dead band of ``hold_node_count``, a fraction in (0, 1).
    """

    strategy: str = "drag"
    retriangulate_every: int = 30
    relax_iterations: int | None = None
    initial_iterations: int = 60
    retriangulate_iterations: int = 20
    min_angle_trigger: float = 15.0
    max_angle_trigger: float = 135.0
    angle_margin: float = 10.0
    min_angle_margin: float = 0.0
    repair_sweeps: int = 0  # REPAIR_SWEEPS with [mesh] repair = true
    degenerate_area: float = 0.1
    clearance: float = 0.5
    purge_clearance: float = 0.3
    gap_purge: float = 1.1
    min_gap: float | None = None
    default_min_gap: float = 1e-3
    on_outline_factor: float = 1.01
    contact_merge: float = 0.1
    contact_node_spacing: float = 0.3
    wall_overlap: float = 0.1
    wall_overlap_fraction: float = 0.25
    contact_slack: float = 0.02
    mitre_limit: float = 20.0
    junctions: bool = True
    junction_clearance: float = 0.3
    cleanup_passes: int = 2
    cleanup_clearance: float = 0.3
    background: str | None = None
    relax_params: RelaxParams = RelaxParams()
    drag_reach: float = 3.0
    drag_full: float = 1.0
    drag_field: str = "harmonic"
    seams: str = "bend"
    drag_stiffness: float = 0.8
    drag_halvings: int = 6
    tow_width: float = 2.0
    refine_area: float = 1.6
    coarsen_ratio: float = 0.7
    hold_node_count: bool = True
    node_count_tolerance: float = 0.02

    def __post_init__(self):
        s = object.__setattr__
        s(self, "strategy", check_strategy(self.strategy))
        s(self, "retriangulate_every", _count("retriangulate_every", self.retriangulate_every, 1))
        if self.relax_iterations is not None:
            s(self, "relax_iterations", _count("relax_iterations", self.relax_iterations, 0))
        for name in ("initial_iterations", "retriangulate_iterations", "cleanup_passes", "drag_halvings",
                     "repair_sweeps"):
            s(self, name, _count(name, getattr(self, name), 0))
        s(self, "min_angle_trigger", v.number(_key("min_angle_trigger"), self.min_angle_trigger,
                                              "a number in [0, 60)", lo=0.0, hi=60.0, hi_open=True))
        s(self, "max_angle_trigger", v.number(_key("max_angle_trigger"), self.max_angle_trigger,
                                              "a number in (60, 180]", lo=60.0, lo_open=True, hi=180.0))
        s(self, "angle_margin", v.nonnegative(_key("angle_margin"), self.angle_margin))
        s(self, "min_angle_margin", v.nonnegative(_key("min_angle_margin"), self.min_angle_margin))
        s(self, "degenerate_area", v.fraction(_key("degenerate_area"), self.degenerate_area))
        for name in ("clearance", "purge_clearance"):
            s(self, name, v.number(_key(name), getattr(self, name), "a number in [0, 2) (multiple of h)",
                                   lo=0.0, hi=2.0, hi_open=True))
        for name in ("gap_purge", "tow_width", "drag_reach", "contact_merge", "contact_node_spacing",
                     "junction_clearance", "cleanup_clearance", "wall_overlap", "contact_slack"):
            s(self, name, v.number(_key(name), getattr(self, name), "a number >= 0 (multiple of h)", lo=0.0))
        s(self, "wall_overlap_fraction", v.number(_key("wall_overlap_fraction"), self.wall_overlap_fraction,
                                                  "a number in [0, 0.5] (fraction of the body's extent)",
                                                  lo=0.0, hi=0.5))
        if self.min_gap is not None:
            s(self, "min_gap", v.positive(_key("min_gap"), self.min_gap))
        s(self, "default_min_gap", v.positive(_key("default_min_gap"), self.default_min_gap))
        s(self, "on_outline_factor", v.number(_key("on_outline_factor"), self.on_outline_factor,
                                              "a number >= 1", lo=1.0))
        s(self, "mitre_limit", v.number(_key("mitre_limit"), self.mitre_limit, "a number >= 1", lo=1.0))
        s(self, "junctions", bool(self.junctions))
        if self.background is not None:
            v.choice(_key("background"), self.background, ("fk", "delaunay"))
        v.choice(_key("drag_field"), self.drag_field, ("harmonic", "ramp"))
        v.choice(_key("seams"), self.seams, ("bend", "clip"))
        if not isinstance(self.relax_params, RelaxParams):
            raise v.fail(_key("relax_params"), self.relax_params, "a RelaxParams")
        s(self, "drag_full", v.number(_key("drag_full"), self.drag_full,
                                      f"a number in [0, drag_reach = {self.drag_reach!r}) (multiple of h)",
                                      lo=0.0, hi=max(self.drag_reach, 1e-300), hi_open=True))
        s(self, "drag_stiffness", v.fraction(_key("drag_stiffness"), self.drag_stiffness))
        s(self, "refine_area", v.number(_key("refine_area"), self.refine_area, "a number > 1", lo=1.0,
                                        lo_open=True))
        s(self, "coarsen_ratio", v.fraction(_key("coarsen_ratio"), self.coarsen_ratio, lo_open=True,
                                            hi_open=True))
        s(self, "hold_node_count", v.boolean(_key("hold_node_count"), self.hold_node_count))
        s(self, "node_count_tolerance", v.fraction(_key("node_count_tolerance"), self.node_count_tolerance,
                                                   lo_open=True, hi_open=True))

    @property
    def step_iterations(self) -> int:
        """Relaxation sweeps per physical step: ``relax_iterations`` or the strategy's default."""
        if self.relax_iterations is not None:
            return self.relax_iterations
        return 20 if self.strategy == "regenerate" else 3

    def min_gap_for(self, h: float) -> float:
        """The contact distance (length units) for target size ``h``."""
        return self.default_min_gap * h if self.min_gap is None else self.min_gap

    def background_for(self, graded: bool) -> str:
        """The background kind: ``background`` if set, else ``"delaunay"`` if ``graded`` else ``"fk"``."""
        if self.background is not None:
            return self.background
        return "delaunay" if graded else "fk"


#: names of the :class:`MeshParams` fields (the keyword arguments of ``MovingMesh``)
PARAM_NAMES = tuple(f.name for f in fields(MeshParams))


def mesh_params(params: MeshParams | None = None, **overrides) -> MeshParams:
    """``params`` (default :class:`MeshParams`) with the keyword ``overrides`` replaced.

    Unknown keywords raise ``TypeError`` as for any Python function.
    """
    unknown = [k for k in overrides if k not in PARAM_NAMES]
    if unknown:
        raise TypeError(f"MovingMesh() got an unexpected keyword argument {unknown[0]!r}")
    if params is None:
        return MeshParams(**overrides)
    if not isinstance(params, MeshParams):
        raise v.fail(_key("params"), params, "a MeshParams")
    return replace(params, **overrides) if overrides else params
