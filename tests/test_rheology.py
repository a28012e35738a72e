"""Side loads (sides.csv) and the Couette-cell rheometer (run.json 'rheology'): exact cells, the
momentum balance of a channel, Einstein's dilute slope, restarts and bad input."""

import json

import numpy as np
import pytest

from fluidem import Simulation
from fluidem.errors import SceneError
from fluidem.io import read_sides
from fluidem.rheology import blocking_standard_error
from fluidem.scene import Scene

RHO, NU, U, L, H = 2.0, 0.5, 3.0, 2.0, 1.0
MU = RHO * NU


def _cell(model="stokes", top=U, bottom=0.0, body_force=(0.0, 0.0), bodies=(), t_end=1.0, dt=0.1, h=0.25,
          output=None, box=(0.0, L, 0.0, H), element="th", grading=None):
    dom = {"box": list(box), "left": "periodic", "right": "periodic",
           "top": {"type": "moving-wall", "velocity": [top, 0.0]} if top else "wall",
           "bottom": {"type": "moving-wall", "velocity": [bottom, 0.0]} if bottom else "wall"}
    mesh = {"h": h} if grading is None else {"h": h, "grading": grading}
    return Scene.from_dict({"fluid": {"model": model, "viscosity": NU, "density": RHO, "element": element,
                                      "body_force": list(body_force), "solver": "direct"},
                            "domain": dom, "bodies": list(bodies), "mesh": mesh,
                            "time": {"dt": dt, "t_end": t_end}, "output": {"fields": False, **(output or {})}})


def _run(scene, out, **kw):
    Simulation(scene).run(out_dir=out, **kw)
    return json.loads((out / "run.json").read_text()), read_sides(out)


def test_empty_couette_cell_is_exact(tmp_path):
    """Stokes Couette flow u = U y / H is in the velocity space: the walls carry ∓ μ U / H · L
    and the rheometer reads μ_eff / μ = 1 (measured: exactly 1; the forces to 8.9e-16 of μ U L / H, their
    sum to 2.9e-15)."""
    scene = _cell()
    assert any(n.startswith("rheometer: Couette cell between bottom and top") and "shear rate 3 (1/time)" in n
               and "[0.5, 1]" in n and "second half of the run" in n for n in scene.plan().notes), scene.plan().notes
    rec, sides = _run(scene, tmp_path / "c")
    assert list(sides["side"][:2]) == ["bottom", "top"] and list(np.unique(sides["step"])) == list(range(1, 11))
    F = np.column_stack([sides["fx"], sides["fy"]]).reshape(-1, 2, 2)  # (steps, bottom/top, x/y)
    exact = MU * U / H * L  # 6: the fluid drags the bottom wall along and holds the top one back
    assert np.abs(F[:, 0] - [exact, 0.0]).max() < 1e-12 * exact  # measured 8.9e-16 relative
    assert np.abs(F[:, 0] + F[:, 1]).max() < 1e-12 * exact  # equal and opposite: measured 2.9e-15
    rh = rec["rheology"]
    assert rh["shear_rate"] == U / H and rh["window"] == [0.5, 1.0] and rh["samples"] == 6
    assert abs(rh["mu_eff_over_mu"] - 1.0) < 1e-12 and rh["standard_error"] < 1e-12  # measured 0, 0
    assert rh["walls"] == ["bottom", "top"] and rh["viscosity"] == MU


def test_couette_cell_with_walls_moving_both_ways_and_a_window(tmp_path):
    """Walls at −U/2 and +U/2: the same shear rate U / H; a window of two samples [0.7, 0.8] (its ends included)."""
    scene = _cell(top=U / 2, bottom=-U / 2, output={"rheology_window": [0.7, 0.8]})
    assert any("[0.7, 0.8] (output.rheology_window)" in n for n in scene.plan().notes)
    rh, _ = _run(scene, tmp_path / "c")
    rh = rh["rheology"]
    assert rh["shear_rate"] == U / H and rh["samples"] == 2 and rh["window_from"] == "output.rheology_window"
    assert abs(rh["mu_eff_over_mu"] - 1.0) < 1e-12  # measured 2.2e-16


