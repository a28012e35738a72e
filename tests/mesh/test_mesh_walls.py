"""Bodies near and touching the box walls: the wall joins the contact policy.

A body closer than ``min_gap`` to a box side (touching it, or overlapping it by up to
``wall_overlap · h``) is meshed with the wall as one closed outline
(:mod:`fluidem.mesh.contact_outline`): the fluid between them narrower than ``min_gap`` is
filled, the box facets under the body are dropped, and the wall nodes where the outline
leaves the side slide along it with the body.
"""

import numpy as np
import pytest
import shapely

from fluidem.geometry import rectangle
from fluidem.mesh import MovingMesh
from fluidem.mesh.nodes import CONTACT, CORNER

BOX = (0.0, 2.0, 0.0, 1.0)
H = 0.05


def _disk(r=0.1, n=32):
    t = np.linspace(0.0, 2.0 * np.pi, n + 1)[:-1]
    return r * np.column_stack([np.cos(t), np.sin(t)])


def _check_valid(mm):
    """No inverted element, no node or element inside a body, outline facets present, and the
    named boundaries are exactly the boundary facets (the box facets stop at the body)."""
    q = mm.quality()
    assert q.n_inverted == 0, q
    assert q.n_nodes_inside_bodies == 0, q
    assert mm.outline_facets_present()
    polys = mm._polygons()
    centroids = mm.points[mm.triangles].mean(axis=1)
    for poly in polys:
        assert not shapely.contains_xy(poly, centroids[:, 0], centroids[:, 1]).any()
    m = mm.skfem_mesh()
    named = np.concatenate([np.asarray(f) for f in m.boundaries.values()])
    assert len(named) == len(np.unique(named))
    assert np.array_equal(np.sort(named), np.sort(m.boundary_facets()))
    xmin, xmax, ymin, ymax = mm.box
    for name, on in (("bottom", lambda p: np.abs(p[1] - ymin)), ("top", lambda p: np.abs(p[1] - ymax)),
                     ("left", lambda p: np.abs(p[0] - xmin)), ("right", lambda p: np.abs(p[0] - xmax))):
        f = m.boundaries[name]
        mid = m.p[:, m.facets[:, f]].mean(axis=1)
        assert (on(mid) < 1e-9).all(), name  # box facets lie on their side ...
        for poly in polys:  # ... and not under a body
            assert (shapely.distance(poly, shapely.points(mid.T)) > 0.0).all(), name
    for b, name in enumerate(mm.body_names):
        assert len(m.boundaries[name]) > 0
    return q


@pytest.mark.parametrize("body, y, angle", [
    (rectangle(0.3, 0.1), 0.05, 0.0),           # flat on the floor, touching
    (rectangle(0.3, 0.1), 0.05 + 2e-5, 0.0),    # a gap below min_gap (5e-5)
    (rectangle(0.3, 0.1), 0.05 - 1e-3, 0.0),    # overlapping the floor by 1e-3 (wall_overlap · h = 5e-3)
    (rectangle(0.3, 0.1), 0.15 * np.sin(0.3) + 0.05 * np.cos(0.3), 0.3),   # a corner on the floor
    (_disk(), 0.1, 0.0),                        # a vertex on the floor
])
def test_a_body_on_the_floor_is_meshed_with_the_wall(body, y, angle):
    mm = MovingMesh(BOX, [body], [[0.8, y, angle]], h=H)
    assert mm.walls.tolist() == [[0, 0]]
    q = _check_valid(mm)
    assert q.min_angle > 15.0, q
    # the wall nodes lie on the floor and belong to the body (one where a corner touches it)
    wall = np.flatnonzero(mm.kind == CONTACT)
    assert len(wall) >= 1 and np.all(mm.points[wall, 1] == 0.0) and np.all(mm.body_of[wall] == 0)


def test_a_body_in_a_corner_touches_two_walls():
    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.15, 0.05, 0.0]], h=H)
    assert mm.walls.tolist() == [[0, 0], [0, 3]]
    _check_valid(mm)
    assert not ((mm.kind == CORNER) & (mm.points[:, 0] == 0.0) & (mm.points[:, 1] == 0.0)).any()


@pytest.mark.parametrize("gap", [0.0, 1e-4, 0.2 * H])
def test_a_long_slide_along_the_floor_keeps_its_quality(gap):
    """140 steps of 0.2 h touching, at 2 min_gap and at h/5: the box-side nodes ahead of the
    body are coarsened at re-triangulation instead of piling up (measured worst min angle
    15.1–15.4°, 12–13 re-triangulations; before, elements of 0.4° between piled-up nodes)."""
    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.3, 0.05 + gap, 0.0]], h=H)
    n = 0
    for k in range(1, 141):
        ev = mm.update([[0.3 + 0.01 * k, 0.05 + gap, 0.0]])
        q = _check_valid(mm)
        assert q.min_angle >= 12.0, (k, q)
        n += ev.retriangulated
    assert n <= 26


