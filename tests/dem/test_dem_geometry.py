"""Bodies, overlap geometry and broad phase of the DEM against independent computations."""

import subprocess
import sys

import numpy as np
import pytest
import shapely

from fluidem.dem import Body, ContactModel, DEM
from fluidem.dem.contact import grid_pairs, polygon_overlaps, wall_overlaps
from fluidem.dem.system import _pad_vertices


def test_mass_and_inertia_of_rectangle_and_disk():
    b = Body.rectangle(0.3, 0.1, density=7.0, position=(1.0, 2.0))
    assert b.mass == pytest.approx(7.0 * 0.03)
    # rectangle about its centre: m (w² + h²) / 12
    assert b.inertia == pytest.approx(b.mass * (0.09 + 0.01) / 12.0)
    np.testing.assert_allclose(b.vertices.mean(axis=0), 0.0, atol=1e-15)
    d = Body.disk(0.5, segments=1000, density=2.0)
    assert d.mass == pytest.approx(2.0 * np.pi * 0.25, rel=1e-5)
    assert d.inertia == pytest.approx(0.5 * d.mass * 0.25, rel=1e-5)


def test_off_centre_outline_is_recentred():
    """Vertices far from the origin: inertia is about the centroid (parallel axis theorem)."""
    v = np.array([[10.0, 10.0], [12.0, 10.0], [12.0, 11.0], [10.0, 11.0]])
    b = Body.polygon(v, density=1.0)
    assert b.inertia == pytest.approx(2.0 * (4.0 + 1.0) / 12.0)
    np.testing.assert_allclose(b.vertices.mean(axis=0), 0.0, atol=1e-12)


def _random_pairs(rng, n):
    bodies = []
    for _ in range(2 * n):
        bodies.append(Body.random_convex(1.0, int(rng.integers(3, 9)), rng.uniform(1, 2), rng=rng,
                                         position=rng.uniform(-0.6, 0.6, 2)))
    return bodies


def test_overlap_area_centroid_and_crossings_match_shapely():
    rng = np.random.default_rng(3)
    bodies = _random_pairs(rng, 300)
    V, nv = _pad_vertices(bodies)
    pos = np.array([b.position for b in bodies])
    W = V + pos[:, None, :]
    i = np.arange(0, 600, 2)
    j = i + 1
    ov = polygon_overlaps(W, nv, pos, i, j)
    polys = np.array([shapely.Polygon(W[k, : nv[k]]) for k in range(len(bodies))])
    inter = shapely.intersection(polys[i], polys[j])
    area = shapely.area(inter)
    hit = area > 1e-12
    assert np.array_equal(np.sort(ov["i"]), i[hit])
    k = np.searchsorted(i, ov["i"])
    np.testing.assert_allclose(ov["area"], area[k], rtol=1e-10)
    cen = shapely.get_coordinates(shapely.centroid(inter[k]))
    np.testing.assert_allclose(ov["centroid"], cen, atol=1e-10)
    # the two crossing points lie on both outlines
    for p in ("p1", "p2"):
        pts = shapely.points(ov[p])
        d1 = shapely.distance(shapely.boundary(polys[ov["i"]]), pts)
        d2 = shapely.distance(shapely.boundary(polys[ov["j"]]), pts)
        assert np.max(d1) < 1e-10 and np.max(d2) < 1e-10


def test_wall_overlap_of_tilted_square():
    b = Body.rectangle(1.0, 1.0, angle=np.pi / 4, position=(0.0, 0.6))
    V, nv = _pad_vertices([b])
    pos = b.position[None, :]
    W = V @ np.array([[np.cos(np.pi / 4), np.sin(np.pi / 4)], [-np.sin(np.pi / 4), np.cos(np.pi / 4)]]) + pos
    ov = wall_overlaps(W, nv, pos, W.min(axis=1), W.max(axis=1), (-5, 5, 0, 5), np.array([0]))
    depth = np.sqrt(0.5) - 0.6
    assert ov["j"][0] == -3
    assert ov["area"][0] == pytest.approx(depth**2)          # right-angled corner: A = δ²
    np.testing.assert_allclose(ov["centroid"][0], [0.0, -depth / 3], atol=1e-14)
    np.testing.assert_allclose(sorted([ov["p1"][0, 0], ov["p2"][0, 0]]), [-depth, depth], atol=1e-14)


def test_grid_broad_phase_finds_every_close_pair():
    rng = np.random.default_rng(0)
    n = 3000
    c = rng.uniform(0, 30, (n, 2))
    r = rng.uniform(0.2, 0.5, n)
    r[:3] = [4.0, 6.0, 3.0]                      # large bodies take the brute-force path
    movable = np.ones(n, bool)
    i, j = grid_pairs(c, r, 2 * 0.5 + 0.1, movable, skin=0.1)
    d = np.sqrt(((c[:, None] - c[None]) ** 2).sum(-1))
    ii, jj = np.nonzero(np.triu(d < (r[:, None] + r[None] + 0.1), 1))
    assert set(zip(i.tolist(), j.tolist())) == set(zip(ii.tolist(), jj.tolist()))


