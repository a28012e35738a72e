"""The plan as a list of named rules (fluidem.plan.rules): one effect per effect rule, in the
order the Plan documents; a rule left out takes only its own line; every rule small and named."""

import inspect

import pytest

import fluidem.plan as plan_mod
from fluidem.plan import Effect, make_plan
from fluidem.plan.rules import RULES, Caution, Context, Note, Refusal, apply_rules, defaults_note
from fluidem.scene import Scene

EFFECTS = ["fluid", "inertia", "moving-bodies", "mesh", "ale", "contacts", "gravity", "buoyancy", "coupling",
           "rotation", "remeshing", "periodic", "solver"]

DISK = {"shape": "disk", "radius": 0.05, "position": [0.5, 0.5]}
SCENES = {
    "dry": {"gravity": [0, -9.81], "domain": {"box": [0, 1, 0, 1]}, "bodies": [DISK], "contact": {"E": 1e5}},
    "stokes": {"fluid": {"model": "stokes"}, "domain": {"box": [0, 1, 0, 1]}, "bodies": [{**DISK, "motion": "fixed"}],
               "mesh": {"h": 0.05}},
    "moving": {"fluid": {}, "domain": {"box": [0, 2, 0, 1], "left": "periodic", "right": "periodic"},
               "bodies": [{**DISK, "motion": "prescribed", "velocity": [0.1, 0.0]}], "mesh": {"h": 0.05},
               "time": {"dt": 0.01, "t_end": 0.1}},
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_each_effect_rule_gives_one_effect_in_the_plans_order(name):
    s = Scene.from_dict(SCENES[name])
    ctx = Context.of(s)
    out = [list(rule(s, ctx)) for rule in RULES[:len(EFFECTS)]]
    assert all(len(o) == 1 and type(o[0]) is Effect for o in out), out
    assert [o[0].name for o in out] == EFFECTS
    later = [item for rule in RULES[len(EFFECTS):] for item in rule(s, ctx)]
    assert all(type(item) in (Note, Caution, Refusal) for item in later), later  # no effect after the effects
    assert [e.name for e in make_plan(s).effects] == EFFECTS


def test_a_rule_left_out_takes_only_its_own_line(monkeypatch):
    def memory():  # one machine for both plans: the available memory read twice differs on a busy machine
        return 16e9, 8e9

    monkeypatch.setattr(plan_mod, "machine_memory", memory)
    s = Scene.from_dict({"fluid": {}, "domain": {"box": [0, 1, 0, 1]}})  # no [time], no mesh.h: two default notes
    full = make_plan(s)
    ctx = Context.of(s, memory=memory)
    mine = [str(n) for n in defaults_note(s, ctx)]
    assert len(mine) == 2 and mine == full.notes[-2:], full.notes
    less = apply_rules(s, ctx, [r for r in RULES if r is not defaults_note])
    assert less.notes == full.notes[:-2]
    assert (less.effects, less.warnings, less.unsupported, less.estimate) == (full.effects, full.warnings,
                                                                           full.unsupported, full.estimate)
    assert all(type(n) is str for n in full.notes + full.warnings + full.unsupported)  # plain strings in the plan


def test_every_rule_is_small_named_and_documented():
    sizes = {r.__name__: len(inspect.getsource(r).splitlines()) for r in RULES}
    assert len(sizes) == len(RULES) == 33  # 13 effects, 20 notes, warnings and refusals
    assert all(r.__doc__ for r in RULES)
    assert max(sizes.values()) <= 25, sizes  # measured: 20 (solver, fluid_contacts_note)
