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


def test_settling_disk_restarts_bit_for_bit(tmp_path):
    d = settling("navier-stokes", nu=0.01, steps=6, h=0.05).to_dict()
    d["fluid"]["solver"] = "direct"
    d["output"] = {"checkpoint_every": 3}
    full, part = tmp_path / "full", tmp_path / "part"
    Simulation(Scene.from_dict(d)).run(out_dir=full)
    Simulation(Scene.from_dict(d)).run(out_dir=part, n_steps=3)
    Simulation(Scene.from_dict(d)).run(out_dir=part, restart=part / "checkpoints" / "ckpt_0000003.npz")
    a, b = read_history(full), read_history(part)
    assert np.array_equal(a["step"], b["step"])
    assert max(float(np.abs(a[k] - b[k]).max()) for k in a) == 0.0
    assert a["vy"][-1] < -1e-3                             # it does settle
