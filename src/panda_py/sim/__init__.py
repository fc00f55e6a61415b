"""panda-sim: a simulated Franka (FER or FR3) that speaks the real FCI protocol.

Use :class:`Simulator` from Python, ``panda-sim`` from the shell, or the ``panda_sim``
pytest fixture (``panda_py.sim.testing``); :class:`InProcessRobot` is the same robot in
your own process, ticked by you, without sockets (the fast training world runs on it).

Importing this package is cheap: the names below load on first use (PEP 562), so the
pytest plugin, which lives in this package and is imported into every pytest session of
the environment, costs nothing until a test asks for a simulator. Even then the caller's
process loads neither MuJoCo nor the simulator's server: :class:`Simulator` runs them in
a process of its own.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from panda_py.sim.api import Simulator, SimulatorError, free_loopback_host
    from panda_py.sim.config import SimConfig
    from panda_py.sim.inprocess import InProcessRobot

# public name -> submodule that defines it
_LAZY: dict[str, str] = {
    "InProcessRobot": "panda_py.sim.inprocess",
    "SimConfig": "panda_py.sim.config",
    "Simulator": "panda_py.sim.api",
    "SimulatorError": "panda_py.sim.api",
    "free_loopback_host": "panda_py.sim.api",
}

__all__ = ["InProcessRobot", "SimConfig", "Simulator", "SimulatorError", "free_loopback_host"]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'panda_py.sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