def test_a_body_sliding_along_the_floor_stays_meshable():
    """Gaps from 2 min_gap down to touching and back while sliding."""
    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.5, 0.05 + 1e-4, 0.0]], h=H)
    g = mm.min_gap
    gaps = np.concatenate([np.geomspace(2 * g, 1e-3 * g, 20), np.zeros(20), np.geomspace(1e-3 * g, 0.5 * g, 20)])
    reasons = []
    for k, gap in enumerate(gaps):
        ev = mm.update([[0.5 + 0.01 * (k + 1), 0.05 + gap, 0.0]])
        reasons.append(ev.reason)
        _check_valid(mm)
        assert (ev.walls.tolist() == [[0, 0]]) == (gap < g)
    assert "contact" in reasons
    # the wall nodes slid with the body, on the floor
    wall = np.flatnonzero(mm.kind == CONTACT)
    assert np.all(mm.points[wall, 1] == 0.0)


def test_a_tilted_body_sliding_on_its_corner():
    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.5, 0.15 * np.sin(0.3) + 0.05 * np.cos(0.3), 0.3]], h=H)
    for k in range(1, 41):
        a = 0.3 + 0.002 * k
        ev = mm.update([[0.5 + 0.01 * k, 0.15 * np.sin(a) + 0.05 * np.cos(a), a]])
        _check_valid(mm)
        assert ev.walls.tolist() == [[0, 0]]


def test_a_disk_settling_onto_the_floor_stays_meshable():
    """A disk approaching the floor vertically, gap halving every step from 0.5 h to touching."""
    r = 0.1
    mm = MovingMesh(BOX, [_disk(r)], [[0.8, r + 0.5 * H, 0.0]], h=H)
    gaps = np.concatenate([0.5 * H * 0.5 ** np.arange(1, 25), np.zeros(5)])
    for gap in gaps:
        mm.update([[0.8, r + gap, 0.0]])
        _check_valid(mm)
    assert mm.walls.tolist() == [[0, 0]]


def test_two_bodies_touching_each_other_and_the_floor():
    """A pair in contact resting on the floor: one cluster with the wall, body pairs as before."""
    sq = rectangle(0.2, 0.2)
    mm = MovingMesh(BOX, [sq, sq], [[0.6, 0.1, 0.0], [0.8, 0.1, 0.0]], h=H)
    assert mm.contacts.tolist() == [[0, 1]] and mm.walls.tolist() == [[0, 0], [1, 0]]
    _check_valid(mm)


def test_fluid_cut_off_by_a_body_on_the_floor_is_a_pore():
    """An arch standing on the floor encloses 0.2 × 0.1 of fluid between its legs: meshed and
    reported as a pore (it needs its own pressure reference)."""
    arch = np.array([[-0.2, -0.1], [-0.1, -0.1], [-0.1, 0.0], [0.1, 0.0], [0.1, -0.1], [0.2, -0.1],
                     [0.2, 0.1], [-0.2, 0.1]])
    mm = MovingMesh(BOX, [arch], [[0.8, 0.1, 0.0]], h=H)
    _check_valid(mm)
    assert np.allclose(mm.pore_areas, [0.02])
    lifted = MovingMesh(BOX, [arch], [[0.8, 0.2, 0.0]], h=H)
    assert len(lifted.pore_areas) == 0 and len(lifted.walls) == 0


def test_a_flow_step_on_a_mesh_with_a_body_on_the_floor():
    """Navier–Stokes BDF2 on the merged outline: walls no-slip, the body's rigid motion on its
    facets (applied last, so it wins at the wall nodes, which move with the body)."""
    from fluidem.fluid import FlowProblem, FlowSpace, RigidMotion, VelocityBC
    from fluidem.fluid.navier_stokes import BDF2Stepper

    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.05, 0.0]], h=H)
    space = FlowSpace(mm.skfem_mesh(), "th")
    bcs = [VelocityBC(["bottom", "right", "top", "left"], (0.0, 0.0)),
           VelocityBC("body0", RigidMotion((1.0, 0.0), 0.0, (0.8, 0.05)))]
    st = BDF2Stepper(FlowProblem(space, 0.01, bcs), 0.01)
    for _ in range(2):
        state = st.step()
    x = np.asarray(state.x)
    assert np.isfinite(x).all()
    u = x[: space.n_u]
    # the body's facets carry its velocity (1, 0) ...
    dofs = space.ub.get_dofs(space.mesh.boundaries["body0"]).all()
    ux, uy = u[space.ub.split_indices()[0]], u[space.ub.split_indices()[1]]
    on_body = np.isin(space.ub.split_indices()[0], dofs)
    assert np.allclose(ux[on_body], 1.0) and np.allclose(uy[np.isin(space.ub.split_indices()[1], dofs)], 0.0)
    # ... and the fluid moves with it, boundedly (the displaced fluid runs over the body)
    assert 0.05 < np.abs(u[~np.isin(np.arange(space.n_u), dofs)]).max() < 3.0


