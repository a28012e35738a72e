import numpy as np
import pytest
import shapely
from shapely import affinity

from fluidem import geometry as g


def test_square_area_centroid_inertia():
    sq = g.rectangle(2.0, 1.0)
    assert g.polygon_area(sq) == pytest.approx(2.0)
    np.testing.assert_allclose(g.polygon_centroid(sq + [3.0, 4.0]), [3.0, 4.0])
    # rectangle polar moment about its centre: A (w² + h²) / 12
    assert g.polygon_polar_moment(sq) == pytest.approx(2.0 * (4.0 + 1.0) / 12.0)


def test_regular_polygon_tends_to_disk():
    v = g.regular_polygon(0.5, 2000)
    assert g.polygon_area(v) == pytest.approx(np.pi * 0.25, rel=1e-5)
    assert g.polygon_polar_moment(v) == pytest.approx(np.pi * 0.5**4 / 2, rel=1e-5)


def test_validate_rejects_bad_outlines():
    with pytest.raises(ValueError, match="clockwise"):
        g.validate_polygon(g.rectangle(1, 1)[::-1])
    with pytest.raises(ValueError, match="intersects itself"):
        g.validate_polygon([[0, 0], [4, 0], [4, 4], [2, -1], [0, 4]])
    with pytest.raises(ValueError, match="not convex"):
        g.validate_polygon([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]], require_convex=True)
    with pytest.raises(ValueError, match="at least 3"):
        g.validate_polygon([[0, 0], [1, 0]])


def test_point_in_polygon_and_transform():
    sq = g.transform(g.rectangle(1, 1), (2.0, 0.0), np.pi / 4)
    inside = g.point_in_polygon([[2.0, 0.0], [2.0, 0.69], [2.0, 0.72], [3.0, 0.0]], sq)
    assert inside.tolist() == [True, True, False, False]


# ---- the kernels: rigid transforms, orientation and areas, barycentric coordinates ----------


def _random_bodies(rng, n, k=8):
    """n convex polygons padded to k rows (repeating vertex 0), their counts and poses (n, 3)."""
    V = np.zeros((n, k, 2))
    counts = rng.integers(3, k + 1, n)
    for b in range(n):
        V[b, :counts[b]] = g.regular_polygon(rng.uniform(0.1, 2.0), int(counts[b]), phase=rng.uniform(0, 6))
        V[b, counts[b]:] = V[b, 0]
    poses = np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-7, 7, n)])
    return V, counts, poses


