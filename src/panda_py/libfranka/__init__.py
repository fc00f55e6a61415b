"""A pure-Python libfranka: the Franka FCI client with panda-py's (and pylibfranka's)
Python API, speaking every robot protocol version 3-10 from one install::

    from panda_py.libfranka import Robot, Torques, motion_finished
    robot = Robot("172.16.0.2")              # negotiates the protocol version
    robot.read_once().q
    model = robot.load_model()               # computed locally, no download

See :class:`Robot`, :class:`Gripper`, :class:`Model` and :class:`RobotState`.
"""

from __future__ import annotations

from panda_py.libfranka._active import ActiveControl, TorqueIO
from panda_py.libfranka.async_control import AsyncPositionControlHandler, TargetStatus
from panda_py.libfranka.commands import (
    CartesianPose,
    CartesianVelocities,
    JointPositions,
    JointVelocities,
    Torques,
    is_homogeneous_transformation,
    is_valid_elbow,
    motion_finished,
)
from panda_py.libfranka.errors import (
    CommandException,
    ControlException,
    FrankaException,
    IncompatibleVersionException,
    InvalidOperationException,
    ModelException,
    NetworkException,
    ProtocolException,
    RealtimeException,
)
from panda_py.libfranka.gripper import CommandFuture, Gripper
from panda_py.libfranka.limits import (
    RateLimits,
    cartesian_lowpass_filter,
    limit_rate,
    limit_rate_cartesian_pose,
    limit_rate_cartesian_velocity,
    limit_rate_joint_positions,
    limit_rate_joint_velocities,
    lowpass_filter,
)
from panda_py.libfranka.model import Model
from panda_py.libfranka.realtime import (
    has_realtime_kernel,
    set_current_thread_to_highest_priority,
)
from panda_py.libfranka.robot import Robot
from panda_py.libfranka.state import GripperState, RobotState
from panda_py.libfranka.types import (
    ControllerMode,
    Duration,
    Errors,
    Frame,
    RealtimeConfig,
    RobotMode,
)
from panda_py.libfranka.vacuum import (
    VacuumGripper,
    VacuumGripperDeviceStatus,
    VacuumGripperProductionSetupProfile,
    VacuumGripperState,
)

#: panda-py 1.1.1's name of the torque-rate limit [Nm/s] (libfranka kMaxTorqueRate).
MAX_TORQUE_RATE = RateLimits.for_robot("fer").max_torque_rate.tolist()

__all__ = [
    "MAX_TORQUE_RATE",
    "ActiveControl",
    "AsyncPositionControlHandler",
    "CartesianPose",
    "CartesianVelocities",
    "CommandException",
    "CommandFuture",
    "ControlException",
    "ControllerMode",
    "Duration",
    "Errors",
    "Frame",
    "FrankaException",
    "Gripper",
    "GripperState",
    "IncompatibleVersionException",
    "InvalidOperationException",
    "JointPositions",
    "JointVelocities",
    "Model",
    "ModelException",
    "NetworkException",
    "ProtocolException",
    "RateLimits",
    "RealtimeConfig",
    "RealtimeException",
    "Robot",
    "RobotMode",
    "RobotState",
    "TargetStatus",
    "TorqueIO",
    "Torques",
    "VacuumGripper",
    "VacuumGripperDeviceStatus",
    "VacuumGripperProductionSetupProfile",
    "VacuumGripperState",
    "cartesian_lowpass_filter",
    "has_realtime_kernel",
    "is_homogeneous_transformation",
    "is_valid_elbow",
    "limit_rate",
    "limit_rate_cartesian_pose",
    "limit_rate_cartesian_velocity",
    "limit_rate_joint_positions",
    "limit_rate_joint_velocities",
    "lowpass_filter",
    "motion_finished",
    "set_current_thread_to_highest_priority",
]
