"""Robot learning on the same code: Gymnasium environments that run unchanged on a fast
in-process training world and on any ``Panda`` (a robot, or ``panda-sim``).

    import gymnasium
    import panda_py.learning  # registers the environments

    env = gymnasium.make("PandaReach-v0")  # the fast world
    env = gymnasium.make("PandaPickAndPlace-v0", backend=RobotArm(sim.host, scene=sim))

Needs the ``learning`` extra (``pip install "panda-py-pure[learning]"``: gymnasium); the
rest of panda_py never imports this package.
"""

from __future__ import annotations

try:
    import gymnasium
except ImportError as exc:  # the one optional dependency of this package
    raise ImportError(
        'panda_py.learning needs gymnasium: pip install "panda-py-pure[learning]"'
    ) from exc

from panda_py.learning.actions import ActionKind
from panda_py.learning.arm import RobotArm, Scene
from panda_py.learning.backend import Backend, Snapshot
from panda_py.learning.env import PandaEnv, Reward
from panda_py.learning.policies import pick_and_place_policy, reach_policy
from panda_py.learning.tasks import PandaPickAndPlaceEnv, PandaReachEnv
from panda_py.learning.world import FastWorld

__all__ = [
    "ENVIRONMENTS",
    "ActionKind",
    "Backend",
    "FastWorld",
    "PandaEnv",
    "PandaPickAndPlaceEnv",
    "PandaReachEnv",
    "Reward",
    "RobotArm",
    "Scene",
    "Snapshot",
    "pick_and_place_policy",
    "reach_policy",
]

#: the registered ids: id -> (entry point, episode length in policy steps)
ENVIRONMENTS = {
    "PandaReach-v0": ("panda_py.learning.tasks:PandaReachEnv", 50),
    "PandaPickAndPlace-v0": ("panda_py.learning.tasks:PandaPickAndPlaceEnv", 100),
}


def _register() -> None:
    for env_id, (entry, steps) in ENVIRONMENTS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=entry, max_episode_steps=steps)


_register()
