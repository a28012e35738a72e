"""MovingMesh: invariants while bodies move, strategies, contacts, pores, outputs and bad input."""

import numpy as np
import pytest

from fluidem.cases.packings import pore_ring
from fluidem.geometry import rectangle, regular_polygon
from fluidem.mesh import MovingMesh


def check_invariants(mm, min_area_rel=1e-6):
    """No inverted element, no node inside a body, every outline present as boundary facets."""
    q = mm.quality()
    assert q.n_inverted == 0, q
    assert q.n_nodes_inside_bodies == 0, q
    assert mm.outline_facets_present()
    assert q.min_area > min_area_rel * mm.h**2, q
    return q


def three_bodies():
    bodies = [regular_polygon(0.3, 6), rectangle(0.5, 0.3), regular_polygon(0.25, 3)]
    poses = np.array([[1.0, 1.0, 0.0], [2.0, 1.2, 0.3], [1.5, 2.0, 0.1]])
    return bodies, poses


@pytest.mark.parametrize("strategy", ["drag", "regenerate"])
def test_invariants_hold_every_step(strategy):
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 3, 0, 3), bodies, poses, h=0.1, strategy=strategy)
    check_invariants(mm)
    worst = 90.0
    for _ in range(40):
        poses = poses + np.array([0.004, 0.002, 0.01])
        ev = mm.update(poses)
        q = check_invariants(mm)
        worst = min(worst, q.min_angle)
        assert ev.n_nodes == q.n_nodes
    assert worst > 15.0, worst
    assert q.frac_above_135 < 0.01


def test_drag_keeps_connectivity_between_retriangulations():
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 3, 0, 3), bodies, poses, h=0.1, retriangulate_every=10)
    t0 = mm.triangles.copy()
    ev = mm.update(poses + [0.001, 0.0, 0.0])
    assert not ev.retriangulated and np.array_equal(mm.triangles, t0)
    reasons = [mm.update(poses + [0.001 * (k + 2), 0.0, 0.0]).reason for k in range(9)]
    assert reasons[-1] == "periodic" and set(reasons[:-1]) == {""}


def test_node_velocity_is_rigid_on_outlines():
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 3, 0, 3), bodies, poses, h=0.1)
    dt = 0.01
    vel = np.array([[0.2, -0.1, 0.5], [0.0, 0.1, -0.3], [0.1, 0.1, 0.0]])
    mm.update(poses + dt * vel)
    w = mm.node_velocity(dt)
    assert w.shape == mm.points.shape
    for b in range(3):
        on = mm.body_of == b
        x = mm.points[on]
        # exact finite difference of the rigid motion: rotation by ω dt about the old centre
        x_prev = mm._prev_points[on]
        np.testing.assert_allclose(w[on], (x - x_prev) / dt, atol=1e-12)
        r = x_prev - poses[b, :2]
        expected = vel[b, :2] + vel[b, 2] * np.column_stack([-r[:, 1], r[:, 0]])
        # the finite difference departs from the rigid velocity by |ω|² |r| dt / 2: measured 3.75e-4 (body 0)
        np.testing.assert_allclose(w[on], expected, atol=1e-3)
    with pytest.raises(ValueError, match="dt"):
        mm.node_velocity(0.0)


def test_node_velocity_after_retriangulation_is_finite():
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 3, 0, 3), bodies, poses, h=0.1, retriangulate_every=1)
    ev = mm.update(poses + [0.01, 0.0, 0.0])
    assert ev.retriangulated
    w = mm.node_velocity(0.1)
    assert np.all(np.isfinite(w))
    on = mm.body_of >= 0
    np.testing.assert_allclose(w[on], np.tile([0.1, 0.0], (on.sum(), 1)), atol=1e-9)
    # nodes new to this mesh take means of old nodes' velocities: they stay within their range
    old = np.isin(mm.uid, mm._prev_uid)
    assert (~old).any(), "the re-triangulation inserted no node: the test needs one"
    lo, hi = w[old].min(axis=0), w[old].max(axis=0)
    assert np.all(w[~old] >= lo - 1e-12) and np.all(w[~old] <= hi + 1e-12)


