"""Fluid core against analytic solutions and the DFG 2D-1 reference values."""

import numpy as np
import pytest

from fluidem.cases.dfg import REFERENCE, dfg_2d1, dfg_mesh, dfg_problem
from fluidem.fluid.elements import element_pair
from fluidem.fluid.forces import periodic_stats
from fluidem.fluid.navier_stokes import BDF2Stepper, BDFStepper, FlowProblem, solve_steady, solve_stokes
from fluidem.fluid.space import FlowSpace, VelocityBC
from fluidem.mesh.background import GradedSize
from fluidem.mesh.triangulate import Obstacle, to_skfem, triangulate_box
from fluidem.geometry import rectangle

H, L, U, NU = 1.0, 3.0, 1.0, 0.05


def poiseuille(x, y, t=0.0):
    return np.array([4 * U * y * (H - y) / H**2, 0 * y])


def channel_problem(element, h=0.2):
    mesh = to_skfem(triangulate_box((0, L, 0, H), [], h))
    bcs = [VelocityBC(("bottom", "top"), (0, 0)), VelocityBC("left", poiseuille)]
    return FlowProblem(FlowSpace(mesh, element), NU, bcs)


@pytest.mark.parametrize("element", ["p2b", "th", "p3"])
def test_poiseuille_is_reproduced_exactly(element):
    """Plane Poiseuille flow is a quadratic Navier–Stokes solution with do-nothing outflow:
    quadratic velocity spaces reproduce it to round-off, pressure p = 8νU(L − x)/H²."""
    pr = channel_problem(element)
    st = solve_steady(pr)
    xy = pr.space.ub.doflocs
    ux = pr.space.ub.get_dofs().all("u^1")
    np.testing.assert_allclose(st.u[ux], poiseuille(*xy[:, ux])[0], atol=1e-10)
    pts = np.array([[0.5, 0.3], [1.5, 0.7], [2.5, 0.5]])
    p = pr.space.probe_matrix(pts) @ st.p
    np.testing.assert_allclose(p, 8 * NU * U * (L - pts[:, 0]) / H**2, atol=1e-9)
    # divergence-free: B u = 0 on every pressure test function
    assert np.abs(pr.B @ st.u).max() < 1e-12


def test_mini_converges_on_poiseuille():
    """MINI is first order: the velocity error falls when h is halved."""
    errs = []
    for h in (0.2, 0.1):
        pr = channel_problem("mini", h)
        st = solve_stokes(pr)
        d = pr.space.ub.get_dofs().nodal["u^1"]
        errs.append(np.abs(st.u[d] - poiseuille(*pr.space.ub.doflocs[:, d])[0]).max())
    assert errs[1] < 0.6 * errs[0]


def test_unsteady_reaches_steady_poiseuille():
    """BDF2 from rest with steady data converges to the steady solution."""
    pr = channel_problem("th")
    steady = solve_steady(pr)
    stepper = BDF2Stepper(pr, dt=0.5)
    for _ in range(60):
        stepper.step()
    assert np.abs(stepper.state.u - steady.u).max() < 1e-8


@pytest.mark.parametrize("convection", ["semi-implicit", "newton", "explicit"])
def test_bdf2_is_second_order_in_time(convection):
    """Start-up flow past a square with inflow U(t) = sin(t): halving dt divides the error by ~4.

    The obstacle makes the convection term non-zero, so each linearisation is exercised.
    """
    sq = Obstacle(rectangle(0.3, 0.3) + [0.7, 0.5], "square")
    mesh = to_skfem(triangulate_box((0, 2, 0, 1), [sq], 0.2))
    ramp = lambda x, y, t: np.array([4 * np.sin(t) * y * (1 - y), 0 * y])  # noqa: E731
    bcs = [VelocityBC(("bottom", "top", "square"), (0, 0)), VelocityBC("left", ramp)]
    pr = FlowProblem(FlowSpace(mesh, "th"), 0.05, bcs)

    def run(dt):
        s = BDF2Stepper(pr, dt, convection=convection)
        for _ in range(int(round(1.0 / dt))):
            s.step()
        return s.state.u, s.last_cfl

    ref, _ = run(1 / 320)
    u1, cfl = run(1 / 20)
    e1 = np.abs(u1 - ref).max()
    e2 = np.abs(run(1 / 40)[0] - ref).max()
    assert 3.0 < e1 / e2 < 5.0
    if convection == "explicit":
        assert 0 < cfl < 1


