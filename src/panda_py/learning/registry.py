"""The learning environments' Gymnasium ids (:data:`ENVIRONMENTS`) and their
registration (:func:`register`), where gymnasium is installed: importing
:mod:`panda_py.learning` registers them, and a rollout worker calls :func:`register` in
its own process."""

from __future__ import annotations

import importlib
import importlib.util
from typing import Any

__all__ = ["ENVIRONMENTS", "env_class", "register"]

#: the registered Gymnasium ids: id -> (entry point, episode length in policy steps)
ENVIRONMENTS = {
    "PandaReach-v0": ("panda_py.learning.tasks:PandaReachEnv", 50),
    "PandaPickAndPlace-v0": ("panda_py.learning.tasks:PandaPickAndPlaceEnv", 100),
}
# id -> what ``gymnasium.make_vec`` makes by default: a PandaVectorEnv (worker processes)
_VECTOR_ENTRY_POINTS = {
    "PandaReach-v0": "panda_py.learning.vector:reach",
    "PandaPickAndPlace-v0": "panda_py.learning.vector:pick_and_place",
}


def register() -> None:
    """Register the environments' ids with Gymnasium, where it is installed (the entry
    points are strings: nothing of the environments loads until one is made)."""
    if importlib.util.find_spec("gymnasium") is None:
        return
    import gymnasium

    for env_id, (entry, steps) in ENVIRONMENTS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=entry, max_episode_steps=steps,
                               vector_entry_point=_VECTOR_ENTRY_POINTS[env_id])  # fmt: skip


def env_class(env_id: str) -> Any:
    """The environment class registered as ``env_id`` (ValueError naming the ids)."""
    if env_id not in ENVIRONMENTS:
        raise ValueError(f"env_id: expected one of {sorted(ENVIRONMENTS)}, got {env_id!r}")
    module, _, name = ENVIRONMENTS[env_id][0].partition(":")
    return getattr(importlib.import_module(module), name)
