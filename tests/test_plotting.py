"""The figures of `fluidem plot`: labelled axes with units, labelled colorbars, no empty panels, long boxes split
or cropped, the field's own geometry, a history figure."""

import numpy as np
import pytest

import fluidem
from fluidem.cases.scenes import example_scene
from fluidem.plotting import figures, plot_run, view_windows

pytest.importorskip("matplotlib")


def _has_data(ax):
    return bool(ax.lines or ax.collections or ax.images or ax.patches)


def _check_labelled(figs):
    """Every data axes has x and y labels with a unit in brackets, has something drawn, and every colorbar a label."""
    for name, fig in figs.items():
        for ax in fig.axes:
            if ax.get_label() == "<colorbar>":
                assert "[" in ax.get_ylabel() and "]" in ax.get_ylabel(), (name, "colorbar")
                continue
            assert _has_data(ax), (name, "an empty panel")
            if ax.get_xlabel() == "" and ax.get_shared_x_axes().get_siblings(ax) != [ax]:
                pass  # a shared x axis is labelled on the bottom panel only
            else:
                assert "[" in ax.get_xlabel(), (name, ax.get_xlabel())
            assert "[" in ax.get_ylabel() and ax.get_ylabel().endswith("]"), (name, ax.get_ylabel())


@pytest.fixture(scope="module")
def channel_run(tmp_path_factory):
    """The DFG channel (5.4:1) coarse, Stokes, one step: a fixed body in a fluid."""
    s = example_scene("dfg-cylinder")
    s.fluid.model = "stokes"
    s.mesh.h, s.mesh.grading = 0.04, None
    s.time.dt = s.time.t_end = 1.0
    s.domain.inflow_profile["ramp"] = 0.0
    s.validate()
    out = tmp_path_factory.mktemp("channel")
    fluidem.Simulation(s).run(out_dir=out)
    return out


def test_fixed_body_in_a_long_channel(channel_run):
    figs = figures(channel_run)
    assert list(figs) == ["mesh", "velocity", "pressure", "history"]  # a fixed body: no bodies/trajectory panels
    _check_labelled(figs)
    vel = figs["velocity"]
    panels = [ax for ax in vel.axes if ax.get_label() != "<colorbar>"]
    assert len(panels) == 2  # 5.4:1 split into two stacked 2.7:1 views covering the box
    assert panels[0].get_xlim() == (0.0, 1.1) and panels[1].get_xlim() == (1.1, 2.2)
    (cbar,) = [ax for ax in vel.axes if ax.get_label() == "<colorbar>"]
    assert cbar.get_ylabel() == "|u| [length/time]"
    assert panels[0].get_xlabel() == "x [length]"
    hist = figs["history"]
    assert [ax.get_ylabel() for ax in hist.axes][0] == "hydrodynamic load [force/depth]"
    si = figures(channel_run, units="SI")
    assert si["velocity"].axes[0].get_xlabel() == "x [m]"
    assert any(ax.get_ylabel() == "p [N/m²]" for ax in si["pressure"].axes)
    import matplotlib.pyplot as plt

    for f in list(figs.values()) + list(si.values()):
        plt.close(f)


def test_the_pressure_colours_follow_the_field_not_its_spikes_and_the_title_says_so(channel_run):
    """The colour limits are ± the 99th percentile of |p| when a few nodes exceed it by more than 5 % (the
    spikes next to touching bodies), and the title says where the colours are clipped."""
    from fluidem.io import read_fields
    from fluidem.plotting import PRESSURE_PERCENTILE, pressure_limit

    fig = figures(channel_run)["pressure"]
    tc = fig.axes[0].collections[0]
    p = read_fields(channel_run, full=False).point_data["pressure"]  # the series the figures draw
    lim, top = pressure_limit(p)
    assert tc.get_clim() == pytest.approx((-lim, lim))
    assert lim == pytest.approx(max(np.percentile(np.abs(p), PRESSURE_PERCENTILE), 0) if top else np.abs(p).max())
    assert ("colours clipped" in fig.axes[0].get_title()) == (top is not None)


def test_field_titles_say_when_the_run_went_on_past_the_last_fields(tmp_path):
    """Fields are written every output.every steps: a run whose last fields are older than its last history row
    (stopped, or fields dropped) says both times, not the fields' alone."""
    s = example_scene("dfg-cylinder")
    s.fluid.model = "stokes"
    s.mesh.h, s.mesh.grading = 0.04, None
    s.time.dt, s.time.t_end, s.output.every = 0.5, 1.5, 2
    s.domain.inflow_profile["ramp"] = 0.0
    s.validate()
    fluidem.Simulation(s).run(out_dir=tmp_path)
    assert figures(tmp_path)["mesh"].axes[0].get_title().startswith("mesh at t = 1.5: ")
    pvd = tmp_path / "fields.pvd"  # as if the fields of the last step had not been written
    pvd.write_text("".join(ln for ln in pvd.read_text().splitlines(True) if 'step="3"' not in ln))
    figs = figures(tmp_path)
    for name in ("mesh", "velocity", "pressure"):
        assert "t = 1 (last fields written; the run reached t = 1.5)" in figs[name].axes[0].get_title(), name


def test_field_figures_draw_the_holes_of_the_field_mesh(channel_run):
    """The body drawn in a field figure is the hole of that step's mesh (same instant as the field)."""
    import meshio

    from fluidem.io import read_pvd
    from fluidem.plotting import _holes

    m = meshio.read(read_pvd(channel_run / "fields.pvd")[-1][1])
    (hole,) = _holes(m.points[:, :2], m.cells_dict["triangle"])[0]
    r = np.hypot(hole[:, 0] - 0.2, hole[:, 1] - 0.2)
    assert np.allclose(r, 0.05, rtol=1e-9)  # the cylinder's outline nodes lie on the circle


