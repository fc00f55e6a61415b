"""What a move is and how it ended, as both processes see them: the user's process plans
a move (:class:`JointPlan`, :class:`PosePlan`: the trajectory sampled at the robot's 1 ms
period and how to track and judge it) and the control process answers how it ended
(:class:`MoveResult`). The laws that track the plans are in :mod:`.moves`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from panda_py.motion.online import OnlineLimits

__all__ = ["JointPlan", "MoveResult", "PosePlan", "Progress", "rotation_angle"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Progress:
    """How far a move is, for its ``until`` condition: ``elapsed`` [s] since it started,
    ``distance`` to its goal ([rad], the largest joint's, for a joint move; [m] for a
    Cartesian one)."""

    elapsed: float
    distance: float


@dataclass
class MoveResult:
    """How a move ended: ``success`` as panda-py judges it and why not; for a move ended
    by its ``until`` condition, which one and when."""

    success: bool
    reason: str  # "" on success
    joint_error: float = math.nan  # [rad] largest joint distance to the goal
    position_error: float = math.nan  # [m]
    orientation_error: float = math.nan  # [rad]
    duration: float = 0.0  # [s] the trajectory's
    elapsed: float = 0.0  # [s] until the move ended
    error: BaseException | None = None  # what aborted it
    condition: str = ""  # the until condition that ended it ("" if none did)
    condition_time: float = math.nan  # [s] into the move when it held
    cancelled: bool = False  # cancelled, or replaced by another move (reason says which)
    # time.monotonic() in the control process when it ended (or another took over): the
    # same clock as the user's process on one machine
    end_time: float = math.nan


@dataclass(frozen=True)
class JointPlan:
    """A joint move as the user's process planned it: the trajectory sampled at the
    robot's 1 ms period and how to track and judge it (``Panda.move_to_joint_position``).

    ``limits`` bound the online generator (the joints' velocity, acceleration and jerk,
    scaled by the speed factor) that leads in when this move replaces a running one;
    ``stop_limits`` (the same at no less than half the robot's) when it brings the arm to
    rest (cancelled, or its ``until`` condition held: a stop must not take as long as a
    slow move's own acceleration would); a lead-in joins the plan at sample ``join`` (the
    goal when it is the last)."""

    q: FloatArray  # (N, 7) [rad]
    dq: FloatArray  # (N, 7) [rad/s]
    ddq: FloatArray  # (N, 7) [rad/s^2]
    stiffness: FloatArray  # (7,) [Nm/rad]
    damping: FloatArray  # (7,) [Nm s/rad]
    dq_threshold: float  # [rad/s] at rest below this
    success_threshold: float  # [rad] success within this of the goal
    limits: OnlineLimits
    join: int = -1
    stop_limits: OnlineLimits | None = None  # None: ``limits``


@dataclass(frozen=True)
class PosePlan:
    """A Cartesian move as the user's process planned it: positions, orientations, twists
    and their derivatives sampled at 1 ms, and how to track and judge it
    (``Panda.move_to_pose``); ``limits`` (translation x, y, z, rotation x, y, z) and
    ``join``, ``stop_limits`` as :class:`JointPlan`'s."""

    position: FloatArray  # (N, 3) [m]
    orientation: FloatArray  # (N, 4) unit quaternions (x, y, z, w)
    twist: FloatArray  # (N, 6) [m/s, rad/s]
    accel: FloatArray  # (N, 6) [m/s^2, rad/s^2]
    q_nullspace: FloatArray  # (7,) [rad] the nullspace's rest configuration
    impedance: FloatArray  # (6, 6) [N/m, Nm/rad]
    damping_ratio: float
    nullspace_stiffness: float  # [Nm/rad]
    dq_threshold: float  # [rad/s]
    success_threshold: float  # [m]
    orientation_threshold: float  # [rad]
    limits: OnlineLimits
    join: int = -1
    stop_limits: OnlineLimits | None = None


def rotation_angle(q0: FloatArray, q1: FloatArray) -> float:
    """Angle of the rotation between two unit quaternions [rad] (q and -q are equal)."""
    d = min(1.0, abs(float(q0 @ q1)) / math.sqrt(float(q0 @ q0) * float(q1 @ q1)))
    return 2.0 * math.acos(d)
