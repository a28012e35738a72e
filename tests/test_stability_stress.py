"""Stress suite: moving packings in Stokes flow and fluid pockets enclosed by touching bodies.

:mod:`fluidem.cases.stress`.  A pocket (fluid enclosed by a ring of touching bodies) has a pressure
without reference: before its own pin, the saddle-point matrix was singular (a square frame of four
touching bars around a 0.6 × 0.6 pocket: the direct solve's residual 0.31 with the top bar pushed in)
or the pocket's pressure was whatever the round-off made it (the frame translating: the largest
|p| jumped from 7.15 to 11.1 between two steps of the same motion).  Now each closed region gets its
own pin and zero mean (:mod:`fluidem.fluid.pockets`); a motion that keeps the pocket's area moves its
fluid rigidly to round-off, one that would change it stops with :class:`PocketError`.  Random moving
packings (φ 0.2–0.72, gaps down to 1 % of the body size) drawn by ``hypothesis`` finish with finite
fields and bounded diagnostics or stop with fluidem's own error.  The whole table:
``benchmarks/results/stability_stress.md``.
"""

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from skfem import MeshTri

from fluidem.cases.stress import BOUNDS, pocket_run, pocket_scene, stress_run, within_bounds
from fluidem.errors import FluidemError, InputError, RunWarning
from fluidem.fluid import FlowProblem, FlowSpace, VelocityBC, solve_stokes
from fluidem.fluid.pockets import PocketError, fluid_components
from fluidem.diagnostics import RunDiagnostics


