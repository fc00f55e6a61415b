"""Robot data (one source of truth) and the model generators built on it."""

from panda_py.robots.params import (
    FER,
    FR3,
    FR3_PRE_5_9,
    FRANKA_HAND,
    GRAVITY,
    ROBOTS,
    START_POSE,
    CartesianLimits,
    HandSpec,
    Inertial,
    JointLimits,
    RobotKind,
    RobotSpec,
    get_robot,
    position_based_velocity_limits,
    robot_for_protocol,
)

__all__ = [
    "FER",
    "FR3",
    "FR3_PRE_5_9",
    "FRANKA_HAND",
    "GRAVITY",
    "ROBOTS",
    "START_POSE",
    "CartesianLimits",
    "HandSpec",
    "Inertial",
    "JointLimits",
    "RobotKind",
    "RobotSpec",
    "get_robot",
    "position_based_velocity_limits",
    "robot_for_protocol",
]
