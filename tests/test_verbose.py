"""Verbose progress: one plain line per step with the solver's iterations and residual, the CFL number and the cost."""

import io
import re

import numpy as np
import pytest

from fluidem import Scene, Simulation
from fluidem.cli import main
from tiny_scene import tiny_channel

TINY = tiny_channel(h=0.05, t_end=0.4)

LINE = re.compile(r"^step (\d+)/4  t = (\S+)  linear (\S+) it (\d+) res (\S+) LU (\d+)  CFL (\S+)  .* = \S+ ms$")


def test_verbose_prints_one_line_per_step_with_iterations_residual_and_cfl(tmp_path):
    (tmp_path / "s.toml").write_text(TINY)
    sim = Simulation(Scene.from_toml(tmp_path / "s.toml"))
    out = io.StringIO()  # not a terminal: plain lines
    sim.run(out_dir=None, verbose=out)
    lines = out.getvalue().splitlines()
    assert len(lines) == 4 and "\r" not in out.getvalue()
    rows = [LINE.match(ln) for ln in lines]
    assert all(rows), lines
    assert [int(r.group(1)) for r in rows] == [1, 2, 3, 4]
    assert all(float(r.group(5)) < 1e-10 for r in rows)  # each solve met the solver's tolerance
    # the per-step Krylov iterations add up to the solver's own count
    assert sum(int(r.group(4)) for r in rows) == sim.flow.stepper.solver_summary()["krylov_iterations"]
    # the last CFL number recomputed independently: max over elements of |u| dt / (longest edge)
    sp = sim.flow.space
    uq = sp.ub.interpolate(sim.flow.x[:sp.n_u])
    speed = np.sqrt(uq[0] ** 2 + uq[1] ** 2).max(axis=1)
    p, t = sp.mesh.p, sp.mesh.t
    h = np.max([np.linalg.norm(p[:, t[i]] - p[:, t[(i + 1) % 3]], axis=0) for i in range(3)], axis=0)
    cfl = float((speed * 0.1 / h).max())
    assert abs(sim.step_info()["cfl"] - cfl) < 1e-12 * cfl  # measured: equal to round-off; cfl = 1.054
    assert abs(float(rows[-1].group(7)) - cfl) < 5e-3 * cfl  # printed with 3 digits


def test_run_verbose_flag_replaces_the_bar_with_lines_on_a_dry_scene(tmp_path, capsys):
    assert main(["run", "--example", "dry-heap", "--steps", "3", "--out", str(tmp_path / "o"), "-v"]) == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("step ")]
    assert [ln.split()[1] for ln in lines] == ["1/3", "2/3", "3/3"]
    assert all(re.search(r"  contacts \d+  bodies [\d.]+ \+ .* ms$", ln) for ln in lines), lines
    assert "[#" not in err and "ETA" not in err  # no progress bar beside them


def _settling_on_the_floor(**contact):
    """A free disk 0.03 above the floor (within reach of it from the first step), contacts on."""
    return {"gravity": [0, -9.81], "fluid": {"viscosity": 0.05, "element": "th"},
            "domain": {"box": [0.0, 1.0, 0.0, 1.0]},
            "bodies": [{"shape": "disk", "radius": 0.1, "segments": 16, "position": [0.5, 0.13], "density": 2.0}],
            "contact": {"E": 1e4, "mu": 0.3, "gamma": 0.3, **contact}, "mesh": {"h": 0.05},
            "time": {"dt": 0.02, "t_end": 0.04}}


