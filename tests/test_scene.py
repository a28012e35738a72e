"""Scene files: every contract key parsed, clear errors for typical mistakes, the plan, many bodies."""

import time

import numpy as np
import pytest

from fluidem.errors import InputError
from fluidem.scene import BodySpec, Scene

CONTRACT = """
gravity = [0.0, -980.0]
[fluid]
density = 1.0
viscosity = 0.01
model = "navier-stokes"
body_force = [0.0, 0.0]
[domain]
box = [0.0, 2.0, 0.0, 8.0]
left = "wall"
right = "outflow"
bottom = "inflow"
top = { type = "moving-wall", velocity = [1.0, 0.0] }
inflow_profile = { type = "parabolic", umax = 1.5 }
[[bodies]]
shape = "disk"
radius = 0.1
segments = 48
position = [1.0, 7.2]
angle = 0.0
density = 1.01
motion = "free"
[[bodies]]
shape = "polygon"
vertices = [[0.0, 0.0], [0.2, 0.0], [0.1, 0.15]]
position = [0.5, 2.0]
motion = "fixed"
[[bodies]]
shape = "rectangle"
width = 0.2
height = 0.1
position = [1.5, 2.0]
motion = "prescribed"
velocity = [0.0, 0.1]
omega = 0.5
[[bodies]]
shape = "ellipse"
a = 0.1
b = 0.05
segments = 24
position = [1.0, 4.0]
[bodies_table]
file = "particles.csv"
[contact]
E = 1e5
mu = 0.2
gamma = 0.05
[mesh]
h = 0.02
grading = { region = [0.0, 2.0, 5.0, 8.0], growth = 1.2 }
strategy = "drag"
retriangulate_every = 30
[time]
dt = 1e-3
t_end = 5.0
[output]
dir = "out"
every = 10
"""

CSV = ("shape,radius,segments,width,height,x,y,angle,density\ndisk,0.05,8,,,0.3,6.0,0.0,2.0\n"
       "rectangle,,,0.1,0.05,1.7,6.0,0.3,2.5\n")


@pytest.fixture
def contract_file(tmp_path):
    (tmp_path / "particles.csv").write_text(CSV)
    p = tmp_path / "scene.toml"
    p.write_text(CONTRACT)
    return p


def test_every_contract_key_is_parsed(contract_file):
    s = Scene.from_toml(contract_file)
    assert s.gravity == (0.0, -980.0)
    assert (s.fluid.density, s.fluid.viscosity, s.fluid.model, s.fluid.body_force) == (1.0, 0.01, "navier-stokes",
                                                                                         (0.0, 0.0))
    assert s.domain.box == (0.0, 2.0, 0.0, 8.0)
    assert s.domain.left.type == "wall" and s.domain.right.type == "outflow"
    assert s.domain.top.type == "moving-wall" and s.domain.top.velocity == (1.0, 0.0)
    assert s.domain.inflow_profile == {"type": "parabolic", "umax": 1.5, "ramp": 0.0}
    assert len(s.bodies) == 6
    d = s.bodies[0]
    assert (d.shape, d.radius, d.segments, d.position, d.angle, d.density, d.motion) == (
        "disk", 0.1, 48, (1.0, 7.2), 0.0, 1.01, "free")
    assert np.allclose(_area_centroid(s.bodies[1].vertices), 0.0, atol=1e-12)  # area centroid at the origin
    assert s.bodies[2].omega == 0.5 and s.bodies[2].velocity == (0.0, 0.1)
    assert (s.bodies[3].a, s.bodies[3].b) == (0.1, 0.05)
    assert s.bodies[4].density == 2.0 and s.bodies[5].shape == "rectangle" and s.bodies[5].angle == 0.3
    assert (s.contact.E, s.contact.mu, s.contact.gamma) == (1e5, 0.2, 0.05)
    assert s.mesh.h == 0.02 and s.mesh.grading["region"] == (0.0, 2.0, 5.0, 8.0) and s.mesh.grading["growth"] == 1.2
    assert (s.mesh.strategy, s.mesh.retriangulate_every) == ("drag", 30)
    assert (s.time.dt, s.time.t_end, s.time.n_steps) == (1e-3, 5.0, 5000)
    assert (s.output.dir, s.output.every) == ("out", 10)
    plan = s.plan()
    assert plan.on("fluid") and plan.on("inertia") and plan.mesh == "moving"
    assert not plan.unsupported and plan.on("coupling")


def _area_centroid(v):
    """Centroid of the polygon area (shoelace formula), not the mean of its vertices."""
    v = np.asarray(v, float)
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = 0.5 * cross.sum()
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)


