"""The stages of the moving mesh on their own: node kinds, contact outline, cut-out, drag,
gaps and triggers (the pure functions MovingMesh composes)."""

import numpy as np
import pytest
import shapely

from fluidem.cases.packings import pore_ring
from fluidem.geometry import rectangle, regular_polygon
from fluidem.mesh import MovingMesh
from fluidem.mesh.contact_outline import contact_outline
from fluidem.mesh.cutout import cut_out
from fluidem.mesh.drag import DragAssociation, dragged_positions
from fluidem.mesh.gaps import BOX, NOT_ON_BOUNDARY, boundary_owner, structural_narrow
from fluidem.mesh.nodes import (
    CONTACT,
    CORNER,
    FREE,
    JUNCTION,
    OUTLINE,
    SIDE,
    UidSource,
    box_ring,
    classify_box,
    outline_nodes,
    to_body,
    world,
)
from fluidem.mesh.params import MeshParams
from fluidem.mesh.proximity import PolygonTable
from fluidem.mesh.relax import mesh_topology
from fluidem.mesh.triggers import ElementShape, element_shape, quality_baseline, quality_dropped, retriangulation_reason


def _bodies(poses, size=0.4):
    sq = rectangle(size, size)
    polys = shapely.polygons([world(sq, np.zeros(4, dtype=np.int64), poses[i:i + 1]) for i in range(len(poses))])
    ol = outline_nodes([sq] * len(poses), poses, lambda p: np.full(len(p), 0.05), 0.05)
    return sq, polys, ol


def test_world_and_body_frames_are_inverse():
    rng = np.random.default_rng(0)
    local = rng.normal(size=(20, 2))
    pose = np.tile([0.3, -1.2, 0.7], (20, 1))
    np.testing.assert_allclose(to_body(world(local, np.zeros(20, dtype=np.int64), pose[:1]), pose), local,
                               atol=1e-14)


def test_box_ring_closes_the_box_with_side_markers():
    box = (0.0, 2.0, 0.0, 1.0)
    g = np.array([[x, y] for y in np.linspace(0, 1, 5) for x in np.linspace(0, 2, 9)])
    kind, _ = classify_box(g, box)
    assert (kind == CORNER).sum() == 4 and (kind == SIDE).sum() == 2 * 7 + 2 * 3
    seg, mark = box_ring(g, kind, box)
    length = np.linalg.norm(g[seg[:, 0]] - g[seg[:, 1]], axis=1)
    assert len(seg) == 24 and length.sum() == pytest.approx(6.0)
    for m, total in zip((1, 2, 3, 4), (2.0, 1.0, 2.0, 1.0)):
        assert length[mark == m].sum() == pytest.approx(total)
    assert np.array_equal(seg[1:, 0], seg[:-1, 1]) and seg[-1, 1] == seg[0, 0]  # one closed ring


def test_outline_nodes_keep_the_corners_and_close_each_ring():
    poses = np.array([[1.0, 1.0, 0.3], [2.0, 1.0, 0.0]])
    sq, _, ol = _bodies(poses)
    for b in range(2):
        rows = np.flatnonzero(ol.body == b)
        assert len(rows) == 4 * 8  # each side of 0.4 cut at 0.05
        np.testing.assert_allclose(ol.local[rows[::8]], sq, atol=1e-14)
        nxt = ol.next[rows]
        assert set(nxt) == set(rows)  # a permutation: a closed ring


def test_contact_outline_separate_bodies_keep_their_outlines():
    poses = np.array([[1.0, 1.0, 0.0], [2.0, 1.0, 0.0]])
    _, polys, ol = _bodies(poses)
    co = contact_outline(polys, shapely.STRtree(polys), ol.world(poses), ol, 0.05, 5e-5, MeshParams())
    assert len(co.contacts) == 0 and not co.clustered.any() and co.keep_outline.all()
    assert len(co.segments) == len(ol.local) and len(co.holes) == 2 and len(co.contact_points) == 0