def test_skfem_mesh_has_named_boundaries():
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 3, 0, 3), bodies, poses, h=0.1)
    m = mm.skfem_mesh()
    assert set(m.boundaries) == {"bottom", "right", "top", "left", "body0", "body1", "body2"}
    for b in range(3):
        f = m.boundaries[f"body{b}"]
        mid = m.p[:, m.facets[:, f]].mean(axis=1).T
        # facets of body b lie on its outline: total length equals the perimeter
        lengths = np.linalg.norm(m.p[:, m.facets[0, f]] - m.p[:, m.facets[1, f]], axis=0)
        v = bodies[b]
        perim = np.linalg.norm(v - np.roll(v, -1, axis=0), axis=1).sum()
        assert lengths.sum() == pytest.approx(perim, rel=1e-9)
        assert len(mid) > 0
    xmin = m.p[0, m.facets[:, m.boundaries["left"]]]
    np.testing.assert_allclose(xmin, 0.0)


def test_fixed_strategy_meshes_once_and_rejects_motion():
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 3, 0, 3), bodies, poses, h=0.1, strategy="fixed")
    p0 = mm.points.copy()
    ev = mm.update(poses)
    assert not ev.retriangulated and np.array_equal(mm.points, p0)
    with pytest.raises(ValueError, match="fixed"):
        mm.update(poses + [0.1, 0, 0])


def test_graded_mesh_is_coarse_far_away():
    bodies, poses = three_bodies()
    mm = MovingMesh((0, 12, 0, 6), bodies, poses, h=0.1,
                    grading={"region": (0, 3, 0, 3), "growth": 1.2, "h_max": 1.0})
    check_invariants(mm)
    far = (mm.points[:, 0] > 8).sum() / (4 * 6)
    near = ((mm.points[:, 0] < 3) & (mm.points[:, 1] < 3)).sum() / 9
    assert near > 20 * far


def test_sliding_past_each_other_with_gap_h_over_10():
    """Hard case 2 (short run): two bodies sliding in opposite directions, gap h/10."""
    h = 0.1
    bodies = [rectangle(1.0, 0.3), rectangle(1.0, 0.3)]
    poses = np.array([[1.5, 1.0, 0.0], [2.5, 1.3 + h / 10, 0.0]])
    mm = MovingMesh((0, 4, 0, 2.3), bodies, poses, h=h)
    n_narrow = []
    for k in range(60):
        poses[0, 0] += 0.01
        poses[1, 0] -= 0.01
        mm.update(poses)
        q = check_invariants(mm)
        n_narrow.append(q.n_narrow_gap_triangles)
        assert q.min_angle > 15.0 and q.frac_above_135 < 0.01, q
    assert max(n_narrow) > 0  # the overlap region is a narrow gap


# ---------------------------------------------------------------- contacts and pores
@pytest.mark.parametrize("gap", [0.0, -0.01, 1e-7, 0.002])
def test_touching_and_overlapping_bodies_mesh_cleanly(gap):
    """Contact policy: closer than min_gap -> one closed outline; never a zero-area element."""
    sq = rectangle(0.4, 0.4)
    poses = np.array([[1.0, 1.0, 0.0], [1.4 + gap, 1.0, 0.0], [1.2, 1.4 + gap, 0.3]])
    mm = MovingMesh((0, 2.5, 0, 2.5), [sq, sq, sq], poses, h=0.05)
    check_invariants(mm)
    if gap <= 0:
        assert {tuple(c) for c in mm.contacts} >= {(0, 1)}
    for _ in range(15):
        poses[1, 0] -= 0.0005  # push into contact / deeper overlap
        poses[0, 2] += 0.002
        ev = mm.update(poses)
        check_invariants(mm)
    assert len(ev.contacts) >= 2


