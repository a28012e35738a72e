"""Point–polygon queries of :mod:`fluidem.mesh.proximity`, checked against shapely (GEOS)."""

from __future__ import annotations

import doctest

import numpy as np
import pytest
import shapely

from fluidem.mesh import proximity
from fluidem.mesh.proximity import PolygonTable


def _star_polygons(rng, n, box=10.0):
    """Random simple star-shaped polygons (non-convex in general), 3–9 vertices, CCW."""
    verts, counts, polys = [], [], []
    while len(polys) < n:
        m = int(rng.integers(3, 10))
        ang = np.sort(rng.uniform(0.0, 2 * np.pi, m))
        rad = rng.uniform(0.3, 1.0, m)
        v = rng.uniform(0.0, box, 2) + np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
        pg = shapely.Polygon(v)
        if not pg.is_valid or pg.area < 1e-3:
            continue
        verts.append(v)
        counts.append(m)
        polys.append(pg)
    return np.vstack(verts), np.array(counts), np.array(polys, dtype=object)


@pytest.fixture(scope="module")
def setup():
    rng = np.random.default_rng(3)
    verts, counts, polys = _star_polygons(rng, 60)
    pts = rng.uniform(-1.0, 11.0, (30000, 2))
    return PolygonTable(verts, counts), polys, pts, rng


def test_distance_to_outline_and_to_solid_match_shapely(setup):
    tab, polys, pts, rng = setup
    body = rng.integers(0, len(polys), len(pts))
    sp = shapely.points(pts)
    d_outline = tab.distance(pts, body)
    d_solid = tab.distance(pts, body, solid=True)
    assert np.allclose(d_outline, shapely.distance(shapely.boundary(polys[body]), sp), rtol=0, atol=1e-12)
    assert np.allclose(d_solid, shapely.distance(polys[body], sp), rtol=0, atol=1e-12)
    # the inside test agrees with GEOS on every point (none lies on an outline here)
    inside = shapely.contains(polys[body], sp)
    assert inside.any() and (~inside).any()
    assert np.array_equal(d_solid == 0.0, inside)


def test_pairs_within_finds_exactly_the_pairs_geos_finds(setup):
    tab, polys, pts, rng = setup
    radius = rng.uniform(0.0, 0.6, len(pts))
    pi, bi, d = tab.pairs_within(pts, radius, solid=True)
    assert np.all(np.diff(pi) >= 0)  # sorted by point
    sp = shapely.points(pts)
    a, b = shapely.STRtree(polys).query(sp, predicate="dwithin", distance=radius)
    dref = shapely.distance(polys[b], sp[a])
    keep = dref < radius[a]
    assert set(zip(pi.tolist(), bi.tolist())) == set(zip(a[keep].tolist(), b[keep].tolist()))
    assert np.allclose(d, shapely.distance(polys[bi], sp[pi]), rtol=0, atol=1e-12)
    # scalar radius and outline distance
    pi2, bi2, d2 = tab.pairs_within(pts, 0.25)
    ref = shapely.distance(shapely.boundary(polys[bi2]), sp[pi2])
    assert np.allclose(d2, ref, rtol=0, atol=1e-12) and (d2 < 0.25).all()


def test_mixed_vertex_counts_match_shapely():
    """Disks (64-gons) among triangles: the pairs are sorted by vertex count internally."""
    rng = np.random.default_rng(5)
    verts, counts, polys = [], [], []
    for i in range(40):
        m = 64 if i % 10 == 0 else 3
        ang = np.sort(rng.uniform(0, 2 * np.pi, m)) if m == 3 else np.linspace(0, 2 * np.pi, m, endpoint=False)
        v = rng.uniform(0, 10, 2) + 0.6 * np.column_stack([np.cos(ang), np.sin(ang)])
        verts.append(v)
        counts.append(m)
        polys.append(shapely.Polygon(v))
    tab = PolygonTable(np.vstack(verts), counts)
    polys = np.array(polys, dtype=object)
    pts = rng.uniform(-1, 11, (20000, 2))
    body = rng.integers(0, len(polys), len(pts))
    sp = shapely.points(pts)
    assert np.allclose(tab.distance(pts, body), shapely.distance(shapely.boundary(polys[body]), sp), atol=1e-12)
    assert np.allclose(tab.distance(pts, body, solid=True), shapely.distance(polys[body], sp), atol=1e-12)


def test_far_points_and_empty_inputs_give_no_pairs(setup):
    tab, _, _, _ = setup
    far = np.array([[100.0, 100.0], [-50.0, 3.0]])
    pi, bi, d = tab.pairs_within(far, 1.0)
    assert len(pi) == len(bi) == len(d) == 0
    pi, bi, d = tab.pairs_within(np.zeros((0, 2)), 1.0)
    assert len(pi) == 0
    assert len(tab.distance(np.zeros((0, 2)), np.zeros(0, dtype=int))) == 0


def test_one_polygon_spanning_the_grid():
    # a single large polygon: the grid has one cell; every point is a candidate
    sq = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    tab = PolygonTable(sq, [4])
    pts = np.array([[2.0, 2.0], [4.5, 2.0], [5.5, 2.0], [2.0, -0.2]])
    pi, _, d = tab.pairs_within(pts, 1.0, solid=True)
    assert pi.tolist() == [0, 1, 3]
    assert np.allclose(d, [0.0, 0.5, 0.2])


@pytest.mark.parametrize("verts,counts", [
    (np.zeros((4, 3)), [4]),
    (np.zeros((4, 2)), [5]),
    (np.zeros((2, 2)), [2]),
])
def test_bad_input_is_named(verts, counts):
    with pytest.raises(ValueError, match="counts"):
        PolygonTable(verts, counts)


def test_docstring_examples_run():
    assert doctest.testmod(proximity).failed == 0
