"""Free bodies in a fluid through the scene path: Stokes mobility (Faxén), rest, restart."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fluidem.io import read_history
from fluidem.scene import Scene
from fluidem.simulation import Simulation


def faxen(k):
    """F/(μU) of a cylinder between two plane walls (Faxén 1946, REFERENCES.md)."""
    return 4 * math.pi / (math.log(1 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6
                          - 4.5913 * k**8)


def settling(model, k=0.2, steps=6, dt=0.01, density=1.5, nu=1.0, h=0.025, **body):
    """A disk (radius 0.1, 64 sides) on the centre line of a closed vertical channel of half-width
    0.1/k, released at rest under g = (0, −1)."""
    half = 0.1 / k
    return Scene.from_dict({
        "gravity": [0.0, -1.0], "fluid": {"model": model, "viscosity": nu, "density": 1.0, "element": "th"},
        "domain": {"box": [-half, half, 0.0, 12 * half]},
        "bodies": [{"shape": "disk", "radius": 0.1, "segments": 64, "position": [0.0, 6 * half], "density": density,
                    **body}],
        "mesh": {"h": h, "grading": {"growth": 1.3, "h_max": 0.3}, "retriangulate_every": 3},
        "time": {"dt": dt, "t_end": dt * steps}})


def test_free_disk_settles_at_the_faxen_speed_in_stokes_flow():
    sim = Simulation(settling("stokes"))
    vel = []
    sim.run(out_dir=None, progress=lambda k, n, t, c: vel.append(sim.flow.body_velocities[0].copy()))
    vel = np.array(vel)
    area = 0.5 * 64 * 0.1**2 * math.sin(2 * math.pi / 64)
    U = 0.5 * area * 1.0 / faxen(0.2)                     # buoyant weight / (μ Faxén), μ = 1
    assert sim.counters["triangulations"] >= 2             # the mesh was rebuilt on the way
    # measured U/U_Faxén − 1 = +5.85e-4 to +5.86e-4 at every step (64-gon, h = 0.025 graded, 4k
    # DOFs; the prescribed disk's resistance in test_simulation is −8e-4 off, the inverse)
    assert np.abs(-vel[:, 1] / U - 1).max() < 1.5e-3
    # no drift or spin beyond the mesh asymmetry: measured |U_x|/U 2.6e-5, a|ω|/U 3.2e-5
    assert np.abs(vel[:, 0]).max() < 8e-5 * U and np.abs(vel[:, 2]).max() * 0.1 < 1e-4 * U
    assert sim.flow.poses[0, 1] == pytest.approx(6 * 0.5 - U * 6 * 0.01, rel=1e-6)


def test_neutrally_buoyant_disk_in_fluid_at_rest_stays_at_rest():
    sim = Simulation(settling("navier-stokes", density=1.0, nu=0.01, steps=8, h=0.04))
    sim.run(out_dir=None)
    assert sim.counters["triangulations"] >= 2
    assert np.abs(sim.flow.body_velocities).max() == 0.0
    assert np.abs(sim.flow.x).max() == 0.0


@pytest.mark.parametrize("ale_form", ["non-conservative", "conservative"])
def test_settling_disk_restarts_bit_for_bit(tmp_path, ale_form):
    """Also in the conservative ALE form, whose checkpoints carry the mass-weighted history."""
    d = settling("navier-stokes", nu=0.01, steps=6, h=0.05).to_dict()
    d["fluid"].update(solver="direct", ale_form=ale_form)
    d["output"] = {"checkpoint_every": 3}
    full, part = tmp_path / "full", tmp_path / "part"
    Simulation(Scene.from_dict(d)).run(out_dir=full)
    Simulation(Scene.from_dict(d)).run(out_dir=part, n_steps=3)
    Simulation(Scene.from_dict(d)).run(out_dir=part, restart=part / "checkpoints" / "ckpt_0000003.npz")
    a, b = read_history(full), read_history(part)
    assert np.array_equal(a["step"], b["step"])
    assert max(float(np.abs(a[k] - b[k]).max()) for k in a) == 0.0
    assert a["vy"][-1] < -1e-3                             # it does settle


@pytest.mark.parametrize("element", ["th", "p2b"])
def test_spinning_disk_feels_the_torque_of_the_true_viscous_traction(element):
    """T = −4πμa²Ω (1 + O(a²/R²)) for a disk spinning in fluid at rest; the Laplacian form of the
    viscous term gave half of it (its boundary term misses ν (∇u)ᵀ n, which a rotation has)."""
    d = {"gravity": [0.0, 0.0], "fluid": {"model": "stokes", "viscosity": 1.0, "element": element},
         "domain": {"box": [-4.0, 4.0, -4.0, 4.0]},
         "bodies": [{"shape": "disk", "radius": 0.1, "segments": 64, "motion": "prescribed", "omega": 1.0}],
         "mesh": {"h": 0.01, "grading": {"growth": 1.2, "h_max": 0.4}}, "time": {"dt": 0.05, "t_end": 0.05}}
    sim = Simulation(Scene.from_dict(d))
    sim.run(out_dir=None)
    # measured T / (−4πμa²Ω) − 1 = +5.8e-4 (th and p2b; the box adds ~2e-4); 0.50 before
    assert abs(sim.last_loads[1][0] / (-4 * math.pi * 0.01) - 1) < 1.5e-3


def shear_cell(radius, h, steps=2, shape=None):
    """Stokes shear cell: walls y = ±1 moving at ±1 (shear rate 1), periodic in x over [0, 4]."""
    body = shape or {"shape": "disk", "radius": radius, "segments": 64}
    return Scene.from_dict({
        "gravity": [0.0, 0.0], "fluid": {"model": "stokes", "viscosity": 1.0, "element": "th"},
        "domain": {"box": [0.0, 4.0, -1.0, 1.0], "left": "periodic", "right": "periodic",
                   "bottom": {"type": "moving-wall", "velocity": [-1.0, 0.0]},
                   "top": {"type": "moving-wall", "velocity": [1.0, 0.0]}},
        "bodies": [{**body, "position": [2.0, 0.0]}],
        "mesh": {"h": h, "grading": {"growth": 1.2, "h_max": 0.2}}, "time": {"dt": 0.05, "t_end": 0.05 * steps}})


def test_free_disk_in_a_shear_cell_turns_at_half_the_shear_rate():
    """Ω = −γ̇/2 (1 − c (a/H)²) with the walls at H = 1: c the same for two radii."""
    coef = []
    for a, h in ((0.1, 0.02), (0.05, 0.01)):
        sim = Simulation(shear_cell(a, h))
        sim.run(out_dir=None)
        U, V, om = sim.flow.body_velocities[0]
        assert abs(U) < 1e-5 and abs(V) < 1e-5                # measured 2.6e-7, 4.5e-7: the centre stays
        coef.append((1 + om / 0.5) / a**2)
    # measured c = 0.546 (a = 0.1) and 0.541 (a = 0.05): Ω/(−γ̇/2) = 0.9945, 0.99865
    assert coef[0] == pytest.approx(coef[1], rel=0.03) and 0.3 < coef[0] < 0.8


def _settling_velocity(ratio, coupling, steps=30):
    sc = settling("navier-stokes", density=ratio, nu=0.01, steps=steps, h=0.04)
    sc.fluid.coupling = coupling
    sc.validate()
    sim = Simulation(sc)
    vy = []
    sim.run(out_dir=None, progress=lambda k, n, t, c: vy.append(sim.flow.body_velocities[0, 1]))
    return np.array(vy), sim


def test_explicit_coupling_blows_up_at_density_ratio_one_and_agrees_with_implicit_for_heavy_bodies():
    """The staggered step lags the added mass by one step: it diverges (sign-alternating) at
    ρ_s/ρ_f = 1.01, where the implicit step settles smoothly; at ratio 10 both agree."""
    with pytest.warns(UserWarning, match="density ratio rho_s/rho_f = 1.01"):
        exp, _ = _settling_velocity(1.01, "explicit")
    imp, _ = _settling_velocity(1.01, "implicit")
    assert np.all(np.diff(imp) < 0)                      # implicit: monotone settling
    # measured |v| at step 30: explicit 0.257, implicit 6.7e-4; the explicit one flips sign
    assert abs(exp[-1]) > 100 * abs(imp[-1]) and np.any(np.sign(exp[10:]) > 0)
    heavy_exp, _ = _settling_velocity(10.0, "explicit")
    heavy_imp, _ = _settling_velocity(10.0, "implicit")
    # measured relative difference at step 30: 1.3 % (the explicit step lags the force by dt)
    assert heavy_exp[-1] == pytest.approx(heavy_imp[-1], rel=0.04)


def jeffery_half_period(a, h, r=2.0, dt=0.05, t_end=8.5):
    """Half period and the extreme angular velocities of a free ellipse (semi-axes a, a/r) in the
    Stokes shear cell, turning from its start along the flow through π."""
    sc = shear_cell(None, h, steps=int(round(t_end / dt)),
                    shape={"shape": "ellipse", "a": a, "b": a / r, "segments": 64})
    sim = Simulation(sc)
    rows = []
    sim.run(out_dir=None, progress=lambda k, n, t, c: rows.append((t, sim.flow.poses[0, 2],
                                                                  sim.flow.body_velocities[0, 2])))
    t, angle, om = np.array(rows).T
    return float(np.interp(np.pi, -angle, t)), float(om.min()), float(om.max()), sim.counters["triangulations"]


@pytest.mark.slow(seconds=130)
def test_free_ellipse_in_shear_follows_a_jeffery_orbit():
    """Jeffery (1922): half period π (r + 1/r)/γ̇ and ω between −γ̇ r²/(r²+1) and −γ̇/(r²+1),
    up to the walls' confinement, which grows as (a/H)²."""
    r = 2.0
    T_half = np.pi * (r + 1 / r)
    t_far, om_min, om_max, n_tri = jeffery_half_period(0.1, 0.01)
    t_near, *_ = jeffery_half_period(0.2, 0.02)
    assert n_tri > 10                                     # the mesh followed the turning body
    # measured half periods 7.928 (a = 0.1) and 8.152 (a = 0.2) against 7.854: +0.94 %, +3.79 %
    assert t_far / T_half - 1 < 0.015
    assert (t_near / T_half - 1) / (t_far / T_half - 1) == pytest.approx(4.0, rel=0.15)  # measured 4.03
    # measured ω between −0.8014 and −0.1961 against −0.8 and −0.2
    assert om_min == pytest.approx(-r * r / (r * r + 1), rel=0.005)
    assert om_max == pytest.approx(-1 / (r * r + 1), rel=0.05)


