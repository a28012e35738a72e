"""The DEM in periodic boxes (fluidem.dem.periodic): unwrapped positions, every pair between nearest
images (contacts, repulsion, lubrication, the fluid coupling's pair searches), walls only on the
non-periodic sides."""

import numpy as np
import pytest

from fluidem.dem import DEM, Body, ContactModel
from fluidem.dem.bodies import random_convex_vertices
from fluidem.dem.lubrication import Lubrication
from fluidem.dem.repulsion import Repulsion
from fluidem.errors import InputError

VA = random_convex_vertices(0.1, 6, 1.3, rng=np.random.default_rng(1))
VB = random_convex_vertices(0.1, 5, 1.5, rng=np.random.default_rng(2))
MODEL = ContactModel(E=1e4, mu=0.5, gamma=0.3)
MID = np.array([0.5, 0.5])


def _pair(pa, pb, period=(1.0, 1.0), walls=None, swap=False, **kw):
    """Two irregular polygons at ``pa``, ``pb``, turning and moving (tangential spring, damping)."""
    a = Body.polygon(VA, density=1.0, position=tuple(pa), angle=0.3, velocity=(-0.3, 0.1), omega=2.0)
    b = Body.polygon(VB, density=1.0, position=tuple(pb), angle=-0.2, velocity=(0.2, 0.0), omega=-1.0)
    return DEM([b, a] if swap else [a, b], walls=walls, gravity=(0.0, 0.0), contact=MODEL, period=period,
               overlap_tolerance=0.05, **kw)


def _run_pair(pa, pb, steps=40, **kw):
    sim = _pair(pa, pb, **kw)
    F, T, n = [], [], []
    for _ in range(steps):
        sim.step(0.5 * sim.dt_max)
        F.append(sim.forces.copy())
        T.append(sim.torques.copy())
        n.append(len(sim.contacts))
    return sim, np.array(F), np.array(T), np.array(n)


# B relative to A: overlapping by ~1 % of the smaller area in the middle of the box
D_CONTACT = np.array([-0.064, 0.02])

# (A's position, B's periodic offset in periods, period, walls): the pair meets across the left/right seam,
# A's outline over the left side; across the bottom/top seam; at a corner (both seams); far unwrapped (A
# crossed twice, B once); across the seam with walls on the box whose x sides must not act
SEAMS = {
    "x": ((0.01, 0.5), (1, 0), (1.0, 1.0), None),
    "y": ((0.6, 0.99), (0, -1), (1.0, 1.0), None),
    "corner": ((0.01, 0.99), (1, -1), (1.0, 1.0), None),
    "unwrapped": ((2.01, -0.7), (-1, 1), (1.0, 1.0), None),
    "x with y walls": ((0.01, 0.5), (1, 0), (1.0, None), (0.0, 1.0, 0.0, 1.0)),
}


@pytest.mark.parametrize("seam", list(SEAMS))
def test_contact_across_a_seam_is_the_translated_contact(seam):
    """Two polygons overlapping through a periodic seam feel, step after step (elastic, damping and friction
    forces, torques), what the same pair feels translated to the middle of the box, to round-off, and move by
    the same displacements (positions stay unwrapped)."""
    pa, k, period, walls = SEAMS[seam]
    pa = np.array(pa)
    L = np.array([1.0, 1.0])
    pb = pa + D_CONTACT + np.array(k) * L
    ref, Fr, Tr, nr = _run_pair(MID, MID + D_CONTACT, period=period, walls=walls)
    sim, F, T, n = _run_pair(pa, pb, period=period, walls=walls)
    assert nr[:10].min() == 1  # measured: the pair touches for the first 14 of the 40 steps, then parts
    np.testing.assert_array_equal(n, nr)
    scale = np.abs(Fr).max()
    # measured, of the largest force / torque: 7.5e-14 / 6.8e-14 (x, x with y walls), 1.3e-13 / 1.1e-13 (y),
    # 7.8e-14 / 7.6e-14 (corner), 4.2e-13 / 3.0e-13 (unwrapped, coordinates near 2)
    assert np.abs(F - Fr).max() < 1e-12 * scale
    assert np.abs(T - Tr).max() < 9e-13 * np.abs(Tr).max()
    # A and B moved alike: unwrapped positions, the same displacements as in the middle
    np.testing.assert_allclose(sim.positions - [pa, pb], ref.positions - [MID, MID + D_CONTACT], rtol=0,
                               atol=1e-14)  # measured: ≤ 4.2e-15 (unwrapped), 1.6e-15 (x)
    np.testing.assert_allclose(sim.velocities, ref.velocities, rtol=0, atol=1.5e-12)  # measured: ≤ 5.9e-13
    # the contact at the start sees B's image shifted back by its offset
    assert _pair(pa, pb, period=period, walls=walls).contacts.shift.tolist() == [(-np.array(k) * L).tolist()]


