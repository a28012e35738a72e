"""Contacts of many bodies at the cost of the physics in play (fluidem.coupling.contacts.FluidContacts.sub_steps,
fluidem.dem.lubrication.implicit_damping, fluidem.coupling.free_bodies.AndersonMixing): the sub-steps follow
the stiffness that can act, the film's damping is implicit, and the contact counts reach history.csv."""

import numpy as np
import pytest

from fluidem.coupling import contacts as fluid_contacts
from fluidem.dem import DEM, Body, ContactModel
from fluidem.dem.lubrication import Lubrication
from fluidem.io import read_history
from fluidem.simulation import Simulation

from test_fluid_contacts import A, _floor_scene, _run  # same folder (pytest puts it on the path)


def _at_the_dems_bound(self, dt, poses, *args, **kwargs):
    """FluidContacts.sub_step_groups as before the stiffness in play: every body, every pass at the DEM's bound."""
    return [(np.arange(len(poses)), max(int(np.ceil(dt / self.dem.dt_max - 1e-9)), 1), -np.inf, "the DEM's bound")]


def test_a_disk_draining_onto_the_floor_takes_the_sub_steps_in_play_and_follows_the_bounded_run(monkeypatch):
    """A disk (ρ_s/ρ_f = 1.5, Re ≈ 1.8, h = 0.04, dt = 0.04) settling from a gap of 0.05 into the
    lubrication film of the floor (cut-off h, the repulsion a backstop at 0.01 h): no overlap can form and
    the repulsion is out of reach in every pass, so a pass needs only the sub-steps that follow the gap.
    Against the same run at the DEM's bound (0.1π√(m/k) with the repulsion's stiffness at contact), measured
    to t = 2.4: 93 sub-steps in 93 passes against 4 278, largest gap difference 5.3e-5 (0.26 % of the last
    gap 0.0204), largest speed difference 1.12e-4 = 0.55 % of the largest speed; no pass redone."""
    sim, r = _run(_floor_scene(h=0.04, dt=0.04, t_end=2.4, start=0.15))
    fc = sim.flow.contacts
    monkeypatch.setattr(fluid_contacts.FluidContacts, "sub_step_groups", _at_the_dems_bound)
    ref_sim, ref = _run(_floor_scene(h=0.04, dt=0.04, t_end=2.4, start=0.15))
    ref_fc = ref_sim.flow.contacts
    assert fc.dem_calls == ref_fc.dem_calls > 50                    # the film acts in most steps: measured 93
    assert fc.substeps < 0.05 * ref_fc.substeps, (fc.substeps, ref_fc.substeps)  # measured 93 against 4 278
    assert fc.redone == 0
    assert np.abs(r[:, 2] - ref[:, 2]).max() < 1.5e-4              # measured 5.3e-5
    assert np.abs(r[:, 3] - ref[:, 3]).max() < 0.015 * np.abs(ref[:, 3]).max()  # measured 0.55 %
    assert r[-1, 2] == pytest.approx(ref[-1, 2], rel=0.01)          # measured 0.26 %


