"""Pickling of classes and functions defined in a script, by value.

A user-written controller usually lives in the script the user runs (``__main__``),
which the control process cannot import (importing it would run the script again). Such
classes and the functions they use are sent as their code objects (``marshal``, the same
interpreter runs both processes) with the globals their code names; modules go by name,
everything importable by reference, as ``pickle`` always does.
"""

from __future__ import annotations

import builtins
import importlib
import io
import marshal
import pickle
import types
from typing import Any

__all__ = ["dumps"]

_BY_VALUE_MODULES = ("__main__", "__mp_main__")
MODULE_NAME = "__panda_py_main__"  # the __module__ of what arrives by value


def _global_names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _global_names(const)
    return names


def _make_function(code: bytes, name: str, ncells: int) -> types.FunctionType:
    closure = tuple(types.CellType() for _ in range(ncells)) or None
    return types.FunctionType(marshal.loads(code), {"__builtins__": builtins}, name, None, closure)


def _fill_function(func: types.FunctionType, state: dict[str, Any]) -> None:
    func.__globals__.update(state["globals"])
    func.__defaults__ = state["defaults"]
    func.__kwdefaults__ = state["kwdefaults"]
    func.__qualname__ = state["qualname"]
    func.__module__ = MODULE_NAME
    func.__dict__.update(state["dict"])
    for cell, value in zip(func.__closure__ or (), state["cells"], strict=True):
        if value is not _EMPTY:
            cell.cell_contents = value


def _make_class(name: str, bases: tuple[type, ...], metaclass: type) -> type:
    return metaclass(name, bases, {"__module__": MODULE_NAME})


def _fill_class(cls: type, state: dict[str, Any]) -> None:
    for key, value in state.items():
        setattr(cls, key, value)


class _Empty:
    """Marks an empty closure cell."""

    def __reduce__(self) -> str:
        return "_EMPTY"


_EMPTY = _Empty()


def _cell_value(cell: types.CellType) -> Any:
    try:
        return cell.cell_contents
    except ValueError:
        return _EMPTY


class _Pickler(pickle.Pickler):
    def reducer_override(self, obj: Any) -> Any:
        if isinstance(obj, types.ModuleType):
            return importlib.import_module, (obj.__name__,)
        module = getattr(obj, "__module__", None)
        if module not in _BY_VALUE_MODULES:
            return NotImplemented
        if isinstance(obj, types.FunctionType):
            code = obj.__code__
            names = _global_names(code)
            glob = {k: v for k, v in obj.__globals__.items() if k in names}
            state = {
                "globals": glob,
                "defaults": obj.__defaults__,
                "kwdefaults": obj.__kwdefaults__,
                "qualname": obj.__qualname__,
                "dict": obj.__dict__,
                "cells": [_cell_value(c) for c in obj.__closure__ or ()],
            }
            args = (marshal.dumps(code), obj.__name__, len(obj.__closure__ or ()))
            return _make_function, args, state, None, None, _fill_function
        if isinstance(obj, type):
            skip = {"__dict__", "__weakref__", "__module__"}
            state = {k: v for k, v in vars(obj).items() if k not in skip}
            cls_args = (obj.__name__, obj.__bases__, type(obj))
            return _make_class, cls_args, state, None, None, _fill_class
        return NotImplemented


def dumps(obj: Any) -> bytes:
    """Pickle ``obj``, sending what ``__main__`` defines by value."""
    buf = io.BytesIO()
    _Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return buf.getvalue()
