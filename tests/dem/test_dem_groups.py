"""A grouped DEM.advance (fluidem.dem.DEM.advance(bodies=...)): each group of bodies that cannot reach another
moves as if alone, the others keep their state, springs and contacts."""

import numpy as np
import pytest

from fluidem.dem import DEM, Body, ContactModel
from fluidem.dem.lubrication import Lubrication
from fluidem.dem.repulsion import Repulsion
from fluidem.errors import InputError


def _two_heaps(**kw):
    """Two heaps 1.0 apart on the floor: a rectangle pressed into the floor, a square bouncing on it (overlaps,
    springs), a hexagon in the rectangle's film, sliding and spinning; a prescribed rectangle above the right heap;
    the repulsion and the film acting."""
    bodies = []
    for x0 in (0.0, 1.0):
        bodies.append(Body.rectangle(0.2, 0.05, density=100.0, position=(x0, 0.0249), velocity=(0.1, 0.0),
                                     omega=0.3))
        bodies.append(Body.rectangle(0.05, 0.05, density=100.0, position=(x0 + 0.01, 0.0765), angle=0.1,
                                     velocity=(-0.2, -0.1), omega=-1.0))
        bodies.append(Body.disk(0.03, segments=6, density=150.0, position=(x0 + 0.12, 0.08), velocity=(-0.05, 0.0)))
    bodies.append(Body.rectangle(0.1, 0.02, density=1.0, position=(1.3, 0.3), motion="prescribed",
                                 path=lambda t: ((1.3 - 0.1 * t, 0.3), 0.0)))
    return DEM(bodies, walls=(-0.5, 2.0, 0.0, 1.0), contact=ContactModel(E=1e4, mu=0.3, gamma=0.2),
               repulsion=Repulsion(range=0.002, force=0.05, epsilon=1e-2),
               lubrication=Lubrication(viscosity=0.01, range=0.02, min_gap=0.002), **kw)


LEFT, RIGHT = np.arange(3), np.arange(3, 7)


def _state(sim):
    return np.column_stack([sim.positions, sim.angles, sim.velocities, sim.omegas])


def test_groups_advanced_one_after_the_other_move_as_the_whole_does():
    """The two heaps cannot reach each other: advancing the left and then the right one by the same 30
    sub-steps gives every body the state, and the contacts the springs, of advancing all together: measured to
    8.3e-16 of the largest value (states), 2.9e-15 (forces), the springs bit for bit (the film's implicit solve
    over fewer bodies rounds differently)."""
    whole, grouped = _two_heaps(), _two_heaps()
    dt = 0.5 * whole.dt_max
    whole.advance(30 * dt, n=30)
    grouped.advance(30 * dt, n=30, bodies=LEFT)
    assert grouped.time == 0.0                                       # the caller sets it after every group
    grouped.advance(30 * dt, n=30, bodies=RIGHT)
    grouped.time = whole.time
    ref = _state(whole)
    assert len(whole.contacts) == len(grouped.contacts) == 4          # square on rectangle on floor, twice
    assert np.abs(_state(grouped) - ref).max() <= 2.5e-15 * np.abs(ref).max()     # measured 8.3e-16
    kw, kg = whole.spring_history, grouped.spring_history
    assert np.array_equal(kw["key"], kg["key"])
    assert np.abs(kw["xi"] - kg["xi"]).max() <= 2.5e-15 * np.abs(kw["xi"]).max()  # measured 0.0
    assert np.abs(whole.forces - grouped.forces).max() <= 8e-15 * np.abs(whole.forces).max()  # measured 2.9e-15


def test_a_group_leaves_the_other_bodies_and_their_springs_as_they_were():
    """Advancing the right heap alone: the left heap's poses, velocities, spring history and contacts are those
    before, bit for bit, and the right heap moves as when every body moves (measured to 9.0e-16 of its largest
    value)."""
    sim = _two_heaps()
    dt = 0.5 * sim.dt_max
    sim.advance(10 * dt, n=10)
    before, springs = _state(sim), sim.spring_history
    left_contacts = sim.contacts.key[sim.contacts.i < 3]
    left_keys = springs["key"][(springs["key"] >> 32) < 3]
    sim.advance(30 * dt, n=30, bodies=RIGHT)
    assert np.array_equal(_state(sim)[LEFT], before[LEFT])
    after = sim.spring_history
    keep = np.isin(after["key"], left_keys)
    assert keep.sum() == len(left_keys) > 0
    assert np.array_equal(after["xi"][keep], springs["xi"][np.isin(springs["key"], left_keys)])
    assert len(left_contacts) == 2 and np.isin(left_contacts, sim.contacts.key).all()  # the left heap's contacts

    whole = _two_heaps()  # the right heap as when every body moves
    whole.advance(10 * dt, n=10)
    whole.advance(30 * dt, n=30)
    ref = _state(whole)[RIGHT]
    assert np.abs(_state(sim)[RIGHT] - ref).max() <= 2.5e-15 * np.abs(ref).max()  # measured 9.0e-16


@pytest.mark.parametrize("bodies", [[0, 7], [[0, 1]], [0.5], [-1]])
def test_bad_bodies_of_a_grouped_advance_are_refused_in_one_line(bodies):
    with pytest.raises(InputError, match=r"DEM.advance\(bodies=...\).*body indices in \[0, 7\)"):
        _two_heaps().advance(1e-4, n=1, bodies=np.array(bodies))