@pytest.mark.parametrize("convection", ["semi-implicit", "newton", "explicit"])
def test_bdf3_is_third_order_in_time(convection):
    """The same start-up flow with order=3, from t = 0.5 with exact past states: halving dt divides
    the error at t = 1 by ~8 (measured 8.3 for all three linearisations).

    The past states come from a reference run (dt = 1/320); a start from rest instead would pass
    through one BDF1 and one BDF2 step, whose O(dt²) local error makes the run second order
    (measured ratios 4.1–4.5 here: the wall layers of a flow started from rest are not smooth in t).
    """
    sq = Obstacle(rectangle(0.3, 0.3) + [0.7, 0.5], "square")
    mesh = to_skfem(triangulate_box((0, 2, 0, 1), [sq], 0.2))
    ramp = lambda x, y, t: np.array([4 * np.sin(t) * y * (1 - y), 0 * y])  # noqa: E731
    bcs = [VelocityBC(("bottom", "top", "square"), (0, 0)), VelocityBC("left", ramp)]
    pr = FlowProblem(FlowSpace(mesh, "th"), 0.05, bcs)
    n_u, dref = pr.space.n_u, 1 / 320
    ref = BDFStepper(pr, dref, convection=convection, order=3)
    xs = [ref.state.x.copy()]
    for _ in range(320):
        xs.append(ref.step().x.copy())

    def error(m):  # dt = m dref from step 160 (t = 0.5) to 320
        s = BDFStepper(pr, m * dref, convection=convection, order=3)
        s.set_state({"t": 0.5, "x": xs[160], "u_prev": xs[160 - m][:n_u], "u_prev2": xs[160 - 2 * m][:n_u],
                     "n_steps": 2})
        for _ in range(160 // m):
            s.step()
        return np.abs(s.state.u - xs[320][:n_u]).max()

    e16, e8 = error(16), error(8)
    assert 6.5 < e16 / e8 < 10.0


def test_explicit_step_residual_is_the_generic_one():
    """The explicit step's one-mat-vec residual equals the residual assembled term by term (to 1e-12)."""
    pr = dfg_problem(dfg_mesh(0), "th", lambda t: 1.5)
    s = BDFStepper(pr, 0.002, convection="explicit", order=3)
    for _ in range(4):
        s.step()
    a0, hist = s._last
    generic = s.residual(s.state.x, a0, hist, None)
    generic[: pr.space.n_u] += s._explicit_conv
    fast = s.last_residual()
    assert np.abs(fast - generic).max() <= 1e-12 * np.abs(generic).max()
    assert np.abs(pr.reduce(fast)).max() < 1e-8 * np.abs(fast).max()  # the step solved its equations


def test_bdf_order_is_checked():
    pr = channel_problem("th")
    with pytest.raises(ValueError, match="BDF order must be 2 or 3, got 4"):
        BDFStepper(pr, 0.1, order=4)


def test_explicit_convection_blowup_is_reported():
    """Far beyond the CFL bound the explicit scheme diverges: a clear error, not NaNs."""
    mesh = dfg_mesh(0)
    pr = dfg_problem(mesh, "th", lambda t: 1.5)
    s = BDF2Stepper(pr, 0.1, convection="explicit")
    with pytest.raises(FloatingPointError, match="reduce dt = 0.1"):
        for _ in range(200):
            s.step()


@pytest.mark.parametrize(
    "element, level, tol",
    # tolerances: 2.5x the relative errors measured at these levels of the default meshes
    # (p3/1, 26.9k DOFs: 1.15e-5, 2.44e-3, 8.0e-4; p2b/1, 21.8k: 2.43e-4, 4.82e-2, 3.31e-3;
    # th/1, 11.1k: 2.77e-6, 8.54e-2, 1.77e-2; the finer levels are slow tests)
    [("p3", 1, {"cd": 2.9e-5, "cl": 6.1e-3, "dp": 2.0e-3}),
     ("p2b", 1, {"cd": 6.1e-4, "cl": 0.12, "dp": 8.3e-3}),
     ("th", 1, {"cd": 6.9e-6, "cl": 0.21, "dp": 4.4e-2})],
)
def test_dfg_2d1_against_reference(element, level, tol):
    res = dfg_2d1(element, level)
    errs = res.relative_errors()
    for k, t in tol.items():
        assert errs[k] < t, (k, res.quantities[k], REFERENCE["dfg-2d1"][k], errs[k])
    assert res.extra["final_residual"] < 1e-11


def test_dfg_2d1_polygon_error_follows_4_over_n2():
    """A straight-sided cylinder with N segments holds c_D about 4/N² (relative) low."""
    curved = dfg_2d1("p3", 1, curved=True).quantities["cd"]
    poly = dfg_2d1("p3", 1, curved=False).quantities["cd"]
    n = len(dfg_mesh(1).boundaries["cylinder"])  # straight segments on the outline
    rel = (curved - poly) / curved
    assert 2.0 / n**2 < rel < 6.0 / n**2


def _cell_size_at(mesh, d, band=0.01):
    """√(mean cell area) of the cells whose centroid is d ± band from the DFG cylinder, m."""
    x = mesh.p[:, mesh.t[:3]]  # (2, 3, n_cells)
    c = x.mean(axis=1)
    r = np.hypot(c[0] - 0.2, c[1] - 0.2) - 0.05
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    area = 0.5 * np.abs(e1[0] * e2[1] - e1[1] * e2[0])
    return float(np.sqrt(area[np.abs(r - d) < band].mean()))


def test_dfg_mesh_levels_halve_the_cells_everywhere():
    """The default family quarters the cell area everywhere per level (cells x4 within 10 %:
    measured x4.06 from level 0 to 1 and x4.02 from 1 to 2); the fixed-slope family refines only
    near the cylinder and far away (measured x2.52 and x2.50).  Level 0 is one mesh in both."""
    n = {g: [dfg_mesh(lv, grading=g).t.shape[1] for lv in (0, 1, 2)] for g in ("halving", "fixed-slope")}
    assert n["halving"][0] == n["fixed-slope"][0]
    for a, b in zip(n["halving"], n["halving"][1:]):
        assert b / a == pytest.approx(4.0, rel=0.1)
    for a, b in zip(n["fixed-slope"], n["fixed-slope"][1:]):
        assert b / a < 3.0
    # 0.1 m from the cylinder, where the fixed-slope family hardly refines: cell size ratio of
    # levels 1 and 2 measured 2.07 (halving) and 1.37 (fixed-slope)
    assert _cell_size_at(dfg_mesh(1), 0.1) / _cell_size_at(dfg_mesh(2), 0.1) == pytest.approx(2.0, rel=0.1)
    ratio_fixed = _cell_size_at(dfg_mesh(1, grading="fixed-slope"), 0.1) / _cell_size_at(
        dfg_mesh(2, grading="fixed-slope"), 0.1)
    assert ratio_fixed < 1.6
    with pytest.raises(ValueError, match="grading = 'uniform': expected one of 'halving', 'fixed-slope'"):
        dfg_mesh(1, grading="uniform")


def test_periodic_stats_of_a_sine():
    t = np.arange(0, 10, 0.01)
    y = 0.3 + 1.2 * np.sin(2 * np.pi * t / 0.33130)
    s = periodic_stats(t, y, t_start=2.0)
    assert s.period == pytest.approx(0.33130, rel=1e-6)
    assert s.max == pytest.approx(1.5, abs=1e-5) and s.min == pytest.approx(-0.9, abs=1e-5)
    assert s.rms == pytest.approx(1.2 / np.sqrt(2), rel=2e-3)
    with pytest.raises(ValueError, match="full period"):
        periodic_stats(t, y, t_start=9.8)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="element = 'q9': expected one of 'p2b'"):
        element_pair("q9")
    mesh = dfg_mesh(0)
    with pytest.raises(ValueError, match="viscosity nu must be a positive number, got -1"):
        dfg_problem(mesh, "th", lambda t: 1.0, nu=-1.0)
    with pytest.raises(ValueError, match="not inside the domain"):
        triangulate_box((0, 1, 0, 1), [Obstacle(rectangle(0.5, 0.5) + [0.9, 0.5], "box")], 0.1)
    pr = dfg_problem(mesh, "th", lambda t: 1.0)
    with pytest.raises(ValueError, match="time step dt must be a positive number, got 0"):
        BDF2Stepper(pr, 0.0)
    with pytest.raises(ValueError, match="unknown boundary 'inlet'"):
        FlowProblem(pr.space, 1e-3, [VelocityBC("inlet", (1, 0))])
    with pytest.raises(ValueError, match="mesh level must be an integer"):
        dfg_mesh(-1)
    with pytest.raises(ValueError, match="h_min must be a positive number"):
        GradedSize(h_min=0.0, growth=1.2, h_max=1.0, region=(0, 1, 0, 1))


