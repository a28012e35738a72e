"""Field transfer at re-triangulation: interpolation and conservative L2 projection on a supermesh."""

import numpy as np
import pytest
from skfem import (Basis, ElementTriMini, ElementTriP1, ElementTriP1DG, ElementTriP2, ElementTriP2B, ElementVector,
                   Functional, MeshTri)

from fluidem.mesh.background import friedrichs_keller_grid
from fluidem.mesh.transfer import (interpolate, locate, locate_clustered, probe_matrix, project_l2, supermesh,
                                   values_at)
from fluidem.mesh.triangulate import to_skfem, triangulate_box


def f_scalar(x):
    return np.sin(np.pi * x[0]) * np.cos(np.pi * x[1]) + x[0] ** 2


def f_vector(x):
    return np.stack([f_scalar(x), np.cos(2 * x[0]) * x[1]])


def two_meshes(h):
    """A Friedrichs-Keller grid (old) and a Delaunay mesh (new) of the unit square."""
    p, t = friedrichs_keller_grid((0, 1, 0, 1), h)
    return MeshTri(p.T.copy(), t.T.copy()), to_skfem(triangulate_box((0, 1, 0, 1), (), size=0.9 * h))


def l2_error(mesh, elem, u, f):
    b = Basis(mesh, elem, intorder=10)
    if len(b._base_tensor_order):
        form = Functional(lambda w: ((w["u"] - f(w.x)) ** 2).sum(axis=0))
    else:
        form = Functional(lambda w: (w["u"] - f(w.x)) ** 2)
    return np.sqrt(form.assemble(b, u=b.interpolate(u)))


def integral(mesh, elem, u):
    b = Basis(mesh, elem, intorder=10)
    return Functional(lambda w: w["u"]).assemble(b, u=b.interpolate(u)) if not len(b._base_tensor_order) else \
        Functional(lambda w: w["u"][0] + w["u"][1]).assemble(b, u=b.interpolate(u))


PAIRS = [  # (element, field, expected order of the L2 error)
    (ElementVector(ElementTriP2B()), f_vector, 3),  # p2b velocity
    (ElementTriP1DG(), f_scalar, 2),  # p2b pressure
    (ElementVector(ElementTriP2()), f_vector, 3),  # Taylor-Hood velocity
    (ElementTriP1(), f_scalar, 2),  # Taylor-Hood / MINI pressure
    (ElementVector(ElementTriMini()), f_vector, 2),  # MINI velocity
]


@pytest.mark.parametrize("elem,f,order", PAIRS, ids=["p2b-u", "p2b-p", "th-u", "th-p", "mini-u"])
@pytest.mark.parametrize("method", ["interpolate", "project_l2"])
def test_transfer_error_converges_at_element_order(elem, f, order, method):
    transfer = {"interpolate": interpolate, "project_l2": project_l2}[method]
    errs = []
    for h in (0.125, 0.0625):
        m_old, m_new = two_meshes(h)
        b_old, b_new = Basis(m_old, elem), Basis(m_new, elem)
        u_old = b_old.project(f)
        u_new = transfer(b_old, u_old, b_new)
        errs.append(l2_error(m_new, elem, u_new, f))
    rate = np.log2(errs[0] / errs[1])
    assert rate > order - 0.35, (errs, rate)


@pytest.mark.parametrize("elem,f", [(ElementVector(ElementTriP2B()), f_vector), (ElementTriP1DG(), f_scalar)])
def test_l2_projection_conserves_the_integral(elem, f):
    m_old, m_new = two_meshes(0.125)
    b_old, b_new = Basis(m_old, elem), Basis(m_new, elem)
    u_old = b_old.project(f)
    i_old = integral(m_old, elem, u_old)
    assert integral(m_new, elem, project_l2(b_old, u_old, b_new)) == pytest.approx(i_old, abs=1e-12)
    # interpolation is not conservative (its defect is what the projection removes)
    assert abs(integral(m_new, elem, interpolate(b_old, u_old, b_new)) - i_old) > 1e-9


def test_supermesh_tiles_both_meshes():
    m_old, m_new = two_meshes(0.2)
    sm, ia, ib = supermesh(m_old, m_new)
    def area(m):
        d1, d2 = m.p[:, m.t[1]] - m.p[:, m.t[0]], m.p[:, m.t[2]] - m.p[:, m.t[0]]
        return 0.5 * np.abs(d1[0] * d2[1] - d1[1] * d2[0])

    a = area(sm)
    assert a.sum() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(np.bincount(ia, a, m_old.nelements), area(m_old), atol=1e-12)
    np.testing.assert_allclose(np.bincount(ib, a, m_new.nelements), area(m_new), atol=1e-12)


