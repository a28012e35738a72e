"""One table of names: every name (and alias) of fluidem.names.REGISTRY means the same in a
scene file, on the command line and in the Python factories.

For each kind, every place that takes such a name is asked for every registry name and
alias, and must answer with the registry's canonical name (a factory: the object that name
stands for).  Conversely each place's own table of names is the registry's.  A factory that
does not accept a registry alias yet is an ``xfail(strict=True)`` case naming the factory.
"""

import argparse

import pytest

from fluidem import names
from fluidem.errors import InputError, SceneError
from fluidem.scene import Scene

# ---------------------------------------------------------------------------------------
# scenes: one small scene per kind, with the value typed where a user would type it
# ---------------------------------------------------------------------------------------
_BOX = [0.0, 2.0, 0.0, 1.0]
_SHAPE_KEYS = {"disk": {"radius": 0.1}, "polygon": {"vertices": [[0.0, 0.0], [0.2, 0.0], [0.1, 0.15]]},
               "rectangle": {"width": 0.2, "height": 0.1}, "ellipse": {"a": 0.1, "b": 0.05}}


def _fluid_scene(**fluid):
    return {"fluid": fluid, "domain": {"box": _BOX}, "time": {"dt": 0.1, "t_end": 0.1}}


def _scene_solver(v):
    return Scene.from_dict(_fluid_scene(solver=v)).fluid.solver


def _scene_convection(v):
    return Scene.from_dict(_fluid_scene(convection=v)).fluid.convection


def _scene_element(v):
    return Scene.from_dict(_fluid_scene(element=v)).fluid.element


def _scene_model(v):
    return Scene.from_dict(_fluid_scene(model=v)).fluid.model


def _scene_strategy(v):
    d = _fluid_scene()
    d["mesh"] = {"strategy": v}
    return Scene.from_dict(d).mesh.strategy


def _scene_shape(v):
    params = _SHAPE_KEYS.get(names.REGISTRY["shape"].aliases.get(v, v), {})  # an unknown shape: no sizes
    d = {"domain": {"box": _BOX}, "bodies": [dict(shape=v, position=[1.0, 0.5], **params)]}
    return Scene.from_dict(d).bodies[0].shape


def _scene_motion(v):
    d = {"domain": {"box": _BOX}, "bodies": [{"shape": "disk", "radius": 0.1, "position": [1.0, 0.5],
                                               "motion": v}]}
    return Scene.from_dict(d).bodies[0].motion


def _scene_coupling(v):
    d = _fluid_scene()
    d["fluid"]["coupling"] = v
    return Scene.from_dict(d).fluid.coupling


def _scene_ale_form(v):
    d = _fluid_scene()
    d["fluid"]["ale_form"] = v
    return Scene.from_dict(d).fluid.ale_form


def _scene_lu_backend(v):
    from fluidem.fluid.solvers.pardiso import pardiso_available

    d = _fluid_scene()
    d["fluid"]["lu_backend"] = v
    if v == "pardiso" and not pardiso_available():
        with pytest.raises(SceneError, match=r"fluid.lu_backend = 'pardiso' needs the optional package pypardiso"):
            Scene.from_dict(d)
        return "pardiso"
    return Scene.from_dict(d).fluid.lu_backend


def _scene_side_type(v):
    d = _fluid_scene()
    d["domain"] = {"box": _BOX, "left": v, "right": v, "inflow_profile": {"type": "uniform", "umax": 1.0}}
    s = Scene.from_dict(d)
    assert s.domain.right.type == s.domain.left.type
    return s.domain.left.type


def _scene_side(v):
    d = _fluid_scene()
    d["domain"] = {"box": _BOX, v: "outflow"}
    s = Scene.from_dict(d)
    (open_side,) = [k for k in names.choices("side") if s.domain.side(k).type == "outflow"]
    assert s.domain.side(v) is s.domain.side(open_side)
    return open_side


def _scene_profile(v):
    d = _fluid_scene()
    d["domain"] = {"box": _BOX, "left": "inflow", "inflow_profile": {"type": v, "umax": 1.0}}
    return Scene.from_dict(d).domain.profile_of("left")["type"]


def _scene_units(v):
    return Scene.from_dict({"domain": {"box": _BOX}, "units": v}).units


