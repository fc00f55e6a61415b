"""The docstring of a module-level constant, wherever the package re-exports it from.

Sphinx reads a constant's docstring (the string literal after ``NAME = ...``, or ``#:``
comments before it) from the source of the module it documents it under, and
``automodule``'s ``:members:`` shows no constant without one there. The package re-exports
constants from the modules that define them (``panda_py.robots.FER`` from
``panda_py.robots.params``): the API pages name those in ``autodata`` directives, and this
extension gives each the docstring written at its definition, following the imports. Used
by the docs build (:func:`setup`) and by ``tests/test_docs.py``; no Sphinx import here.
"""

from __future__ import annotations

import ast
import importlib.util
import inspect
from pathlib import Path
from typing import Any


def _assigned_names(node: ast.stmt) -> list[str]:
    if isinstance(node, ast.Assign):
        return [t.id for t in node.targets if isinstance(t, ast.Name)]
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
        return [node.target.id]
    return []


def _comment_doc(lines: list[str], lineno: int) -> str:
    """The ``#:`` comment lines right above line ``lineno`` (1-based)."""
    found: list[str] = []
    index = lineno - 2
    while index >= 0 and lines[index].lstrip().startswith("#:"):
        found.insert(0, lines[index].lstrip()[2:].strip())
        index -= 1
    return " ".join(found)


def _lazy_source(node: ast.stmt, name: str) -> str:
    """The module a PEP 562 lazy export names for ``name`` (``_LAZY = {"name": "module"}``,
    as ``panda_py`` and ``panda_py.sim`` export their names), or ""."""
    if "_LAZY" not in _assigned_names(node):
        return ""
    value = node.value  # type: ignore[attr-defined]
    if not isinstance(value, ast.Dict):
        return ""
    for key, source in zip(value.keys, value.values, strict=True):
        if isinstance(key, ast.Constant) and key.value == name and isinstance(source, ast.Constant):
            return str(source.value)
    return ""


def attribute_docstring(
    module: str, name: str, *, follow: bool = True, _seen: frozenset[str] = frozenset()
) -> str:
    """The docstring of the constant ``name`` of ``module``: from the module's own source,
    else (``follow``) from the module it imports ``name`` from (``from x import name`` or
    ``*``, or a lazy export)."""
    if module in _seen:
        return ""
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return ""
    text = Path(spec.origin).read_text()
    lines = text.splitlines()
    body = ast.parse(text).body
    for node, following in zip(body, [*body[1:], None], strict=True):
        if name not in _assigned_names(node):
            continue
        if (
            isinstance(following, ast.Expr)
            and isinstance(following.value, ast.Constant)
            and isinstance(following.value.value, str)
        ):
            return following.value.value.strip()
        return _comment_doc(lines, node.lineno)
    if not follow:
        return ""
    package = module if spec.submodule_search_locations else module.rpartition(".")[0]
    for node in body:
        lazy = _lazy_source(node, name)
        if lazy:
            return attribute_docstring(lazy, name, _seen=_seen | {module})
        if not isinstance(node, ast.ImportFrom):
            continue
        if any(alias.name in (name, "*") and alias.asname is None for alias in node.names):
            source = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            doc = attribute_docstring(source, name, _seen=_seen | {module})
            if doc:
                return doc
    return ""


def _docstring_from_definition(
    app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]
) -> None:
    if what != "data":
        return
    module, _, attr = name.rpartition(".")
    doc = attribute_docstring(module, attr)
    if doc:
        lines[:] = inspect.cleandoc(doc).splitlines()


def setup(app: Any) -> dict[str, Any]:
    app.setup_extension("sphinx.ext.autodoc")
    app.connect("autodoc-process-docstring", _docstring_from_definition)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
