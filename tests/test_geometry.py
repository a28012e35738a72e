import numpy as np
import pytest

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