def test_transfer_across_a_moving_mesh_retriangulation():
    from fluidem.geometry import regular_polygon
    from fluidem.mesh import MovingMesh

    bodies = [regular_polygon(0.2, 6), regular_polygon(0.15, 5), regular_polygon(0.2, 4)]
    poses = np.array([[0.4, 0.4, 0.0], [0.8, 0.45, 0.2], [0.45, 0.85, 0.1]])  # no contacts
    mm = MovingMesh((0, 1.2, 0, 1.2), bodies, poses, h=0.05, retriangulate_every=1)
    ev = mm.update(poses + [0.01, 0.0, 0.02])
    assert ev.retriangulated and len(ev.contacts) == 0
    old = MeshTri(ev.old_points.T.copy(), ev.old_triangles.T.copy())
    new = mm.skfem_mesh()
    elem = ElementVector(ElementTriP2B())
    b_old, b_new = Basis(old, elem), Basis(new, elem)
    u_old = b_old.project(f_vector)
    u_int = interpolate(b_old, u_old, b_new)
    u_prj = project_l2(b_old, u_old, b_new)
    e_old = l2_error(old, elem, u_old, f_vector)
    e_best = l2_error(new, elem, b_new.project(f_vector), f_vector)
    # L2 projection is a contraction on the common domain: error <= e_old + e_best (a theorem)
    assert l2_error(new, elem, u_prj, f_vector) <= (e_old + e_best) * (1 + 1e-9)
    # interpolation has no such bound; it stays within a small multiple of it
    assert l2_error(new, elem, u_int, f_vector) < 3 * (e_old + e_best)


def test_locate_near_finds_what_locate_finds():
    """Points near a vertex (hint) get the cell and coordinates :func:`locate` gives them; points
    without a hint or outside the hint's star fall back to it."""
    from fluidem.mesh.transfer import locate, locate_near

    old, _ = two_meshes(0.1)
    rng = np.random.default_rng(3)
    n_v = old.p.shape[1]
    hint = rng.integers(0, n_v, 300)
    x = np.clip(old.p[:, hint] + rng.normal(0, 0.02, (2, 300)), 0, 1)  # mostly inside the star
    x[:, :20] = rng.random((2, 20))  # far from their hint
    hint[20:40] = -1
    c0, b0 = locate(old, x)
    c1, b1 = locate_near(old, x, hint)
    pos0 = np.einsum("nk,knd->nd", b0, old.p.T[old.t[:, c0]])
    pos1 = np.einsum("nk,knd->nd", b1, old.p.T[old.t[:, c1]])
    assert np.abs(pos1 - x.T).max() < 1e-14 and np.abs(pos0 - x.T).max() < 1e-14  # measured 1.1e-16
    # the same cells (but where a point lies on an edge shared by two) with the same coordinates
    same = c0 == c1
    assert same.mean() >= 0.99 and np.array_equal(b0[same], b1[same])  # measured: all 300 the same


@pytest.mark.parametrize("elem", [ElementTriP2B(), ElementVector(ElementTriP2B()), ElementVector(ElementTriMini())])
def test_values_at_points_are_those_of_the_probe_matrix(elem):
    """``values_at`` (the scalar basis summed per component, no matrix) gives what ``probe_matrix(basis, x) @ u``
    gives, for one field and two at once, scalar and vector (skfem's interleaved component order), at points
    inside and just outside the mesh: measured 1.4e-16 of the largest value apart at most (summation order)."""
    old, _ = two_meshes(0.1)
    b = Basis(old, elem)
    rng = np.random.default_rng(3)
    u = rng.standard_normal((b.N, 2))
    x = np.vstack([rng.uniform(-0.01, 1.01, 500), rng.uniform(0.0, 1.0, 500)])
    comp = 2 if isinstance(elem, ElementVector) else 1
    ref = (probe_matrix(b, x) @ u).reshape(comp, 500, 2)
    both, one = values_at(b, u, x), values_at(b, u[:, 1], x)
    assert both.shape == (comp, 500, 2) and one.shape == (comp, 500)
    scale = np.abs(ref).max()
    assert np.abs(both - ref).max() <= 4e-16 * scale                                   # measured 1.4e-16
    assert np.abs(one - ref[..., 1]).max() <= 4e-16 * scale


def test_points_located_by_cluster_are_located_as_one_by_one():
    """``locate_clustered`` (each cluster's nearest cells tried by all its points) gives the cells and barycentric
    coordinates ``locate`` gives, bit for bit: the quadrature points of a Delaunay mesh (16 an element) in a
    Friedrichs–Keller grid, and the same points shifted by 0.02 so that clusters at the sides lie partly
    outside (those points go to ``locate``, clamped onto the nearest cell)."""
    old, new = two_meshes(0.05)
    x = np.asarray(Basis(new, ElementTriP2B(), intorder=8).global_coordinates())  # (2, n_elements, 16)
    for shift in (0.0, 0.02):
        pts = x + shift
        cells, bary = locate_clustered(old, pts, chunk=1000)  # several chunks
        ref_cells, ref_bary = locate(old, pts.reshape(2, -1))
        assert np.array_equal(cells, ref_cells) and np.array_equal(bary, ref_bary)
    outside = (x + 0.02).reshape(2, -1).max(axis=0) > 1.0
    assert outside.sum() > 100                                                         # points outside the mesh

