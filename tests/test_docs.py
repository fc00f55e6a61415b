"""Every public name is documented: it has a docstring, and the API reference (the autodoc
directives in ``docs/api/*.rst``) has a directive that shows it.

The public API is each public module's ``__all__`` (:data:`PUBLIC_MODULES`), plus the
names of :data:`EXTRA_NAMES`; of each public class, its public methods and properties.
No Sphinx here: the directives are read as text and their targets imported, so this runs
in a second; ``.ci/run`` builds the site itself, with warnings as errors. The guides' code
blocks run in ``tests/test_doc_blocks.py``, the README's in ``tests/examples/test_readme.py``.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import inspect
import re
import types
from functools import cached_property
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
API_DIR = ROOT / "docs" / "api"


def _load_attribute_docs() -> types.ModuleType:
    # the docs build's own reader of constants' docstrings (docs/_ext), so that this test
    # and the site agree on where a constant's docstring is
    spec = importlib.util.spec_from_file_location(
        "attribute_docs", ROOT / "docs" / "_ext" / "attribute_docs.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


attribute_docstring = _load_attribute_docs().attribute_docstring

PUBLIC_MODULES = (
    "panda_py",
    "panda_py.panda",
    "panda_py.controllers",
    "panda_py.conditions",
    "panda_py.constants",
    "panda_py.libfranka",
    "panda_py.desk",
    "panda_py.kinematics",
    "panda_py.motion",
    "panda_py.dynamics",
    "panda_py.robots",
    "panda_py.sim",
    "panda_py.sim.desk",
    "panda_py.learning",
    "panda_py.cli",
    "panda_py.fci",
)
# public names of modules without an __all__
EXTRA_NAMES = {"panda_py.sim.testing": ("panda_sim",)}

# ``.. autoclass:: target`` and its options (``:members:``) on the lines below it
DIRECTIVE = re.compile(r"^\.\. (auto\w+):: *(\S+)\s*$")
OPTION = re.compile(r"^\s+:([\w-]+):(.*)$")


@dataclasses.dataclass(frozen=True)
class Directive:
    kind: str  # "automodule", "autoclass", ...
    target: str  # the dotted name it documents
    options: frozenset[str]  # "members", "inherited-members", ...
    where: str  # file:line, for the messages
    excluded: frozenset[str] = frozenset()  # :exclude-members: (documented elsewhere)


def read_directives(text: str, source: str) -> list[Directive]:
    """The autodoc directives of one reST source."""
    lines = text.splitlines()
    found = []
    for i, line in enumerate(lines):
        match = DIRECTIVE.match(line)
        if not match:
            continue
        options, excluded = set(), set()
        for following in lines[i + 1 :]:
            option = OPTION.match(following)
            if not option:
                break
            options.add(option.group(1))
            if option.group(1) == "exclude-members":
                excluded |= {name.strip() for name in option.group(2).split(",") if name.strip()}
        where = f"{source}:{i + 1}"
        found.append(Directive(match[1], match[2], frozenset(options), where, frozenset(excluded)))
    return found


def resolve(dotted: str) -> Any:
    """The object a dotted name stands for: the longest importable module prefix, then
    attributes (as autodoc finds it)."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(dotted)


def public_names(module: str) -> list[str]:
    if module in EXTRA_NAMES:
        return list(EXTRA_NAMES[module])
    names = importlib.import_module(module).__all__
    # the version string and the submodules panda_py exposes have pages (or directives) of
    # their own, checked as modules below
    return [name for name in names if name != "__version__"]


def _is_constant(obj: Any) -> bool:
    return not (callable(obj) or isinstance(obj, (type, types.ModuleType)))


class Reference:
    """What the API reference documents: dotted names, the objects behind them (for
    re-exports documented under another public name) and the options they are shown with
    (a module's :members: apply to its classes, as in autodoc)."""

    def __init__(self, directives: list[Directive]) -> None:
        self.names: dict[str, frozenset[str]] = {}  # documented dotted name -> options
        self.modules: set[str] = set()
        for directive in directives:
            if directive.kind == "automodule":
                self.modules.add(directive.target)
                if "members" in directive.options:
                    module = importlib.import_module(directive.target)
                    for name in set(module.__all__) - directive.excluded:
                        # as autodoc: a constant only with its docstring in this module
                        if not _is_constant(getattr(module, name)) or attribute_docstring(
                            directive.target, name, follow=False
                        ):
                            self.names[f"{directive.target}.{name}"] = directive.options
            else:
                self.names[directive.target] = directive.options
        self.by_object: dict[int, list[str]] = {}
        for name in self.names:
            self.by_object.setdefault(id(resolve(name)), []).append(name)

    def covers(self, module: str, name: str, obj: Any) -> str | None:
        """The documented name that shows ``module.name``, or None. A class or function
        re-exported under two public names is documented once and found by identity;
        numbers and strings only under their own name (equal ones may be one object)."""
        dotted = f"{module}.{name}"
        if dotted in self.names:
            return dotted
        if isinstance(obj, types.ModuleType):
            return obj.__name__ if obj.__name__ in self.modules else None
        if isinstance(obj, (int, float, str, bytes, tuple, type(None))):
            return None
        return next(iter(self.by_object.get(id(obj), [])), None)