def test_rigid_transform_of_many_bodies_matches_shapely():
    rng = np.random.default_rng(1)
    V, counts, poses = _random_bodies(rng, 30)
    W = g.rigid_transform(V, poses)
    assert W.shape == V.shape
    for b in range(len(V)):
        ref = affinity.translate(affinity.rotate(shapely.Polygon(V[b, :counts[b]]), poses[b, 2], origin=(0, 0),
                                                 use_radians=True), *poses[b, :2])
        np.testing.assert_allclose(W[b, :counts[b]], np.asarray(ref.exterior.coords)[:-1], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(W[b, counts[b]:], np.broadcast_to(W[b, 0], W[b, counts[b]:].shape))
        # the one-body form is the same kernel
        np.testing.assert_array_equal(g.transform(V[b], poses[b, :2], poses[b, 2]), W[b])
    # one body per point, and back to body coordinates
    body = rng.integers(0, len(V), 200)
    xi = rng.normal(size=(200, 2))
    x = g.rigid_transform(xi, poses, body)
    np.testing.assert_array_equal(x, np.stack([g.rigid_transform(xi[m], poses[body[m]]) for m in range(200)]))
    np.testing.assert_allclose(g.to_body_frame(x, poses, body), xi, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.to_body_frame(W, poses), V, rtol=0, atol=1e-12)
    # rotate: a quarter turn of (1, 0) is (0, 1)
    np.testing.assert_allclose(g.rotate([[1.0, 0.0], [0.0, 2.0]], [np.pi / 2, np.pi]), [[0, 1], [0, -2]], atol=1e-15)


def test_triangle_areas_orientation_and_ccw_against_shapely():
    rng = np.random.default_rng(2)
    p = rng.uniform(-3, 3, (60, 2))
    t = np.array([rng.choice(60, 3, replace=False) for _ in range(200)])
    area = g.triangle_areas(p, t)
    polys = shapely.polygons(p[t])
    sign = np.where(shapely.is_ccw(shapely.get_exterior_ring(polys)), 1.0, -1.0)
    np.testing.assert_allclose(area, sign * shapely.area(polys), rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(g.orient2d(p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]), 2 * area)
    ccw = g.orient_ccw(p, t)
    np.testing.assert_allclose(g.triangle_areas(p, ccw), np.abs(area), rtol=0, atol=0)
    np.testing.assert_array_equal(np.sort(ccw, axis=1), np.sort(t, axis=1))
    assert g.orient2d([0, 0], [1, 0], [2, 0]) == 0.0  # collinear


def test_triangle_areas_is_bit_for_bit_the_relaxation_areas():
    # mesh/relax.py's signed_areas has the same operation order (its relaxation test is bit for bit)
    from fluidem.mesh.relax import signed_areas

    rng = np.random.default_rng(3)
    p = rng.normal(size=(500, 2)) * 1e-3 + 7.0
    t = rng.integers(0, 500, (900, 3))
    np.testing.assert_array_equal(g.triangle_areas(p, t), signed_areas(p, t))


def test_barycentric_coordinates_reconstruct_points_and_classify_inside():
    rng = np.random.default_rng(4)
    corners = rng.uniform(-1, 1, (300, 3, 2))
    pts = rng.uniform(-1, 1, (300, 2))
    lam = g.barycentric(pts, corners[:, 0], corners[:, 1], corners[:, 2])
    assert lam.shape == (300, 3)
    np.testing.assert_allclose(lam.sum(axis=1), 1.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("nk,nkd->nd", lam, corners), pts, rtol=0, atol=1e-9)
    inside = shapely.contains_xy(shapely.polygons(corners), pts[:, 0], pts[:, 1])
    clear = np.abs(lam).min(axis=1) > 1e-9
    np.testing.assert_array_equal((lam.min(axis=1) > 0)[clear], inside[clear])
    # scikit-fem's component-first layout (2, n) gives the same numbers
    np.testing.assert_array_equal(g.barycentric(pts.T, *(corners[:, k].T for k in range(3)), axis=0), lam)
    # the corners themselves and the centroid
    tri = np.array([[1.0, 1.0], [4.0, 1.0], [1.0, 5.0]])
    np.testing.assert_allclose(g.barycentric(tri, *tri), np.eye(3), atol=1e-15)
    np.testing.assert_allclose(g.barycentric(tri.mean(axis=0), *tri), [1 / 3] * 3, atol=1e-15)


def test_padded_polygon_area_centroid_against_shapely_far_from_origin():
    rng = np.random.default_rng(5)
    V, counts, poses = _random_bodies(rng, 40)
    W = g.rigid_transform(V, poses) + 1e6  # far from the origin: taken about each first vertex
    area, cen = g.polygon_area_centroid(W)
    polys = [shapely.Polygon(W[b, :counts[b]]) for b in range(len(W))]
    np.testing.assert_allclose(area, [q.area for q in polys], rtol=1e-9)
    np.testing.assert_allclose(cen, [q.centroid.coords[0] for q in polys], rtol=0, atol=1e-9)
    # the batched polygon_area / polygon_centroid give the single-polygon values
    np.testing.assert_allclose(g.polygon_area(V), [g.polygon_area(V[b, :counts[b]]) for b in range(len(V))],
                               rtol=1e-12)
    np.testing.assert_allclose(g.polygon_centroid(V), np.zeros((len(V), 2)), atol=1e-12)