def test_couette_cell_across_x(tmp_path):
    """Walls left and right, periodic in y, the right wall moving at −U along y: shear rate −U / L,
    and still μ_eff / μ = 1 (measured: 1 + 6.2e-15); the fluid drags the left wall along −y (fy < 0)."""
    s = Scene.from_dict({"fluid": {"model": "stokes", "viscosity": NU, "density": RHO, "element": "th"},
                         "domain": {"box": [0.0, L, 0.0, H], "bottom": "periodic", "top": "periodic",
                                    "right": {"type": "moving-wall", "velocity": [0.0, -U]}},
                         "mesh": {"h": 0.25}, "time": {"dt": 0.1, "t_end": 0.2}, "output": {"fields": False}})
    assert any("between left and right (left at rest; right at -3 along y), gap 2: shear rate -1.5" in n
               for n in s.plan().notes)
    rec, sides = _run(s, tmp_path / "v")
    rh = rec["rheology"]
    assert rh["walls"] == ["left", "right"] and rh["shear_rate"] == -U / L and rh["wall_length"] == H
    assert abs(rh["mu_eff_over_mu"] - 1.0) < 1e-12  # measured 6.2e-15
    left = sides["fy"][sides["side"] == "left"]
    assert np.all(np.abs(left / (-MU * U / L * H) - 1.0) < 1e-12)  # measured 5.7e-15


def test_poiseuille_channel_walls_each_carry_half_the_body_force(tmp_path):
    """A periodic channel driven by fluid.body_force f between walls at rest: the momentum balance
    gives each wall half of ρ f L H (measured: to 7.4e-16 relative, the parabola is in the P2 space),
    and no rheology (no shear rate), which the plan says."""
    f = 0.3
    scene = _cell(top=0.0, body_force=(f, 0.0))
    note = [n for n in scene.plan().notes if n.startswith("no rheology")]
    assert note and "bottom and top are the walls of a cell periodic in x but do not move relative to each other" \
        in note[0] and "(no shear rate)" in note[0]
    rec, sides = _run(scene, tmp_path / "p")
    F = np.column_stack([sides["fx"], sides["fy"]]).reshape(-1, 2, 2)
    half = 0.5 * RHO * f * L * H
    assert np.abs(F[:, :, 0] - half).max() < 1e-12 * half and np.abs(F[:, :, 1]).max() < 1e-12 * half
    assert "rheology" not in rec


def test_sides_csv_is_cut_back_on_a_restart(tmp_path):
    """Navier–Stokes start-up of a Couette cell (forces change every step): a restart from the
    step-5 checkpoint cuts sides.csv back to step 5 and continues it, bit for bit with the
    uninterrupted run (fresh LU every step), no step twice; the rheology averages the whole
    record over its window."""
    scene = _cell(model="navier-stokes", output={"checkpoint_every": 5})
    rec_a, a = _run(scene, tmp_path / "a")
    out = tmp_path / "b"
    _run(scene, out)
    _, b = _run(_cell(model="navier-stokes", output={"checkpoint_every": 5}), out,
                restart=out / "checkpoints" / "ckpt_0000005.npz")
    assert list(b["step"]) == list(np.repeat(np.arange(1, 11), 2))
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert len(np.unique(a["fx"][::2])) == 10  # the start-up: a new wall force every step
    rh = json.loads((out / "run.json").read_text())["rheology"]
    assert rh == rec_a["rheology"] and rh["samples"] == 6


def test_blocking_standard_error_of_correlated_samples():
    """Blocking (Flyvbjerg & Petersen 1989) of an AR(1) series x_k = a x_{k−1} + e_k: the standard
    error of the mean is σ_e / (1 − a) / √n for long series (a = 0.9: 10/√n; the naive σ/√n is
    √((1 + a)/(1 − a)) = 4.4 times smaller); measured 0.0791 against 0.0781 for n = 2^14 (1.2 %; the
    estimate's own error at 128 blocks is 6 %), 4.36 times the naive one."""
    rng = np.random.default_rng(7)
    a, n = 0.9, 2 ** 14
    e = rng.standard_normal(n)
    x = np.zeros(n)
    for k in range(1, n):  # a test series, built once
        x[k] = a * x[k - 1] + e[k]
    se, blocks = blocking_standard_error(x)
    exact = 1.0 / (1.0 - a) / np.sqrt(n)
    assert abs(se / exact - 1.0) < 0.12 and blocks < n // 8  # measured 0.012, 128 blocks
    assert se > 3.0 * np.sqrt(x.var() / (n - 1))  # measured 4.36