def test_dry_scene_builds_no_mesh_and_no_fluid():
    code = ("import sys\nfrom fluidem.dem import Body, DEM\n"
            "s = DEM([Body.disk(0.01, 8, density=1.0, position=(0, 0.02))], walls=(-1, 1, 0, 1))\n"
            "s.step(s.dt_max)\n"
            "bad = [m for m in sys.modules if m.startswith(('fluidem.fluid', 'fluidem.mesh', 'skfem', 'triangle'))]\n"
            "assert not bad, bad\n")
    subprocess.run([sys.executable, "-c", code], check=True)


# ---- bad input ------------------------------------------------------------------------------
def test_bad_polygons_and_density_raise():
    with pytest.raises(ValueError, match="clockwise"):
        Body.polygon([[0, 0], [0, 1], [1, 1], [1, 0]])
    with pytest.raises(ValueError, match="not convex"):
        Body.polygon([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]])
    for rho in (0.0, -3.0):
        with pytest.raises(ValueError, match=rf"Body\(density=\.\.\.\) = {rho}: expected a positive finite number"):
            Body.disk(1.0, 6, density=rho)
    with pytest.raises(ValueError,
                       match=r"Body\(motion=\.\.\.\) = 'wobbly': expected one of 'free', 'fixed', 'prescribed'"):
        Body.disk(1.0, 6, motion="wobbly")


def test_overlap_at_start_names_bodies():
    a = Body.disk(1.0, 8, position=(0, 0))
    b = Body.disk(1.0, 8, position=(1.0, 0))
    with pytest.raises(ValueError, match=r"body 0 and body 1 overlap at start by .* allowed"):
        DEM([a, b], gravity=(0, 0))
    c = Body.disk(1.0, 8, position=(0, 0.5))
    with pytest.raises(ValueError, match=r"body 0 and wall -3 \(ymin\)"):
        DEM([c], walls=(-5, 5, 0, 5))


def test_time_step_above_bound_names_lightest_body():
    bodies = [Body.disk(0.01, 6, density=1.0, position=(0, 0)),
              Body.disk(0.005, 6, density=1.0, position=(0.1, 0))]
    sim = DEM(bodies, contact=ContactModel(E=1e5))
    m = bodies[1].mass
    assert sim.dt_max == pytest.approx(0.1 * np.pi * np.sqrt(m / 1e5))
    with pytest.raises(ValueError, match=r"exceeds the stability bound .* body 1 \(mass"):
        sim.step(1.01 * sim.dt_max)
    n = sim.advance(10.5 * sim.dt_max)            # automatic sub-stepping instead
    assert n == 11


def test_bad_model_parameters_raise():
    with pytest.raises(ValueError, match=r"ContactModel\(E=\.\.\.\) = 0\.0: expected a positive finite number"):
        ContactModel(E=0.0)
    with pytest.raises(ValueError, match=r"ContactModel\(mu=\.\.\.\) = -0\.1: expected a finite number >= 0"):
        ContactModel(mu=-0.1)


@pytest.mark.parametrize("make,message", [
    (lambda: Body.disk(1.0, 6, position=(0.0, np.nan)), r"Body\(position=\.\.\.\) = \(0\.0, nan\): expected a pair"),
    (lambda: Body.disk(1.0, 6, angle="up"), r"Body\(angle=\.\.\.\) = 'up': expected a finite number"),
    (lambda: Body.disk(1.0, 6, motion="prescribed"), r"Body\(path=\.\.\.\) = None: expected a callable"),
    (lambda: Body.random_convex(0.01, 2), r"random_convex_vertices\(n_vertices=\.\.\.\) = 2: expected an integer >= 3"),
    (lambda: Body.random_convex(0.01, 5, jitter=1.0),
     r"random_convex_vertices\(jitter=\.\.\.\) = 1\.0: expected a number in \[0, 1\)"),
    (lambda: ContactModel(gamma_t=-1.0), r"ContactModel\(gamma_t=\.\.\.\) = -1\.0: expected a finite number >= 0"),
    (lambda: DEM([Body.disk(1.0, 6)], gravity=(0.0,)), r"DEM\(gravity=\.\.\.\) = \(0\.0,\): expected a pair"),
    (lambda: DEM([Body.disk(1.0, 6)], walls=(1, -1, 0, 1)), r"DEM\(walls=\.\.\.\) = \(1, -1, 0, 1\): expected \(xmin"),
    (lambda: DEM([Body.disk(1.0, 6)], order=7), r"DEM\(order=\.\.\.\) = 7: expected one of 2, 3, 4, 5"),
    (lambda: DEM([Body.disk(1.0, 6), "disk"]),
     r"DEM\(bodies=\.\.\.\)\[1\] = <str object>: expected a fluidem\.dem\.Body"),
    (lambda: DEM([]), r"DEM\(bodies=\.\.\.\) = \[\]: expected at least one"),
    (lambda: DEM([Body.disk(1.0, 6)]).step(0.0), r"DEM\.step\(dt=\.\.\.\) = 0\.0: expected a positive finite number"),
    (lambda: DEM([Body.disk(1.0, 6)]).run(1.0, 1e-3, every=0),
     r"DEM\.run\(every=\.\.\.\) = 0: expected an integer >= 1"),
])
def test_bad_arguments_name_parameter_and_value(make, message):
    from fluidem.errors import InputError

    with pytest.raises(InputError, match=message):
        make()
