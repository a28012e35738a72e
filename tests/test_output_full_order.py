"""Full-order field output: the VTU files carry the computed finite element solution, read back with meshio."""

import sys

import meshio
import numpy as np
import pytest
from skfem import MeshTri

from fluidem import Scene, Simulation
from fluidem.fluid.space import FlowSpace
from fluidem.cases.scenes import example_scene
from fluidem.errors import InputError
from tiny_scene import tiny_channel
from fluidem.io import OutputWriter, field_series, fluid_point_data, full_order_fields, read_fields, write_xdmf



def _tiny(element, full, xdmf):
    return tiny_channel(h=0.05, element=element, density=2.0, output=f"every = 1\nfull_order = {full}\nxdmf = {xdmf}")



def _mesh():
    # a mix of triangle orientations and edge directions: a tensor mesh, its nodes shuffled
    m = MeshTri.init_tensor(np.linspace(0, 1, 5), np.linspace(0, 2, 6))
    perm = np.random.default_rng(1).permutation(m.p.shape[1])
    inv = np.argsort(perm)
    return MeshTri(m.p[:, perm], inv[m.t])


def _cross(a, b):
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def _written(tmp_path, space, x):
    w = OutputWriter(tmp_path)
    path = w.fields_full(0, 0.0, *full_order_fields(space, x, rho=1.0))
    w.close()
    return meshio.read(path)


def _interpolated(space, f, g):
    x = np.zeros(space.n_dofs)
    x[:space.n_u] = space.ub.project(lambda X: np.array(f(X[0], X[1])))
    x[space.n_u:] = space.pb.project(lambda X: g(X[0], X[1]))
    return x


def test_p2_velocity_is_exact_at_the_midpoints_of_the_written_triangle6_cells(tmp_path):
    space = FlowSpace(_mesh(), "th")

    def f(x, y):
        return 1 + x ** 2 - 2 * x * y + 0.5 * y ** 2, x * y - y ** 2 + 3 * x

    def g(x, y):
        return x - 2 * y

    m = _written(tmp_path, space, _interpolated(space, f, g))
    (block,) = m.cells
    assert block.type == "triangle6" and block.data.shape == (space.mesh.t.shape[1], 6)
    P = m.points[:, :2]
    c = block.data
    for k, (i, j) in enumerate([(0, 1), (1, 2), (2, 0)]):  # VTK order: midpoints of edges 01, 12, 20
        np.testing.assert_allclose(P[c[:, 3 + k]], 0.5 * (P[c[:, i]] + P[c[:, j]]), atol=1e-14)
    mid = np.unique(c[:, 3:])
    ux, uy = f(P[mid, 0], P[mid, 1])
    u = m.point_data["velocity"]
    assert np.abs(u[mid, 0] - ux).max() < 1e-12 and np.abs(u[mid, 1] - uy).max() < 1e-12  # measured 1.8e-15
    assert np.abs(m.point_data["pressure"] - g(P[:, 0], P[:, 1])).max() < 1e-12  # P1 pressure; measured 1.8e-15
    # every cell counter-clockwise, and the cells tile the domain (area 2)
    a = _cross(P[c[:, 1]] - P[c[:, 0]], P[c[:, 2]] - P[c[:, 0]])
    assert a.min() > 0 and abs(a.sum() / 2 - 2.0) < 1e-12
    assert len(P) == space.mesh.nvertices + space.mesh.facets.shape[1]  # each midpoint written once


def test_p3_cubic_is_exact_at_the_nodes_of_the_refined_mesh(tmp_path):
    space = FlowSpace(_mesh(), "p3")

    def f(x, y):
        return x ** 3 - x * y * y + 1, y ** 3 + x ** 2 * y - 2 * x

    def g(x, y):  # P2 pressure
        return x * x - x * y + 3 * y

    m = _written(tmp_path, space, _interpolated(space, f, g))
    (block,) = m.cells
    n_tri = space.mesh.t.shape[1]
    assert block.type == "triangle" and block.data.shape == (9 * n_tri, 3)
    assert np.array_equal(np.bincount(m.cell_data["element"][0].astype(int)), np.full(n_tri, 9))
    P = m.points[:, :2]
    assert len(P) == space.mesh.nvertices + 2 * space.mesh.facets.shape[1] + n_tri  # shared points once
    ux, uy = f(P[:, 0], P[:, 1])
    u = m.point_data["velocity"]
    assert np.abs(u[:, 0] - ux).max() < 1e-12 and np.abs(u[:, 1] - uy).max() < 1e-12  # measured 8.9e-15
    assert np.abs(m.point_data["kinematic_pressure"] - g(P[:, 0], P[:, 1])).max() < 1e-12  # measured 4.0e-15
    c = block.data
    a = _cross(P[c[:, 1]] - P[c[:, 0]], P[c[:, 2]] - P[c[:, 0]])
    assert a.min() > 0 and abs(a.sum() / 2 - 2.0) < 1e-12


@pytest.mark.parametrize("element", ["p2b", "mini"])
def test_bubble_fields_agree_with_the_vertex_output_at_the_vertices(tmp_path, element):
    """At the mesh vertices the full-order output has the vertex output's values; inside the
    triangles it has the bubble's contribution, which the vertex output misses."""
    space = FlowSpace(_mesh(), element)
    x = np.random.default_rng(2).standard_normal(space.n_dofs)
    if element == "mini":
        x[space.n_u:] = 0.0  # continuous P1 pressure: no averaging involved
    m = _written(tmp_path, space, x)
    vtx = fluid_point_data(space, x)
    P = m.points[:, :2]
    key = {tuple(np.round(q, 12)): k for k, q in enumerate(P)}
    idx = np.array([key[tuple(np.round(q, 12))] for q in space.mesh.p.T])
    np.testing.assert_allclose(m.point_data["velocity"][idx], vtx["velocity"], atol=1e-13)
    np.testing.assert_allclose(m.point_data["pressure"][idx], vtx["pressure"], atol=1e-13)
    inner = np.setdiff1d(np.arange(len(P)), idx)
    assert np.abs(m.point_data["velocity"][inner]).max() > 0.1  # the bubbles are there