def test_a_tilted_plate_in_the_film_of_a_wall_does_not_gain_energy():
    """A thin plate (0.2 × 0.02, tilted 0.01 rad) with its corner 0.001 above the floor, falling at 0.1 and
    turning at 0.5 rad/s: the film acts at the corner, 0.1 from the centre, where the turn adds
    c r²Δt/I ≈ 3 × c Δt/m to the translational share.  An explicit damper capped with the translational mass
    alone (cΔt/m ≤ 1) has cΔt(1/m + r²/I) ≈ 4 > 2 and pumps energy (measured on the capped version: kinetic
    plus elastic energy up to 212 × its start, 127 × the start gained in one step, ω alternating 0.5, −0.56,
    −0.78, −0.44, −0.96).  The implicit damper only dissipates; the corners touch the floor (the contact law
    acts in 31 steps), whose elastic energy at the predicted positions moves by at most 6.2e-4 of the start
    in a step.  Measured over 300 steps at dt_max: energy at most its start, 0.33 of it at the end."""
    a, L, H = 0.01, 0.2, 0.02
    lowest = 0.5 * L * np.sin(a) + 0.5 * H * np.cos(a)  # the lowest corner below the centre
    plate = Body.rectangle(L, H, density=1.0, angle=a, position=(0.0, lowest + 0.001), velocity=(0.0, -0.1),
                           omega=0.5)
    sim = DEM([plate], walls=(-np.inf, np.inf, 0.0, np.inf), gravity=(0.0, 0.0),
              contact=ContactModel(E=1e4, mu=0.0, gamma=0.0),
              lubrication=Lubrication(viscosity=0.01, range=0.02, min_gap=1e-5))
    assert float(sim.world_vertices()[0, :, 1].min()) == pytest.approx(0.001, rel=1e-9)
    E = [sim.kinetic_energy()]
    for _ in range(300):
        sim.step(sim.dt_max)
        E.append(sim.kinetic_energy() + sim.elastic_energy())
    E = np.array(E)
    assert np.isfinite(E).all()
    assert E.max() <= 1.0 * E[0] * (1 + 1e-12)          # measured: the start is the largest
    assert np.diff(E).max() < 2e-3 * E[0]               # measured 6.2e-4 (the contact law's elastic energy)
    assert E[-1] < 0.5 * E[0]                           # measured 0.33


@pytest.mark.filterwarnings("ignore:the mesh has degenerate triangles")  # the disk 2e-4 above the floor
def test_history_counts_the_contacts_of_bodies_in_a_fluid(tmp_path):
    """In a fluid the repulsion keeps bodies apart: a body resting on the floor sits inside the repulsion's
    range (at ρ(1 − √ε) under its weight), not on an overlap.  history.csv counts the bodies and walls within
    that range (it said 0 for every body of a fluid scene): 1 for a disk whose lowest vertex is half the
    range above the floor, 0 for one at twice the range."""
    sc = _floor_scene(h=0.04, dt=0.04, t_end=0.04, start=0.5)
    rng = 0.01 * sc.mesh.h  # the default repulsion range, BACKSTOP × h
    d = sc.to_dict()
    d["bodies"][0]["position"] = [d["bodies"][0]["position"][0], A + 0.5 * rng]
    from fluidem.scene import Scene

    sim = Simulation(Scene.from_dict(d))
    assert sim.flow.contacts.repulsion.range == pytest.approx(rng)
    assert sim.bodies.loads()[2].tolist() == [1]
    sim.run(out_dir=tmp_path / "run", progress=False)
    h = read_history(tmp_path / "run" / "history.csv")
    assert h["contacts"].tolist() == [1, 1]  # steps 0 and 1: the film holds the disk in range
    poses = sim.flow.poses.copy()
    poses[0, 1] = A + 2.0 * rng
    assert sim.flow.contacts.contact_counts(poses).tolist() == [0]


def _two_polygons():
    """A hexagon and a pentagon 5.7e-3 apart at :data:`TWO_POSES`, inside the repulsion's range 0.01 (no gravity),
    as :class:`~fluidem.coupling.contacts.FluidContacts`."""
    from fluidem.coupling.contacts import FluidContacts
    from fluidem.dem.bodies import random_convex_vertices
    from fluidem.scene import Scene

    va = random_convex_vertices(0.1, 6, 1.3, rng=np.random.default_rng(1))
    vb = random_convex_vertices(0.1, 5, 1.5, rng=np.random.default_rng(2))
    sc = Scene.from_dict({
        "gravity": [0.0, 0.0], "fluid": {"density": 1.0, "viscosity": 0.01}, "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
        "bodies": [{"name": "a", "shape": "polygon", "vertices": va.tolist(), "position": [1.0, 0.5], "density": 1.2},
                   {"name": "b", "shape": "polygon", "vertices": vb.tolist(), "position": [0.928, 0.52],
                    "density": 1.2}],
        "contact": {"E": 1e4, "mu": 0.0, "repulsion_force": 0.01, "repulsion_range": 0.01},
        "mesh": {"h": 0.04}, "time": {"dt": 0.01, "t_end": 0.1}})
    return FluidContacts(sc.bodies, np.array([0, 1]), [va, vb], [None, None], domain=sc.domain, fluid=sc.fluid,
                         contact=sc.contact, gravity=sc.gravity, h=sc.mesh.h)


