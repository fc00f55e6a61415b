"""The package's architecture, as its imports have it: every arrow between the top-level
units points down the layers docs/architecture.md draws, nothing imports a private module or name
of another unit, and the simulator and the client never import each other.

Imports under ``if TYPE_CHECKING:`` count too: an arrow hidden from the run time is still
an arrow in the design.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "panda_py"

# bottom first; a unit may import the units of lower layers (and itself) only
LAYERS: list[set[str]] = [
    {"checks", "fci", "jit", "overloads", "progress", "warmstart"},
    {"robots", "desk"},
    {"constants", "kinematics", "dynamics", "motion"},
    {"libfranka", "sim"},
    {"controllers"},
    {"rt", "conditions"},
    {"panda"},
    {"cli", "demo", "doctor", "learning", "__init__"},
]
LEVEL = {unit: i for i, layer in enumerate(LAYERS) for unit in layer}
CLIENT = {"libfranka", "controllers", "rt", "panda", "desk", "cli", "doctor"}
# the only ways from the client to the simulator: the demo starts an embedded one (lazily);
# learning runs the simulator's robot core in process (its fast training world)
SIM_ALLOWED_FROM = {"demo", "learning"}


def _unit(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


Import = tuple[str, int, str, str, list[str]]


@functools.cache
def _imports() -> list[Import]:
    """(file, line, importing unit, imported module, imported names) for every import of
    panda_py in the package; read once, when a test first asks (not while collecting,
    which every worker of the suite does)."""
    found: list[Import] = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent)
        me = _unit(".".join(rel.with_suffix("").parts))
        where = str(rel)
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (
                isinstance(node, ast.ImportFrom)
                and node.module
                and node.module.startswith("panda_py")
            ):
                names = [a.name for a in node.names]
                if node.module == "panda_py":  # from panda_py import fci, checks
                    for name in names:
                        found.append((where, node.lineno, me, f"panda_py.{name}", []))
                else:
                    found.append((where, node.lineno, me, node.module, names))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("panda_py."):
                        found.append((where, node.lineno, me, alias.name, []))
    return found


def test_every_unit_has_a_layer() -> None:
    units = {p.stem if p.is_file() else p.name for p in SRC.iterdir() if p.name != "py.typed"}
    units = {u for u in units if not u.startswith("__pycache__")}
    assert units - set(LEVEL) == set()


def test_imports_point_down_the_layers() -> None:
    up = [
        f"{f}:{line}: {me} -> {mod}"
        for f, line, me, mod, _ in _imports()
        if _unit(mod) != me and LEVEL[_unit(mod)] >= LEVEL[me]
    ]
    assert up == []


def test_no_private_module_or_name_crosses_a_unit() -> None:
    private = [
        f"{f}:{line}: {me} imports {mod} {names}"
        for f, line, me, mod, names in _imports()
        if _unit(mod) != me
        and (
            any(p.startswith("_") for p in mod.split(".")[1:])
            or any(n.startswith("_") for n in names)
        )
    ]
    assert private == []


@pytest.mark.parametrize("side", ["sim", "client"])
def test_the_simulator_and_the_client_do_not_import_each_other(side: str) -> None:
    if side == "sim":
        bad = [
            f"{f}:{line}: {mod}"
            for f, line, me, mod, _ in _imports()
            if me == "sim"
            # (jit: the compiled modules and their cache, the kinematics use too, no client code)
            and _unit(mod)
            not in {"sim", "fci", "robots", "kinematics", "checks", "warmstart", "jit"}
        ]
    else:
        bad = [
            f"{f}:{line}: {mod}"
            for f, line, me, mod, _ in _imports()
            if me in CLIENT and _unit(mod) == "sim"
        ]
        bad += [
            f"{f}:{line}: {mod}"
            for f, line, me, mod, _ in _imports()
            if _unit(mod) == "sim" and me not in {"sim", *SIM_ALLOWED_FROM}
        ]
    assert bad == []


def _module_graph() -> dict[str, set[str]]:
    """Every module of the package (packages by their name) -> the package's modules it
    imports (``from panda_py.x import y`` names module y where y is one, else x)."""
    modules = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets: list[str] = []
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("panda_py"):
                assert node.module is not None
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    targets.append(sub if sub in modules else node.module)
            elif isinstance(node, ast.Import):
                targets += [a.name for a in node.names if a.name.startswith("panda_py")]
            for target in targets:
                while target not in modules:
                    target = target.rsplit(".", 1)[0]
                if target != module:
                    graph[module].add(target)
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_import_circle_inside_a_unit() -> None:
    """Not even through a package's ``__init__``, a lazy import or one for the type
    checker only: a circle is an arrow pointing back, whatever the run time sees."""
    graph = _module_graph()
    inside = {m: {t for t in ts if _unit(t) == _unit(m)} for m, ts in graph.items()}
    assert _circles(inside) == []


def test_the_circle_finder_finds_one() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _circles(graph) == [["a", "b", "c"]]


def _reaches_in(where: str, me: str, tree: ast.AST) -> list[str]:
    """Attributes with a private name (``_x``, not dunders) reached through a name that an
    import bound to another unit's module or object (``kinematics._backend``,
    ``laws.fused()._KEY``): a reach the import test does not see."""
    foreign: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("panda_py"):
            assert node.module is not None
            for alias in node.names:
                module = f"panda_py.{alias.name}" if node.module == "panda_py" else node.module
                if _unit(module) != me:
                    foreign.add(alias.asname or alias.name)
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute) or not node.attr.startswith("_"):
            continue
        if node.attr.startswith("__"):
            continue
        base = node.value
        while isinstance(base, (ast.Attribute, ast.Call)):
            base = base.func if isinstance(base, ast.Call) else base.value
        if isinstance(base, ast.Name) and base.id in foreign:
            found.append(f"{where}:{node.lineno}: {base.id} ... {node.attr}")
    return found


def test_no_private_attribute_is_reached_across_units() -> None:
    found = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent)
        me = _unit(".".join(rel.with_suffix("").parts))
        found += _reaches_in(str(rel), me, ast.parse(path.read_text(), str(path)))
    assert sorted(set(found)) == []


def test_the_reach_finder_finds_one() -> None:
    source = (
        "from panda_py import kinematics\n"
        "from panda_py.controllers import laws\n"
        "from panda_py.sim.physics import Physics\n"
        "a = kinematics._backend.ik\n"
        "b = laws.fused().__name__\n"
        "c = laws.fused()._KEY\n"
        "d = Physics._links\n"
    )
    found = sorted(_reaches_in("x.py", "sim", ast.parse(source)))
    assert found == ["x.py:4: kinematics ... _backend", "x.py:6: laws ... _KEY"]
