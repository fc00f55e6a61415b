"""panda_py: program Franka robots (FER "Panda", FR3) from pure Python.

Import stays cheap: the heavier submodules are imported on first use of one of their
names (``panda_py.fk`` imports ``panda_py.kinematics`` then).
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

# public name -> submodule that defines it (imported lazily, PEP 562)
_LAZY: dict[str, str] = {
    "fk": "panda_py.kinematics",
    "ik": "panda_py.kinematics",
    "ik_full": "panda_py.kinematics",
    "JointTrajectory": "panda_py.motion",
    "CartesianTrajectory": "panda_py.motion",
    "Desk": "panda_py.desk",
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'panda_py' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
