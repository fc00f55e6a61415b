"""Time-optimal joint-space trajectories through waypoints (panda-py's JointTrajectory)."""

from __future__ import annotations

import time as _time
from typing import NamedTuple

import numpy as np

from panda_py.motion import _checks
from panda_py.motion._path import Array, build_path, check_deadline, merge_duplicates
from panda_py.motion._profile import BoxBounds, Profile
from panda_py.robots.params import RobotKind, RobotSpec, get_robot

N_JOINTS = 7


class JointSamples(NamedTuple):
    """Joint states at many times, each of shape ``times.shape + (7,)``."""

    positions: Array  # [rad]
    velocities: Array  # [rad/s]
    accelerations: Array  # [rad/s^2]


class JointTrajectory:
    """The time-optimal joint motion through ``waypoints`` under the robot's joint velocity
    and acceleration limits, each scaled by ``speed_factor`` (as panda-py does).

    The path is straight between waypoints; with ``max_deviation > 0`` [rad] its corners
    are rounded by circular blends passing within that distance of the waypoint, otherwise
    the motion stops exactly at every waypoint. The velocity profile is time-optimal along
    the path (Kunz & Stilman, RSS 2012; closed form, see :mod:`panda_py.motion._profile`).
    It starts and ends at rest; before ``t = 0`` and from ``get_duration()`` on it rests on
    the first and last waypoint.

    :param waypoints: joint positions [rad], a sequence of 7-vectors (or (7, 1)) or an
        (N, 7) array; N >= 1, every one within the robot's joint limits.
    :param speed_factor: fraction of the joint velocity and acceleration limits, in (0, 1].
    :param max_deviation: how far blends may cut corners [rad], >= 0.
    :param timeout: planning time budget [s]; :class:`~panda_py.motion.PlanningTimeoutError`
        past it.
    :param robot: whose limits apply: ``"fer"`` (default, as panda-py), ``"fr3"``,
        ``"fr3-pre-5.9"`` or a :class:`~panda_py.robots.params.RobotSpec`.
    """

    def __init__(
        self,
        waypoints: object,
        speed_factor: float = 0.2,
        max_deviation: float = 0.0,
        timeout: float = 30.0,
        *,
        robot: str | RobotKind | RobotSpec = "fer",
    ) -> None:
        deadline_timeout = _checks.timeout(timeout)
        deadline = _time.perf_counter() + deadline_timeout
        self.speed_factor = _checks.speed_factor(speed_factor)
        self.max_deviation = _checks.max_deviation(max_deviation)
        self.robot = get_robot(robot)
        points = _joint_waypoints(waypoints, self.robot)
        limits = self.robot.joints
        #: the bounds the trajectory keeps [rad/s], [rad/s^2]
        self.max_velocity = self.speed_factor * np.array(limits.dq_max)
        self.max_acceleration = self.speed_factor * np.array(limits.ddq_max)
        self.waypoints = points
        check_deadline(deadline, deadline_timeout)
        kept = points[merge_duplicates(points)]
        path = build_path(kept, self.max_deviation, deadline, deadline_timeout)
        self._profile = Profile(
            path,
            BoxBounds(self.max_velocity, self.max_acceleration),
            points[0].copy(),
            points[-1].copy(),
            deadline,
            deadline_timeout,
        )
        self._duration = self._profile.duration

    def get_duration(self) -> float:
        """Duration of the motion [s]."""
        return self._duration

    def get_joint_positions(self, time: float) -> Array:
        """Joint positions at ``time`` [s], shape (7,) [rad]."""
        return self._profile.position(time)

    def get_joint_velocities(self, time: float) -> Array:
        """Joint velocities at ``time`` [s], shape (7,) [rad/s]."""
        return self._profile.velocity(time)

    def get_joint_accelerations(self, time: float) -> Array:
        """Joint accelerations at ``time`` [s], shape (7,) [rad/s^2] (right-continuous)."""
        return self._profile.acceleration(time)

    def sample(self, times: object) -> JointSamples:
        """Positions, velocities and accelerations at all of ``times`` [s] at once (array of
        any shape; results have shape ``times.shape + (7,)``). Beyond panda-py's API."""
        return JointSamples(*self._profile.evaluate(times)[:3])

    def __repr__(self) -> str:
        return (
            f"JointTrajectory({len(self.waypoints)} waypoints, robot={self.robot.name!r}, "
            f"speed_factor={self.speed_factor}, duration={self._duration:.4f} s)"
        )


def _joint_waypoints(waypoints: object, robot: RobotSpec) -> Array:
    """Validate and stack the waypoints into an (N, 7) float array."""
    try:
        arr = np.array(waypoints, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            "waypoints: expected a sequence of joint positions of shape (7,) [rad], "
            f"got {type(waypoints).__name__} that is not a numeric array ({exc})"
        ) from exc
    if arr.size == 0:
        raise ValueError("waypoints: expected at least one waypoint, got none")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]  # panda-py style (7, 1) column vectors
    if arr.ndim != 2 or arr.shape[1] != N_JOINTS:
        raise ValueError(
            f"waypoints: expected shape (N, 7) (a sequence of 7-vectors) [rad], got shape "
            f"{arr.shape}"
        )
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"waypoints[{i}][{j}]: expected a finite number [rad], got {arr[i, j]}")
    q_min = np.array(robot.joints.q_min)
    q_max = np.array(robot.joints.q_max)
    out = (arr < q_min) | (arr > q_max)
    if out.any():
        i, j = np.argwhere(out)[0]
        raise ValueError(
            f"waypoints[{i}][{j}]: joint {j + 1} at {arr[i, j]:.6g} rad is outside the "
            f"{robot.name} joint limits [{q_min[j]}, {q_max[j]}] rad"
        )
    return arr