def test_polygon_vertices_are_shifted_to_their_area_centroid():
    """A quadrilateral whose vertex mean and area centroid differ: ``position`` places the latter."""
    quad = [[0.0, 0.0], [0.4, 0.0], [0.4, 0.1], [0.0, 0.3]]
    s = Scene.from_dict({"domain": {"box": [0.0, 2.0, 0.0, 1.0]},
                         "bodies": [{"shape": "polygon", "vertices": quad, "position": [1.0, 0.5]}]})
    v = s.bodies[0].vertices
    assert np.allclose(_area_centroid(v), 0.0, atol=1e-12)
    assert np.allclose(v - v[0], np.asarray(quad) - quad[0])  # a pure shift
    assert np.linalg.norm(v.mean(axis=0)) > 0.01  # the vertex mean is not what is zeroed


def _mutate(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


MISTAKES = [
    # (description, old, new, words that must appear in the message)
    ("typo in a key", "viscosity = 0.01", "viscosty = 0.01", ["fluid.viscosty", "0.01", "viscosity"]),
    ("negative viscosity", "viscosity = 0.01", "viscosity = -0.01", ["fluid.viscosity", "-0.01", "positive"]),
    ("unknown model", 'model = "navier-stokes"', 'model = "euler"', ["fluid.model", "euler", "stokes"]),
    ("body outside the box", "position = [1.0, 7.2]", "position = [1.0, 7.95]", ["bodies[0]", "7.95", "inside"]),
    ("overlapping bodies", "position = [1.0, 4.0]", "position = [1.0, 7.25]", ["bodies[0]", "bodies[3]", "overlap"]),
    ("inflow without profile", 'inflow_profile = { type = "parabolic", umax = 1.5 }\n', "",
     ["domain.bottom", "inflow", "profile", "parabolic"]),
    ("periodic on one side", 'left = "wall"', 'left = "periodic"', ["domain.left", "periodic", "right", "pairs"]),
    ("unknown side type", 'left = "wall"', 'left = "slippery"', ["domain.left", "slippery", "moving-wall"]),
    ("unknown shape", 'shape = "disk"', 'shape = "star"', ["bodies[0].shape", "star", "polygon"]),
    ("disk without radius", "radius = 0.1\n", "", ["bodies[0]", "radius"]),
    ("bad motion", 'motion = "free"', 'motion = "floating"', ["bodies[0].motion", "floating", "prescribed"]),
    ("negative time step", "dt = 1e-3", "dt = -1e-3", ["time.dt", "-0.001", "positive"]),
    ("unknown mesh strategy", 'strategy = "drag"', 'strategy = "magic"', ["mesh.strategy", "magic", "regenerate"]),
    ("gravity not a pair", "gravity = [0.0, -980.0]", "gravity = -980.0", ["gravity", "-980", "pair"]),
    ("box reversed", "box = [0.0, 2.0, 0.0, 8.0]", "box = [2.0, 0.0, 0.0, 8.0]", ["domain.box", "xmax > xmin"]),
    ("negative friction", "mu = 0.2", "mu = -0.2", ["contact.mu", "-0.2", ">= 0"]),
    ("unknown table", "[output]", "[outputs]", ["outputs", "allowed keys", "output"]),
    ("segments not integer", "segments = 48", "segments = 4.5", ["bodies[0].segments", "4.5", "integer"]),
    ("non-convex polygon", "vertices = [[0.0, 0.0], [0.2, 0.0], [0.1, 0.15]]",
     "vertices = [[0.0, 0.0], [0.2, 0.0], [0.1, 0.02], [0.1, 0.15]]", ["bodies[1].vertices", "convex"]),
    ("moving-wall velocity on a wall", 'left = "wall"', 'left = { type = "wall", velocity = [1.0, 0.0] }',
     ["domain.left.velocity", "moving-wall"]),
]


@pytest.mark.parametrize("what,old,new,words", MISTAKES, ids=[m[0] for m in MISTAKES])
def test_mistakes_name_key_value_and_allowed(tmp_path, what, old, new, words):
    (tmp_path / "particles.csv").write_text(CSV)
    p = tmp_path / "scene.toml"
    p.write_text(_mutate(CONTRACT, old, new))
    with pytest.raises(ValueError) as exc:
        Scene.from_toml(p)
    msg = str(exc.value)
    for w in words:
        assert w in msg, f"{what}: {w!r} not in {msg!r}"


def test_bad_table_column_and_missing_file(tmp_path):
    p = tmp_path / "scene.toml"
    p.write_text(CONTRACT)
    with pytest.raises(ValueError, match="particles.csv.*does not exist"):
        Scene.from_toml(p)
    (tmp_path / "particles.csv").write_text("shape,radius,xx,y\ndisk,0.1,1,1\n")
    with pytest.raises(ValueError, match=r"unknown column 'xx' \(did you mean 'x'\?\); allowed columns"):
        Scene.from_toml(p)
    with pytest.raises(ValueError, match="does not exist"):
        Scene.from_toml(tmp_path / "nope.toml")


def _dry(bodies, **kw):
    d = {"gravity": [0.0, -9.81], "domain": {"box": [0.0, 1.0, 0.0, 1.0]}, "bodies": bodies,
         "contact": {"E": 1e5, "mu": 0.3, "gamma": 0.1}, "time": {"dt": 1e-3, "t_end": 0.1}}
    d.update(kw)
    return Scene.from_dict(d)


def test_plan_contacts_reach():
    lone = _dry([{"shape": "disk", "radius": 0.05, "position": [0.5, 0.5]}])
    p = lone.plan()
    assert not p.on("contacts") and "can meet" in p.effect("contacts").why and not p.on("fluid")
    assert p.mesh == "none"
    # near the floor: 0.5 g t^2 = 0.049 > gap 0.03
    low = _dry([{"shape": "disk", "radius": 0.05, "position": [0.5, 0.08]}])
    assert low.plan().on("contacts")
    # two bodies close together, no gravity, moving towards each other
    pair = _dry([{"shape": "disk", "radius": 0.05, "position": [0.3, 0.5], "velocity": [1.5, 0.0]},
                 {"shape": "disk", "radius": 0.05, "position": [0.5, 0.5]}], gravity=[0.0, 0.0])
    assert pair.plan().contact_pairs == 1
    off = _dry([{"shape": "disk", "radius": 0.05, "position": [0.5, 0.08]}], contact={"enabled": False})
    assert not off.plan().on("contacts") and "enabled = false" in off.plan().effect("contacts").why


def _fluid(model, bodies, t_end=0.3, **kw):
    d = {"fluid": {"model": model, "viscosity": 0.1}, "domain": {"box": [0.0, 2.0, 0.0, 1.0]}, "bodies": bodies,
         "mesh": {"h": 0.1}, "time": {"dt": 0.1, "t_end": t_end}}
    d.update(kw)
    return Scene.from_dict(d)


def test_plan_fluid_effects():
    fixed = _fluid("stokes", [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5], "motion": "fixed"}])
    p = fixed.plan()
    assert p.mesh == "once" and not p.on("inertia") and not p.on("ale") and not p.on("remeshing")
    assert not p.unsupported
    spin = _fluid("navier-stokes", [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5], "motion": "prescribed",
                                     "omega": 2.0}])
    p = spin.plan()
    assert p.mesh == "once" and p.on("rotation") and p.on("inertia") and p.on("moving-bodies")
    move = _fluid("navier-stokes", [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5], "motion": "prescribed",
                                     "velocity": [0.1, 0.0]}])
    assert move.plan().mesh == "moving" and move.plan().on("ale")
    one = _fluid("stokes", [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5], "motion": "prescribed",
                             "velocity": [0.1, 0.0]}], t_end=0.1)
    assert one.plan().mesh == "once" and not one.plan().unsupported
    free = _fluid("stokes", [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5]}], gravity=[0.0, -1.0])
    assert not free.plan().unsupported and free.plan().on("buoyancy")
    assert dict((e.name, e.value) for e in free.plan().effects)["coupling"] == "mobility"
    per = _fluid("stokes", [], domain={"box": [0.0, 2.0, 0.0, 1.0], "left": "periodic", "right": "periodic"})
    assert not per.plan().unsupported and per.plan().on("periodic")
    assert "left/right (period 2 in x)" in per.plan().effect("periodic").why
    text = str(fixed.plan())
    for word in ("inertia", "moving-bodies", "contacts", "gravity", "buoyancy", "rotation", "remeshing", "solver"):
        assert word in text


