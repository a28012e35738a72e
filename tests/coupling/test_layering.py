"""The coupling layer does not depend on the scene schema: its modules import neither
``fluidem.scene`` nor ``fluidem.plan``, take no parameter named ``scene`` and read no ``scene``
(a name or an attribute such as ``self.scene``); they take the specs they need
(:mod:`fluidem.build` takes a scene apart for them)."""

import ast
import pathlib

import fluidem.coupling

COUPLING = pathlib.Path(fluidem.coupling.__file__).parent
FORBIDDEN = ("fluidem.scene", "fluidem.plan")


def _imported(node: ast.AST, package: str) -> list:
    """The absolute module names an import statement in ``package`` names (``from .. import scene``:
    ``fluidem.scene``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if not isinstance(node, ast.ImportFrom):
        return []
    if node.level:
        parts = package.split(".")
        base = ".".join(parts[: len(parts) - (node.level - 1)] + ([node.module] if node.module else []))
    else:
        base = node.module or ""
    return [base] + [f"{base}.{a.name}" for a in node.names]


def scene_uses(source: str, package: str = "fluidem.coupling") -> list:
    """Every way ``source`` (a module of ``package``) depends on the scene: a forbidden import, a
    parameter named ``scene``, a name or attribute ``scene`` read; ``(line, what)`` pairs."""
    found = []
    for node in ast.walk(ast.parse(source)):
        for name in _imported(node, package):
            if any(name == f or name.startswith(f + ".") for f in FORBIDDEN):
                found.append((node.lineno, f"imports {name}"))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            a = node.args
            params = [*a.posonlyargs, *a.args, *a.kwonlyargs, *(p for p in (a.vararg, a.kwarg) if p)]
            found += [(node.lineno, f"parameter {p.arg!r}") for p in params if p.arg == "scene"]
        elif isinstance(node, ast.Name) and node.id == "scene":
            found.append((node.lineno, "reads the name 'scene'"))
        elif isinstance(node, ast.Attribute) and node.attr == "scene":
            found.append((node.lineno, f"reads {ast.unparse(node)}"))
    return sorted(set(found))


def test_the_check_finds_each_kind_of_scene_dependence():
    """The check is not vacuous: each way of depending on the scene is found."""
    bad = ("from ..scene import Scene\n"
           "from .. import plan\n"
           "import fluidem.scene.specs\n"
           "def f(bodies, *, scene=None):\n"
           "    return scene.domain\n"
           "class A:\n"
           "    def g(self):\n"
           "        return self.scene.fluid\n")
    whats = [w for _, w in scene_uses(bad)]
    assert "imports fluidem.scene" in whats and "imports fluidem.plan" in whats
    assert "imports fluidem.scene.specs" in whats
    assert "parameter 'scene'" in whats and "reads the name 'scene'" in whats and "reads self.scene" in whats
    assert scene_uses("from ..dem import DEM\ndef f(domain, bodies):\n    return domain.box\n") == []


def test_coupling_modules_take_specs_not_the_scene():
    files = sorted(COUPLING.rglob("*.py"))
    assert len(files) >= 10  # the package's modules were found
    bad = {}
    for f in files:
        package = "fluidem.coupling" if f.parent == COUPLING else \
            "fluidem.coupling." + ".".join(f.parent.relative_to(COUPLING).parts)
        uses = scene_uses(f.read_text(encoding="utf-8"), package)
        if uses:
            bad[f.name] = uses
    assert bad == {}
