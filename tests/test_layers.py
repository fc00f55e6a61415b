"""The package's architecture, as its imports have it: every arrow between the top-level
units points down the layers the README draws, nothing imports a private module or name
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