def test_thousand_bodies_load_plan_validate_under_a_second(tmp_path):
    rows = ["shape,radius,segments,width,height,x,y,angle,density"]
    for j in range(25):
        for i in range(40):
            x, y = 0.025 + i * 0.05, 0.025 + j * 0.05
            rows.append(f"rectangle,,,0.03,0.02,{x},{y},0.3,2.5" if (i + j) % 3 == 0 else
                        f"disk,0.02,{6 + i % 3},,,{x},{y},0.1,2.5")
    (tmp_path / "particles.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "big.toml").write_text('gravity = [0.0, -9.81]\n[domain]\nbox = [0.0, 2.0, 0.0, 2.0]\n'
                                       '[bodies_table]\nfile = "particles.csv"\n[contact]\nE = 1e5\n'
                                       '[time]\ndt = 1e-3\nt_end = 1.0\n')
    Scene.from_toml(tmp_path / "big.toml").plan()  # warm up imports
    t0 = time.perf_counter()
    s = Scene.from_toml(tmp_path / "big.toml")
    plan = s.plan()
    elapsed = time.perf_counter() - t0
    assert len(s.bodies) == 1000 and plan.on("contacts")
    assert elapsed < 1.0, elapsed


def test_scene_in_python_and_round_trip(tmp_path):
    s = Scene(bodies=[BodySpec(shape="disk", radius=0.1, position=(0.5, 0.5))], gravity=(0.0, -1.0))
    s.validate()
    assert s.bodies[0].name == "body0"
    s2 = Scene.from_dict(s.to_dict())
    assert s2.to_dict() == s.to_dict()


