"""Re-triangulation cadence of the dragged mesh around a translating, turning plate.

A 0.3 × 0.1 plate moving at 1 and turning at 0.5 rad per time unit in a closed 3 × 1 channel,
h = 0.05, dt = 0.01 (0.2 h per step).  With the drag weight ramp the band between
``drag_full`` and ``drag_reach`` sheared by 0.1 per step and the quality trigger fired every
4–8 steps (11 re-triangulations in 60 steps, the first at step 8); with the harmonic drag
field the first one is the periodic one (step 30) and there are 5 in 60 steps.  The paper
(Sec. 4.2) re-triangulates every 20–50 steps.
"""

import numpy as np

from fluidem.geometry import rectangle
from fluidem.mesh import MovingMesh


def _plate_events(n_steps=60, **params):
    mm = MovingMesh((0.0, 3.0, 0.0, 1.0), [rectangle(0.3, 0.1)], [[0.8, 0.5, 0.0]], h=0.05, **params)
    events = []
    for k in range(1, n_steps + 1):
        t = 0.01 * k
        ev = mm.update([[0.8 + t, 0.5, 0.5 * t]])
        if ev.retriangulated:
            events.append((k, ev.reason))
    return mm, events


def test_translating_plate_retriangulates_at_the_configured_cadence():
    mm, events = _plate_events()
    assert len(events) <= 7, events  # measured 5 (the ramp: 11)
    assert events[0] == (30, "periodic"), events  # the ramp: (8, "quality")
    q = mm.quality()
    assert q.n_inverted == 0 and q.min_angle >= 15.0 and q.max_angle <= 140.0, q


def test_the_ramp_is_still_available():
    _, events = _plate_events(n_steps=12, drag_field="ramp")
    assert events and events[0][1] == "quality" and events[0][0] < 12, events
    assert np.all([r in ("quality", "periodic") for _, r in events])


def test_harmonic_drag_slides_along_the_walls_and_survives_a_pickle():
    import pickle

    from fluidem.mesh.nodes import SIDE, classify_box

    mm, _ = _plate_events(n_steps=3)
    side = mm.kind == SIDE
    assert (classify_box(mm.points[side], mm.box)[0] == SIDE).all()  # box-side nodes stay on their side
    copy = pickle.loads(pickle.dumps(mm))
    for k in range(4, 8):
        pose = [[0.8 + 0.01 * k, 0.5, 0.005 * k]]
        assert mm.update(pose).reason == copy.update(pose).reason
    assert np.array_equal(mm.points, copy.points)


def _there_and_back(body, omega, n_steps=300, **params):
    """h = 0.04 in the 3 × 1 box; U = 1 along x for n/2 steps, then back (the geometry at the end
    is the start's up to the angle), turning at ``omega`` rad per time unit; dt = 0.01."""
    mm = MovingMesh((0.0, 3.0, 0.0, 1.0), [body], [[0.8, 0.5, 0.0]], h=0.04, **params)
    counts, events, half = [len(mm.points)], [], n_steps // 2
    for k in range(1, n_steps + 1):
        x = 0.8 + 0.01 * (k if k <= half else 2 * half - k)
        ev = mm.update([[x, 0.5, omega * 0.01 * k]])
        counts.append(ev.n_nodes)
        if ev.retriangulated:
            events.append((k, ev.reason))
    return mm, np.array(counts), events


def test_node_count_holds_over_a_long_plate_run():
    """300 steps there and back: the count stays within 6 % of the first mesh's (measured:
    within +3.0 %, 1962 -> 2000; before the node budget +25 %, 1962 -> 2448 with a peak of
    2500), and re-triangulations stay at the cadence (measured 16 in 300 steps, 13 of them
    by quality, a median 15 steps apart; before 29)."""
    mm, counts, events = _there_and_back(rectangle(0.3, 0.1), 0.5)
    drift = np.abs(counts / counts[0] - 1.0).max()
    assert drift < 0.065, (drift, counts[0], counts.min(), counts.max())
    assert len(events) <= 28, events
    assert all(r in ("periodic", "quality") for _, r in events), events
    assert np.median(np.diff([k for k, _ in events])) >= 8, events  # not every few steps (measured 15)
    q = mm.quality()
    assert q.n_inverted == 0 and q.min_angle >= 15.0, q


def test_node_count_holds_for_a_translating_disk_and_a_fast_turning_plate():
    """Disk: measured within +3.5 % (before +26.6 %); plate at 2 rad/s: within +1.9 % (before
    +26.7 %), 25 re-triangulations in 300 steps, all by quality (before 46)."""
    t = np.linspace(0.0, 2.0 * np.pi, 33)[:-1]
    _, counts, _ = _there_and_back(0.1 * np.column_stack([np.cos(t), np.sin(t)]), 0.0)
    assert np.abs(counts / counts[0] - 1.0).max() < 0.065, (counts[0], counts.min(), counts.max())
    _, counts, events = _there_and_back(rectangle(0.3, 0.1), 2.0)
    assert np.abs(counts / counts[0] - 1.0).max() < 0.065, (counts[0], counts.min(), counts.max())
    assert len(events) <= 54, events


def test_without_the_node_budget_the_count_drifts():
    _, counts, _ = _there_and_back(rectangle(0.3, 0.1), 0.5, n_steps=60, hold_node_count=False)
    assert counts.max() > 1.1 * counts[0]  # the first re-triangulation refines behind, keeps ahead
