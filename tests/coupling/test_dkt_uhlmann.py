"""The DKT accuracy variant of Uhlmann (2005) through the kiss, against the overset-grid trajectories
of Koblitz et al. (2017, Fig. 10; digitised, ``benchmarks/reference/dkt_uhlmann/``).

The coarsest resolution of ``benchmarks/bench_dkt_uhlmann.py`` (h = 0.02 cm = d/12.5, dt = 1 ms),
run to t = 0.2 s (11.1 t_ref), through the kiss, which lasts from 9.5 to 14 t_ref in both
references: with the lubrication correction it lasts from 9.49 to 15.5 t_ref (measured to
t = 0.3 s); with the resolved film alone the pair rebounds at 10.1 t_ref (0.182 s, within this
run), and the repulsion at the range h of earlier versions swapped the fall speeds within a step
of the kiss.  Measured there (the
benchmark's finer meshes agree): kissing time (centres closer than 1.1 d) 0.1710 s against
Koblitz's 0.1711 s and Uhlmann's 0.1666 s; fall distances before the kiss within 0.016 d (leading)
and 0.015 d (trailing) of Koblitz's curves (Uhlmann's and Koblitz's differ from each other by 0.16 d
for the leading disk); the lateral offsets of ±d/250 grow to 0.017 d by t = 0.15 s.
"""

import pathlib

import numpy as np
import pytest

from fluidem.cases.dkt import UHLMANN, uhlmann_dkt_scene
from fluidem.simulation import Simulation

REFERENCE = pathlib.Path(__file__).resolve().parents[2] / "benchmarks" / "reference" / "dkt_uhlmann"
D, H, T_REF = UHLMANN["d"], UHLMANN["height"], UHLMANN["t_ref"]


def _koblitz_fall(disk):
    """Fall distance from the top wall (cm) against t (s), sorted by time."""
    a = np.loadtxt(REFERENCE / f"Koblitz2017-fig10c-{disk}-particle.csv")
    a = a[np.argsort(a[:, 0])]
    return a[:, 0] * T_REF, -a[:, 1] * D


@pytest.mark.slow(seconds=120)
def test_uhlmann_dkt_follows_the_overset_grid_trajectories_and_keeps_the_kiss():
    sim = Simulation(uhlmann_dkt_scene(h=0.02, dt=0.001, t_end=0.2))
    fl = sim.flow
    rows = []
    sim.run(out_dir=None, progress=lambda k, n, t, cost: rows.append([fl.t, *fl.poses[:2, :2].ravel()]))
    assert fl.contacts.lubrication is not None and fl.contacts.repulsion.range == pytest.approx(2e-4)
    R = np.array(rows)
    t, fall = R[:, 0], H - R[:, [2, 4]]  # leading, trailing
    dist = np.hypot(R[:, 1] - R[:, 3], R[:, 2] - R[:, 4])
    t_kiss = t[np.flatnonzero(dist < 1.1 * D)[0]]
    assert t_kiss == pytest.approx(0.1711, abs=0.0015)  # measured 0.1710 (Koblitz 0.1711, Uhlmann 0.1666)
    # the kiss lasts (centres within 1.1 d) to the end of the run, 11.1 t_ref: no rebound (the film alone: 10.1)
    assert (dist[t >= t_kiss] < 1.1 * D).all()
    # the outlines stay apart: never within the mesh's contact distance 1e-3 h (measured 5.1e-5 cm)
    assert dist.min() - D > 2e-5
    for k, disk in enumerate(("leading", "trailing")):
        tr, fr = _koblitz_fall(disk)
        before = (tr > t[0]) & (tr < 0.1711)
        dev = np.abs(np.interp(tr[before], t, fall[:, k]) - fr[before]).max() / D
        assert dev < 0.05, (disk, dev)  # measured 0.016 (leading), 0.015 (trailing)
    # the pair stays near the centre line while drafting: the offsets of ±d/250 grow to 0.017 d by t = 0.15 s
    assert np.abs(R[t < 0.15][:, [1, 3]] - UHLMANN["width"] / 2).max() < 0.05 * D