@pytest.mark.parametrize("angle", [0.0, 0.05])
def test_an_overlap_shallower_than_min_gap_leaves_no_outline_node_inside_the_other_body(angle):
    """Outline nodes of one body inside another one by less than ``on_outline_factor · min_gap``
    lie within the tolerance of the closed outline; they are no nodes of it all the same."""
    sq = rectangle(0.4, 0.4)
    h = 0.05
    depth = 0.5e-3 * h  # half of min_gap = 1e-3 h: within the on-outline tolerance
    poses = np.array([[1.0, 1.0, 0.0], [1.4 - depth, 1.02, angle]])
    mm = MovingMesh((0, 2.5, 0, 2.5), [sq, sq], poses, h=h)
    assert {tuple(c) for c in mm.contacts} == {(0, 1)}
    # without the rule: 2 outline nodes of body 0 inside body 1 at angle 0 (by 2.5e-5)
    assert len(mm.nodes_inside_bodies()) == 0
    check_invariants(mm)
    for k in range(5):  # and every re-triangulation on the way into a deeper overlap
        poses[1, 0] -= 0.2 * depth
        mm.update(poses)
        check_invariants(mm)


def test_enclosed_pore_is_detected_and_meshed():
    bodies, poses = pore_ring()
    mm = MovingMesh((0, 2.5, 0, 2.5), bodies, poses, h=0.05)
    check_invariants(mm)
    assert len(mm.pore_areas) == 1
    # the pore is the hexagon inside the ring minus nothing: area between 0.4 and 0.7
    assert 0.4 < mm.pore_areas[0] < 0.7
    inside = np.hypot(mm.points[:, 0] - 1.25, mm.points[:, 1] - 1.25) < 0.3
    assert inside.sum() > 20  # the pore is meshed
    # without contact there is no pore
    poses2 = np.array(poses)
    poses2[:, :2] = 1.25 + 1.3 * (poses2[:, :2] - 1.25)
    assert len(MovingMesh((0, 2.5, 0, 2.5), bodies, poses2, h=0.05).pore_areas) == 0


# ---------------------------------------------------------------- bad input
def test_bad_input_is_rejected_with_clear_errors():
    sq = rectangle(0.4, 0.4)
    dom = (0, 2, 0, 2)
    with pytest.raises(ValueError, match="not inside the domain"):
        MovingMesh(dom, [sq], [[1.9, 1.0, 0.0]], h=0.1)
    with pytest.raises(ValueError, match="clockwise"):
        MovingMesh(dom, [sq[::-1]], [[1.0, 1.0, 0.0]], h=0.1)
    with pytest.raises(ValueError, match="intersects itself"):
        bowtie = np.array([[0, 0], [0.4, 0.4], [0.4, 0], [0.2, 0.5], [0, 0.4]]) - 0.2
        MovingMesh(dom, [bowtie], [[1.0, 1.0, 0.0]], h=0.1)
    for h in (0.0, -0.1, np.inf):
        with pytest.raises(ValueError, match="mesh size h"):
            MovingMesh(dom, [sq], [[1.0, 1.0, 0.0]], h=h)
    with pytest.raises(ValueError, match="unknown mesh strategy 'warp'"):
        MovingMesh(dom, [sq], [[1.0, 1.0, 0.0]], h=0.1, strategy="warp")
    with pytest.raises(ValueError, match=r"\(1, 3\)"):
        MovingMesh(dom, [sq], [[1.0, 1.0]], h=0.1)
    with pytest.raises(ValueError, match="domain"):
        MovingMesh((0, -1, 0, 2), [sq], [[1.0, 1.0, 0.0]], h=0.1)
    with pytest.raises(ValueError, match="grading"):
        MovingMesh(dom, [sq], [[1.0, 1.0, 0.0]], h=0.1, grading={"growth": 1.2})
    mm = MovingMesh(dom, [sq], [[1.0, 1.0, 0.0]], h=0.1)
    with pytest.raises(ValueError, match="not inside the domain"):
        mm.update([[2.5, 1.0, 0.0]])