# -- Einstein -------------------------------------------------------------------------------

def _einstein(k, a_over_h, out):
    """(μ_eff/μ − 1) / (2φ) of one free, neutrally buoyant disk of radius a = k H on the centre line
    of a square Stokes Couette cell (L = H = 1, bottom at rest, top at 1), mesh a / a_over_h at the
    disk; one quasi-steady step (the disk spins in place, force- and torque-free)."""
    H_, a = 1.0, k
    body = {"shape": "disk", "radius": a, "position": [0.5, 0.5], "motion": "free", "density": 1.0}
    s = Scene.from_dict({"fluid": {"model": "stokes", "viscosity": 1.0, "density": 1.0, "element": "th"},
                         "domain": {"box": [0.0, 1.0, 0.0, H_], "left": "periodic", "right": "periodic",
                                    "top": {"type": "moving-wall", "velocity": [1.0, 0.0]}},
                         "bodies": [body],
                         "mesh": {"h": a / a_over_h, "grading": {"region": "bodies", "growth": 1.2, "h_max": 0.1}},
                         "time": {"dt": 0.01, "t_end": 0.01}, "output": {"fields": False}})
    Simulation(s).run(out_dir=out)
    rh = json.loads((out / "run.json").read_text())["rheology"]
    assert rh["samples"] == 1 and rh["standard_error"] is None
    phi = np.pi * a ** 2
    return (rh["mu_eff_over_mu"] - 1.0) / (2.0 * phi)


def test_einstein_dilute_slope_converges_as_the_disk_shrinks(tmp_path):
    """Einstein's 2D coefficient is 2, μ_eff = μ (1 + 2φ).  Between the walls of the periodic cell
    the disk's stresslet is larger by about 4 k² (k = a/H, L = H): measured (μ_eff/μ − 1)/(2φ) =
    1.0376 at k = 0.1 and 1.0083 at k = 0.05 (mesh a/10 at the disk), so within 2 % of 1 at
    k = 0.05 and not at k = 0.1, converging with order 2.18 (log2 of 0.0376/0.0083)."""
    r1 = _einstein(0.1, 10, tmp_path / "k1")
    r2 = _einstein(0.05, 10, tmp_path / "k2")
    assert abs(r2 - 1.0) < 0.02  # measured 0.0083
    assert 0.03 < r1 - 1.0 < 0.05  # measured 0.0376 (0.0392 extrapolated to h -> 0): the walls' k² term
    order = np.log2((r1 - 1.0) / (r2 - 1.0))
    assert 1.7 < order < 2.7  # measured 2.18: the wall correction vanishes like k²


@pytest.mark.slow(seconds=25)
def test_einstein_wall_correction_is_four_k_squared(tmp_path):
    """k = 0.1, 0.05, 0.025, each at mesh a/10 and a/20 at the disk, extrapolated to h -> 0 (the
    rheometer's error is second order in h/a): (μ_eff/μ − 1)/(2φ) − 1 = c k² with c = 3.92, 3.95,
    3.96 (measured: 1.0376/1.0388, 1.0083/1.0095, 1.0010/1.0021 before extrapolation, 1.0392,
    1.0099, 1.0025 after); the slope is within 2 % of Einstein's from k = 0.05 down."""
    cs = []
    for k in (0.1, 0.05, 0.025):
        coarse, fine = _einstein(k, 10, tmp_path / f"c{k}"), _einstein(k, 20, tmp_path / f"f{k}")
        r = fine + (fine - coarse) / 3.0
        cs.append((r - 1.0) / k ** 2)
        if k <= 0.05:
            assert abs(r - 1.0) < 0.02  # measured 0.0099, 0.0025
    assert max(cs) / min(cs) < 1.03  # measured 1.009: the slope converges to Einstein's like k²


# -- bad input ------------------------------------------------------------------------------

@pytest.mark.parametrize("window, match", [
    ([0.5, 2.0], r"^output.rheology_window = \[0.5, 2.0\]: expected \[t0, t1\] with 0 <= t0 < t1 <= time.t_end = 1 "),
    ([-0.1, 0.5], r"^output.rheology_window = \[-0.1, 0.5\]: expected \[t0, t1\] with 0 <= t0 < t1"),
    ([0.6, 0.6], r"^output.rheology_window = \[0.6, 0.6\]: expected \[t0, t1\] with 0 <= t0 < t1"),
    ("late", r"^output.rheology_window = 'late': expected \[t0, t1\], two finite times within the run$"),
])
def test_a_window_outside_the_run_is_one_line(window, match):
    with pytest.raises(SceneError, match=match) as err:
        _cell(output={"rheology_window": window})
    assert "\n" not in str(err.value)


