"""The Move request as one value, and protocol v10's asynchronous motion generator.

Sources: libfranka 0.21.2 ``common/include/research_interface/robot/service_types.h``
(``Move::Request``), ``src/robot.cpp`` (``startAsyncControl``),
``src/async_control/async_position_control_handler.cpp``; pylibfranka 0.21.3
``examples/async_position_control.py``.

What v10 adds on the wire (and only that): the Move request ends in
``use_async_motion_generator`` (bool) and ``maximum_velocity`` (f64[7], rad/s; zeros when
the flag is off; libfranka refuses an async Move without them: "Maximum velocities must be
provided for variable rate"). No new enum value, RobotCommand or RobotState field:

* libfranka's ``AsyncPositionControlHandler`` sends Move(ctrl=JointImpedance,
  mg=JointPosition, async=true, maximum_velocity) and then, at whatever rate the user
  calls ``setJointPositionTarget`` (the example: 50 Hz), ordinary RobotCommands whose
  ``q_c`` is the *target*; between them it sends nothing. The robot moves to the newest
  target with its own limited trajectory and reports that trajectory in ``q_d``/``dq_d``;
* ``stopControl`` sends ``q_c`` = zeros with ``motion_generation_finished``, repeated for
  every state until the state shows the generator idle, then awaits the Move's final
  response: the zeros are not a target;
* the handler's :class:`TargetStatus` is computed by the *client* from the state
  (:func:`target_status`): Reflex/UserStopped -> aborted; Move/Idle -> reached when
  ``|q_d - target| < goal_tolerance`` (default 1e-3 rad) and ``|dq_d| < 0.01`` rad/s
  (Euclidean norms over the 7 joints), otherwise executing.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py.fci.enums import MoveControllerMode, MoveMotionGeneratorMode, RobotMode
from panda_py.fci.robot import DEFAULT_DEVIATION, Dialect

__all__ = [
    "ASYNC_GOAL_TOLERANCE",
    "ASYNC_REACHED_VELOCITY",
    "MoveRequest",
    "TargetStatus",
    "target_status",
]

ASYNC_GOAL_TOLERANCE = 0.001
"""libfranka's default goal tolerance of asynchronous position control [rad]
(``kDefaultGoalTolerance``, async_position_control_handler.cpp)."""
ASYNC_REACHED_VELOCITY = 0.01
"""The joint velocity below which libfranka's asynchronous position control counts a target as
reached [rad/s] (``kTargetReachedVelocityThreshold``)."""


class TargetStatus(enum.IntEnum):
    """libfranka ``franka::TargetStatus`` (client-side, never on the wire)."""

    IDLE = 0
    EXECUTING = 1
    TARGET_REACHED = 2
    ABORTED = 3


Deviation = tuple[float, float, float]


@dataclass(frozen=True)
class MoveRequest:
    """A Move request; ``maximum_velocity`` is set exactly when the motion is asynchronous."""

    controller_mode: MoveControllerMode
    motion_generator_mode: MoveMotionGeneratorMode
    maximum_path_deviation: Deviation = DEFAULT_DEVIATION
    maximum_goal_pose_deviation: Deviation = DEFAULT_DEVIATION
    maximum_velocity: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.maximum_velocity is not None and len(self.maximum_velocity) != 7:
            raise ValueError(
                "maximum_velocity: expected 7 joint velocities [rad/s], "
                f"got {len(self.maximum_velocity)}"
            )

    @property
    def is_async(self) -> bool:
        """Whether this Move starts the robot's asynchronous motion generator (v10; it carries a
        maximum velocity)."""
        return self.maximum_velocity is not None

    def fields(self, d: Dialect) -> dict[str, Any]:
        """The request's payload fields in ``d``'s layout (for ``encode_request``)."""
        out: dict[str, Any] = dict(
            controller_mode=int(self.controller_mode),
            motion_generator_mode=int(self.motion_generator_mode),
            maximum_path_deviation=self.maximum_path_deviation,
            maximum_goal_pose_deviation=self.maximum_goal_pose_deviation,
        )
        if d.has_async_motion_generator:
            out["use_async_motion_generator"] = self.is_async
            out["maximum_velocity"] = self.maximum_velocity or (0.0,) * 7
        elif self.is_async:
            raise ValueError(
                f"an asynchronous Move needs robot protocol v10 or later, got v{d.version}"
            )
        return out

    @classmethod
    def from_fields(cls, fields: dict[str, Any]) -> MoveRequest:
        """The request of decoded payload ``fields`` (any version).

        Raises ValueError for an unknown mode (the robot answers kInvalidArgumentRejected).
        """
        velocity = None
        if fields.get("use_async_motion_generator", False):
            velocity = tuple(float(v) for v in fields["maximum_velocity"])
        return cls(
            MoveControllerMode(int(fields["controller_mode"])),
            MoveMotionGeneratorMode(int(fields["motion_generator_mode"])),
            _deviation(fields["maximum_path_deviation"]),
            _deviation(fields["maximum_goal_pose_deviation"]),
            velocity,
        )


def _deviation(values: Sequence[float]) -> Deviation:
    a, b, c = (float(v) for v in values)
    return (a, b, c)


def target_status(
    robot_mode: int,
    q_d: Sequence[float],
    dq_d: Sequence[float],
    target: Sequence[float] | None,
    goal_tolerance: float = ASYNC_GOAL_TOLERANCE,
) -> TargetStatus:
    """libfranka's ``getTargetFeedback`` verdict on one state for the last ``target``.

    Modes other than Move/Idle/Reflex/UserStopped leave libfranka's status at its default
    (IDLE).
    """
    mode = RobotMode(int(robot_mode))
    if mode in (RobotMode.REFLEX, RobotMode.USER_STOPPED):
        return TargetStatus.ABORTED
    if target is None or mode not in (RobotMode.MOVE, RobotMode.IDLE):
        return TargetStatus.IDLE
    error = float(np.linalg.norm(np.asarray(q_d, dtype=float) - np.asarray(target, dtype=float)))
    speed = float(np.linalg.norm(np.asarray(dq_d, dtype=float)))
    if error < goal_tolerance and speed < ASYNC_REACHED_VELOCITY:
        return TargetStatus.TARGET_REACHED
    return TargetStatus.EXECUTING