def test_seam_contact_with_the_bodies_listed_the_other_way_round():
    """The same with B (just inside the right side) first in the list: the pair (0, 1) then sees A's image
    shifted the other way."""
    pa = np.array([0.01, 0.5])
    pb = pa + D_CONTACT + [1.0, 0.0]
    ref, Fr, Tr, _ = _run_pair(MID, MID + D_CONTACT)
    sim, F, T, n = _run_pair(pa, pb, swap=True)
    assert n[:10].min() == 1  # measured: touching for the first 14 steps
    assert np.abs(F[:, ::-1] - Fr).max() < 1.5e-13 * np.abs(Fr).max()  # measured: 5.4e-14
    assert np.abs(T[:, ::-1] - Tr).max() < 1.5e-13 * np.abs(Tr).max()  # measured: 5.0e-14
    assert _pair(pa, pb, swap=True).contacts.shift.tolist() == [[1.0, 0.0]]


# B relative to A: a gap of 5.7e-3 between the outlines in the middle of the box, closing at about 0.5
D_NEAR = np.array([-0.072, 0.02])
NEAR = dict(repulsion=Repulsion(range=0.01, force=0.05, epsilon=0.05),
            lubrication=Lubrication(viscosity=0.05, range=0.02, min_gap=0.002))


@pytest.mark.parametrize("seam", ["x", "corner", "x with y walls"])
def test_repulsion_and_lubrication_across_a_seam_are_the_translated_ones(seam):
    """A pair approaching within the repulsion's and the lubrication's ranges across a seam: the same forces
    (repulsion, and the implicit film's share folded into them), torques and velocities as in the middle."""
    pa, k, period, walls = SEAMS[seam]
    pa = np.array(pa)
    pb = pa + D_NEAR + np.array(k)
    ref, Fr, Tr, nr = _run_pair(MID, MID + D_NEAR, period=period, walls=walls, **NEAR)
    sim, F, T, n = _run_pair(pa, pb, period=period, walls=walls, **NEAR)
    assert nr.max() == 0 and ref.repulsion_pairs == 1 and ref.lubrication_pairs == 1  # measured: no overlap, 1 and 1
    assert (sim.repulsion_pairs, sim.lubrication_pairs) == (1, 1)
    # the repulsion and the film change the velocities: the free flight would keep them
    assert np.abs(ref.velocities[0] - [-0.3, 0.1]).max() > 0.05  # measured: 0.228
    # measured, of the largest force / torque: 3.8e-14 / 6.7e-14 (x, x with y walls), 3.5e-14 / 8.2e-14 (corner)
    assert np.abs(F - Fr).max() < 1e-13 * np.abs(Fr).max()
    assert np.abs(T - Tr).max() < 2.5e-13 * np.abs(Tr).max()
    np.testing.assert_allclose(sim.velocities, ref.velocities, rtol=0, atol=1e-14)  # measured: ≤ 3.2e-15
    # the closest gap met (5.4e-3): measured equal to 8.0e-14 (corner), 7.5e-14 (x)
    assert sim.closest_gap_seen == pytest.approx(ref.closest_gap_seen, rel=2.5e-13)


