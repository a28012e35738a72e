"""Verbose progress: one plain line per step with the solver's iterations and residual, the CFL number and the cost."""

import io
import re

import numpy as np

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
