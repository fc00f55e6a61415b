"""The robot's own joint moves, which no FCI client commands: the Desk's "move to pack
pose". A quintic (minimum-jerk) path in joint space from where the arm is to the goal, at
most ``SPEED_SHARE`` of each joint's velocity limit, tracked by the robot's joint
impedance controller as it holds the arm between motions."""

from __future__ import annotations

import numpy as np

from panda_py.robots.params import RobotSpec

__all__ = ["SPEED_SHARE", "JointDrive"]

# A Desk-driven move's peak joint speed, as a share of the joints' limits (Desk's own
# moves are deliberate; this one takes 2-3 s from the start pose to the pack pose).
SPEED_SHARE = 0.5
MIN_DURATION = 0.5  # [s] even for a short move
_PEAK = 1.875  # peak speed of the quintic over its mean speed (15/8)


class JointDrive:
    """A quintic path from ``q_start`` to ``q_goal`` [rad], advanced one tick at a time."""

    def __init__(self, spec: RobotSpec, q_start: np.ndarray, q_goal: np.ndarray) -> None:
        self.q0 = np.array(q_start, dtype=float)
        self.goal = np.array(q_goal, dtype=float)
        self.delta = self.goal - self.q0
        vmax = SPEED_SHARE * np.asarray(spec.joints.dq_max, dtype=float)
        self.duration = max(MIN_DURATION, float(np.max(_PEAK * np.abs(self.delta) / vmax)))
        self.t = 0.0

    @property
    def finished(self) -> bool:
        return self.t >= self.duration

    def advance(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Move on by ``dt`` [s]: the reference (position [rad], velocity [rad/s],
        acceleration [rad/s^2]) there."""
        self.t = min(self.t + dt, self.duration)
        T = self.duration
        s = self.t / T
        pos = s * s * s * (10.0 + s * (-15.0 + 6.0 * s))
        vel = s * s * (30.0 + s * (-60.0 + 30.0 * s)) / T
        acc = s * (60.0 + s * (-180.0 + 120.0 * s)) / (T * T)
        return self.q0 + pos * self.delta, vel * self.delta, acc * self.delta