def all_directives() -> list[Directive]:
    directives = []
    for path in sorted(API_DIR.glob("*.rst")):
        directives += read_directives(path.read_text(), path.relative_to(ROOT).as_posix())
    return directives


def own_docstring(obj: Any) -> str:
    """A class's own docstring, not one it inherits nor the signature that dataclasses
    and named tuples write in its place."""
    doc = obj.__dict__.get("__doc__") or ""
    if re.fullmatch(rf"{re.escape(obj.__name__)}\(.*\)", doc.strip(), re.S):
        return ""
    return doc.strip()


def docstring_of(module: str, name: str, obj: Any) -> str:
    if inspect.isclass(obj):
        return own_docstring(obj)
    if isinstance(obj, types.ModuleType):
        return (obj.__doc__ or "").strip()
    if (callable(obj) and hasattr(obj, "__code__")) or inspect.isbuiltin(obj):
        return (obj.__doc__ or "").strip()
    if callable(getattr(obj, "__wrapped__", None)):  # a decorated function (a fixture)
        return (obj.__wrapped__.__doc__ or "").strip()
    return attribute_docstring(module, name)


def public_methods(cls: type) -> dict[str, type]:
    """The public methods and properties of a class that its page shows: those it defines
    and those of its private base classes (``_Applied``), each with where it is defined.
    Those of public bases are shown on the base's own page."""
    found: dict[str, type] = {}
    for owner in cls.__mro__:
        if owner is not cls and not owner.__name__.startswith("_"):
            break
        for name, attr in vars(owner).items():
            if name.startswith("_") or name in found:
                continue
            if isinstance(attr, (staticmethod, classmethod)):
                attr = attr.__func__
            if inspect.isfunction(attr) or isinstance(attr, (property, cached_property)):
                found[name] = owner
    return found


def method_docstring(cls: type, name: str) -> str:
    # inherited from the method it overrides, as autodoc shows it
    return (inspect.getdoc(getattr(cls, name)) or "").strip()


PUBLIC = [
    (module, name) for module in (*PUBLIC_MODULES, *EXTRA_NAMES) for name in public_names(module)
]


@pytest.fixture(scope="module")
def reference() -> Reference:
    return Reference(all_directives())


def test_the_reader_finds_directives_and_their_options() -> None:
    text = (
        "Title\n=====\n\n.. automodule:: panda_py.motion\n   :members:\n"
        "   :exclude-members: JointTrajectory, TrajectoryError\n\n"
        ".. autoclass:: panda_py.Panda\n\n.. autofunction:: panda_py.kinematics.fk\n"
    )
    assert read_directives(text, "x.rst") == [
        Directive(
            "automodule",
            "panda_py.motion",
            frozenset({"members", "exclude-members"}),
            "x.rst:4",
            frozenset({"JointTrajectory", "TrajectoryError"}),
        ),
        Directive("autoclass", "panda_py.Panda", frozenset(), "x.rst:8"),
        Directive("autofunction", "panda_py.kinematics.fk", frozenset(), "x.rst:10"),
    ]


def test_the_checks_reject_what_is_undocumented() -> None:
    @dataclasses.dataclass
    class Bare:
        x: int

    class Plain:
        def method(self) -> None:
            pass

    assert own_docstring(Bare) == ""
    assert method_docstring(Plain, "method") == ""
    assert attribute_docstring("panda_py.constants", "JOINT_POSITION_START")
    assert attribute_docstring("panda_py.constants", "np") == ""
    reference = Reference([Directive("autoclass", "panda_py.Panda", frozenset(), "x.rst:1")])
    import panda_py

    assert reference.covers("panda_py", "Panda", panda_py.Panda) == "panda_py.Panda"
    assert reference.covers("panda_py", "PandaContext", panda_py.PandaContext) is None


def test_every_directive_names_something_that_exists() -> None:
    for directive in all_directives():
        try:
            resolve(directive.target)
        except (ImportError, AttributeError) as exc:
            pytest.fail(f"{directive.where}: {directive.target} does not exist ({exc})")


@pytest.mark.parametrize(("module", "name"), PUBLIC, ids=[f"{m}.{n}" for m, n in PUBLIC])
def test_public_name_is_documented(module: str, name: str, reference: Reference) -> None:
    obj = getattr(importlib.import_module(module), name)
    where = reference.covers(module, name, obj)
    assert where, f"{module}.{name} is public but no directive in docs/api/ documents it"
    assert docstring_of(module, name, obj), f"{module}.{name} has no docstring"
    if not inspect.isclass(obj):
        return
    methods = public_methods(obj)
    options = reference.names.get(where, frozenset())
    if methods:
        assert "members" in options, (
            f"{where}'s methods are public but its directive has no :members:"
        )
    if any(owner is not obj for owner in methods.values()):
        assert "inherited-members" in options, (
            f"{where} inherits public methods from a private base: its directive needs "
            ":inherited-members: (naming the public base where the page should stop)"
        )
    undocumented = [m for m in methods if not method_docstring(obj, m)]
    assert not undocumented, f"{module}.{name}: methods without a docstring: {undocumented}"


def test_ci_builds_the_site_with_warnings_as_errors_before_the_tests() -> None:
    # (tests/examples/test_readme.py holds that the README's second command is .ci/run's)
    command = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert '".[dev,examples,docs,learning]"' in command
    assert "-m sphinx -W" in command and command.index("-m sphinx") < command.index("-m pytest")