def test_probe_outside_domain_is_an_error():
    pr = channel_problem("th")
    with pytest.raises(ValueError, match="outside the fluid mesh"):
        pr.space.probe_matrix([[5.0, 0.5]])


def test_dfg_2d2_coarse_sheds_at_the_right_frequency():
    """Coarse 2D-2 (Taylor–Hood level 1, BDF2 dt = 0.01, window [2, 4]): shedding starts after the
    kick and St is within 1e-2 (measured 4.5e-3 on this window, where BDF2's time error offsets
    part of the mesh's: BDF3 at the same dt gives +1.09 %, and St −1.8 % on [4, 6] at dt 0.005);
    the fine check is a slow test."""
    from fluidem.cases.dfg import dfg_2d2

    res = dfg_2d2(element="th", level=1, dt=0.01, t_end=4.0, window=2.0, order=2)
    assert res.extra["periods_measured"] >= 5
    assert res.relative_errors()["st"] < 1e-2


@pytest.mark.parametrize("element", ["th", "p2b"])
def test_direct_and_iterative_paths_agree(element):
    """Stokes and one unsteady BDF2 step on the DFG mesh: LU and block-preconditioned GMRES
    (pyamg velocity block; ν M_p⁻¹, plus Cahouet–Chabard for the unsteady step) agree to the
    solver tolerance: GMRES stops at a relative residual of 1e-10, which bounds the relative
    solution difference by 1e-10 times the condition number (measured differences: 4e-10 for
    Stokes, 6e-8 after three unsteady p2b steps)."""
    from fluidem.fluid.navier_stokes import make_flow_solver

    pr = dfg_problem(dfg_mesh(0), element, lambda t: 0.3)
    a = solve_stokes(pr, solver=make_flow_solver(pr, "direct"))
    it = make_flow_solver(pr, "iterative")
    b = solve_stokes(pr, solver=it)
    assert it.last_info.iterations > 0
    assert np.abs(a.x - b.x).max() < 1e-8 * np.abs(a.x).max()
    assert it.last_info.relative_residual < 1e-10
    steps = [BDF2Stepper(pr, 0.01, solver=make_flow_solver(pr, m, dt=0.01)) for m in ("direct", "iterative")]
    for s in steps:
        for _ in range(3):
            s.step()
    assert np.abs(steps[0].state.x - steps[1].state.x).max() < 1e-6 * np.abs(steps[0].state.x).max()
    with pytest.raises(ValueError, match="solver = 'umf': expected one of 'auto'"):
        make_flow_solver(pr, "umf")
