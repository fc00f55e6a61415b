"""panda_py: program Franka robots (FER "Panda", FR3) from pure Python.

Import stays cheap: the heavier submodules are imported on first use of one of their
names (``panda_py.fk`` imports ``panda_py.kinematics`` then).
"""

from __future__ import annotations

import importlib
from typing import Any

from panda_py import warmstart

__version__ = "0.1.0"

# What the server control processes are forked from loads (panda_py.warmstart): named
# here, at the package's import, so that it is named before anything can start that
# server (a simulator started first would otherwise start it without).
warmstart.register("panda_py.rt.warm")

# public name -> submodule that defines it (imported lazily, PEP 562)
_LAZY: dict[str, str] = {
    "fk": "panda_py.kinematics",
    "ik": "panda_py.kinematics",
    "ik_full": "panda_py.kinematics",
    "JointTrajectory": "panda_py.motion",
    "CartesianTrajectory": "panda_py.motion",
    "Panda": "panda_py.panda",
    "PandaContext": "panda_py.panda",
    "realtime_priority_available": "panda_py.panda",
    "MotionHandle": "panda_py.panda",
    "JointMotion": "panda_py.panda",
    "PoseMotion": "panda_py.panda",
    "ControlProcessError": "panda_py.rt.process",
    # panda-py's name for a robot speaking a protocol version no client here speaks
    "IncompatibleVersionError": "panda_py.libfranka.errors",
    "Desk": "panda_py.desk",
    "TOKEN_PATH": "panda_py.desk",
}

# submodules panda-py exposes as attributes (``panda_py.controllers``, ...), imported lazily
_SUBMODULES = ("constants", "controllers", "libfranka", "motion")

__all__ = ["__version__", *sorted(_LAZY), *_SUBMODULES]


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        return importlib.import_module(f"panda_py.{name}")
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'panda_py' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES))