def _periodic_scene():
    """Two polygons in a box periodic in x and y (2 × 1), fluid at rest, no gravity."""
    from fluidem.scene import Scene

    sides = dict.fromkeys(("left", "right", "bottom", "top"), "periodic")
    return Scene.from_dict({
        "gravity": [0.0, 0.0], "fluid": {"density": 1.0, "viscosity": 0.01},
        "domain": {"box": [0.0, 2.0, 0.0, 1.0], **sides},
        "bodies": [{"name": "a", "shape": "polygon", "vertices": VA.tolist(), "position": [0.6, 0.5], "density": 1.2},
                   {"name": "b", "shape": "polygon", "vertices": VB.tolist(), "position": [1.4, 0.5], "density": 1.2}],
        "contact": {"E": 1e4, "mu": 0.0, "repulsion_force": 0.01, "repulsion_range": 0.01},
        "mesh": {"h": 0.04}, "time": {"dt": 0.01, "t_end": 0.1}})


@pytest.mark.parametrize("offset", [(2.0, 0.0), (0.0, -1.0), (2.0, -1.0)])
def test_fluid_contacts_across_a_seam_are_the_translated_ones(offset):
    """FluidContacts of a scene with periodic sides: the DEM gets the periods, and the pair searches
    (within_reach, sub_steps), the repulsion's force and stiffness, the contact counts and the sub-stepped
    contact load of a pair across a seam are those of the pair in the middle."""
    from fluidem.coupling.contacts import FluidContacts

    sc = _periodic_scene()
    c = FluidContacts(sc.bodies, np.array([0, 1]), [VA, VB], [None, None],
                      domain=sc.domain, fluid=sc.fluid, contact=sc.contact, gravity=sc.gravity, h=sc.mesh.h)
    assert c.dem.period == (2.0, 1.0)
    pa = np.array({(2.0, 0.0): (0.01, 0.5), (0.0, -1.0): (0.6, 0.995), (2.0, -1.0): (0.01, 0.99)}[offset])
    mid = np.array([[1.0, 0.5, 0.3], [1.0 + D_NEAR[0], 0.5 + D_NEAR[1], -0.2]])
    seam = mid + np.r_[pa - mid[0, :2], 0.0]
    seam[1, :2] += offset
    assert np.linalg.norm(seam[1, :2] - seam[0, :2]) > 0.5  # the unwrapped centres lie a period apart
    vel = np.array([[-0.3, 0.1, 2.0], [0.2, 0.0, -1.0]])
    dt = 0.01
    assert c.within_reach(mid, 0.0) and c.within_reach(seam, 0.0)
    # measured: 35 sub-steps in both, the DEM's bound (the gap 5.7e-3 may close in the pass); a pair the
    # search missed would give 1 ("no gap within the short-range models' reach")
    assert c.sub_steps(dt, seam, vel, vel) == c.sub_steps(dt, mid, vel, vel)
    assert c.sub_steps(dt, seam, vel, vel)[0] > 1
    Fm, Km = c.repulsion_linearised(mid)
    Fs, Ks = c.repulsion_linearised(seam)
    assert np.abs(Fm).max() > 1.0  # measured: 4.5 (gap 5.7e-3 in the range 0.01)
    np.testing.assert_allclose(Fs, Fm, rtol=0, atol=3e-13 * np.abs(Fm).max())  # measured: ≤ 1.07e-13 of it
    np.testing.assert_allclose(Ks.toarray(), Km.toarray(), rtol=0,
                               atol=1.5e-13 * np.abs(Km.toarray()).max())  # measured: ≤ 5.5e-14 of it
    assert c.contact_counts(seam).tolist() == c.contact_counts(mid).tolist() == [1, 1]
    Lm = c.load_function(0.0, dt, mid, vel)(vel[[0, 1]], np.zeros((2, 3)))
    c.seen_last_step = None  # the seam's pass a first step too, not one after the middle's
    Ls = c.load_function(0.0, dt, seam, vel)(vel[[0, 1]], np.zeros((2, 3)))
    assert np.abs(Lm).max() > 0.1  # measured: 0.65
    np.testing.assert_allclose(Ls, Lm, rtol=0, atol=2.5e-13 * np.abs(Lm).max())  # measured: ≤ 9.2e-14 of it