def _scene_time_scheme(v):
    d = _fluid_scene()
    d["time"] = {"dt": 0.1, "t_end": 0.1, "scheme": v}
    return Scene.from_dict(d).time.scheme


SCENE = {"units": _scene_units, "time scheme": _scene_time_scheme,
         "solver": _scene_solver, "convection": _scene_convection, "element": _scene_element,
         "fluid model": _scene_model, "strategy": _scene_strategy, "shape": _scene_shape, "motion": _scene_motion,
         "side type": _scene_side_type, "side": _scene_side, "profile": _scene_profile,
         "coupling": _scene_coupling, "ALE form": _scene_ale_form, "LU backend": _scene_lu_backend}


# ---------------------------------------------------------------------------------------
# the command line: the option taking each kind
# ---------------------------------------------------------------------------------------
def _parser():
    from fluidem.cli import _build_parser

    return _build_parser()


def _bench_action(dest):
    p = _parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return next(a for a in sub.choices["bench"]._actions if a.dest == dest)


def _cli(option):
    def parse(v):
        return getattr(_parser().parse_args(["bench", "dfg-2d1", option, v]), option.lstrip("-"))
    return parse


def _cli_case(v):
    return _parser().parse_args(["bench", v]).name


def _cli_example(v):
    from fluidem.cli import _scene_from_args

    args = _parser().parse_args(["plan", "--example", v])
    return _scene_from_args(args).name


def _cli_units(v):
    return _parser().parse_args(["plot", "out", "--units", v]).units


CLI = {"solver": _cli("--solver"), "convection": _cli("--convection"), "element": _cli("--element"),
       "case": _cli_case, "example": _cli_example, "units": _cli_units, "time scheme": _cli("--scheme")}
CLI_DEST = {"solver": "solver", "convection": "convection", "element": "element", "case": "name",
            "time scheme": "scheme"}


# ---------------------------------------------------------------------------------------
# the Python API: the factories on this branch
# ---------------------------------------------------------------------------------------
_PROBLEM = []


def _problem():
    if not _PROBLEM:
        from fluidem.fluid.navier_stokes import FlowProblem
        from fluidem.fluid.space import FlowSpace, VelocityBC
        from fluidem.mesh.triangulate import to_skfem, triangulate_box

        mesh = to_skfem(triangulate_box((0.0, 1.0, 0.0, 1.0), [], 0.5))
        _PROBLEM.append(FlowProblem(FlowSpace(mesh, "th"), 0.1, [VelocityBC(("bottom", "top", "left"), (0, 0))]))
    return _PROBLEM[0]


def _py_element(v):
    from fluidem.fluid.elements import element_pair

    return element_pair(v).name


def _py_convection(v):
    from fluidem.fluid.navier_stokes import BDF2Stepper

    return BDF2Stepper(_problem(), 0.1, convection=v).convection


def _py_strategy(v):
    from fluidem.geometry import rectangle
    from fluidem.mesh import MovingMesh

    return MovingMesh((0.0, 2.0, 0.0, 1.0), [rectangle(0.3, 0.2)], [[1.0, 0.5, 0.0]], h=0.25, strategy=v).strategy


def _py_solver(v):
    from fluidem.fluid import solvers
    from fluidem.fluid.solvers import make_solver

    by_class = {solvers.DirectSolver: "direct", solvers.BlockKrylovSolver: "iterative",
                solvers.LaggedLUSolver: "lagged", solvers.AutoSolver: "auto"}
    return by_class[type(make_solver(v, problem=_problem()))]


def _py_case(v):
    from fluidem.cases import CASES, get_case

    fn = get_case(v)
    return next(k for k, f in CASES.items() if f is fn)


def _py_example(v):
    from fluidem.cases.scenes import example_scene

    return example_scene(v).name


def _py_schur(v):
    import scipy.sparse as sp

    from fluidem import names
    from fluidem.fluid.solvers import BlockKrylovSolver

    s = BlockKrylovSolver(2, schur=v, pressure_mass=sp.identity(1, format="csr"), dt=0.1)
    # "auto" resolves to the approximation it stands for at this dt
    return "auto" if names.lookup("schur", v) == "auto" and s.schur == "cahouet-chabard" else s.schur


