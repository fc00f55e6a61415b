"""Client-side rate limiting and low-pass filtering, as libfranka applies them to commands.

The algorithms follow libfranka's ``rate_limiting.cpp`` and ``lowpass_filter.cpp``:

* low-pass: first order, ``y = y_last + gain (x - y_last)`` with
  ``gain = dt / (dt + 1 / (2 pi f_cutoff))``; poses interpolate the orientation along the
  shortest arc (a slerp) with the same gain;
* joint velocities: differentiate to jerk, clip the jerk, integrate to acceleration, clip
  the acceleration to a bound that shrinks near the velocity limits
  (``max_jerk / max_acc * (v_limit - v_last)``), integrate to velocity; joint positions
  run the same on their finite-difference velocity;
* Cartesian twists: the same on the norm of the translational and rotational 3-vectors;
  poses on their finite-difference twist (rotational limits scaled by 0.99), then
  integrated back onto the last commanded pose;
* torques: the rate ``|d tau / dt|`` is clipped.

Limits come from :mod:`panda_py.robots.params` minus libfranka's margins (``kLimitEps``
and, for the FER as in libfranka 0.9, three lost packets of acceleration); the FR3's joint
velocity limits depend on the position (``position_based_velocity_limits``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import fci
from panda_py.robots.params import RobotKind, RobotSpec, get_robot

__all__ = [
    "DELTA_T",
    "LIMIT_EPS",
    "MAX_CUTOFF_FREQUENCY",
    "RateLimits",
    "cartesian_lowpass_filter",
    "limit_rate",
    "limit_rate_cartesian_pose",
    "limit_rate_cartesian_velocity",
    "limit_rate_joint_positions",
    "limit_rate_joint_velocities",
    "lowpass_filter",
]

FloatArray = NDArray[np.float64]

DELTA_T = fci.PERIOD  # [s] control period (libfranka kDeltaT)
LIMIT_EPS = 1e-3  # margin below each published limit (libfranka kLimitEps)
NORM_EPS = float(np.finfo(float).eps)  # below this a Cartesian jerk/acc counts as zero
MAX_CUTOFF_FREQUENCY = 1000.0  # [Hz] at and above this the low-pass filter is off
# Rotational limits of the Cartesian pose interface are scaled by this
# (libfranka kFactorCartesianRotationPoseInterface).
POSE_ROTATION_FACTOR = 0.99
# Lost packets the velocity limits leave room for: 3 in libfranka 0.9 (FER), 0 for the FR3
# (libfranka >= 0.10, kTolNumberPacketsLost).
_TOL_PACKETS_FER = 3.0
_TOL_PACKETS_FR3 = 0.0


@dataclass(frozen=True, eq=False)
class RateLimits:
    """The limits the client-side rate limiter enforces for one robot."""

    spec: RobotSpec
    position_based: bool  # joint velocity limits depend on q (FR3)
    max_torque_rate: FloatArray  # [Nm/s]
    max_joint_jerk: FloatArray  # [rad/s^3]
    max_joint_acceleration: FloatArray  # [rad/s^2]
    max_joint_velocity: FloatArray  # [rad/s] (the cap of the position-based limits)
    translation: tuple[float, float, float]  # velocity [m/s], acceleration, jerk
    rotation: tuple[float, float, float]  # velocity [rad/s], acceleration, jerk
    elbow: tuple[float, float, float]  # velocity [rad/s], acceleration, jerk
    _tolerance: FloatArray
    _q_min: FloatArray
    _q_max: FloatArray
    _offset: FloatArray
    _decel2: FloatArray

    @classmethod
    def for_robot(cls, robot: str | RobotKind | RobotSpec) -> RateLimits:
        """Limits of ``robot`` ("fer"/"panda", "fr3", "fr3-pre-5.9" or a RobotSpec)."""
        spec = get_robot(robot)
        fer = spec.kind is RobotKind.FER
        tol = _TOL_PACKETS_FER if fer else _TOL_PACKETS_FR3
        j, c = spec.joints, spec.cartesian
        acc = np.asarray(j.ddq_max) - LIMIT_EPS
        tolerance = LIMIT_EPS + tol * DELTA_T * acc

        def triple(v: float, a: float, jerk: float) -> tuple[float, float, float]:
            a_lim = a - LIMIT_EPS
            return (v - LIMIT_EPS - tol * DELTA_T * a_lim, a_lim, jerk - LIMIT_EPS)

        return cls(
            spec=spec,
            position_based=not fer,
            max_torque_rate=np.asarray(j.dtau_max) - LIMIT_EPS,
            max_joint_jerk=np.asarray(j.dddq_max) - LIMIT_EPS,
            max_joint_acceleration=acc,
            max_joint_velocity=np.asarray(j.dq_max) - tolerance,
            translation=triple(
                c.translation_velocity, c.translation_acceleration, c.translation_jerk
            ),
            rotation=triple(c.rotation_velocity, c.rotation_acceleration, c.rotation_jerk),
            elbow=triple(c.elbow_velocity, c.elbow_acceleration, c.elbow_jerk),
            _tolerance=tolerance,
            _q_min=np.asarray(j.q_min),
            _q_max=np.asarray(j.q_max),
            _offset=np.asarray(j.dq_offset),
            _decel2=2.0 * np.asarray(j.ddq_decel),
        )

    def joint_velocity_limits(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(upper, lower)`` joint velocity limits [rad/s] at joint positions ``q`` [rad]."""
        if not self.position_based:
            return self.max_joint_velocity, -self.max_joint_velocity
        cap = self.max_joint_velocity + self._tolerance
        up = np.sqrt(np.maximum(0.0, self._decel2 * (self._q_max - q))) - self._offset
        lo = np.sqrt(np.maximum(0.0, self._decel2 * (q - self._q_min))) - self._offset
        upper = np.minimum(cap, np.maximum(0.0, up)) - self._tolerance
        lower = -np.minimum(cap, np.maximum(0.0, lo)) + self._tolerance
        return upper, lower


