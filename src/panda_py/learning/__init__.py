"""Robot learning on the same code: deploying policies (DROID's action contract, chunked
actions at a policy rate, :mod:`~panda_py.learning.deploy`,
:mod:`~panda_py.learning.policy_runner`) and recording episodes
(:mod:`~panda_py.learning.recording`).

Importing this package is cheap: its modules load on first use of one of the names below
(PEP 562); recording needs the ``learning`` extra (h5py).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from panda_py.learning.deploy import ActionSpace, DroidActions
    from panda_py.learning.policy_runner import PolicyRunner, RunStats
    from panda_py.learning.recording import EpisodeWriter, read_recording

# public name -> submodule that defines it
_LAZY: dict[str, str] = {
    "ActionSpace": "panda_py.learning.deploy",
    "DroidActions": "panda_py.learning.deploy",
    "EpisodeWriter": "panda_py.learning.recording",
    "PolicyRunner": "panda_py.learning.policy_runner",
    "RunStats": "panda_py.learning.policy_runner",
    "read_recording": "panda_py.learning.recording",
}

__all__ = [
    "ActionSpace",
    "DroidActions",
    "EpisodeWriter",
    "PolicyRunner",
    "RunStats",
    "read_recording",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'panda_py.learning' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
