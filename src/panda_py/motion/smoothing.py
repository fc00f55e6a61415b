"""Smoothing a sampled trajectory so that a torque-controlled arm can follow it.

The time-optimal profiles (:class:`~panda_py.motion.JointTrajectory`,
:class:`~panda_py.motion.CartesianTrajectory`, as panda-py's) switch between full
acceleration and none from one sample to the next. A reference tracked through impedance
with an inertial feed-forward turns that step into a torque step, which the torque rate
limit (the robot's 1000 Nm/s; the control loop's 386 Nm/s, panda_py.panda.plan_torques)
spreads over several milliseconds: the arm overshoots each switch, and the last one (the
arrival) leaves it a few millimetres from the goal, held there by the joints' dry
friction. (A Cartesian plan whose ramps would still ask for torques faster than the loop
delivers is smoothed wider: :func:`panda_py.panda.plan_torques.smoothing_width`.)

A moving average of width ``T`` (one box filter over every sampled quantity, position,
velocity and acceleration alike: the filter commutes with the derivatives) turns each
step into a ramp of ``T``: the jerk is bounded by ``2 a_max / T`` and the trajectory lasts
``T`` longer, at rest at both ends as before. A moving average of samples within the
limits (of velocity, acceleration, their norms) stays within them, and the path moves by
at most about ``a_max T^2 / 24`` from the original (0.07 mm at 1.8 m/s^2 and 30 ms).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["SMOOTHING_TIME", "box_filter", "smooth_quaternions"]

FloatArray = NDArray[np.float64]

SMOOTHING_TIME = 0.03  # [s] the moving average's width a move's samples get


def box_filter(samples: FloatArray, width: int) -> FloatArray:
    """The moving average of ``width`` samples along the first axis of ``samples`` (N,
    ...), padded with the first and the last sample: N + width - 1 samples, from the
    first sample to the last."""
    x = np.asarray(samples, dtype=np.float64)
    if isinstance(width, bool) or not isinstance(width, (int, np.integer)) or width < 1:
        raise ValueError(f"width: expected a whole number of samples >= 1, got {width!r}")
    if width == 1 or len(x) == 0:
        return x.copy()
    pad = np.concatenate([np.repeat(x[:1], width - 1, axis=0), x,
                          np.repeat(x[-1:], width - 1, axis=0)])  # fmt: skip
    c = np.cumsum(pad, axis=0)
    c = np.concatenate([np.zeros((1, *x.shape[1:])), c])
    return (c[width:] - c[:-width]) / width


def smooth_quaternions(quats: FloatArray, width: int) -> FloatArray:
    """:func:`box_filter` for unit quaternions (N, 4): each made the same sign as the one
    before, averaged and normalized (within one window a move turns by a few hundredths of
    a radian, where the normalized mean is the rotations' mean to second order)."""
    q = np.array(quats, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4 or not np.isfinite(q).all():
        raise ValueError(f"quats: expected finite quaternions of shape (N, 4), got shape {q.shape}")
    if len(q) == 0:
        return q
    flips = np.cumsum(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0.0) % 2
    q[1:][flips == 1] *= -1.0
    out = box_filter(q, width)
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out
