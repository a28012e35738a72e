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