#: their poses and velocities: turning and closing fast enough that the gap may close in a step of 0.01
TWO_POSES = np.array([[1.0, 0.5, 0.3], [0.928, 0.52, -0.2]])
TWO_VELOCITIES = np.array([[-0.3, 0.1, 2.0], [0.2, 0.0, -1.0]])


def test_the_next_pass_of_a_step_takes_its_sub_steps_from_the_gap_the_last_one_met():
    """Two polygons 5.7e-3 apart inside the repulsion's range 0.01, turning and closing fast enough that
    the gap may close in the step by the kinematic bound: the first pass takes the DEM's bound (35 sub-steps).
    It meets a closest gap of 5.64e-3, so the next pass of the same step (the same start, the contact load of
    the first in its solve) takes the repulsion's stiffness at half that gap: 21 sub-steps, no pass redone.
    Its load is that of the same pass at the DEM's bound to 2.0e-4 (relative to the largest component)."""
    contacts = _two_polygons
    poses, vel = TWO_POSES, TWO_VELOCITIES
    dt = 0.01
    c = contacts()
    load = c.load_function(0.0, dt, poses, vel)
    first = load(vel, np.zeros((2, 3)))
    n_first = c.substeps
    assert n_first == int(np.ceil(dt / c.dem.dt_max - 1e-9)) == 35                  # the DEM's bound
    assert 0.0 < c.dem.closest_gap_seen < c.repulsion.range                         # measured 5.64e-3
    second = load(vel, first)
    assert c.substeps - n_first < 0.7 * n_first and c.redone == 0                  # measured 21 of 35
    by = c.last_set_by
    assert by.startswith("the repulsion's stiffness at the gap floor") and "half the closest gap" in by
    assert "softer with a larger contact.repulsion_epsilon or repulsion_range" in by  # the keys to change
    ref = contacts()
    at_bound = ref.load_function(0.0, dt, poses, vel)(vel, first)                    # a first pass: the bound
    assert ref.substeps == 35
    assert np.abs(second - at_bound).max() < 5e-4 * np.abs(at_bound).max()           # measured 2.0e-4


@pytest.mark.filterwarnings("ignore:the mesh has degenerate triangles")  # the disk 2e-4 above the floor
def test_a_step_starts_from_no_contact_load_when_the_fluid_regions_changed_and_a_checkpoint_keeps_the_count():
    """The contact load a step starts from (``contact_guess``) is the last step's while the mesh has as many fluid
    regions as when that load was found, and no load once the count changed (a closed pore opened or closed:
    :func:`fluidem.coupling.free_bodies.carried_contact_load`); the count goes through a checkpoint."""
    sc = _floor_scene(h=0.04, dt=0.04, t_end=0.2, start=0.5)
    d = sc.to_dict()
    d["bodies"][0]["position"] = [d["bodies"][0]["position"][0], A + 0.5 * 0.01 * sc.mesh.h]  # in the film
    from fluidem.scene import Scene

    fl = Simulation(Scene.from_dict(d)).flow
    guesses, loads = [], []
    step = fl.coupled.step

    def spy(*args, contact_guess=None, **kwargs):
        guesses.append(contact_guess)
        loads.append(fl.coupled.last_contact_load.copy())
        return step(*args, contact_guess=contact_guess, **kwargs)

    fl.coupled.step = spy
    fl.step(0.04)
    fl.step(0.04)
    assert fl.problem.components.n_components == 1 and fl._load_regions == 1
    assert guesses[1] is not None and np.array_equal(guesses[1], loads[1])
    assert np.abs(loads[1][:, 1]).max() > 0.0  # the film carries the disk: a load that could be carried
    fl._load_regions = 2  # as if the last load had been found on a mesh with a closed pore
    fl.step(0.04)
    assert guesses[2] is None and fl._load_regions == 1
    state = fl.get_state()
    assert state["bodies"]["contact_regions"] == 1
    state["bodies"]["contact_regions"] = 2
    fl.set_state(state)
    assert fl._load_regions == 2
    del state["bodies"]["contact_regions"]  # a checkpoint written before the count: the guess is kept
    fl.set_state(state)
    assert fl._load_regions is None


