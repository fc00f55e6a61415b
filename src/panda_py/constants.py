"""Commonly used constants (panda-py's ``panda_py.constants``), read from
:mod:`panda_py.robots`, the one source of truth for robot data.

Each is a fresh float64 array of shape (7,) [rad], as panda-py exposes them.
"""

from __future__ import annotations

import numpy as np

from panda_py.robots.params import FER, FR3, FR3_PRE_5_9, START_POSE

__all__ = [
    "JOINT_LIMITS_LOWER",
    "JOINT_LIMITS_LOWER_FR3",
    "JOINT_LIMITS_LOWER_FR3_5_9",
    "JOINT_LIMITS_UPPER",
    "JOINT_LIMITS_UPPER_FR3",
    "JOINT_LIMITS_UPPER_FR3_5_9",
    "JOINT_POSITION_START",
]

JOINT_POSITION_START = np.array(START_POSE)
"""Common start pose of the robot: high manipulability, far from the joint limits."""

JOINT_LIMITS_LOWER = np.array(FER.joints.q_min)
"""Lower joint position limits of the Franka Emika Robot (FER) [rad]."""

JOINT_LIMITS_UPPER = np.array(FER.joints.q_max)
"""Upper joint position limits of the Franka Emika Robot (FER) [rad]."""

JOINT_LIMITS_LOWER_FR3 = np.array(FR3_PRE_5_9.joints.q_min)
"""Lower joint position limits of the FR3 with a robot system older than 5.9.0 [rad]."""

JOINT_LIMITS_UPPER_FR3 = np.array(FR3_PRE_5_9.joints.q_max)
"""Upper joint position limits of the FR3 with a robot system older than 5.9.0 [rad]."""

JOINT_LIMITS_LOWER_FR3_5_9 = np.array(FR3.joints.q_min)
"""Lower joint position limits of the FR3 with robot system 5.9.0 or later [rad]
(5.9.0 widened them to the data sheet's values)."""

JOINT_LIMITS_UPPER_FR3_5_9 = np.array(FR3.joints.q_max)
"""Upper joint position limits of the FR3 with robot system 5.9.0 or later [rad]."""
