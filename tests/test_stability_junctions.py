"""Cross-flow at junctions (paper Sec. 3.2, Fig. 4): the flux split at a junction between four
bodies, channels one element wide, with and without a junction node, against a fine body-fitted
mesh of the same fluid (:mod:`fluidem.cases.junction_split`; the full table is
``benchmarks/results/stability_junctions.md``).

The reference here is the body-fitted mesh at h = gap/4 (0.2 s); it differs from the benchmark's
gap/16 one by at most 4e-4 of the inflow (P2-bubble, both angles), well below every bound below.
"""

import numpy as np
import pytest

from fluidem.cases.junction_split import (flux_split, junction_case, junction_geometry, junction_mesh,
                                          reference_mesh)
from fluidem.errors import InputError

GAP = 0.1


@pytest.fixture(scope="module")
def references():
    out = {}
    for angle, element in ((90.0, "p2b"), (90.0, "th"), (45.0, "p2b")):
        geo = junction_geometry(angle, GAP)
        out[angle, element] = flux_split(reference_mesh(geo, GAP / 4), geo, element)
    return out


def test_the_reference_conserves_the_inflow_and_splits_it_three_ways(references):
    ref = references[90.0, "p2b"]
    # Poiseuille inflow of unit centre speed: Q = 2/3 · gap exactly (P2 holds the parabola)
    assert abs(ref["inflow"] - 2 * GAP / 3) < 1e-12
    assert ref["mass_defect"] < 1e-10  # measured 2e-16: P1dc pressure, element-wise mass conservation
    # measured right 0.358, top 0.335, bottom 0.307 (the junction sits 0.021 above the box centre: the top
    # branch is shorter than the bottom one); the benchmark's gap/16 reference differs by 1e-4
    np.testing.assert_allclose(ref["split"], [0.358, 0.335, 0.307], atol=2e-3)


def test_the_mesh_inserts_no_junction_point_at_a_four_body_junction():
    """Two junction triangles of 45-45-90° (90°) or 45-67.5-67.5° (45°): a point inside a triangle
    halves one of its angles at least, so no split keeps the [25°, 125°] screen of
    :func:`fluidem.mesh.junctions.junction_points`, and junctions=True gives the mesh of junctions=False."""
    for angle in (90.0, 45.0):
        geo = junction_geometry(angle, GAP)
        for h in (0.15, 0.1):
            on, n_on = junction_mesh(geo, h, "library")
            off, _ = junction_mesh(geo, h, "off")
            assert n_on == 0  # measured 0 in every row of the benchmark
            assert np.array_equal(on.t, off.t) and np.array_equal(on.p, off.p)


def test_a_one_element_junction_sends_too_much_straight_on_with_p2_bubble(references):
    """P2-bubble/P1dc, 90°, h = gap: 8 % of the inflow goes straight on instead of turning."""
    r = junction_case(90.0, 0.1, "off", reference=references[90.0, "p2b"])
    assert r["n_points"] == 0
    assert r["split"][0] - references[90.0, "p2b"]["split"][0] > 0.04  # measured +0.080
    assert 0.04 < r["error"] < 0.16  # measured 0.080
    # two elements across the gap (h = gap/2): the junction has a free node, the error falls 30x
    fine = junction_case(90.0, 0.05, "off", reference=references[90.0, "p2b"])
    assert fine["error"] < 0.006  # measured 0.0022


def test_a_centre_node_in_the_junction_restores_the_split(references):
    """The same junction with one node at the crossing of the diagonals of its two junction
    triangles (four triangles around it): the error falls 13x at a 10 % rise of κ₁."""
    ref = references[90.0, "p2b"]
    off = junction_case(90.0, 0.1, "off", reference=ref)
    centre = junction_case(90.0, 0.1, "centre", reference=ref)
    assert centre["n_points"] == 1
    assert centre["error"] < 0.015  # measured 0.0060
    assert off["error"] / centre["error"] > 5  # measured 13.3
    assert centre["condition"] / off["condition"] < 1.5  # measured 1.11 (4.83e6 against 4.36e6)


def test_the_unscreened_voronoi_point_does_not_help_and_doubles_the_condition(references):
    """The paper's point inside one junction triangle (Voronoi vertex, else incentre or centroid)
    without the angle screen: one point in each of the two triangles, split error unchanged (90°:
    0.083 against 0.080; 45°: 0.0102 against 0.0102), κ₁ 2.2x (90°) and 1.6x (45°)."""
    for angle, bound in ((90.0, 0.04), (45.0, 0.005)):
        ref = references[angle, "p2b"]
        off = junction_case(angle, 0.1, "off", reference=ref)
        vor = junction_case(angle, 0.1, "voronoi", reference=ref)
        assert vor["n_points"] >= 1  # measured 2 (90°), 1 (45°)
        assert vor["error"] > 0.9 * off["error"] > bound  # measured 0.083 / 0.080 (90°), 0.0102 / 0.0102 (45°)
        assert vor["condition"] / off["condition"] > 1.3  # measured 2.2 (90°), 1.6 (45°)


def test_p2_p1_splits_a_one_element_junction_without_a_node(references):
    """Taylor–Hood (continuous P1 pressure) on the same 90° mesh: the split error without a node is
    0.0018, 44x below P2-bubble's; the junction is a P2-bubble/P1dc matter here."""
    r = junction_case(90.0, 0.1, "off", "th", reference=references[90.0, "th"])
    assert r["error"] < 0.006  # measured 0.0018


def test_bad_geometry_names_the_value():
    with pytest.raises(InputError, match=r"angle=\.\.\.\) = 10.*\[30, 90\]"):
        junction_geometry(10.0)
    with pytest.raises(InputError, match="junction variant 'middle'"):
        junction_mesh(junction_geometry(), 0.1, "middle")
