"""Asynchronous joint position control (protocol v10; libfranka 0.15+ / pylibfranka
``AsyncPositionControlHandler``): send joint position targets at any rate; the robot's
own generator moves to the newest one. The wire facts are in :mod:`panda_py.fci.move`.

Same names and results as pylibfranka's class (its example runs unchanged against this
one). Where ours differs: a target that is not 7 finite joint positions within the
robot's joint range is refused with an error message and *not sent*, the control keeps
running (libfranka sends what it is given and aborts on a non-finite one);
``maximum_joint_velocities`` must be within the robot's joint velocity limits.
"""

from __future__ import annotations

import logging
import math
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import TargetStatus
from panda_py.libfranka._active import ActiveControl
from panda_py.libfranka.commands import JointPositions
from panda_py.libfranka.types import ControllerMode, RobotMode
from panda_py.robots.params import RobotSpec

__all__ = ["AsyncPositionControlHandler", "TargetStatus", "check_maximum_velocities"]

log = logging.getLogger("panda_py.libfranka")

_ABORTED = "Control interface is in aborted state."


def check_maximum_velocities(spec: RobotSpec, values: Any) -> tuple[float, ...]:
    """``values`` as 7 velocities [rad/s], each > 0 and at most the robot's ``dq_max``."""
    if values is None:
        raise ValueError("maximum_joint_velocities: required for asynchronous control")
    try:
        v = [float(x) for x in values]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"maximum_joint_velocities: expected 7 numbers, got {values!r}") from exc
    limit = spec.joints.dq_max
    if len(v) != 7 or not all(0.0 < x <= lim for x, lim in zip(v, limit, strict=False)):
        raise ValueError(
            f"maximum_joint_velocities: expected 7 values in (0, dq_max] with dq_max "
            f"{list(limit)} rad/s ({spec.name}), got {v}"
        )
    return tuple(v)


@dataclass
class _Configuration:
    maximum_joint_velocities: Sequence[float] | None = None  # [rad/s]
    goal_tolerance: float | None = None  # [rad]; libfranka's default 1e-3


@dataclass
class _ConfigurationResult:
    handler: AsyncPositionControlHandler | None = None
    error_message: str | None = None


@dataclass
class _JointPositionTarget:
    joint_positions: Sequence[float]  # [rad] (7,)


@dataclass
class _CommandResult:
    motion_uuid: str | None = None
    was_successful: bool = False
    error_message: str | None = None


@dataclass
class _TargetFeedback:
    status: TargetStatus = TargetStatus.IDLE
    error_message: str | None = None


class AsyncPositionControlHandler:
    """Targets in, feedback out; created by :meth:`configure`."""

    Configuration = _Configuration
    ConfigurationResult = _ConfigurationResult
    JointPositionTarget = _JointPositionTarget
    CommandResult = _CommandResult
    TargetFeedback = _TargetFeedback

    def __init__(self, control: ActiveControl, spec: RobotSpec, goal_tolerance: float) -> None:
        self._control: ActiveControl | None = control
        self._q_min = spec.joints.q_min
        self._q_max = spec.joints.q_max
        self._tolerance = goal_tolerance
        self._target: list[float] | None = None
        self._aborted = False
        self._uuid = str(uuid.uuid4())

    @classmethod
    def configure(cls, robot: Any, configuration: _Configuration) -> _ConfigurationResult:
        """Start the asynchronous motion on ``robot`` (a :class:`~panda_py.libfranka.Robot`);
        the result holds the handler or the reason there is none."""
        try:
            tolerance = configuration.goal_tolerance
            tolerance = fci.ASYNC_GOAL_TOLERANCE if tolerance is None else float(tolerance)
            if not tolerance > 0.0 or math.isinf(tolerance):
                raise ValueError(f"goal_tolerance: expected finite > 0 rad, got {tolerance}")
            control = robot.start_async_joint_position_control(
                ControllerMode.kJointImpedance, configuration.maximum_joint_velocities
            )
        except Exception as exc:  # reported as pylibfranka does, in the result
            return _ConfigurationResult(error_message=str(exc))
        return _ConfigurationResult(handler=cls(control, robot._limits.spec, tolerance))

    def _check_target(self, q: Sequence[float]) -> list[float] | str:
        try:
            values = [float(x) for x in q]
        except (TypeError, ValueError):
            return f"joint_positions: expected 7 numbers, got {q!r}"
        if len(values) != 7 or not all(math.isfinite(x) for x in values):
            return f"joint_positions: expected 7 finite values [rad], got {values}"
        lo, hi = self._q_min, self._q_max
        if not all(lo[i] <= values[i] <= hi[i] for i in range(7)):
            return f"joint_positions: {values} outside the joint range {list(lo)}..{list(hi)}"
        return values

    def set_joint_position_target(self, target: _JointPositionTarget) -> _CommandResult:
        """Send the next target (the robot moves to the newest one it received)."""
        control = self._control
        if self._aborted or control is None:
            return _CommandResult(error_message=_ABORTED)
        q = self._check_target(target.joint_positions)
        if isinstance(q, str):
            return _CommandResult(error_message=q)
        try:
            if control._last_data is None:
                control.readOnce()  # a command answers a state
            control.writeOnce(JointPositions(q))
        except Exception as exc:
            self._aborted = True
            return _CommandResult(error_message=str(exc))
        self._target = q
        return _CommandResult(motion_uuid=self._uuid, was_successful=True)

    def get_target_feedback(self, robot_state: Any = None) -> _TargetFeedback:
        """The status of the last target, judged on ``robot_state`` or a fresh state."""
        control = self._control
        if self._aborted or control is None:
            return _TargetFeedback(TargetStatus.ABORTED, _ABORTED)
        if self._target is None:
            return _TargetFeedback(TargetStatus.IDLE)
        try:
            state = robot_state if robot_state is not None else control.readOnce()[0]
        except Exception as exc:
            self._aborted = True
            return _TargetFeedback(TargetStatus.ABORTED, str(exc))
        mode = int(state.robot_mode)
        status = fci.target_status(mode, state.q_d, state.dq_d, self._target, self._tolerance)
        message = {
            RobotMode.kReflex: "Control aborted due to reflex.",
            RobotMode.kUserStopped: "Control aborted due to user stop.",
        }.get(RobotMode(mode))
        return _TargetFeedback(status, message)

    def stop_control(self) -> None:
        """Finish the motion: the robot comes to rest; the handler is aborted afterwards."""
        control, self._control = self._control, None
        self._aborted = True
        if control is None or control.finished:
            return
        finish = JointPositions(np.zeros(7))
        finish.motion_finished = True
        try:
            if control._last_data is None:
                control.readOnce()
            control.writeOnce(finish)
        except Exception as exc:  # as libfranka: stopping logs, never raises
            log.error("stopping asynchronous position control: %s", exc)
            control.cancel()