def test_a_run_writes_the_full_order_series_and_read_fields_reads_it(tmp_path):
    out = tmp_path / "o"
    (tmp_path / "s.toml").write_text(_tiny("th", "true", "false"))
    Simulation(Scene.from_toml(tmp_path / "s.toml")).run(out_dir=out)
    series = field_series(out)
    assert [s for s, _, _ in series] == [0, 1, 2] and all(p.parent.name == "fields_full" for _, _, p in series)
    m = read_fields(out)
    assert m.field_data["t"][0] == pytest.approx(0.2) and "triangle6" in m.cells_dict
    P, u = m.points[:, :2], m.point_data["velocity"]
    # curved cells: the nodes on the cylinder (midpoints too) lie on the circle and carry no-slip
    on = np.abs(np.hypot(P[:, 0] - 0.3, P[:, 1] - 0.2) - 0.05) < 1e-9
    assert on.sum() > 2 * 6 and np.abs(u[on]).max() < 1e-12
    # the inflow is the parabola at every written node of the left side (midpoints too)
    left = P[:, 0] < 1e-12
    np.testing.assert_allclose(u[left, 0], 0.3 * 4 * P[left, 1] * (0.4 - P[left, 1]) / 0.4 ** 2, atol=1e-12)
    np.testing.assert_allclose(m.point_data["pressure"], 2.0 * m.point_data["kinematic_pressure"], rtol=1e-15)
    assert read_fields(out, step=1, full=False).cells[0].type == "triangle"
    with pytest.raises(ValueError, match="step = 7: expected one of the output steps 0, 1, 2"):
        read_fields(out, step=7)


def test_full_order_false_writes_only_the_vertex_series(tmp_path):
    out = tmp_path / "o"
    (tmp_path / "s.toml").write_text(_tiny("p2b", "false", "false"))
    Simulation(Scene.from_toml(tmp_path / "s.toml")).run(out_dir=out)
    assert not (out / "fields_full.pvd").exists() and (out / "fields.pvd").exists()
    assert field_series(out)[-1][2].parent.name == "fields"


def test_xdmf_time_series_holds_every_output_step_of_a_fixed_mesh_run(tmp_path, monkeypatch):
    pytest.importorskip("h5py")
    out = tmp_path / "o"
    (tmp_path / "s.toml").write_text(_tiny("p3", "true", "true"))
    monkeypatch.chdir(tmp_path)  # the HDF5 file goes beside the XDMF file, not into the working directory
    Simulation(Scene.from_toml(tmp_path / "s.toml")).run(out_dir=out)
    assert (out / "fields_full.xdmf").exists() and (out / "fields_full.h5").exists()
    assert not (tmp_path / "fields_full.h5").exists()
    series = field_series(out)
    with meshio.xdmf.TimeSeriesReader(out / "fields_full.xdmf") as r:
        points, cells = r.read_points_cells()
        assert r.num_steps == len(series) == 3
        for k, (_, t, path) in enumerate(series):
            tk, pd, _ = r.read_data(k)
            vtu = meshio.read(path)
            assert tk == t and np.array_equal(points, vtu.points) and np.array_equal(cells[0].data, vtu.cells[0].data)
            for name in ("velocity", "speed", "pressure", "kinematic_pressure"):
                assert np.array_equal(pd[name], vtu.point_data[name])  # the same numbers, bit for bit


def test_xdmf_is_refused_for_a_moving_mesh_and_without_h5py(tmp_path, monkeypatch):
    d = example_scene("settling-disk").to_dict()
    d["output"]["xdmf"] = True
    with pytest.raises(InputError, match="output.xdmf = true: an XDMF time series holds one mesh, and this "
                                         "scene's mesh moves"):
        Simulation(Scene.from_dict(d)).run(out_dir=tmp_path / "moving")
    assert not (tmp_path / "moving" / "history.csv").exists()  # refused before anything was written
    monkeypatch.setitem(sys.modules, "h5py", None)
    (tmp_path / "s.toml").write_text(_tiny("th", "true", "true"))
    with pytest.raises(InputError, match=r'^output.xdmf = true needs h5py: pip install "fluidem\[xdmf\]" \(in an '
                                         r'editable checkout: pip install -e "\.\[xdmf\]"\)$'):
        Simulation(Scene.from_toml(tmp_path / "s.toml")).run(out_dir=tmp_path / "o")
    assert not (tmp_path / "o").exists()


def test_write_xdmf_refuses_a_series_whose_mesh_changes(tmp_path):
    pytest.importorskip("h5py")
    w = OutputWriter(tmp_path)
    for step, n in enumerate((3, 4)):
        space = FlowSpace(MeshTri.init_tensor(np.linspace(0, 1, n), np.linspace(0, 1, n)), "th")
        w.fields_full(step, 0.1 * step, *full_order_fields(space, np.zeros(space.n_dofs)))
    w.close()
    with pytest.raises(InputError, match="fields_full: the mesh changes at step 1"):
        write_xdmf(tmp_path)
    assert not (tmp_path / "fields_full.xdmf").exists() and not (tmp_path / "fields_full.h5").exists()
