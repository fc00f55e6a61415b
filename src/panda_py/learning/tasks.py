"""The tasks: reaching a random point, and picking up the 4 cm cube and placing it at a
random point (on the table or in the air), as panda-gym 3's ``PandaReach`` and
``PandaPickAndPlace``.

Where they differ from panda-gym's (besides running on a robot): positions are in the
robot's base frame (the table top is z = 0; panda-gym puts its origin on the table,
0.6 m in front of the robot); the observation starts with the robot's joints
``q`` [rad] and ``dq`` [rad/s] (7 each), the end effector's position [m] and orientation
(quaternion x, y, z, w) (21 values; panda-gym: the end effector's position and velocity),
then the task's part (picking: the fingers' opening [m] and the cube's position [m];
panda-gym adds the cube's orientation and velocities); the hand is opened or closed by
the action's last value, not moved by a width.
"""

from __future__ import annotations

import numpy as np

from panda_py.learning.backend import FloatArray, Snapshot
from panda_py.learning.env import PandaEnv

__all__ = [
    "CUBE_HIGH",
    "CUBE_LOW",
    "REACH_HIGH",
    "REACH_LOW",
    "PandaPickAndPlaceEnv",
    "PandaReachEnv",
]

# [m] where reaching goals are drawn (base frame)
REACH_LOW = np.array([0.3, -0.2, 0.15])
REACH_HIGH = np.array([0.6, 0.2, 0.45])
# [m] where the cube (its centre) and the placing goals are drawn
CUBE_LOW = np.array([0.4, -0.15])
CUBE_HIGH = np.array([0.6, 0.15])
CUBE_Z = 0.02  # [m] the cube's centre resting on the table (4 cm edge)
GOAL_LIFT = 0.2  # [m] placing goals up to this above the table (panda-gym's)
ON_TABLE = 0.3  # share of placing goals on the table (panda-gym's)
GOAL_APART = 0.1  # [m] a placing goal at least this far from where the cube starts


class PandaReachEnv(PandaEnv):
    """Bring the end effector (the TCP between the fingertips) to a random point; the
    hand stays open and the actions have no hand value (panda-gym's blocked gripper)."""

    def _sample(self, rng: np.random.Generator) -> FloatArray | None:
        self.goal = self._uniform(rng, REACH_LOW, REACH_HIGH)
        return None

    def _achieved(self, snap: Snapshot) -> FloatArray:
        return snap.O_T_EE[:3, 3].copy()


class PandaPickAndPlaceEnv(PandaEnv):
    """Pick up the cube from a random place on the table and bring it to a random goal,
    on the table or up to 20 cm above it."""

    uses_hand = True
    uses_cube = True
    task_size = 4

    def _sample(self, rng: np.random.Generator) -> FloatArray | None:
        cube = np.append(self._uniform(rng, CUBE_LOW, CUBE_HIGH), CUBE_Z)
        while True:  # redrawn from the same generator: still one episode per seed
            goal = np.append(self._uniform(rng, CUBE_LOW, CUBE_HIGH), CUBE_Z)
            if rng.random() >= ON_TABLE:
                goal[2] += GOAL_LIFT * rng.random()
            if np.linalg.norm(goal - cube) >= GOAL_APART:
                break
        self.goal = goal
        return cube

    def _task_observation(self, snap: Snapshot) -> FloatArray:
        return np.append(snap.gripper_width, self._cube(snap))

    def _achieved(self, snap: Snapshot) -> FloatArray:
        return self._cube(snap)

    @staticmethod
    def _cube(snap: Snapshot) -> FloatArray:
        assert snap.cube is not None  # the environment's backend has a cube (checked)
        return snap.cube
