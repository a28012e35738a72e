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