def test_contact_outline_ring_of_touching_bodies_encloses_a_pore():
    bodies, poses = pore_ring()
    polys = shapely.polygons([world(v, np.zeros(len(v), dtype=np.int64), poses[i:i + 1])
                              for i, v in enumerate(bodies)])
    ol = outline_nodes(bodies, poses, lambda p: np.full(len(p), 0.05), 0.05)
    co = contact_outline(polys, shapely.STRtree(polys), ol.world(poses), ol, 0.05, 5e-5, MeshParams())
    assert co.clustered.all() and len(co.contacts) >= 6
    assert len(co.pore_areas) == 1 and 0.4 < co.pore_areas[0] < 0.7
    # one hole point for the closed cluster (no body is meshed on its own)
    assert len(co.holes) == 1 and not co.keep_outline.all()
    # the contact nodes move with one of the bodies they touch
    assert len(co.contact_body) == len(co.contact_points) and set(co.contact_body) <= set(range(len(bodies)))


def test_cut_out_purges_free_nodes_near_bodies_and_drops_rebuilt_kinds():
    poses = np.array([[1.0, 1.0, 0.0]])
    sq, _, _ = _bodies(poses)
    table = PolygonTable(sq + poses[0, :2], [4])
    cand = np.array([[1.0, 1.0], [1.22, 1.0], [1.5, 1.5], [0.0, 0.0], [1.2, 1.2], [0.5, 0.5]])
    kind = np.array([FREE, FREE, FREE, CORNER, OUTLINE, JUNCTION], np.int8)
    cut = cut_out(cand, kind, np.full(len(cand), 0.1), table, 0.5, 1.1, (0.0, 2.0, 0.0, 2.0))
    # inside the body, 0.02 < 0.05 from it: purged; far away and the box corner: kept
    assert cut.keep.tolist() == [False, False, True, True, False, False] and cut.n_purged == 2


def test_drag_moves_fully_dragged_nodes_rigidly():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    tri = np.array([[0, 1, 2], [1, 3, 2]])
    kind = np.full(4, FREE, np.int8)
    assoc = DragAssociation(np.array([0, 1, 2, 3]), np.zeros(4, dtype=np.int64), np.ones(4), np.ones(4))
    old, new = np.array([[0.5, 0.5, 0.0]]), np.array([[0.6, 0.4, 0.2]])
    none = np.zeros(0, dtype=np.int64)
    x = dragged_positions(pts, tri, kind, np.full(4, -1), np.zeros((0, 2)), none, none, np.zeros((0, 2)),
                          np.full(4, -1), np.ones((4, 2)), assoc, none, np.zeros((0, 3), dtype=np.int64),
                          np.zeros((0, 3)), old, new, 6)
    expect = world(to_body(pts, np.repeat(old, 4, axis=0)), np.zeros(4, dtype=np.int64), new)
    np.testing.assert_allclose(x, expect, atol=1e-14)


def test_boundary_owner_and_structural_narrow():
    kind = np.array([OUTLINE, OUTLINE, SIDE, FREE, JUNCTION, CONTACT], np.int8)
    body_of = np.array([0, 1, -1, -1, -1, 1])
    assert boundary_owner(kind, body_of).tolist() == [0, 1, BOX, NOT_ON_BOUNDARY, NOT_ON_BOUNDARY, 1]
    topo = mesh_topology(np.array([[0, 1, 2], [0, 1, 3], [1, 5, 2], [0, 4, 1]]))
    assert structural_narrow(topo, kind, body_of).tolist() == [True, False, True, False]


