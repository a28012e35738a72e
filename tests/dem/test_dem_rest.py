"""Coming to rest: a block and a column of blocks on the floor, against the linearised contact law.

Unit squares (side 1, mass 1), E = 1e5, μ = 0.5, γ = 0.3, dropped from gaps of 1e-3, g = 9.81,
dt = dt_max / 2.  Linearised about rest, a face-on-face contact of chord |S| is a spring
k = E |S| / l in parallel with a dashpot c = γ √(m_eff E) |S| / l (Matuttis & Chen 2014,
ch. 7; l = 4 r for the wall, 2 r between equal blocks, r = 1/2 the centre–centroid distance).
The damping is stiffness proportional, so a mode of frequency ω decays at about
ζ₀ ω² / ω₀: the lowest mode of a column is damped far less than one contact.  The slowest
decay rate is the largest real part of the eigenvalues of the linear chain
(``M ẍ + C ẋ + K x = 0``); the measured one is the slope of log(max |net force| / weight).

=======================  ===================  ==================  ===============================
case                     predicted rate 1/s   measured rate 1/s   net force ≤ 1e-6 weight at
=======================  ===================  ==================  ===============================
single block             23.7 (ω 222 rad/s)   24.0                t < 1 s (1.6e-12 at 1 s)
column of 8              1.072 (ω 52 rad/s)   1.073               t = 13.8 s (6.0e-7; predicted 13.2 s)
=======================  ===================  ==================  ===============================

The column's slow decay (a decade per 2.1 s) is therefore the contact law, not a defect of the
integrator or of the normal-force cap.  Before the clipping treated vertices within
round-off of a clip edge as on it, the collinear side faces of stacked equal squares gave the
intersection points, and so the chord normal, a random tilt of up to the overlap depth: the
perfectly symmetric column drifted sideways by 5e-5 in 1 s.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import eigvals

from fluidem.dem import Body, ContactModel, DEM

E, MU, GAMMA, G = 1e5, 0.5, 0.3, 9.81
WEIGHT = 1.0 * G


def stack(n: int) -> DEM:
    """``n`` unit squares above the floor y = 0, gaps 1e-3, walls far to the sides."""
    bodies = [Body.rectangle(1.0, 1.0, density=1.0, position=(0.0, 0.5 + k * (1.0 + 1e-3))) for k in range(n)]
    return DEM(bodies, walls=(-5.0, 5.0, 0.0, np.inf), gravity=(0.0, -G), contact=ContactModel(E=E, mu=MU,
                                                                                              gamma=GAMMA))


def slowest_linear_decay(n: int) -> float:
    """Slowest decay rate (1/s) of the linearised column of ``n`` unit blocks on the floor."""
    kw, kb = E / 2.0, E                                        # l = 2 (wall), 1 (block-block), |S| = 1
    cw, cb = GAMMA * np.sqrt(E) / 2.0, GAMMA * np.sqrt(0.5 * E)  # m_eff = 1 (wall), 1/2 (blocks)
    K, C = np.zeros((n, n)), np.zeros((n, n))
    K[0, 0], C[0, 0] = kw, cw
    for i in range(n - 1):
        for A, v in ((K, kb), (C, cb)):
            A[i, i] += v
            A[i + 1, i + 1] += v
            A[i, i + 1] -= v
            A[i + 1, i] -= v
    Z, eye = np.zeros((n, n)), np.eye(n)
    lam = eigvals(np.block([[Z, eye], [-K, -C]]))
    return float(-lam.real.max())


def net_force_history(sim: DEM, t_end: float, every: float = 0.05):
    """Times and the largest net force on any body over weight, every ``every`` time units."""
    dt = 0.5 * sim.dt_max
    ts, nets = [], []
    while sim.time < t_end - 1e-9:
        sim.run(sim.time + every, dt)
        ts.append(sim.time)
        nets.append(np.abs(sim.forces).max() / WEIGHT)
    return np.array(ts), np.array(nets)


def decay_rate(ts, nets, lo, hi) -> float:
    """Slope of the log of the running maximum (over 0.5 time units) of ``nets`` where lo < nets < hi."""
    env = np.array([nets[max(0, k - 10):k + 1].max() for k in range(len(nets))])
    sel = (env < hi) & (env > lo)
    return float(-np.polyfit(ts[sel], np.log(env[sel]), 1)[0])


def test_symmetric_column_stays_symmetric_to_round_off():
    sim = stack(8)
    sim.run(1.0, 0.5 * sim.dt_max)
    # measured 6.6e-16 (x spread) and 4.6e-16 rad; 5.1e-5 and 5.8e-6 rad before the clipping
    # snapped vertices lying on a clip edge
    assert np.ptp(sim.positions[:, 0]) < 1e-13
    assert np.abs(sim.angles).max() < 1e-13
    assert np.abs(sim.velocities[:, 0]).max() < 1e-12


def test_single_block_decays_at_the_rate_of_the_linear_contact():
    pred = slowest_linear_decay(1)
    assert pred == pytest.approx(23.7, abs=0.1)                # ζ ω = 0.106 × 222 rad/s
    ts, nets = net_force_history(stack(1), 1.0, every=0.01)
    rate = decay_rate(ts, nets, 1e-7, 1e-2)
    assert rate == pytest.approx(pred, rel=0.03)               # measured 24.0 1/s (+1.2 %)
    assert nets[-1] < 5e-12                                    # measured 1.6e-12 at t = 1


@pytest.mark.slow(seconds=40)
def test_column_comes_to_rest_at_the_rate_of_its_lowest_mode():
    pred = slowest_linear_decay(8)
    assert pred == pytest.approx(1.072, abs=0.002)
    sim = stack(8)
    ts, nets = net_force_history(sim, 5.0)
    # the time at which the slowest linear mode has brought the net force down to 1e-6 weight
    t_rest = 5.0 + np.log(nets[-10:].max() / 1e-6) / pred      # 13.2 s
    t2, n2 = net_force_history(sim, 1.05 * t_rest)
    rate = decay_rate(np.concatenate([ts, t2]), np.concatenate([nets, n2]), 1e-7, 1e-2)
    assert rate == pytest.approx(pred, rel=0.03)               # measured 1.073 (+0.1 %)
    assert n2[-10:].max() < 1e-6                               # measured 6.0e-7 at 13.8 s
    assert np.ptp(sim.positions[:, 0]) < 1e-13                 # symmetric all the way (8e-16)