def test_the_contact_sub_steps_of_a_fluid_step_are_counted_and_what_sets_them_is_named(tmp_path):
    import json
    import math

    out, verbose = tmp_path / "o", io.StringIO()
    sim = Simulation(Scene.from_dict(_settling_on_the_floor()))
    sim.run(out_dir=out, verbose=verbose)
    rec = json.loads((out / "run.json").read_text())
    limit, counts = rec["dem_sub_step"], rec["cost"]["counts"]
    # the default repulsion at contact, 2c/(ερ) with c the buoyant weight, ρ = h/100, ε = h/(100ρ) = 0.01:
    # 2 * 0.308 / (0.01 * 5e-4) = 1.2e5, twelve times contact.E
    assert limit["set_by"].startswith("the repulsion's stiffness at contact 2c/(ερ) = 1.2e+05 force/length "
                                      "(contact.repulsion_epsilon, repulsion_force, repulsion_range) with the "
                                      "lightest free body 0")
    per_pass = math.ceil(0.02 / limit["dt_max"] - 1e-9)  # the DEM's bound: 73 sub-steps a pass here
    # but the disk stays 0.03 above the floor, far outside the repulsion's range (5e-4), and no overlap can
    # form: each pass takes the sub-steps that follow the gap, one (measured: 6 in 6 passes)
    assert counts["dem_passes"] >= 2 and counts["dem_substeps"] == counts["dem_passes"] < per_pass
    assert sim.counters["dem_substeps"] == counts["dem_substeps"]
    per_step = re.findall(r"DEM (\d+) sub-steps in (\d+) passes \(([^)]*)", verbose.getvalue())
    assert len(per_step) == 2 and sum(int(n) for n, _, _ in per_step) == counts["dem_substeps"]
    assert all(by.startswith("the gaps' change") for _, _, by in per_step), per_step
    soft = Simulation(Scene.from_dict(_settling_on_the_floor(repulsion_epsilon=0.2)))  # 2c/(ερ) = 6.2e3 < E
    soft.run(out_dir=None)
    assert soft.dem_limit()["set_by"].startswith("contact.E = 1e+04 force/length with the lightest free body 0")
    assert soft.dem_limit()["dt_max"] > 3 * limit["dt_max"]  # √12: the sub-steps are set by the stiffer law


def test_the_plan_predicts_the_sub_steps_and_refuses_contacts_that_would_never_finish_a_step(tmp_path, capsys):
    from fluidem.plan import contact_sub_steps

    scene = Scene.from_dict(_settling_on_the_floor())
    n, dt_max, by = contact_sub_steps(scene)
    sim = Simulation(scene)
    assert dt_max == pytest.approx(sim.dem_limit()["dt_max"], rel=1e-12) and n == 73  # what the run takes
    assert by.startswith("the repulsion's stiffness at contact 2c/(ερ) = 1.2e+05")  # 2 * 0.300 / (0.01 * 5e-4)
    quiet = Scene.from_dict(_settling_on_the_floor(E=1e8))  # dt_max 9.52e-6: 2 101 sub-steps a pass
    assert contact_sub_steps(quiet)[0] == 2101 and not quiet.plan().warnings
    warned = Scene.from_dict(_settling_on_the_floor(E=1e10))  # 21 007: warned, still runs
    assert warned.plan().warnings == [
        "contacts take up to 2.1e+04 DEM sub-steps per pass over each step of time.dt = 0.02 (dt_max = 9.52e-07, "
        "set by contact.E = 1e+10 force/length, with the lightest free body); expected at most 10000: lower that "
        "stiffness (a smaller E or repulsion_force, a larger repulsion_epsilon or repulsion_range), or time.dt"]
    assert not warned.plan().unsupported
    for contact, by in (({"E": 1e300}, "contact.E = 1e+300 force/length"),
                        ({"repulsion_epsilon": 1e-200}, "the repulsion's stiffness at contact 2c/(ερ) = 1.2e+203"),
                        ({"repulsion_force": 1e300}, "the repulsion's stiffness at contact 2c/(ερ) = 4e+305")):
        p = tmp_path / "s.toml"
        Scene.from_dict(_settling_on_the_floor(**contact)).to_toml(p)
        assert main(["plan", str(p)]) == 2  # refused: such a step would never end (it hung, deaf to SIGTERM)
        out = capsys.readouterr()
        said = out.out + out.err
        assert ("contacts take more than 1e+15 DEM sub-steps per pass over each step of time.dt = 0.02 "
                "(dt_max = ") in said
        assert f"set by {by}" in said