def test_bad_input_names_the_body_the_value_and_what_is_allowed():
    # allowed: max(wall_overlap · h, wall_overlap_fraction · height) = max(0.005, 0.025)
    with pytest.raises(ValueError, match=r"body 0 \(body0\) .* overlaps the bottom wall by 0\.03; expected an "
                                         r"overlap of at most 0\.025 = max\(wall_overlap · h, wall_overlap_fraction "
                                         r"· its extent across the wall\) .*raise \[contact\] E"):
        MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.02, 0.0]], h=H)
    with pytest.raises(ValueError, match=r"body 1 \(body1\) at pose \[2\.5, 0\.5, 0\.0\] .* it lies outside"):
        MovingMesh(BOX, [rectangle(0.3, 0.1)] * 2, [[0.8, 0.5, 0.0], [2.5, 0.5, 0.0]], h=H)
    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.05, 0.0]], h=H)
    with pytest.raises(ValueError, match="overlaps the bottom wall by 0.03"):
        mm.update([[0.8, 0.02, 0.0]])
    with pytest.raises(ValueError, match="wall_overlap"):
        MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.5, 0.0]], h=H, wall_overlap=-1.0)
    # a larger wall_overlap admits the deeper overlap
    _check_valid(MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.02, 0.0]], h=H, wall_overlap=0.7))


def test_regenerate_strategy_and_pickle_with_a_wall_contact():
    import pickle

    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.05, 0.0]], h=H, strategy="regenerate")
    mm.update([[0.82, 0.05, 0.0]])
    _check_valid(mm)
    dm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.8, 0.05, 0.0]], h=H)
    dm.update([[0.81, 0.05, 0.0]])
    copy = pickle.loads(pickle.dumps(dm))
    a, b = dm.update([[0.82, 0.05, 0.0]]), copy.update([[0.82, 0.05, 0.0]])
    assert a.reason == b.reason and np.array_equal(dm.points, copy.points)


def test_a_body_pressed_into_the_wall_between_triangulations():
    """A disk at 2e-5 from the floor pushed 3e-3 into it in one step (within wall_overlap · h):
    its outline nodes cross the wall before the outline is rebuilt; no relaxation with nodes
    outside the box (it would not end), the mesh is rebuilt at once."""
    mm = MovingMesh(BOX, [_disk()], [[0.5, 0.1 + 2e-5, 0.0]], h=H)
    ev = mm.update([[0.5, 0.1 - 3e-3, 0.02]])
    assert ev.retriangulated and ev.reason in ("contact", "inverted", "degenerate"), ev.reason
    _check_valid(mm)
    assert mm.walls.tolist() == [[0, 0]]


def test_a_shallow_edge_crossing_the_top_wall_leaves_no_sliver():
    """The top edge of a square crosses the top wall at 2.7° and runs within min_gap of it: no
    thin strip along the wall is taken from the fluid (the top side keeps its nodes)."""
    mm = MovingMesh(BOX, [rectangle(0.2, 0.2)], [[0.450551, 0.90012, 4.759232]], h=H)
    assert mm.walls.tolist() == [[0, 2]]
    _check_valid(mm)
    m = mm.skfem_mesh()
    top = m.p[:, m.facets[:, m.boundaries["top"]]]
    assert top[0].min() < 1e-12 and np.isclose(top[0].max(), 2.0)  # from corner to corner, apart from the body
    assert (np.abs(top[1] - 1.0) < 1e-12).all()


def test_a_box_corner_comes_back_when_the_body_leaves_it():
    mm = MovingMesh(BOX, [rectangle(0.3, 0.1)], [[0.15, 0.05, 0.0]], h=H)
    assert not ((mm.kind == CORNER) & (np.abs(mm.points).max(axis=1) == 0.0)).any()  # covered
    for k in range(1, 6):
        mm.update([[0.15 + 0.01 * k, 0.05 + 0.005 * k, 0.0]])
        _check_valid(mm)
    assert len(mm.walls) == 0
    assert ((mm.kind == CORNER) & (np.abs(mm.points).max(axis=1) == 0.0)).sum() == 1