def test_a_window_in_a_box_that_is_no_shear_cell_is_noted():
    s = Scene.from_dict({"fluid": {}, "domain": {"box": [0, 1, 0, 1], "top": {"type": "moving-wall",
                                                                            "velocity": [1.0, 0.0]}},
                         "output": {"rheology_window": [0.5, 1.0]}})
    assert any(n.startswith("no rheology: output.rheology_window is set but the box is no shear cell")
               for n in s.plan().notes)
    assert not any("rheology" in n for n in Scene.from_dict({"fluid": {}, "domain": {"box": [0, 1, 0, 1]}})
                   .plan().notes)


def test_side_and_body_loads_of_a_stokes_channel_balance(tmp_path):
    """A Stokes channel (parabolic inflow left, outflow right, walls, a fixed square): the residual
    vanishes on every free DOF and the constant test function has no residual without a body
    force, so the forces on the walls, the inflow and the body add up to zero.  The corner DOFs of
    a wall and the inflow count half for each (without that the sum is off by the corner
    reactions: 5.6 % of the wall force here); measured 6.1e-15 of the wall force."""
    scene = Scene.from_dict({"fluid": {"model": "stokes", "viscosity": 0.1, "density": 2.0, "element": "th"},
                             "domain": {"box": [0.0, 2.0, 0.0, 1.0], "left": "inflow", "right": "outflow",
                                        "inflow_profile": {"type": "parabolic", "umax": 1.0}},
                             "bodies": [{"shape": "rectangle", "width": 0.2, "height": 0.2, "position": [0.8, 0.5],
                                         "motion": "fixed"}],
                             "mesh": {"h": 0.05}, "time": {"dt": 0.1, "t_end": 0.1}, "output": {"fields": False}})
    rec, sides = _run(scene, tmp_path / "ch")
    assert list(sides["side"]) == ["bottom", "top", "left"] and "rheology" not in rec
    F = np.column_stack([sides["fx"], sides["fy"]])
    body = rec["summary"]["bodies"]["body0"]
    total = F.sum(axis=0) + [body["fx"], body["fy"]]
    assert np.abs(total).max() < 1e-12 * abs(F[0, 0])  # measured 6.1e-15


def _suspension_stress(tmp_path, shift):
    """μ_eff/μ of every step of the sheared-suspension example over its first 20 steps, every disk moved
    by ``shift`` along the periodic x (wrapped into the box)."""
    from fluidem.cases.scenes import example_scene
    from fluidem.rheology import shear_cell, wall_shear_stress

    sc = example_scene("sheared-suspension")
    sc.time.t_end = 0.4
    sc.output.rheology_window = (0.1, 0.4)
    for b in sc.bodies:
        b.position = (float((b.position[0] + shift) % 2.0), b.position[1])
    out = tmp_path / f"shift{shift}"
    Simulation(sc).run(out_dir=out)
    cell, _ = shear_cell(sc)
    s = read_sides(out)
    lo, hi = (s["side"] == k for k in cell.sides)
    F = np.column_stack([s["fx"], s["fy"]])
    return wall_shear_stress(F[lo], F[hi], cell) / (cell.viscosity * cell.shear_rate)


@pytest.mark.slow
def test_sheared_suspension_does_not_see_where_the_periodic_sides_are(tmp_path):
    """A periodic cell has no place: the same 20 disks moved by half a period put other disks across the
    sides (meshed as their images) and give the same wall stress at every step to mesh noise: measured
    5.2e-4 at most (2.1e-3 of the disks' share μ_eff/μ − 1 = 0.26), against 1.9e-3 between two steps."""
    a = _suspension_stress(tmp_path, 0.0)
    b = _suspension_stress(tmp_path, 1.0)
    assert len(a) == len(b) == 20
    assert np.abs(a - b).max() < 1.5e-3  # measured 5.2e-4
    assert 1.2 < a.mean() < 1.3  # the suspension's share is there: 1.25 (1 + 2φ = 1.2)