def test_moving_bodies_dry(tmp_path):
    s = fluidem.Scene.from_dict({"gravity": [0, -10], "domain": {"box": [0, 1, 0, 1]},
                                 "bodies": [{"shape": "disk", "radius": 0.05, "position": [0.3, 0.5]},
                                            {"shape": "rectangle", "width": 0.1, "height": 0.05,
                                             "position": [0.7, 0.5], "omega": 1.0}],
                                 "time": {"dt": 0.01, "t_end": 0.1}})
    fluidem.Simulation(s).run(out_dir=tmp_path)
    figs = figures(tmp_path)
    assert list(figs) == ["bodies", "trajectories", "history"]
    _check_labelled(figs)
    labels = [ax.get_ylabel() for ax in figs["history"].axes]
    assert "body velocity [length/time]" in labels and "body kinetic energy [mass·length²/time²]" in labels
    ke = [ax for ax in figs["history"].axes if ax.get_ylabel().startswith("body kinetic")][0]
    t, e = ke.lines[0].get_data()
    # free fall from rest: translational energy of both bodies = 1/2 (m1 + m2) (g t)^2
    m = sum(b.density * fluidem.geometry.polygon_area(b.local_vertices(32)) for b in s.bodies)
    assert e[-1] == pytest.approx(0.5 * m * (10 * t[-1]) ** 2, rel=1e-6)  # symplectic Euler: exact velocities
    assert sorted(p.name for p in plot_run(tmp_path)) == ["bodies.png", "history.png", "trajectories.png"]


def test_trajectories_are_coloured_by_time_with_start_and_end_marked(tmp_path):
    """40 paths of one colour each could not be told apart: the segments carry their mid-step time on one
    colour scale (labelled t), every path has a start (o) and an end (■) marker."""
    from matplotlib.collections import LineCollection

    s = fluidem.Scene.from_dict({"gravity": [0, -10], "domain": {"box": [0, 1, 0, 1]},
                                 "bodies": [{"shape": "disk", "radius": 0.04, "position": [0.15 + 0.1 * k, 0.5]}
                                            for k in range(8)],
                                 "time": {"dt": 0.01, "t_end": 0.1}})
    fluidem.Simulation(s).run(out_dir=tmp_path)
    fig = figures(tmp_path)["trajectories"]
    ax = fig.axes[0]
    lc = [c for c in ax.collections if isinstance(c, LineCollection)][0]
    t = lc.get_array()
    assert len(lc.get_segments()) == 8 * 10 and t.min() == pytest.approx(0.005) and t.max() == pytest.approx(0.095)
    assert [len(line.get_xdata()) for line in ax.lines] == [8, 8]  # the starts and the ends
    assert any(c.get_ylabel() == "t [time]" for c in fig.axes if c.get_label() == "<colorbar>")


def test_view_windows_split_and_crop():
    assert view_windows((0, 10, 0, 1))[0] == [(0.0, 10 / 3, 0.0, 1.0), (10 / 3, 20 / 3, 0.0, 1.0),
                                             (20 / 3, 10.0, 0.0, 1.0)]
    views, crop = view_windows((0, 1, 0, 48), focus=(0.4, 0.6, 40, 40.2))  # tall: cropped around the body
    assert crop and views == [(0.0, 1.0, pytest.approx(38.1), pytest.approx(42.1))]
    views, crop = view_windows((-24, 24, -1, 1), focus=(-0.2, 23.9, -0.2, 0.2))  # bodies far apart: a wider view
    assert crop and views == [(pytest.approx(-2.1), 24.0, -1.0, 1.0)]


def test_scene_units_name_the_labels(tmp_path):
    from fluidem import names
    from fluidem.plotting import UNIT_SYSTEMS

    assert tuple(UNIT_SYSTEMS) == names.choices("units")
    s = fluidem.Scene.from_dict({"units": "cgs", "gravity": [0, -981], "domain": {"box": [0, 10, 0, 10]},
                                 "bodies": [{"shape": "disk", "radius": 0.5, "position": [5, 5]}],
                                 "time": {"dt": 0.01, "t_end": 0.02}})
    assert s.units == "CGS"  # the alias stored canonically
    fluidem.Simulation(s).run(out_dir=tmp_path)
    assert fluidem.Scene.from_toml(tmp_path / "scene.toml").units == "CGS"  # the scene as run keeps it
    figs = figures(tmp_path)
    assert figs["trajectories"].axes[0].get_xlabel() == "x [cm]"
    assert "body velocity [cm/s]" in [ax.get_ylabel() for ax in figs["history"].axes]
    assert figures(tmp_path, units="SI")["trajectories"].axes[0].get_xlabel() == "x [m]"  # the argument wins
    import matplotlib.pyplot as plt

    plt.close("all")


def test_no_bodies_gives_field_figures_only(tmp_path, recwarn):
    s = fluidem.Scene.from_dict({"fluid": {"model": "stokes"}, "mesh": {"h": 0.1}, "time": {"dt": 1.0, "t_end": 1.0},
                                 "domain": {"box": [0, 1, 0, 1], "top": {"type": "moving-wall", "velocity": [1, 0]}}})
    fluidem.Simulation(s).run(out_dir=tmp_path)
    figs = figures(tmp_path)
    assert list(figs) == ["mesh", "velocity", "pressure"]  # an empty history.csv: no history figure
    _check_labelled(figs)
    assert not [w for w in recwarn if "loadtxt" in str(w.message)]
    import matplotlib.pyplot as plt

    plt.close("all")