def _three_groups():
    """Two squares 0.005 apart, inside the repulsion's range 0.01, closing; two disks 0.02 apart in each other's
    film (cut-off h = 0.04), closing; a disk far from everything: three groups that cannot reach each other."""
    from fluidem.coupling.contacts import FluidContacts
    from fluidem.scene import Scene

    sq = [[-0.05, -0.05], [0.05, -0.05], [0.05, 0.05], [-0.05, 0.05]]
    disk = {"shape": "disk", "radius": 0.05, "density": 1.2}
    sc = Scene.from_dict({
        "gravity": [0.0, 0.0], "fluid": {"density": 1.0, "viscosity": 0.01}, "domain": {"box": [0.0, 2.0, 0.0, 1.0]},
        "bodies": [{"name": "a", "shape": "polygon", "vertices": sq, "position": [0.5, 0.5], "density": 1.2},
                   {"name": "b", "shape": "polygon", "vertices": sq, "position": [0.605, 0.5], "density": 1.2},
                   dict(disk, name="c", position=[1.2, 0.5]), dict(disk, name="d", position=[1.32, 0.5]),
                   dict(disk, name="e", position=[1.0, 0.85])],
        "contact": {"E": 1e4, "mu": 0.0, "repulsion_force": 0.01, "repulsion_range": 0.01},
        "mesh": {"h": 0.04}, "time": {"dt": 0.01, "t_end": 0.1}})
    outlines = [np.asarray(b.local_vertices()) for b in sc.bodies]
    c = FluidContacts(sc.bodies, np.arange(5), outlines, [None] * 5, domain=sc.domain, fluid=sc.fluid,
                      contact=sc.contact, gravity=sc.gravity, h=sc.mesh.h)
    poses = np.array([[*b.position, 0.0] for b in sc.bodies])
    vel = np.array([[0.05, 0.0, 0.0], [-0.05, 0.0, 0.2], [0.05, 0.0, 0.0], [-0.05, 0.01, 0.0], [0.1, 0.0, 1.0]])
    return c, poses, vel


def test_each_group_of_bodies_takes_the_sub_steps_of_its_own_stiffness(monkeypatch):
    """Of three groups out of each other's reach (:func:`_three_groups`) only the pair inside the repulsion's
    range takes the sub-steps of its stiffness; the pair in the film takes those that follow its gap, the lone
    disk one.  Against the same pass with every body at the stiff pair's sub-steps (as before groups): the stiff
    pair's load is the same (measured to 3.7e-16 of its largest component), the lone disk feels nothing in both,
    and the film pair's load is that of its own coarser sub-steps, 1st order in them (the dissipative forces,
    :mod:`fluidem.dem.system`): measured 1.1 % of its largest component apart.  With the default
    ``GROUP_OVERHEAD`` three bodies do not pay for groups of their own: all five take the stiff pair's."""
    c, poses, vel = _three_groups()
    dt = 0.01
    merged = c.sub_step_groups(dt, poses, vel, vel)
    assert len(merged) == 1 and merged[0][0].tolist() == [0, 1, 2, 3, 4]    # 2 × (15 − 1) and 1 × 14 < 50
    monkeypatch.setattr(fluid_contacts, "GROUP_OVERHEAD", 0)  # every group on its own
    groups = c.sub_step_groups(dt, poses, vel, vel)
    sizes = {tuple(b.tolist()): n for b, n, _, _ in groups}
    assert set(sizes) == {(0, 1), (2, 3), (4,)}
    n_stiff, n_film = sizes[(0, 1)], sizes[(2, 3)]
    assert n_stiff >= 10 and n_film <= 2 and sizes[(4,)] == 1                 # measured 15, 1, 1
    assert groups[0][3].startswith("the repulsion's stiffness at the gap floor")

    load = c.load_function(0.0, dt, poses, vel)(vel, np.zeros((5, 3)))
    assert c.substeps == n_stiff and c.body_substeps == 2 * n_stiff + 2 * n_film + 1

    ref, _, _ = _three_groups()
    ref.sub_step_groups = lambda dt, poses, *a, **k: [(np.arange(5), n_stiff, -np.inf, "all at the stiff pair's")]
    whole = ref.load_function(0.0, dt, poses, vel)(vel, np.zeros((5, 3)))
    assert ref.body_substeps == 5 * n_stiff
    big = np.abs(whole[:2]).max()
    assert big > 0 and np.abs(load[:2] - whole[:2]).max() <= 1e-15 * big      # measured 3.7e-16
    assert not load[4].any() and not whole[4].any()
    film = np.abs(whole[2:4]).max()
    assert film > 0 and np.abs(load[2:4] - whole[2:4]).max() < 0.03 * film     # measured 1.1 %


