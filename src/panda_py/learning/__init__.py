"""Robot learning on the same code: Gymnasium environments that run unchanged on a fast
in-process training world and on any ``Panda`` (a robot, or ``panda-sim``)
(:mod:`~panda_py.learning.env`, :mod:`~panda_py.learning.tasks`,
:mod:`~panda_py.learning.world`, :mod:`~panda_py.learning.arm`), many of them stepped by
worker processes (:mod:`~panda_py.learning.vector`, ``gymnasium.make_vec``'s default for
the ids); deploying policies
(DROID's action contract, chunked actions at a policy rate,
:mod:`~panda_py.learning.deploy`, :mod:`~panda_py.learning.policy_runner`), serving a
policy to openpi's client (:mod:`~panda_py.learning.policy_server`) and recording
episodes (robomimic's HDF5: :mod:`~panda_py.learning.recording`; LeRobot's datasets:
:mod:`~panda_py.learning.lerobot`, :mod:`~panda_py.learning.lerobot_convert`); rollouts on
many processes and machines with Ray (:mod:`~panda_py.learning.rollouts`).

    import gymnasium
    import panda_py.learning  # registers the environments

    env = gymnasium.make("PandaReach-v0")  # the fast world
    env = gymnasium.make("PandaPickAndPlace-v0", backend=RobotArm(sim.host, scene=sim))

Importing this package is cheap: its modules load on first use of one of the names below
(PEP 562). The environments need gymnasium, recording needs h5py (HDF5) or pyarrow and av
(LeRobot), the policy server msgpack and the rollouts Ray: the ``learning`` extra (``pip
install "panda-py-pure[learning]"``); without gymnasium, the environments' names raise an
ImportError saying so and no id is registered.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from panda_py.learning import registry

if TYPE_CHECKING:
    from panda_py.learning.actions import ActionKind
    from panda_py.learning.arm import RobotArm, Scene
    from panda_py.learning.backend import Backend, Snapshot
    from panda_py.learning.deploy import ActionSpace, DroidActions
    from panda_py.learning.env import PandaEnv, Reward
    from panda_py.learning.lerobot import LeRobotWriter
    from panda_py.learning.lerobot_convert import hdf5_to_lerobot, read_lerobot
    from panda_py.learning.policies import pick_and_place_policy, reach_policy
    from panda_py.learning.policy_runner import PolicyRunner, RunStats
    from panda_py.learning.policy_server import PolicyServer
    from panda_py.learning.recording import EpisodeWriter, read_recording
    from panda_py.learning.rollouts import EpisodeResult, RolloutWorkers, run_rollouts
    from panda_py.learning.tasks import PandaPickAndPlaceEnv, PandaReachEnv
    from panda_py.learning.vector import PandaVectorEnv
    from panda_py.learning.world import FastWorld

# public name -> submodule that defines it
_LAZY: dict[str, str] = {
    "ActionKind": "panda_py.learning.actions",
    "ActionSpace": "panda_py.learning.deploy",
    "Backend": "panda_py.learning.backend",
    "DroidActions": "panda_py.learning.deploy",
    "EpisodeResult": "panda_py.learning.rollouts",
    "EpisodeWriter": "panda_py.learning.recording",
    "FastWorld": "panda_py.learning.world",
    "LeRobotWriter": "panda_py.learning.lerobot",
    "PandaEnv": "panda_py.learning.env",
    "PandaPickAndPlaceEnv": "panda_py.learning.tasks",
    "PandaReachEnv": "panda_py.learning.tasks",
    "PandaVectorEnv": "panda_py.learning.vector",
    "PolicyRunner": "panda_py.learning.policy_runner",
    "PolicyServer": "panda_py.learning.policy_server",
    "Reward": "panda_py.learning.env",
    "RobotArm": "panda_py.learning.arm",
    "RolloutWorkers": "panda_py.learning.rollouts",
    "RunStats": "panda_py.learning.policy_runner",
    "Scene": "panda_py.learning.arm",
    "Snapshot": "panda_py.learning.backend",
    "hdf5_to_lerobot": "panda_py.learning.lerobot_convert",
    "pick_and_place_policy": "panda_py.learning.policies",
    "reach_policy": "panda_py.learning.policies",
    "read_lerobot": "panda_py.learning.lerobot_convert",
    "read_recording": "panda_py.learning.recording",
    "run_rollouts": "panda_py.learning.rollouts",
}

__all__ = [
    "ENVIRONMENTS",
    "ActionKind",
    "ActionSpace",
    "Backend",
    "DroidActions",
    "EpisodeResult",
    "EpisodeWriter",
    "FastWorld",
    "LeRobotWriter",
    "PandaEnv",
    "PandaPickAndPlaceEnv",
    "PandaReachEnv",
    "PandaVectorEnv",
    "PolicyRunner",
    "PolicyServer",
    "Reward",
    "RobotArm",
    "RolloutWorkers",
    "RunStats",
    "Scene",
    "Snapshot",
    "hdf5_to_lerobot",
    "pick_and_place_policy",
    "reach_policy",
    "read_lerobot",
    "read_recording",
    "run_rollouts",
]


#: the registered Gymnasium ids: id -> (entry point, episode length in policy steps)
ENVIRONMENTS = registry.ENVIRONMENTS


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'panda_py.learning' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


registry.register()
