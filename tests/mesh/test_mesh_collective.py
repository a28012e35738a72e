"""Hard case 6 in small: a packing moved as a whole (rotation, breathing, shear), asserted every step.

30 polygons (sizes 0.3-0.6, gaps 0.06-0.18) in a 5 x 5 box, h = 0.1 (about 2.7k nodes), one
period of 60 steps, and a dense cluster (area fraction 0.32, gaps 0.01-0.03) turned and squeezed
until its narrowest gap nearly closes; the full case (120 polygons, h = 0.08, 300 steps) is in
``test_mesh_hard_cases.py`` and ``benchmarks/bench_mesh.py``.
"""

import numpy as np
import pytest

from fluidem.cases.packings import COLLECTIVE_MOTIONS, CollectiveMotion, collective_motion
from fluidem.errors import InputError
from fluidem.mesh import MovingMesh

H = 0.1


def small(kind):
    return collective_motion(kind, h=H, n=30, box_size=5.0, n_steps=60)


@pytest.mark.parametrize("kind", ["rotation", "breathing", "shear"])
def test_a_packing_moved_as_a_whole_keeps_its_mesh(kind):
    m = small(kind)
    assert m.min_gap_seen >= H / 4  # the gaps stay open: measured 0.061, 0.037, 0.044
    mm = MovingMesh(m.box, m.bodies, m.poses0, h=H, strategy="drag")
    worst_min, worst_135, reasons = 90.0, 0.0, {}
    for k, p in enumerate(m.sequence()):
        ev = mm.update(p)
        reasons[ev.reason] = reasons.get(ev.reason, 0) + 1
        q = mm.quality()
        assert q.n_inverted == 0 and q.n_nodes_inside_bodies == 0 and q.min_area > 0, (k, q)
        assert mm.outline_facets_present(), k
        worst_min, worst_135 = min(worst_min, q.min_angle), max(worst_135, q.frac_above_135)
    # measured: worst min angle 18.6°, 15.8°, 18.7°, no angle above 135°
    assert worst_min >= 15.0 and worst_135 <= 0.01
    # no contact, inversion or collapse: the connectivity is kept but for the periodic
    # re-triangulations (every 30 steps) and, in the shear (rim step h/7.5), one for quality
    assert set(reasons) <= {"", "periodic", "quality"}, reasons
    assert reasons[""] >= 57, reasons  # measured 59, 59, 58


def test_collective_motions_are_what_they_say():
    """Rotation: rigid (distances between centres kept); breathing: centre distances scaled by
    1 + a sin; shear: y unchanged, x shifted by γ (y − c_y); one period returns to the start."""
    rot, bre, she = (small(k) for k in ("rotation", "breathing", "shear"))
    k = 15  # a quarter period: s = 1
    d0 = np.linalg.norm(rot.poses0[:, None, :2] - rot.poses0[None, :, :2], axis=2)
    p = rot.poses_at(k)
    assert np.allclose(np.linalg.norm(p[:, None, :2] - p[None, :, :2], axis=2), d0, atol=1e-12)
    assert np.allclose(p[:, 2] - rot.poses0[:, 2], rot.amplitude)
    p = bre.poses_at(k)
    assert np.allclose(p[:, :2] - bre.center, (1 + bre.amplitude) * (bre.poses0[:, :2] - bre.center), atol=1e-12)
    p = she.poses_at(k)
    assert np.allclose(p[:, 1], she.poses0[:, 1])
    assert np.allclose(p[:, 0] - she.poses0[:, 0], she.amplitude * (she.poses0[:, 1] - she.center[1]), atol=1e-12)
    for m in (rot, bre, she):
        assert np.allclose(m.poses_at(60), m.poses0, atol=1e-12)
    # the rotation's default amplitude makes the rim vertices move h/8 in the fastest step
    assert rot.rim_step == pytest.approx(H / 8, rel=0.03)  # measured 0.01233 (1.3 % below: sampled steps)


def test_bad_motion_kind_names_the_value_and_the_choices():
    with pytest.raises(InputError, match=r"'spin'.*rotation"):
        collective_motion("spin")
    m = small("rotation")
    with pytest.raises(InputError, match="'spin'"):
        CollectiveMotion(m.bodies, m.poses0, m.box, "spin", 0.1, 60)
    assert "turn-and-breathe" in COLLECTIVE_MOTIONS


def test_a_dense_cluster_turned_and_squeezed_keeps_its_mesh():
    """30 polygons at area fraction 0.32 with gaps 0.01-0.03 (below h/3), turned by 0.25 rad and
    scaled by 2 % over one period of 150 steps (rim step h/5.7): the narrowest gap closes to
    h/26 without overlap.  Dragging keeps the connectivity between the periodic
    re-triangulations, the angles outside narrow gaps stay within the bounds, and inside the
    narrow gaps they are those of a fresh triangulation at the narrowest step (a gap g ≪ h is
    spanned by one layer of elements between outline nodes h apart)."""
    m = collective_motion("turn-and-breathe", h=H, n=30, phi=0.32, min_gap=0.01, box_size=5.0, n_steps=150,
                          amplitude=(0.25, 0.02))
    assert 0.0 < m.min_gap_seen < H / 10  # measured 0.0039: the gaps nearly close, no body overlaps
    mm = MovingMesh(m.box, m.bodies, m.poses0, h=H, strategy="drag")
    worst_min, worst_all, worst_135, reasons = 90.0, 90.0, 0.0, {}
    for k, p in enumerate(m.sequence()):
        ev = mm.update(p)
        reasons[ev.reason] = reasons.get(ev.reason, 0) + 1
        q = mm.quality()
        assert q.n_inverted == 0 and q.n_nodes_inside_bodies == 0 and q.min_area > 0, (k, q)
        worst_min, worst_135 = min(worst_min, q.min_angle), max(worst_135, q.frac_above_135)
        worst_all = min(worst_all, q.min_angle_all)
    # measured: worst min angle outside narrow gaps 17.4°, share above 135° 0.007 %
    assert worst_min >= 15.0 and worst_135 <= 0.01
    # measured: the 5 periodic re-triangulations only (no contact, inversion, collapse or quality)
    assert set(reasons) <= {"", "periodic", "quality"}, reasons
    assert reasons[""] >= 143, reasons  # measured 145
    narrowest = int(np.argmin([m._min_gap(m.poses_at(k)) for k in range(m.n_steps + 1)]))
    fresh = MovingMesh(m.box, m.bodies, m.poses_at(narrowest), h=H, strategy="drag").quality()
    # measured: 3.94° dragged and fresh (at step 112, gap 0.0039); about atan(2g/h) = 4.5°
    assert worst_all >= 0.9 * fresh.min_angle_all
