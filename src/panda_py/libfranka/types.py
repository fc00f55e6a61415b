"""libfranka's value types: modes, :class:`Duration` and :class:`Errors` (the commands are
in :mod:`.commands`).

Enum members keep libfranka's ``k`` names (``RobotMode.kIdle``) so that code written for
panda-py 1.1.1 or pylibfranka runs unchanged.
"""

from __future__ import annotations

import datetime
import enum
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.fci import ERROR_NAMES, ERROR_STRINGS

__all__ = [
    "ControllerMode",
    "Duration",
    "Errors",
    "Frame",
    "RealtimeConfig",
    "RobotMode",
]

FloatArray = NDArray[np.float64]


class RobotMode(enum.IntEnum):
    """``RobotState.robot_mode`` (same numbers as on the wire)."""

    kOther = 0
    kIdle = 1
    kMove = 2
    kGuiding = 3
    kReflex = 4
    kUserStopped = 5
    kAutomaticErrorRecovery = 6


class ControllerMode(enum.IntEnum):
    """The robot's internal controller that tracks a motion generator's commands."""

    kJointImpedance = 0
    kCartesianImpedance = 1


class RealtimeConfig(enum.IntEnum):
    """Whether a control loop must run with realtime (``SCHED_FIFO``) priority."""

    kEnforce = 0
    kIgnore = 1

    @classmethod
    def parse(cls, value: Any) -> RealtimeConfig:
        """``value`` as a RealtimeConfig, or a ValueError naming the argument."""
        try:
            return cls(value)
        except ValueError:
            raise ValueError(
                f"realtime_config: expected RealtimeConfig.kEnforce or kIgnore, got {value!r}"
            ) from None


class Frame(enum.IntEnum):
    """Frames of :class:`~panda_py.libfranka.Model` (libfranka's ``franka::Frame``)."""

    kJoint1 = 0
    kJoint2 = 1
    kJoint3 = 2
    kJoint4 = 3
    kJoint5 = 4
    kJoint6 = 5
    kJoint7 = 6
    kFlange = 7
    kEndEffector = 8
    kStiffness = 9


class Duration:
    """A time span in whole milliseconds (libfranka's ``franka::Duration``)."""

    __slots__ = ("_ms",)

    def __init__(self, milliseconds: int | datetime.timedelta | Duration = 0) -> None:
        if type(milliseconds) is int:  # the control loop's case, first
            self._ms: int = milliseconds
        elif isinstance(milliseconds, Duration):
            self._ms = milliseconds._ms
        elif isinstance(milliseconds, datetime.timedelta):
            self._ms = round(milliseconds.total_seconds() * 1000.0)
        elif isinstance(milliseconds, (int, np.integer)) and not isinstance(milliseconds, bool):
            self._ms = int(milliseconds)
        else:
            raise ValueError(
                f"milliseconds: expected an int [ms] or a timedelta, got {milliseconds!r}"
            )

    def to_sec(self) -> float:
        """The span [s]."""
        return self._ms / 1000.0

    def to_msec(self) -> int:
        """The span [ms]."""
        return self._ms

    def __int__(self) -> int:
        return self._ms

    def __float__(self) -> float:
        return self._ms / 1000.0

    def __add__(self, other: Duration) -> Duration:
        return Duration(self._ms + Duration(other)._ms)

    def __sub__(self, other: Duration) -> Duration:
        return Duration(self._ms - Duration(other)._ms)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Duration):
            return self._ms == other._ms
        return NotImplemented

    def __lt__(self, other: Duration) -> bool:
        return self._ms < other._ms

    def __le__(self, other: Duration) -> bool:
        return self._ms <= other._ms

    def __hash__(self) -> int:
        return hash(self._ms)

    def __repr__(self) -> str:
        return f"Duration({self._ms})"


def _flag(index: int) -> Any:
    return property(lambda self: self._flags[index], doc=f"Error flag {ERROR_NAMES[index]}.")


