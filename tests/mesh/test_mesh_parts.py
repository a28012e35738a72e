"""Building blocks of the moving mesh: background grids, relaxation (paper eq. 1-3), quality, junctions."""

import numpy as np
import pytest

from fluidem.mesh.background import GradedSize, friedrichs_keller_grid
from fluidem.mesh.triangulate import graded_background
from fluidem.mesh.junctions import junction_points, split_triangles
from fluidem.mesh.quality import OscillationDetector, mesh_quality, triangle_angles
from fluidem.mesh.relax import RelaxParams, mesh_topology, relax, signed_areas


def test_friedrichs_keller_grid_is_structured_right_isosceles():
    p, t = friedrichs_keller_grid((0, 2, 0, 1), 0.1)
    assert p.shape == (21 * 11, 2) and t.shape == (2 * 20 * 10, 3)
    assert np.all(signed_areas(p, t) > 0)
    ang = np.sort(triangle_angles(p, t), axis=1)
    np.testing.assert_allclose(ang, np.tile([45.0, 45.0, 90.0], (len(t), 1)), atol=1e-9)
    # every interior node has the same connectivity (6 neighbours)
    topo = mesh_topology(t)
    deg = np.bincount(topo.edges.ravel())
    interior = (p[:, 0] > 0) & (p[:, 0] < 2) & (p[:, 1] > 0) & (p[:, 1] < 1)
    assert set(deg[interior]) == {6}


def test_graded_background_is_denser_in_region_of_interest():
    size = GradedSize(0.05, 1.3, 0.5, (0.0, 0.5, 0.0, 0.5))
    p = graded_background((0, 4, 0, 4), size)
    fine = ((p[:, 0] < 0.5) & (p[:, 1] < 0.5)).sum() / 0.25
    coarse = ((p[:, 0] > 3) & (p[:, 1] > 3)).sum() / 1.0
    assert fine > 20 * coarse


@pytest.mark.parametrize("h", [0.0, -1.0, np.nan])
def test_bad_sizes_are_rejected(h):
    with pytest.raises(ValueError, match="h"):
        friedrichs_keller_grid((0, 1, 0, 1), h)


def _perturbed_grid(seed=0, amp=0.3):
    p, t = friedrichs_keller_grid((0, 1, 0, 1), 0.1)
    rng = np.random.default_rng(seed)
    interior = (p[:, 0] > 0) & (p[:, 0] < 1) & (p[:, 1] > 0) & (p[:, 1] < 1)
    p = p.copy()
    p[interior] += rng.uniform(-amp, amp, (interior.sum(), 2)) * 0.1
    t = np.where((signed_areas(p, t) < 0)[:, None], t[:, [0, 2, 1]], t)
    mob = np.where(interior[:, None], 1.0, 0.0) * np.ones((len(p), 2))
    return p, t, mob, interior


def test_relaxation_improves_angles_and_never_inverts():
    p, t, mob, interior = _perturbed_grid()
    topo = mesh_topology(t)
    h = np.full(len(p), 0.1)
    q0 = mesh_quality(p, t)
    x, _ = relax(p, topo, h, mob, 50)
    q1 = mesh_quality(x, t)
    assert q0.n_inverted == 0 and q1.n_inverted == 0
    assert q1.min_angle > q0.min_angle + 5
    # fixed nodes did not move
    np.testing.assert_array_equal(x[~interior], p[~interior])


def test_relaxation_refuses_moves_that_invert():
    # a huge step on a strongly distorted mesh would fold it without the guard
    p, t, mob, _ = _perturbed_grid(seed=3, amp=0.45)
    topo = mesh_topology(t)
    h = np.full(len(p), 0.3)  # target three times the spacing: strong push
    x, _ = relax(p, topo, h, mob, 30, RelaxParams(step=0.3, target_weight=1.0))
    assert np.all(signed_areas(x, t) > 0)


def test_sliding_nodes_stay_on_their_side():
    p, t = friedrichs_keller_grid((0, 1, 0, 1), 0.1)
    rng = np.random.default_rng(1)
    bottom = (p[:, 1] == 0) & (p[:, 0] > 0) & (p[:, 0] < 1)
    p = p.copy()
    p[bottom, 0] += rng.uniform(-0.03, 0.03, bottom.sum())
    mob = np.ones((len(p), 2))
    mob[bottom, 1] = 0.0
    corner_or_other_side = ~bottom & ((p[:, 0] == 0) | (p[:, 0] == 1) | (p[:, 1] == 1) | (p[:, 1] == 0))
    mob[corner_or_other_side] = 0.0
    x, _ = relax(p, mesh_topology(t), np.full(len(p), 0.1), mob, 20, bounds=(0, 1, 0, 1))
    np.testing.assert_array_equal(x[bottom, 1], 0.0)
    assert np.ptp(np.diff(np.sort(x[bottom, 0]))) < np.ptp(np.diff(np.sort(p[bottom, 0])))