# --- low-pass filters ---------------------------------------------------------------------


def _gain(sample_time: float, cutoff_frequency: float) -> float:
    if not (math.isfinite(sample_time) and sample_time >= 0.0):
        raise ValueError(f"sample_time: expected a finite time >= 0 [s], got {sample_time!r}")
    if not (math.isfinite(cutoff_frequency) and cutoff_frequency > 0.0):
        raise ValueError(
            f"cutoff_frequency: expected a finite frequency > 0 [Hz], got {cutoff_frequency!r}"
        )
    return sample_time / (sample_time + 1.0 / (2.0 * math.pi * cutoff_frequency))


def lowpass_filter(sample_time: float, y: Any, y_last: Any, cutoff_frequency: float) -> Any:
    """First-order low-pass: ``y_last + gain (y - y_last)`` (scalars or arrays), with the
    sample time [s] and cut-off frequency [Hz] setting the gain."""
    gain = _gain(sample_time, cutoff_frequency)
    a, b = np.asarray(y, dtype=np.float64), np.asarray(y_last, dtype=np.float64)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("y, y_last: Commanding value is infinite or NaN.")
    out = gain * a + (1.0 - gain) * b
    return float(out) if out.ndim == 0 else out


def _skew(w: FloatArray) -> FloatArray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _exp(w: FloatArray) -> FloatArray:
    """Rotation matrix of the rotation vector ``w`` [rad] (Rodrigues)."""
    theta = math.sqrt(float(w @ w))
    if theta <= NORM_EPS:
        return np.eye(3)
    K = _skew(w / theta)
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def _log(R: FloatArray) -> FloatArray:
    """Rotation vector (axis * angle, angle in [0, pi]) of the rotation matrix ``R``."""
    cos = min(1.0, max(-1.0, (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    sin = math.sqrt(float(v @ v))
    angle = math.atan2(sin, cos)
    if sin > 1e-6:
        return v * (angle / sin)
    if cos > 0.0:
        return v  # small angle: sin(angle) ~ angle
    # near pi: the axis is the dominant column of (R + 1) / 2 = a a^T
    B = (R + np.eye(3)) / 2.0
    k = int(np.argmax(np.diag(B)))
    axis = B[:, k] / math.sqrt(max(B[k, k], NORM_EPS))
    if v @ axis < 0.0:
        axis = -axis
    return axis * angle


def _pose_parts(T: Any) -> tuple[FloatArray, FloatArray]:
    M = np.asarray(T, dtype=np.float64).reshape(4, 4).T  # column-major 16 -> 4x4
    return M[:3, :3], M[:3, 3]


def _pose_flat(R: FloatArray, p: FloatArray) -> FloatArray:
    out = np.zeros(16)
    out[:12].reshape(3, 4)[:, :3] = R.T  # column-major: the columns of R first
    out[12:15] = p
    out[15] = 1.0
    return out


def cartesian_lowpass_filter(
    sample_time: float, y: Any, y_last: Any, cutoff_frequency: float
) -> FloatArray:
    """Low-pass a pose (16 values, column-major): the translation as :func:`lowpass_filter`,
    the orientation along the shortest arc from ``y_last`` towards ``y`` by the gain."""
    gain = _gain(sample_time, cutoff_frequency)
    R, p = _pose_parts(y)
    R_last, p_last = _pose_parts(y_last)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(p))):
        raise ValueError("y: Commanding value is infinite or NaN.")
    R_new = R_last @ _exp(gain * _log(R_last.T @ R))
    return _pose_flat(R_new, gain * p + (1.0 - gain) * p_last)


# --- rate limiters -----------------------------------------------------------------------


def limit_rate(max_derivatives: Any, commanded_values: Any, last_commanded_values: Any) -> Any:
    """Clip the rate of change of each value to ``max_derivatives`` [unit/s] over one
    1 ms period (libfranka's torque-rate limiter)."""
    c = np.asarray(commanded_values, dtype=np.float64)
    if not np.all(np.isfinite(c)):
        raise ValueError("commanded_values: Commanding value is infinite or NaN.")
    last = np.asarray(last_commanded_values, dtype=np.float64)
    m = np.asarray(max_derivatives, dtype=np.float64)
    return last + np.clip((c - last) / DELTA_T, -m, m) * DELTA_T


def limit_rate_joint_velocities(
    upper_velocity: Any,
    lower_velocity: Any,
    max_acceleration: Any,
    max_jerk: Any,
    commanded_velocities: Any,
    last_commanded_velocities: Any,
    last_commanded_accelerations: Any,
) -> FloatArray:
    """Joint velocities [rad/s] limited in jerk, acceleration and velocity (per joint)."""
    v = np.asarray(commanded_velocities, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise ValueError("commanded_velocities: Commanding value is infinite or NaN.")
    lv = np.asarray(last_commanded_velocities, dtype=np.float64)
    la = np.asarray(last_commanded_accelerations, dtype=np.float64)
    ma = np.asarray(max_acceleration, dtype=np.float64)
    mj = np.asarray(max_jerk, dtype=np.float64)
    jerk = ((v - lv) / DELTA_T - la) / DELTA_T
    acc = la + np.minimum(np.maximum(jerk, -mj), mj) * DELTA_T
    ratio = mj / ma
    safe_max = np.minimum(ratio * (np.asarray(upper_velocity) - lv), ma)
    safe_min = np.maximum(ratio * (np.asarray(lower_velocity) - lv), -ma)
    return lv + np.maximum(np.minimum(acc, safe_max), safe_min) * DELTA_T


def limit_rate_joint_positions(
    upper_velocity: Any,
    lower_velocity: Any,
    max_acceleration: Any,
    max_jerk: Any,
    commanded_positions: Any,
    last_commanded_positions: Any,
    last_commanded_velocities: Any,
    last_commanded_accelerations: Any,
) -> FloatArray:
    """Joint positions [rad] whose finite-difference velocity is limited as
    :func:`limit_rate_joint_velocities`."""
    q = np.asarray(commanded_positions, dtype=np.float64)
    if not np.all(np.isfinite(q)):
        raise ValueError("commanded_positions: Commanding value is infinite or NaN.")
    lq = np.asarray(last_commanded_positions, dtype=np.float64)
    v = limit_rate_joint_velocities(
        upper_velocity, lower_velocity, max_acceleration, max_jerk, (q - lq) / DELTA_T,
        last_commanded_velocities, last_commanded_accelerations,
    )  # fmt: skip
    return lq + v * DELTA_T


def _limit_vector(
    max_v: float, max_a: float, max_j: float, v: FloatArray, lv: FloatArray, la: FloatArray
) -> FloatArray:
    jerk = ((v - lv) / DELTA_T - la) / DELTA_T
    acc = la.copy()
    jn = math.sqrt(float(jerk @ jerk))
    if jn > NORM_EPS:
        acc += jerk / jn * min(jn, max_j) * DELTA_T
    an = math.sqrt(float(acc @ acc))
    if an <= NORM_EPS:
        return lv.copy()
    unit = acc / an
    dot = float(unit @ lv)
    # distance to the velocity sphere along the acceleration's direction
    distance = -dot + math.sqrt(max(0.0, dot * dot - float(lv @ lv) + max_v * max_v))
    safe_max = min(max_j / max_a * distance, max_a)
    return lv + unit * min(an, safe_max) * DELTA_T


def limit_rate_cartesian_velocity(
    translation: tuple[float, float, float],
    rotation: tuple[float, float, float],
    O_dP_EE_c: Any,
    last_O_dP_EE_c: Any,
    last_O_ddP_EE_c: Any,
) -> FloatArray:
    """A twist (6,) [m/s, rad/s] limited in the norms of its translational and rotational
    jerk, acceleration and velocity; ``translation``/``rotation`` = (velocity,
    acceleration, jerk) limits."""
    v = np.asarray(O_dP_EE_c, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise ValueError("O_dP_EE_c: Commanding value is infinite or NaN.")
    lv = np.asarray(last_O_dP_EE_c, dtype=np.float64)
    la = np.asarray(last_O_ddP_EE_c, dtype=np.float64)
    out = np.empty(6)
    out[:3] = _limit_vector(*translation, v[:3], lv[:3], la[:3])
    out[3:] = _limit_vector(*rotation, v[3:], lv[3:], la[3:])
    return out


def limit_rate_cartesian_pose(
    translation: tuple[float, float, float],
    rotation: tuple[float, float, float],
    O_T_EE_c: Any,
    last_O_T_EE_c: Any,
    last_O_dP_EE_c: Any,
    last_O_ddP_EE_c: Any,
) -> FloatArray:
    """A pose (16,) column-major [m] whose finite-difference twist is limited as
    :func:`limit_rate_cartesian_velocity` (rotation limits times 0.99), integrated onto
    ``last_O_T_EE_c``."""
    R, p = _pose_parts(O_T_EE_c)
    R_last, p_last = _pose_parts(last_O_T_EE_c)
    twist = np.empty(6)
    twist[:3] = (p - p_last) / DELTA_T
    twist[3:] = _log(R @ R_last.T) / DELTA_T
    f = POSE_ROTATION_FACTOR
    rot = (f * rotation[0], f * rotation[1], f * rotation[2])
    dx = limit_rate_cartesian_velocity(translation, rot, twist, last_O_dP_EE_c, last_O_ddP_EE_c)
    return _pose_flat(_exp(dx[3:] * DELTA_T) @ R_last, p_last + dx[:3] * DELTA_T)


def limit_rate_position(
    limits: tuple[float, float, float],
    commanded_position: float,
    last_position: float,
    last_velocity: float,
    last_acceleration: float,
) -> float:
    """One position (the elbow's joint 3 [rad]) limited like a joint; ``limits`` =
    (velocity, acceleration, jerk)."""
    v_max, a_max, j_max = limits
    v = limit_rate_joint_velocities(
        v_max, -v_max, a_max, j_max, (commanded_position - last_position) / DELTA_T,
        last_velocity, last_acceleration,
    )  # fmt: skip
    return float(last_position + float(v) * DELTA_T)