@pytest.mark.slow(seconds=45)
def test_settling_disk_reaches_its_steady_terminal_velocity():
    """Navier–Stokes, ρ_s/ρ_f = 1.5, Re ≈ 1.8: the coupled run from rest against the terminal
    velocity of steady flows in the disk's frame (fluidem.cases.settling)."""
    from fluidem.cases.settling import settling_disk

    r = settling_disk()
    # measured: extrapolated terminal speed 1.7e-5 below the steady one (0.091933 vs 0.091935;
    # 1.2e-4 on the meshes before the node budget), 0.7 % below it at t = 5 (still approaching);
    # sideways drift 1.1e-5 of the distance fallen (1.4e-5)
    assert r.relative_errors()["u_terminal"] < 3e-4
    assert r.quantities["drift"] < 3e-5


@pytest.mark.parametrize("model", ["navier-stokes", "stokes"])
def test_a_re_triangulated_steps_cost_split_adds_up_to_its_wall_time(model, monkeypatch):
    """The parts of a step's cost split are disjoint and cover the step: at a re-triangulation the
    field transfer was charged twice (to "rebuild" in the hand-over and again to "coupling") and the
    new rigid-body system to no part.  Both are slowed by 0.3 s here so either fault shows: the sum
    of the parts stays within the step's wall time, and less than a third of the injected 0.3 s
    below it (measured: 1.0-1.5 ms below on the re-triangulated steps; before the fix 4 ms above
    with Navier-Stokes, where the two faults nearly cancel, and 0.32 s below with Stokes)."""
    import time

    from fluidem.coupling import free_flow, moving_flow

    def slowed(f):
        def g(*a, **k):
            time.sleep(0.3)
            return f(*a, **k)
        return g

    monkeypatch.setattr(moving_flow.MovingMeshFlow, "_transfer", slowed(moving_flow.MovingMeshFlow._transfer))
    monkeypatch.setattr(free_flow, "RigidBodySystem", slowed(free_flow.RigidBodySystem))
    sim = Simulation(settling(model, steps=4, h=0.05))
    seen = []
    last = [time.perf_counter()]

    def progress(k, n, t, cost):
        now = time.perf_counter()
        if sim.flow.last_event.retriangulated:
            seen.append((now - last[0], cost.total, cost.rebuild))
        last[0] = now

    sim.run(out_dir=None, progress=progress)
    assert seen, "the run re-triangulates (retriangulate_every = 3)"
    for wall, parts, rebuild in seen:
        assert wall - 0.1 <= parts <= wall + 1e-3, (wall, parts)
        assert rebuild >= 0.3 if model == "stokes" else rebuild >= 0.6