def test_area_force_eq3_grows_a_squeezed_element():
    # one small triangle surrounded by big ones: with eq. 3 it grows faster than without
    p, t, mob, interior = _perturbed_grid(seed=0, amp=0.0)
    k = np.flatnonzero(interior)[40]
    nb = np.unique(t[(t == k).any(axis=1)])
    p = p.copy()
    p[nb[nb != k]] = p[k] + 0.6 * (p[nb[nb != k]] - p[k])  # squeeze the star around node k
    t = np.where((signed_areas(p, t) < 0)[:, None], t[:, [0, 2, 1]], t)
    topo = mesh_topology(t)
    star = (t == k).any(axis=1)
    h = np.full(len(p), 0.1)
    grow = {}
    for kappa in (0.0, 0.5):
        x, _ = relax(p, topo, h, mob, 3, RelaxParams(target_weight=0.0, area_weight=kappa))
        grow[kappa] = signed_areas(x, t)[star].sum() / signed_areas(p, t)[star].sum()
    assert grow[0.5] > grow[0.0]


def test_quality_counts():
    p = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2], [2, 0], [1.5, 0.01]])
    t = np.array([[0, 1, 2], [1, 3, 4], [1, 4, 3]])
    q = mesh_quality(p, t)
    assert q.n_inverted == 1 and q.n_triangles == 3
    assert q.max_angle > 135 and q.frac_above_135 == pytest.approx(2 / 9)
    np.testing.assert_allclose(triangle_angles(p, t[:1]), [[60, 60, 60]])


def test_oscillation_detector_flags_flipping_nodes_only():
    det = OscillationDetector(tol=1e-3, min_flips=3)
    h = np.full(3, 1.0)
    found = []
    for k in range(8):
        d = np.zeros((3, 2))
        d[0, 0] = 0.1 * (-1) ** k  # flips back and forth
        d[1, 0] = 0.1  # drifts
        found.append(det.update(d, h))
    assert list(found[-1]) == [0]
    assert all(1 not in f and 2 not in f for f in found)


def test_junction_point_splits_triangle_between_three_bodies():
    import shapely

    from fluidem.geometry import regular_polygon

    # three hexagons around the origin; their nearest corners form a junction triangle
    centres = np.array([[np.cos(a), np.sin(a)] for a in (np.pi / 2, np.pi / 2 + 2 * np.pi / 3,
                                                         np.pi / 2 + 4 * np.pi / 3)]) * 0.7
    polys = np.array([shapely.Polygon(regular_polygon(0.5, 6, phase=np.arctan2(c[1], c[0])) + c) for c in centres])
    pts = np.array([c * (1 - 0.5 / 0.7) for c in centres])  # nearest corner of each body
    tri = np.array([[0, 1, 2]])
    owner = np.array([0, 1, 2])
    jt, q = junction_points(pts, tri, owner, centres, polys, h=0.2, clearance=0.3)
    assert list(jt) == [0]
    np.testing.assert_allclose(q[0], [0, 0], atol=1e-12)  # the Voronoi vertex of the centres
    t2 = split_triangles(tri, jt, [3])
    assert np.all(signed_areas(np.vstack([pts, q]), t2) > 0)
    # no room for a node when the bodies nearly touch (corners 0.04 from the junction)
    c2 = centres / 0.7 * 0.54
    polys2 = np.array([shapely.Polygon(regular_polygon(0.5, 6, phase=np.arctan2(c[1], c[0])) + c) for c in c2])
    pts2 = np.array([c * (1 - 0.5 / 0.54) for c in c2])
    jt, q = junction_points(pts2, tri, owner, c2, polys2, h=0.2, clearance=0.3)
    assert len(jt) == 0


def test_harmonic_drag_over_a_periodic_strip_is_the_strip_s_extension():
    """A strip two cells wide and periodic in x (nodes at x = 0 and 2 matched), its top row moved
    by 1 along x and its bottom row held: the harmonic extension over the strip is the uniform
    shear, 0.5 on the middle row at every x (analytic: the strip has no x-dependence).  Without
    the pairs the side nodes see one side only and the middle row gets 0.625, 0.5, 0.375."""
    import pickle

    from fluidem.mesh.drag import HarmonicDrag

    idx = np.arange(9).reshape(3, 3)
    tris = []
    for j in range(2):
        for i in range(2):
            a, b, c, d = idx[j, i], idx[j, i + 1], idx[j + 1, i], idx[j + 1, i + 1]
            tris += [[a, b, d], [a, d, c]]
    topo = mesh_topology(np.array(tris))
    given = np.zeros((9, 2), dtype=bool)
    given[idx[0]] = given[idx[2]] = True
    disp = np.zeros((9, 2))
    disp[idx[2], 0] = 1.0
    pairs = np.column_stack([idx[:, 0], idx[:, 2]])
    strip = HarmonicDrag(topo, given, pairs)
    for drag in (strip, pickle.loads(pickle.dumps(strip))):
        np.testing.assert_allclose(drag.extend(disp)[idx[1]], [[0.5, 0.0]] * 3, atol=1e-14)
    np.testing.assert_allclose(HarmonicDrag(topo, given).extend(disp)[idx[1], 0], [0.625, 0.5, 0.375], atol=1e-14)
    # a pair with one partner given takes its value: both partners move alike
    given[idx[1, 0]] = True
    disp[idx[1, 0]] = [0.3, 0.1]
    np.testing.assert_allclose(HarmonicDrag(topo, given, pairs).extend(disp)[idx[1, 2]], [0.3, 0.1])