PYTHON = {"element": _py_element, "convection": _py_convection, "strategy": _py_strategy, "solver": _py_solver,
          "case": _py_case, "example": _py_example, "schur": _py_schur}

#: kinds no place of this package reads by name yet
UNREAD: set = set()


def _cases():
    out = []
    for kind, k in names.REGISTRY.items():
        for value in list(k.entries) + list(k.aliases):
            for place, table in (("scene", SCENE), ("cli", CLI), ("python", PYTHON)):
                if kind in table:
                    out.append(pytest.param(place, kind, value, id=f"{place}-{kind}-{value}"))
    return out


@pytest.mark.parametrize("place,kind,value", _cases())
def test_every_registry_name_means_the_same_everywhere(place, kind, value):
    table = {"scene": SCENE, "cli": CLI, "python": PYTHON}[place]
    assert table[kind](value) == names.lookup(kind, value)


def test_every_kind_is_read_somewhere():
    read = set(SCENE) | set(CLI) | set(PYTHON)
    assert set(names.kinds()) == read | UNREAD, set(names.kinds()) ^ (read | UNREAD)


@pytest.mark.parametrize("kind", sorted(SCENE))
def test_scene_rejects_an_unknown_name_with_the_registry_message(kind):
    with pytest.raises(SceneError) as exc:
        SCENE[kind]("nope" if kind != "side" else "middle")
    msg = str(exc.value)
    if kind == "side":  # an unknown side is an unknown key of [domain]
        assert "allowed keys in [domain]" in msg and all(s in msg for s in names.choices("side"))
    else:
        allowed = ", ".join(repr(n) for n in names.choices(kind))
        assert f"= 'nope': expected one of {allowed} ({names.REGISTRY[kind].title})" in msg


@pytest.mark.parametrize("kind", sorted(CLI_DEST))
def test_cli_choices_are_the_registry(kind):
    assert tuple(_bench_action(CLI_DEST[kind]).choices) == names.choices(kind)


def test_cli_example_help_and_unknown_example():
    from fluidem.cli import main

    p = _parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("run", "plan"):
        (action,) = [a for a in sub.choices[command]._actions if a.dest == "example"]
        assert all(n in action.help for n in names.choices("example"))
    assert main(["plan", "--example", "nope"]) == 2


def test_python_tables_are_the_registry():
    from fluidem.cases import CASES
    from fluidem.cases.scenes import example_names
    from fluidem.fluid.elements import ELEMENT_PAIRS
    from fluidem.fluid.navier_stokes import BDF2Stepper
    from fluidem.fluid.solvers import SOLVERS
    from fluidem.mesh.moving import STRATEGIES
    from fluidem.mesh.triangulate import SIDE_NAMES

    assert tuple(ELEMENT_PAIRS) == names.choices("element")
    assert tuple(BDF2Stepper.CONVECTION) == names.choices("convection")
    assert tuple(STRATEGIES) == names.choices("strategy")
    assert tuple(SOLVERS) == names.choices("solver")
    assert tuple(CASES) == names.choices("case")
    assert sorted(example_names()) == sorted(names.choices("example"))
    assert tuple(SIDE_NAMES) == names.choices("side")


def test_get_case_and_example_scene_reject_unknown_names():
    from fluidem.cases import get_case
    from fluidem.cases.scenes import example_scene

    with pytest.raises(InputError, match=r"case = 'nope': expected one of 'dfg-2d1'"):
        get_case("nope")
    with pytest.raises(InputError, match=r"unknown example scene 'nope': expected one of 'dfg-cylinder'"):
        example_scene("nope")


def test_scene_stores_canonical_names_and_writes_them_back(tmp_path):
    d = _fluid_scene(solver="lagged-lu")
    s = Scene.from_dict(d)
    assert s.fluid.solver == "lagged" and s.to_dict()["fluid"]["solver"] == "lagged"
    s.to_toml(tmp_path / "s.toml")
    assert Scene.from_toml(tmp_path / "s.toml").fluid.solver == "lagged"
    assert '"lagged-lu"' not in (tmp_path / "s.toml").read_text()
    assert tuple(k for k in s.to_dict()["domain"] if k in names.choices("side")) == names.choices("side")