def test_scene_dem_gets_the_periods_of_its_sides():
    """A dry DEM built from a scene (DEMBodies) is periodic where the scene's sides are, with no walls there."""
    from fluidem.build import body_outlines
    from fluidem.coupling.bodies import DEMBodies

    sc = _periodic_scene()
    d = DEMBodies(sc.bodies, body_outlines(sc), domain=sc.domain, contact=sc.contact, gravity=sc.gravity).dem
    assert d.period == (2.0, 1.0) and d.walls == (-np.inf, np.inf, -np.inf, np.inf)


def test_doubly_periodic_dry_run_keeps_its_momentum_through_seams():
    """Nine polygons in a doubly periodic box, no walls, no gravity, random velocities, undamped contacts
    (γ = 0; Coulomb friction μ = 0.3 acts): pair forces are equal and opposite across the seams too, so the
    total momentum stays at its start to round-off through many crossings and contacts across seams."""
    rng = np.random.default_rng(3)
    bodies = [Body.polygon(random_convex_vertices(0.2, int(rng.integers(4, 8)), 1.4, rng=rng), density=1.0,
                           position=((k % 3 + 0.5) / 3, (k // 3 + 0.5) / 3), angle=rng.uniform(0, 6),
                           velocity=tuple(rng.normal(0.0, 1.0, 2)), omega=rng.normal(0.0, 3.0)) for k in range(9)]
    sim = DEM(bodies, walls=None, gravity=(0.0, 0.0), contact=ContactModel(E=1e3, mu=0.3, gamma=0.0), period=(1.0, 1.0))
    P0 = (sim.mass[:, None] * sim.velocities).sum(axis=0)
    scale = (sim.mass[:, None] * np.abs(sim.velocities)).sum()
    dt = 0.5 * sim.dt_max
    cells = np.floor(sim.positions)
    crossings = seam_contacts = contacts = 0
    drift = jump = 0.0
    x = sim.positions.copy()
    for _ in range(2000):
        sim.step(dt)
        c = np.floor(sim.positions)
        crossings += int(np.abs(c - cells).sum())
        cells = c
        C = sim.contacts
        contacts += len(C)
        seam_contacts += int((np.abs(C.shift).sum(axis=1) > 0).sum())
        drift = max(drift, np.abs((sim.mass[:, None] * sim.velocities).sum(axis=0) - P0).max())
        jump = max(jump, np.abs(sim.positions - x).max())
        x = sim.positions.copy()
    assert crossings >= 5 and seam_contacts >= 100  # measured: 9 crossings, 280 of 500 contact-steps across seams
    assert drift < 7e-16 * scale  # measured: 2.5e-16 of Σ m|v|
    assert jump < 0.01  # no jump by a period: measured 1.0e-3 (the fastest body's step)


def test_body_crossing_the_seam_between_walls_moves_on_continuously():
    """Periodic in x, walls below and above: a square sliding on the floor (μ = 0) across the right side
    keeps its unwrapped x continuous (it ends beyond the box, x > xmax, not wrapped), the floor holds it and
    the box's x sides do not act."""
    sq = Body.rectangle(0.1, 0.1, density=1.0, position=(0.8, 0.0499), velocity=(4.0, 0.0))
    sim = DEM([sq], walls=(0.0, 1.0, 0.0, 1.0), gravity=(0.0, -9.81), contact=ContactModel(E=1e4, mu=0.0, gamma=0.3),
              period=(1.0, None))
    assert sim.period == (1.0, None) and sim.walls == (0.0, 1.0, 0.0, 1.0)
    dt = 0.5 * sim.dt_max
    xs, ys = [sim.positions[0, 0]], [sim.positions[0, 1]]
    for _ in range(int(0.35 / dt)):
        sim.step(dt)
        xs.append(sim.positions[0, 0])
        ys.append(sim.positions[0, 1])
    xs, ys = np.array(xs), np.array(ys)
    assert xs[-1] > 2.1  # measured: 2.200 (0.8 + 4 × 0.35): it crossed x = 1 and x = 2
    assert np.abs(np.diff(xs) - 4.0 * dt).max() < 4e-16  # measured: 1.4e-16 (steps of 6.3e-4, none wrapped)
    # the floor holds it (free fall would drop it by 0.6): measured lowest 0.04990, last 0.04998
    assert ys.min() > 0.0498


def _disks(*xs, r=0.05):
    return [Body.disk(r, 12, position=(x, 0.5)) for x in xs]


@pytest.mark.parametrize("kwargs, match", [
    (dict(walls=(0.0, 2.0, 0.0, 1.0), period=(1.0, None)), r"DEM\(walls=...\).*span 2, not the period 1"),
    (dict(walls=(0.0, 1.0, 0.0, 1.0), period=(None, 0.5)), r"DEM\(walls=...\).*y axis.*span 1, not the period 0.5"),
    (dict(period=(-1.0, None)), r"DEM\(period=...\) = \(-1.0, None\): expected None or \(L_x, L_y\)"),
    (dict(period="x"), r"DEM\(period=...\) = 'x': expected"),
    (dict(period=(1.0,)), r"DEM\(period=...\) = \(1.0,\): expected"),
    (dict(period=(np.inf, None)), r"DEM\(period=...\) = \(inf, None\): expected"),
])
def test_bad_period_is_a_one_line_error(kwargs, match):
    with pytest.raises(InputError, match=match) as e:
        DEM(_disks(0.2, 0.6), gravity=(0.0, 0.0), **kwargs)
    assert "\n" not in str(e.value)


def test_bodies_wider_than_half_the_period_are_refused_in_one_line():
    """Two disks of radius 0.26 in a period of 1 could touch two images of each other: refused, naming them;
    the same through add_bodies, and with a short-range model's reach on top."""
    with pytest.raises(InputError, match=r"DEM\(period=...\) = \(1, None\): bodies 0 and 1 have bounding radii "
                                         r"0.26 and 0.26 .* >= half the x period 1") as e:
        DEM(_disks(0.3, 0.9, r=0.26), gravity=(0.0, 0.0), period=(1.0, None))
    assert "\n" not in str(e.value)
    sim = DEM(_disks(0.25, r=0.24), gravity=(0.0, 0.0), period=(1.0, None))  # 0.24 + 0.24 < 0.5: allowed
    with pytest.raises(InputError, match=r"DEM.add_bodies\(bodies=...\) = \(1, None\): bodies 1 and 0"):
        sim.add_bodies(_disks(0.75, r=0.27))
    with pytest.raises(InputError, match=r"short-range reach 0.03"):
        DEM(_disks(0.25, 0.75, r=0.24), gravity=(0.0, 0.0), period=(1.0, None),
            repulsion=Repulsion(range=0.03, force=1.0))
    with pytest.raises(InputError, match=r"body 0 has bounding radius 0.55 .* >= the x period 1"):
        DEM(_disks(0.5, r=0.55), gravity=(0.0, 0.0), period=(1.0, None))


@pytest.mark.parametrize("period, cells", [((1.0, 1.0), 0.1), ((1.0, None), 0.1), ((None, 0.3), 0.1),
                                           ((0.25, 0.25), 0.1), ((1.0, 1.0), 0.5)])
def test_periodic_broad_phase_finds_exactly_the_nearest_image_pairs(period, cells):
    """grid_pairs in a periodic box (unwrapped centres, a few periods away; periods of 10, 3, 2.5 and 2 cells,
    one large body tested against all) returns the pairs whose nearest images' bounding circles overlap,
    each once: those of a brute-force search over all pairs."""
    from fluidem.dem.contact import grid_pairs
    from fluidem.dem.periodic import as_period, image_shift

    L = as_period("period", period)
    rng = np.random.default_rng(5)
    n = 300
    c = rng.uniform(-2.0, 3.0, (n, 2))
    r = rng.uniform(0.2, 0.5, n) * 0.5 * cells
    r[7] = 0.11 if L.max() < 1 else 0.3  # larger than a cell: against all
    movable = rng.uniform(size=n) > 0.1
    i, j = grid_pairs(c, r, cells, movable, skin=0.01, period=L)
    a, b = np.triu_indices(n, 1)
    d = c[b] - c[a]
    d = d + image_shift(d, L)
    want = ((d * d).sum(axis=1) < (r[a] + r[b] + 0.01) ** 2) & (movable[a] | movable[b])
    got = np.sort(i * n + j)
    assert len(np.unique(got)) == len(got)  # each pair once
    np.testing.assert_array_equal(got, np.sort(a[want] * n + b[want]))
    assert want.sum() > 30  # measured: 69 to 4920 pairs (9 to 238 of them with the large body)


def test_checkpoint_round_trip_keeps_the_periods_and_reads_older_states():
    """A periodic DEM survives the checkpoint codec with its periods; a state written before periodic boxes
    (no ``_L``, ``_wall_box``, contacts without ``shift``) restores as a non-periodic DEM that steps."""
    from fluidem.checkpoint import decode, encode

    sim = _pair((0.01, 0.5), (0.946, 0.52), period=(1.0, None), walls=(0.0, 1.0, 0.0, 1.0))
    arrays = []
    back = decode(encode(sim, arrays, copy=True), arrays)
    assert back.period == (1.0, None) and back.walls == (0.0, 1.0, 0.0, 1.0)
    back.step(0.5 * back.dt_max)
    sim.step(0.5 * sim.dt_max)
    np.testing.assert_array_equal(back.forces, sim.forces)
    old = _pair(MID, MID + D_CONTACT, period=None, walls=(0.0, 1.0, 0.0, 1.0))
    state = dict(old.__dict__)
    del state["_L"], state["_wall_box"]
    del old.contacts.shift
    restored = DEM.__new__(DEM)
    restored.__setstate__(state)
    assert restored.period == (None, None) and restored.contacts.shift.shape == (1, 2)
    restored.step(0.5 * restored.dt_max)
    assert len(restored.contacts) == 1


def test_a_dry_periodic_scene_runs_with_contacts_across_the_seam(tmp_path):
    """A dry scene with periodic left/right sides (the plan refused it before the DEM had periods): two
    equal disks approach each other through the seam at ∓2 and collide there; momentum stays zero to
    round-off, the undamped (γ = 0), frictionless collision swaps their velocities, and the outputs give
    positions in the box with continuous unwrapped ones."""
    from fluidem.io import read_history
    from fluidem.scene import Scene
    from fluidem.simulation import Simulation

    disk = {"shape": "disk", "radius": 0.05, "segments": 32, "motion": "free"}
    sc = Scene.from_dict({"gravity": [0.0, 0.0],
                          "domain": {"box": [0.0, 1.0, 0.0, 1.0], "left": "periodic", "right": "periodic"},
                          "bodies": [dict(disk, position=[0.9, 0.5], velocity=[2.0, 0.0]),
                                     dict(disk, position=[0.1, 0.5], velocity=[-2.0, 0.0])],
                          "contact": {"E": 1e5, "mu": 0.0, "gamma": 0.0},
                          "time": {"dt": 1e-3, "t_end": 0.06}, "output": {"every": 1000}})
    assert not sc.plan().unsupported
    Simulation(sc).run(out_dir=tmp_path)
    h = read_history(tmp_path)
    a, b = h["id"] == 0, h["id"] == 1
    assert np.abs(h["vx"][a] + h["vx"][b]).max() < 1e-12  # momentum: measured 0 (equal masses)
    assert h["vx"][a][-1] == pytest.approx(-2.0, rel=1e-3)  # velocities swapped: measured -2.0000
    assert ((h["x"] >= 0.0) & (h["x"] < 1.0)).all()
    # they met at the seam: each turned back one radius from it (less the contact's overlap)
    assert 1.0 - h["x_unwrapped"][a].max() == pytest.approx(0.05, abs=3e-3)  # measured 0.0487 (the overlap)
    assert h["x_unwrapped"][b].min() == pytest.approx(0.05, abs=3e-3)  # measured 0.0487 (the overlap)
    turn = np.argmax(h["vx"][a] < 0)  # the collision is at the seam: the contact point x = 1 (= 0)
    assert abs(0.5 * (h["x_unwrapped"][a][turn] + h["x_unwrapped"][b][turn] + 1.0) - 1.0) < 1e-9