def test_body_objects_are_accepted():
    class Body:  # duck-typed like fluidem.dem bodies
        def __init__(self, v, name):
            self.vertices, self.name = v, name

    mm = MovingMesh((0, 2, 0, 2), [Body(rectangle(0.4, 0.4), "box")], [[1.0, 1.0, 0.2]], h=0.1)
    assert "box" in mm.skfem_mesh().boundaries


def _packed_mesh():
    from fluidem.cases.packings import packing

    bodies, poses, box = packing(n=30, phi=0.45, sizes=(0.5, 1.5), n_vertices=(3, 8), min_gap=0.01, seed=4)
    return MovingMesh(box, bodies, poses, h=0.12), bodies, poses


def test_drag_association_finds_every_body_within_reach():
    """Each free node is tied to every body whose outline is closer than drag_reach · h
    (brute force over all bodies with GEOS), with the linear weight of the docstring."""
    import shapely
    from fluidem.cases.packings import world_polygons

    mm, bodies, poses = _packed_mesh()
    polys = world_polygons(bodies, poses)
    free = np.flatnonzero((mm._drag_mobility != 0.0).any(axis=1))
    d = shapely.distance(shapely.boundary(polys)[None, :], shapely.points(mm.points[free])[:, None])
    reach = mm.drag_reach * mm.h_node[free]
    ni, bi = np.nonzero(d < reach[:, None])
    assert len(ni) > len(free) // 4  # a dense packing: many nodes are dragged
    assert set(zip(free[ni].tolist(), bi.tolist())) == set(zip(mm._drag_node.tolist(), mm._drag_body.tolist()))
    # weight 1 within drag_full · h, falling linearly to 0 at drag_reach · h
    k = {(a, b): j for j, (a, b) in enumerate(zip(mm._drag_node.tolist(), mm._drag_body.tolist()))}
    w = mm._drag_weight[[k[(a, b)] for a, b in zip(free[ni].tolist(), bi.tolist())]]
    hn = mm.h_node[free[ni]]
    ref = np.clip((mm.drag_reach * hn - d[ni, bi]) / ((mm.drag_reach - mm.drag_full) * hn), 0.0, 1.0)
    assert np.allclose(w, ref, rtol=0, atol=1e-12)


def test_gap_width_is_the_two_nearest_boundaries():
    """Gap width = sum of the two smallest distances to bodies within the radius and the box."""
    import shapely
    from fluidem.cases.packings import world_polygons

    mm, bodies, poses = _packed_mesh()
    polys = world_polygons(bodies, poses)
    rng = np.random.default_rng(0)
    xmin, xmax, ymin, ymax = mm.box
    pts = np.column_stack([rng.uniform(xmin, xmax, 4000), rng.uniform(ymin, ymax, 4000)])
    radius = rng.uniform(0.0, 3.0 * mm.h, len(pts))
    got = mm._gap_width(pts, radius)
    d = shapely.distance(polys[None, :], shapely.points(pts)[:, None])
    d = np.where(d < radius[:, None], d, np.inf)
    box = np.min(np.column_stack([pts[:, 0] - xmin, xmax - pts[:, 0], pts[:, 1] - ymin, ymax - pts[:, 1]]), axis=1)
    allb = np.sort(np.column_stack([d, box]), axis=1)
    ref = allb[:, 0] + allb[:, 1]
    assert np.isfinite(ref).sum() > 100 and np.isinf(ref).sum() > 100
    assert np.array_equal(np.isinf(got), np.isinf(ref))
    fin = np.isfinite(ref)
    assert np.allclose(got[fin], ref[fin], rtol=0, atol=1e-12)