def test_quality_baseline_fires_a_margin_past_the_bound_or_past_the_start():
    def shape_of(deg):  # isosceles triangles with apex angle `deg` (their smallest or largest angle)
        pts, tris = [], []
        for k, a in enumerate(np.radians(deg)):
            pts += [[3 * k, 0.0], [3 * k + 1, 0.0], [3 * k + np.cos(a), np.sin(a)]]
            tris.append([3 * k, 3 * k + 1, 3 * k + 2])
        return element_shape(np.array(pts), mesh_topology(np.array(tris)))

    base = quality_baseline(shape_of([40.0, 13.0, 13.0]), np.array([False, False, True]), 15.0, 135.0, 3.0)
    lo = np.degrees(np.arccos(base.cos_lo[:2]))
    # 3° below min(bound, where it started): born inside at 40° -> 12°, born outside at 13° -> 10°
    np.testing.assert_allclose(lo, [12.0, 10.0], atol=1e-9)
    assert base.cos_lo[2] == 2.0 and base.cos_hi[2] == -2.0  # narrow-gap: left out
    anchored = lambda idx: np.ones(len(idx), bool)  # noqa: E731
    # an element born inside that crossed the bound by less than the margin does not fire
    # (before the margin it did: 14° < 15°)
    assert not quality_dropped(shape_of([14.0, 10.5, 5.0]), base, anchored)
    assert quality_dropped(shape_of([11.5, 10.5, 5.0]), base, anchored)
    assert quality_dropped(shape_of([16.0, 9.5, 5.0]), base, anchored)
    # a narrow-gap element that got worse, past the widened bound (12°), and is no longer
    # anchored across a gap triggers; one within the margin does not
    assert quality_dropped(shape_of([16.0, 10.5, 5.0]), base, lambda idx: np.zeros(len(idx), bool))
    assert not quality_dropped(shape_of([16.0, 10.5, 12.5]), base, lambda idx: np.zeros(len(idx), bool))


def test_a_fresh_mesh_does_not_fire_just_past_the_bounds():
    """The elements of a fresh triangulation of 12 polygons in a box each pushed 2° past
    max(135°, its largest angle): none fires (without the margin all of them would); pushed
    10.5° past, they fire.  The smallest angle has no margin by default (min_angle_margin = 0):
    0.5° below min(15°, its angle after the triangulation) fires."""
    bodies = [rectangle(0.06, 0.03), regular_polygon(0.03, 6), regular_polygon(0.03, 3)] * 4
    poses = [[0.05 + 0.09 * (k % 4), 0.03 + 0.07 * (k // 4), 0.4 * k] for k in range(12)]
    mm = MovingMesh((0.0, 0.36, 0.0, 0.32), bodies, poses, h=0.02)
    s0 = element_shape(mm.points, mm.topo)
    amin = np.minimum(np.degrees(np.arccos(np.clip(s0.cos_max, -1, 1))), 15.0)
    amax = np.maximum(np.degrees(np.arccos(np.clip(s0.cos_min, -1, 1))), 135.0)

    def pushed(d, d_min):
        return ElementShape(np.cos(np.radians(amin - d_min)), np.cos(np.radians(amax + d)), s0.area)

    def anchored(idx):
        return np.ones(len(idx), bool)

    assert not quality_dropped(pushed(2.0, 0.0), mm.baseline, anchored)
    assert quality_dropped(pushed(10.5, 0.0), mm.baseline, anchored)  # angle_margin = 10°
    assert quality_dropped(pushed(0.0, 0.5), mm.baseline, anchored)  # min_angle_margin = 0
    no_margin = quality_baseline(s0, mm.baseline.narrow, 15.0, 135.0, 0.0)
    assert quality_dropped(pushed(2.0, 0.0), no_margin, anchored)


def test_retriangulation_reasons_come_in_order_and_lazily():
    base = quality_baseline(ElementShape(np.zeros(2), np.zeros(2), np.ones(2)), np.zeros(2, bool), 15.0, 135.0, 3.0)

    def never():
        raise AssertionError("not needed")

    def shape(area):
        return ElementShape(np.zeros(2), np.zeros(2), np.array(area, float))

    assert retriangulation_reason(shape([1.0, -1.0]), base, 0.1, 99, 30, never, never) == "inverted"
    assert retriangulation_reason(shape([1.0, 0.05]), base, 0.1, 99, 30, never, never) == "degenerate"
    assert retriangulation_reason(shape([1.0, 1.0]), base, 0.1, 99, 30, lambda: True, never) == "contact"
    assert retriangulation_reason(shape([1.0, 1.0]), base, 0.1, 30, 30, lambda: False, never) == "periodic"
    assert retriangulation_reason(shape([1.0, 1.0]), base, 0.1, 3, 30, lambda: False, lambda: True) == "quality"
    assert retriangulation_reason(shape([1.0, 1.0]), base, 0.1, 3, 30, lambda: False, lambda: False) == ""


def test_uid_source_hands_out_fresh_ids():
    u = UidSource(100)
    assert u.take(3).tolist() == [100, 101, 102] and u.take(0).tolist() == [] and u.take(1).tolist() == [103]