def test_a_group_that_meets_a_stiffer_force_is_taken_again_from_its_start_alone(monkeypatch):
    """The stiff pair of :func:`_three_groups` given too few sub-steps (2) for the floor it claims: its pass
    meets a gap below that floor and is taken again at the repulsion's stiffness there, from the step's start
    (poses, velocities and springs restored for its bodies only).  Its load is then that of a pass taken at
    those sub-steps from the outset, bit for bit, and the other groups' loads those of the pass without the
    redo, bit for bit."""
    monkeypatch.setattr(fluid_contacts, "GROUP_OVERHEAD", 0)  # every group on its own
    c, poses, vel = _three_groups()
    dt = 0.01
    groups = c.sub_step_groups(dt, poses, vel, vel)
    plain = c.load_function(0.0, dt, poses, vel)(vel, np.zeros((5, 3)))
    too_few = [(b, 2, 0.9 * c.repulsion.range, "too few") if 0 in b else (b, n, f, by) for b, n, f, by in groups]
    c2, _, _ = _three_groups()
    c2.sub_step_groups = lambda *a, **k: too_few
    load = c2.load_function(0.0, dt, poses, vel)(vel, np.zeros((5, 3)))
    assert c2.redone == 1 and c2.last_set_by.startswith("the repulsion's stiffness at half the gap")
    n_again = c2.substeps - 2
    assert n_again > 2
    c3, _, _ = _three_groups()
    c3.sub_step_groups = lambda *a, **k: [(b, n_again, -np.inf, "at once") if 0 in b else (b, n, f, by)
                                          for b, n, f, by in groups]
    at_once = c3.load_function(0.0, dt, poses, vel)(vel, np.zeros((5, 3)))
    assert c3.redone == 0
    assert np.array_equal(load[:2], at_once[:2])
    assert np.array_equal(load[2:], plain[2:])


def test_the_first_pass_of_a_step_takes_its_sub_steps_from_the_gap_the_step_before_met():
    """The two polygons of the test above, a step later: the first pass of the next step (from where the first
    step's last pass ended) takes the repulsion's stiffness at half the gap the step before met, not the DEM's
    bound (in a settling pile of 100 polygons the bound was 119 of a step's 160–190 sub-steps); a step out of
    reach forgets it, and it goes through a checkpoint (``get_state``)."""
    c = _two_polygons()
    poses, vel = TWO_POSES, TWO_VELOCITIES
    dt = 0.01
    c.load_function(0.0, dt, poses, vel)(vel, np.zeros((2, 3)))
    assert c.substeps == 35                                                          # the DEM's bound
    met = c.seen_last_step.copy()
    assert 0.0 < met.min() < c.repulsion.range
    d = c.dem
    poses1, vel1 = np.column_stack([d.positions, d.angles]), np.column_stack([d.velocities, d.omegas])
    c.load_function(dt, dt, poses1, vel1)(vel1, np.zeros((2, 3)))
    assert c.substeps - 35 < 35 and "half the closest gap" in c.last_set_by                # measured 21
    state = c.get_state()
    assert np.array_equal(state["seen_last_step"], c.seen_last_step)
    far = poses1 + np.array([[0.3, 0.0, 0.0], [-0.3, 0.0, 0.0]])                      # out of each other's reach
    assert c.load_function(2 * dt, dt, far, vel1) is None and c.seen_last_step is None
    c.set_state(state)
    assert np.array_equal(c.seen_last_step, state["seen_last_step"])