def test_plan_sees_moving_mesh_availability_replaced(monkeypatch):
    import fluidem.plan

    move = _fluid("navier-stokes", [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5], "motion": "prescribed",
                                     "velocity": [0.1, 0.0]}])
    assert not move.plan().unsupported
    monkeypatch.setattr(fluidem.plan, "moving_mesh_available", lambda: False)
    assert any("moving-mesh layer" in u for u in move.plan().unsupported)


def test_old_spellings_are_stored_canonically_and_plan_modules_agree():
    import fluidem.plan
    import fluidem.scene

    s = _fluid("navier-stokes", [], fluid={"model": "navier-stokes", "viscosity": 0.1, "solver": "lagged-lu"})
    assert s.fluid.solver == "lagged" and "solver lagged" in str(s.plan())
    assert fluidem.scene.Plan is fluidem.plan.Plan
    assert fluidem.scene.contact_candidates is fluidem.plan.contact_candidates
    assert fluidem.scene.SIDES == ("bottom", "right", "top", "left")


def test_conservative_ale_form_with_another_convection_is_refused_naming_both():
    from fluidem.errors import SceneError

    with pytest.raises(SceneError, match=r"fluid.ale_form = 'conservative' with fluid.convection = 'newton': "
                                         r"the conservative form needs convection = 'semi-implicit'"):
        Scene.from_dict({"fluid": {"ale_form": "conservative", "convection": "newton"},
                         "domain": {"box": [0, 1, 0, 1]}})


@pytest.mark.parametrize("bad", [2, "yes", 1])
def test_mesh_repair_is_true_or_false(bad):
    from fluidem.errors import SceneError

    with pytest.raises(SceneError, match=r"^mesh.repair = .*: expected true or false"):
        Scene.from_dict({"fluid": {}, "domain": {"box": [0, 1, 0, 1]}, "mesh": {"repair": bad}})
    assert Scene.from_dict({"fluid": {}, "domain": {"box": [0, 1, 0, 1]}, "mesh": {"repair": True}}).mesh.repair


def test_bodies_overlapping_through_a_periodic_side_are_refused_in_one_line():
    """A body across a periodic side is also where its image is: an overlap with a body at the other side
    (or, doubly periodic, at the opposite corner) is refused like one inside the box."""
    fluid = {"fluid": {"model": "stokes", "viscosity": 1.0}, "mesh": {"h": 0.04},
             "domain": {"box": [0, 2, -0.5, 0.5], "left": "periodic", "right": "periodic"}}
    disk = {"shape": "disk", "radius": 0.1, "motion": "free"}
    with pytest.raises(InputError, match=r"^bodies\[0\] .* and bodies\[1\] .* overlap at start \(through a periodic "
                                         r"side\) by 0\.00697"):
        Scene.from_dict(dict(fluid, bodies=[dict(disk, position=[0.02, 0.0]), dict(disk, position=[1.9, 0.05])]))
    assert len(Scene.from_dict(dict(fluid, bodies=[dict(disk, position=[0.02, 0.0]),
                                                   dict(disk, position=[1.7, 0.05])])).bodies) == 2
    dry = {"domain": {"box": [0, 1, 0, 1], "left": "periodic", "right": "periodic", "bottom": "periodic",
                      "top": "periodic"}}
    corner = [{"shape": "disk", "radius": 0.1, "position": [0.02, 0.03]},
              {"shape": "rectangle", "width": 0.2, "height": 0.1, "position": [0.95, 0.95]}]
    with pytest.raises(InputError, match=r"overlap at start \(through a periodic side\) by 0\.0069 "):
        Scene.from_dict(dict(dry, bodies=corner))
    corner[1]["position"] = [0.6, 0.6]  # a dry scene takes a body across periodic sides (the DEM's images)
    assert len(Scene.from_dict(dict(dry, bodies=corner)).bodies) == 2