@pytest.fixture(autouse=True)
def _quiet():
    """The small meshes warn (few edges per body, thin elements in the narrow gaps): expected here."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunWarning)
        yield


# ---------------------------------------------------------------- regions of a mesh
def _two_cavities(element):
    """Two unit squares no fluid connects, both walled; the top of each slides (a lid-driven cavity)."""
    a = MeshTri.init_tensor(np.linspace(0, 1, 7), np.linspace(0, 1, 7))
    m = MeshTri(np.hstack([a.p, a.p + [[2.0], [0.0]]]), np.hstack([a.t, a.t + a.p.shape[1]]))
    m = m.with_boundaries({"lids": lambda x: x[1] > 1 - 1e-9, "walls": lambda x: x[1] < 1 - 1e-9})
    return FlowSpace(m, element), [VelocityBC("walls"), VelocityBC("lids", (1.0, 0.0))]


@pytest.mark.parametrize("element,kappa", [("p2b", 1.03e7), ("th", 6.03e5)])
def test_two_closed_regions_get_a_pressure_reference_each(element, kappa):
    """Two walled cavities: two closed regions, two pins; the solve succeeds, each cavity's pressure
    has zero mean (measured 1.5e-17 and 4.6e-18 of the largest |p| with p2b, 8.5e-18 with th) and the
    two flows are the same (measured 3.6e-16 and 1.4e-14 of the lid speed).  The condition estimate
    κ₁ of the LU: 1.03e7 (p2b) and 6.03e5 (th); with one pin for the whole mesh 5e20 and 1.1e19, a
    matrix singular to round-off (beyond 1/ε = 4.5e15)."""
    space, bcs = _two_cavities(element)
    fc = fluid_components(space, np.concatenate([space.velocity_dofs(b, c) for b in ("walls", "lids")
                                                 for c in (0, 1)]), [])
    assert fc.n_components == 2 and fc.closed.all()
    pr = FlowProblem(space, 1.0, bcs)
    assert len(pr.fixed) - len(pr._dirichlet_dofs) == 2  # one pin per cavity
    d = RunDiagnostics()
    with d.watching():
        x = solve_stokes(pr).x
    assert d.finish_step(1, 0.0).condition < 1.5 * kappa
    pm = space.pb
    p = np.asarray(pm.interpolate(x[space.n_u:]))
    left = fc.element_label == fc.element_label[0]
    scale = np.abs(p).max()
    for sel in (left, ~left):
        mean = (p[sel] * pm.dx[sel]).sum() / pm.dx[sel].sum()
        assert abs(mean) < 5e-17 * scale
    u = np.asarray(space.ub.interpolate(x[: space.n_u]))
    assert np.abs(u[:, left] - u[:, ~left]).max() < 4e-14  # the same cavity twice (same element order)
    with d.watching():
        solve_stokes(FlowProblem(space, 1.0, bcs, pin_pockets=False))
    assert d.finish_step(2, 0.0).condition > 4.5e15


# ---------------------------------------------------------------- a pocket on the moving mesh
@pytest.mark.parametrize("motion,outflow,tol,p_tol", [("translate", True, 3e-14, 3e-13),
                                                      ("translate", False, 3e-14, 3e-13),
                                                      ("rotate", True, 5e-14, 6e-13)])
def test_pocket_moving_with_its_bodies_moves_rigidly(motion, outflow, tol, p_tol):
    """Four bars touching around a 0.6 × 0.6 pocket, moved as a whole: the pocket is found, its
    pressure has a reference and its fluid moves with the frame.  Measured (p2b, h = 0.08, 15636
    DOFs): velocity error 9.4e-15 (translate) and 1.7e-14 (rotate) of the frame's speed, pocket
    pressure (L2 over the pocket) 1.0e-13 / 2.1e-13 of ν U / side, divergence 1.7e-14 / 3.0e-14 of
    U / side."""
    r = pocket_run(motion, outflow=outflow)
    assert r["ended"] == "finished", r["error"]
    assert r["pockets"] == 1 and abs(r["pocket_area"] - 0.36) < 1e-6  # 0.36 less the two gaps of 1e-6
    assert r["pocket_velocity_error"] < tol
    assert r["pocket_pressure"] < p_tol
    assert r["divergence"] < 3 * tol
    assert abs(r["area_rate"]) < 5e-17  # measured 8.9e-18 (translate), 1.6e-17 (rotate), length²/time


def test_pocket_whose_area_the_bodies_change_stops_with_the_reason():
    """The top bar (width 0.6 − 2e-6) pushed in at 0.1: the pocket would shrink at 0.0599998, measured
    0.05999983 (the facets that cut across the two contact gaps differ by 3.3e-8), which incompressible
    fluid cannot: PocketError naming the pocket, its bodies and the rate."""
    from fluidem.simulation import Simulation

    sim = Simulation(pocket_scene("piston", steps=2))
    with pytest.raises(PocketError, match="would change its area") as info:
        sim.flow.step(0.01)
    err = info.value
    assert isinstance(err, FluidemError)
    assert abs(err.rate + 0.1 * (0.6 - 2e-6)) < 1e-7
    assert set(err.boundaries) == {"bar_left", "bar_right", "bar_bottom", "bar_top"}
    assert abs(err.area - 0.36) < 1e-6
    msg = str(err)
    assert "'bar_top'" in msg and "dA/dt = -0.06" in msg and "\n" not in msg


def test_pocket_is_reported_in_the_health_line():
    """The health record of a step with a pocket says so (``pockets 1``) and warns once, naming it."""
    from fluidem.simulation import Simulation

    sim = Simulation(pocket_scene("translate", steps=2))
    d = sim.diagnostics
    with d.watching():
        sim.flow.step(0.01)
    h = d.finish_step(1, 0.01, sim.flow.last_event, sim.flow.mm, sim.flow.problem)
    assert h.pockets == 1 and "pockets 1" in h.text()
    w = d.check()
    assert len(w) == 1 and "1 enclosed pocket of area 0.36" in w[0]
    assert d.record()["pockets"] == {"max": 1, "max_step": 1, "steps": 1}


@given(motion=st.sampled_from(["translate", "rotate", "piston"]), gap=st.floats(1e-7, 5e-5),
       speed=st.floats(0.01, 1.0), h=st.sampled_from([0.08, 0.1, 0.12]), outflow=st.booleans())
@example(motion="translate", gap=3.6e-5, speed=1.0, h=0.1, outflow=False)  # the gap near the contact gap 1e-4
@example(motion="rotate", gap=4.9e-5, speed=0.5, h=0.08, outflow=True)
@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
def test_random_pockets_move_rigidly_or_stop_with_the_reason(motion, gap, speed, h, outflow):
    """Frames with random contact gaps (1e-7–5e-5, below the mesh's contact gap 1e-3 h), speeds and
    meshes: a motion keeping the pocket's area moves it rigidly, the piston stops with PocketError.
    Velocity error and divergence: round-off amplified by the thin elements at the contacts, measured
    1e-15 to 1.7e-10 and 3.7e-15 to 1.4e-10 of the speed over the drawn frames and 24 drawn outside
    the test, 3.6e-9 and 3.1e-9 for the gap 1e-6 at speed 0.1 (all the large ones at h = 0.1, where
    the mesher leaves a sliver of 0.0006° at a contact; below 4e-14 at h = 0.08 and 0.12); a pocket
    without its own reference is off by O(1)."""
    r = pocket_run(motion, gap=gap, speed=speed, h=h, outflow=outflow)
    assert r["pockets"] == 1
    if motion == "piston":
        assert r["ended"] == "stopped" and r["error"].startswith("PocketError: the fluid pocket")
    else:
        assert r["ended"] == "finished", r["error"]
        assert r["pocket_velocity_error"] < 1e-8 and r["divergence"] < 1e-8


# ---------------------------------------------------------------- moving packings
def _ends_well(r):
    """Finished with finite fields and diagnostics in BOUNDS, or stopped with fluidem's own error."""
    if r["ended"] == "stopped":
        name = r["error"].split(":")[0]
        assert name in {"StateError", "SolverError", "LinearSolverError", "MeshError", "PocketError"}, r["error"]
        return
    assert r["ended"] == "finished" and r["steps_done"] == r["steps"]
    assert within_bounds(r)
    assert all(r["finite"]) and max(r["condition"][i] or 0 for i in range(r["steps"])) < BOUNDS["condition"]


@st.composite
def packings(draw):
    """(n, φ): 4–10 random convex polygons at φ 0.2–0.5, or 16 hexagons at φ 0.6–0.72."""
    if draw(st.booleans()):
        return 16, draw(st.floats(0.6, 0.72))
    return draw(st.integers(4, 10)), draw(st.floats(0.2, 0.5))


@given(packed=packings(), seed=st.integers(0, 10**6), motion_seed=st.integers(0, 10**6),
       amplitude=st.floats(0.2, 2.0))
@example(packed=(16, 0.7), seed=3, motion_seed=4, amplitude=2.0)
@example(packed=(10, 0.5), seed=5, motion_seed=6, amplitude=1.0)
@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
def test_random_moving_packings_finish_bounded_or_stop_with_a_message(packed, seed, motion_seed, amplitude):
    """Random packings (random convex polygons up to φ 0.5, hexagons above), 4 random steps of
    translation ~ 0.02 a and turn ~ 0.04 a rad per body (a the drawn amplitude) keeping every gap
    ≥ 0.01 (1 % of the mean size): finished with finite fields, κ₁ < 1e14 (measured 2.1e8–9.7e10),
    residuals ≤ 1e-8 (the direct solver's own bound; measured ≤ 3.6e-14) and no degenerate element
    (smallest angle measured 0.88°), or a fluidem error; a packing the placement cannot build (φ too
    high for the lattice or the random placement) is refused before the run with the reason."""
    n, phi = packed
    try:
        r = stress_run(n=n, phi=phi, seed=seed, motion_seed=motion_seed, steps=4, h=0.3,
                       sigma_x=0.02 * amplitude, sigma_a=0.04 * amplitude)
    except InputError as err:  # a packing the placement cannot build: said before any run
        assert "phi = " in str(err) and "expected" in str(err)
        return
    _ends_well(r)
    assert r["min_gap_run"] >= 0.01 - 1e-12


@pytest.mark.slow(seconds=6)
def test_packings_at_three_area_fractions_finish_bounded():
    """φ = 0.3, 0.5 (random convex polygons) and 0.7 (hexagons), 16 bodies, 20 random steps each, gaps
    down to 1 % of the body size (measured 0.0120, 0.0107, 0.0101): all finish; largest κ₁ 2.3e9,
    2.9e9, 4.2e10 (bound 1e14), smallest angle 2.4°, 1.5°, 1.05°, 5–7 re-triangulations."""
    for phi in (0.3, 0.5, 0.7):
        r = stress_run(n=16, phi=phi, steps=20)
        _ends_well(r)
        assert r["ended"] == "finished"
        assert r["min_gap_run"] < 0.015  # the narrow gaps are there
        assert r["retriangulations"] >= 1


def test_a_run_reports_its_pocket_and_stops_on_a_squeezed_one(tmp_path):
    """Through ``Simulation.run``: the translated frame's run.json holds the pockets (1, at all 3 steps)
    and the warning naming it, also in events.log; the piston's run stops at step 1 with RunStopped
    carrying the pocket's message, written to events.log."""
    import json

    from fluidem.errors import RunStopped
    from fluidem.simulation import Simulation

    Simulation(pocket_scene("translate", steps=3)).run(out_dir=tmp_path / "t")
    d = json.loads((tmp_path / "t" / "run.json").read_text())["diagnostics"]
    assert d["pockets"] == {"max": 1, "max_step": 1, "steps": 3}
    assert any("1 enclosed pocket of area 0.36" in w for w in d["warnings"])
    assert "enclosed pocket" in (tmp_path / "t" / "events.log").read_text()
    with pytest.raises(RunStopped, match="step 1 .* would change its area at dA/dt = -0.06"):
        Simulation(pocket_scene("piston", steps=3)).run(out_dir=tmp_path / "p")
    assert "would change its area" in (tmp_path / "p" / "events.log").read_text()


def test_bad_stress_input_is_refused_naming_the_value():
    from fluidem.cases.packings import hexagon_packing

    with pytest.raises(InputError, match=r"phi = 0.9: expected at most 0.7\d+ for 4 x 4 hexagons"):
        hexagon_packing(4, 4, phi=0.9)
    with pytest.raises(InputError, match=r"spread = 1.5: expected a number in \[0, 1\)"):
        hexagon_packing(spread=1.5)
    with pytest.raises(InputError, match="pocket motion = 'squeeze': expected one of"):
        pocket_scene("squeeze")
    with pytest.raises(InputError, match="layout = 'grid': expected 'random', 'hexagons' or None"):
        stress_run(layout="grid")