class Errors:
    """The 41 error flags of the robot (``current_errors``, ``last_motion_errors``).

    ``bool(errors)`` is True if any flag is set; ``str(errors)`` is libfranka's
    ``["name", ...]`` list of the set flags; iterating yields the set flags' names.
    """

    __slots__ = ("_flags",)

    def __init__(self, flags: Sequence[Any] | NDArray[Any] = ()) -> None:
        values = [bool(v) for v in np.asarray(flags).reshape(-1).tolist()]
        if len(values) > len(ERROR_NAMES):
            raise ValueError(f"flags: expected at most {len(ERROR_NAMES)} flags, got {len(values)}")
        # protocol v3/v4 carry 37 flags; the 4 appended in v5 are then False
        self._flags: tuple[bool, ...] = tuple(values + [False] * (len(ERROR_NAMES) - len(values)))

    def __bool__(self) -> bool:
        return any(self._flags)

    def __iter__(self) -> Iterator[str]:
        return iter(self.active)

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the set flags (attribute names), in wire order."""
        return tuple(n for n, v in zip(ERROR_NAMES, self._flags, strict=True) if v)

    def __str__(self) -> str:
        names = [s for s, v in zip(ERROR_STRINGS, self._flags, strict=True) if v]
        return "[" + ", ".join(f'"{n}"' for n in names) + "]"

    def __repr__(self) -> str:
        return f"Errors({list(self.active)!r})"

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Errors):
            return self._flags == other._flags
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self._flags)

    def to_array(self) -> NDArray[np.bool_]:
        """The 41 flags as a bool array in wire order."""
        return np.array(self._flags, dtype=bool)

    joint_position_limits_violation = _flag(0)
    cartesian_position_limits_violation = _flag(1)
    self_collision_avoidance_violation = _flag(2)
    joint_velocity_violation = _flag(3)
    cartesian_velocity_violation = _flag(4)
    force_control_safety_violation = _flag(5)
    joint_reflex = _flag(6)
    cartesian_reflex = _flag(7)
    max_goal_pose_deviation_violation = _flag(8)
    max_path_pose_deviation_violation = _flag(9)
    cartesian_velocity_profile_safety_violation = _flag(10)
    joint_position_motion_generator_start_pose_invalid = _flag(11)
    joint_motion_generator_position_limits_violation = _flag(12)
    joint_motion_generator_velocity_limits_violation = _flag(13)
    joint_motion_generator_velocity_discontinuity = _flag(14)
    joint_motion_generator_acceleration_discontinuity = _flag(15)
    cartesian_position_motion_generator_start_pose_invalid = _flag(16)
    cartesian_motion_generator_elbow_limit_violation = _flag(17)
    cartesian_motion_generator_velocity_limits_violation = _flag(18)
    cartesian_motion_generator_velocity_discontinuity = _flag(19)
    cartesian_motion_generator_acceleration_discontinuity = _flag(20)
    cartesian_motion_generator_elbow_sign_inconsistent = _flag(21)
    cartesian_motion_generator_start_elbow_invalid = _flag(22)
    force_controller_desired_force_tolerance_violation = _flag(23)
    start_elbow_sign_inconsistent = _flag(24)
    communication_constraints_violation = _flag(25)
    power_limit_violation = _flag(26)
    cartesian_motion_generator_joint_position_limits_violation = _flag(27)
    cartesian_motion_generator_joint_velocity_limits_violation = _flag(28)
    cartesian_motion_generator_joint_velocity_discontinuity = _flag(29)
    cartesian_motion_generator_joint_acceleration_discontinuity = _flag(30)
    cartesian_position_motion_generator_invalid_frame = _flag(31)
    controller_torque_discontinuity = _flag(32)
    joint_p2p_insufficient_torque_for_planning = _flag(33)
    tau_J_range_violation = _flag(34)
    tau_j_range_violation = _flag(34)  # panda-py 1.1.1's spelling
    instability_detected = _flag(35)
    joint_move_in_wrong_direction = _flag(36)
    cartesian_spline_motion_generator_violation = _flag(37)
    joint_via_motion_generator_planning_joint_limit_violation = _flag(38)
    base_acceleration_initialization_timeout = _flag(39)
    base_acceleration_invalid_reading = _flag(40)
