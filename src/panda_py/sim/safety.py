"""Robot-side checks of motion-generator and controller commands.

A Franka differentiates the commands it receives by backward Euler with the 1 ms tick and
aborts the motion with a reflex when a documented necessary condition is violated (FCI
docs, "Robot and interface specifications"). Each check here returns the error flags it
raised, by name as in libfranka's ``Errors``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py.fci import PERIOD
from panda_py.robots.params import RobotSpec

DT = PERIOD  # [s]
# Numerical slack on every limit: commands computed exactly at a limit must pass.
_REL = 1e-6
_ABS = 1e-9
# How far the first joint command may be from the measured position [rad] (the v10 state
# carries float32 positions, so a client echoing q is off by up to ~1e-7).
START_POSE_TOLERANCE = 1e-4
# How far the first Cartesian command may be from the measured pose [m], [rad].
START_CARTESIAN_TOLERANCE = 1e-3


class JointSignal:
    """Backward-Euler derivatives of a commanded joint signal and its limit checks;
    ``kernels``: the compiled ones (:mod:`._tick_jit`) to run instead of NumPy."""

    def __init__(self, kernels: Any = None) -> None:
        self.q = np.zeros(7)
        self.dq = np.zeros(7)
        self.ddq = np.zeros(7)
        self.dddq = np.zeros(7)
        self._k = kernels

    def reset(self, q: np.ndarray) -> None:
        self.q[:] = q
        self.dq[:] = 0.0
        self.ddq[:] = 0.0
        self.dddq[:] = 0.0

    def push_position(self, q: np.ndarray) -> None:
        if self._k is not None:
            self._k.joint_push(self.q, self.dq, self.ddq, self.dddq, q, self._k.PUSH_POSITION, DT)
            return
        dq = (q - self.q) / DT
        self._push(q, dq)

    def push_velocity(self, dq: np.ndarray) -> None:
        if self._k is not None:
            self._k.joint_push(self.q, self.dq, self.ddq, self.dddq, dq, self._k.PUSH_VELOCITY, DT)
            return
        self._push(self.q + dq * DT, dq)

    def extrapolate(self) -> None:
        """What the robot does with a lost motion command: keep the acceleration."""
        if self._k is not None:
            q = self.q
            self._k.joint_push(q, self.dq, self.ddq, self.dddq, q, self._k.EXTRAPOLATE, DT)
            return
        dq = self.dq + self.ddq * DT
        self._push(self.q + dq * DT, dq)

    def _push(self, q: np.ndarray, dq: np.ndarray) -> None:
        ddq = (dq - self.dq) / DT
        self.dddq[:] = (ddq - self.ddq) / DT
        self.ddq[:] = ddq
        self.dq[:] = dq
        self.q[:] = q

    def violations(self, spec: RobotSpec, *, cartesian: bool) -> list[str]:
        """Flags for a joint motion generator (or, with ``cartesian``, for the joint
        solution of a Cartesian one)."""
        limits = _joint_limits(spec)
        names = _CARTESIAN_JOINT_FLAGS if cartesian else _JOINT_FLAGS
        if self._k is not None:
            bits = self._k.joint_limit_bits(
                self.q, self.dq, self.ddq, self.dddq, limits.upper, limits.lower
            )
            return [n for i, n in enumerate(names) if bits >> i & 1] if bits else []
        # one comparison for position, velocity, acceleration and jerk of all joints
        values = np.concatenate(
            (self.q, self.q, np.abs(self.dq), np.abs(self.ddq), np.abs(self.dddq))
        )
        bad = values > limits.upper
        bad[:7] = self.q < limits.lower
        if not bad.any():
            return []
        rows = np.any(bad.reshape(5, 7), axis=1)
        below, above, vel, acc, jerk = (bool(rows[i]) for i in range(5))
        return [n for n, hit in zip(names, (below or above, vel, acc, jerk), strict=True) if hit]


class _Limits:
    """Joint limits of one robot as one flat vector (q_max, |dq|, |ddq|, |dddq| with
    slack), and q_min."""

    def __init__(self, spec: RobotSpec) -> None:
        j = spec.joints
        slack = 1 + _REL
        self.upper = np.concatenate((
            np.asarray(j.q_max) + _ABS,
            np.asarray(j.q_max) + _ABS,
            np.asarray(j.dq_max) * slack + _ABS,
            np.asarray(j.ddq_max) * slack + _ABS,
            np.asarray(j.dddq_max) * slack + _ABS,
        ))  # fmt: skip
        self.lower = np.asarray(j.q_min) - _ABS


_LIMITS: dict[int, _Limits] = {}


def joint_limit_vectors(spec: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    """The joint limits as ``_tick_jit.joint_limit_bits`` takes them: (upper (35,): q_max
    twice, then the |dq|, |ddq|, |dddq| limits, with the checks' slack; q_min (7,))."""
    limits = _joint_limits(spec)
    return limits.upper, limits.lower


def _joint_limits(spec: RobotSpec) -> _Limits:
    limits = _LIMITS.get(id(spec))
    if limits is None:
        limits = _LIMITS[id(spec)] = _Limits(spec)
    return limits


_JOINT_FLAGS = (
    "joint_motion_generator_position_limits_violation",
    "joint_motion_generator_velocity_limits_violation",
    "joint_motion_generator_velocity_discontinuity",
    "joint_motion_generator_acceleration_discontinuity",
)
_CARTESIAN_JOINT_FLAGS = (
    "cartesian_motion_generator_joint_position_limits_violation",
    "cartesian_motion_generator_joint_velocity_limits_violation",
    "cartesian_motion_generator_joint_velocity_discontinuity",
    "cartesian_motion_generator_joint_acceleration_discontinuity",
)


def pose_error(T_a: np.ndarray, T_b: np.ndarray) -> np.ndarray:
    """Twist [m, rad] taking pose ``T_a`` to ``T_b``, both in the base frame."""
    # On floats: a 3x3 product and an angle cost far less than NumPy calls on tiny arrays.
    a0, a1, a2, ax, a3, a4, a5, ay, a6, a7, a8, az = T_a[:3].ravel().tolist()
    b0, b1, b2, bx, b3, b4, b5, by, b6, b7, b8, bz = T_b[:3].ravel().tolist()
    # R = R_b R_a^T: only the trace and the skew part are needed.
    r00 = b0 * a0 + b1 * a1 + b2 * a2
    r11 = b3 * a3 + b4 * a4 + b5 * a5
    r22 = b6 * a6 + b7 * a7 + b8 * a8
    r21 = b6 * a3 + b7 * a4 + b8 * a5
    r12 = b3 * a6 + b4 * a7 + b5 * a8
    r02 = b0 * a6 + b1 * a7 + b2 * a8
    r20 = b6 * a0 + b7 * a1 + b8 * a2
    r10 = b3 * a0 + b4 * a1 + b5 * a2
    r01 = b0 * a3 + b1 * a4 + b2 * a5
    cos = min(1.0, max(-1.0, (r00 + r11 + r22 - 1.0) / 2.0))
    angle = math.acos(cos)
    s = math.sin(angle)
    k = angle / (2.0 * s) if s > 1e-9 else 0.5
    return np.array((bx - ax, by - ay, bz - az, (r21 - r12) * k, (r02 - r20) * k, (r10 - r01) * k))


class CartesianSignal:
    """Backward-Euler derivatives of a commanded end-effector pose and its checks."""

    def __init__(self) -> None:
        self.T = np.eye(4)
        self.v = np.zeros(6)
        self.a = np.zeros(6)
        self.j = np.zeros(6)

    def reset(self, T: np.ndarray) -> None:
        self.T[:] = T
        self.v[:] = 0.0
        self.a[:] = 0.0
        self.j[:] = 0.0

    def push_pose(self, T: np.ndarray) -> None:
        self._push(T, pose_error(self.T, T) / DT)

    def push_twist(self, v: np.ndarray) -> None:
        self._push(integrate_twist(self.T, v, DT), v)

    def extrapolate(self) -> None:
        v = self.v + self.a * DT
        self._push(integrate_twist(self.T, v, DT), v)

    def _push(self, T: np.ndarray, v: np.ndarray) -> None:
        a = (v - self.v) / DT
        self.j[:] = (a - self.a) / DT
        self.a[:] = a
        self.v[:] = v
        self.T[:] = T

    def violations(self, spec: RobotSpec) -> list[str]:
        c = spec.cartesian
        out = []
        checks = (
            (self.v, c.translation_velocity, c.rotation_velocity,
             "cartesian_motion_generator_velocity_limits_violation"),
            (self.a, c.translation_acceleration, c.rotation_acceleration,
             "cartesian_motion_generator_velocity_discontinuity"),
            (self.j, c.translation_jerk, c.rotation_jerk,
             "cartesian_motion_generator_acceleration_discontinuity"),
        )  # fmt: skip
        for signal, translation, rotation, flag in checks:
            x, y, z, wx, wy, wz = signal.tolist()
            # not (<=): a NaN fails the test
            if not (
                math.hypot(x, y, z) <= translation * (1 + _REL)
                and math.hypot(wx, wy, wz) <= rotation * (1 + _REL)
            ):
                out.append(flag)
        return out


def integrate_twist(T: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
    """Pose reached from ``T`` moving with base-frame twist ``v`` for ``dt`` seconds."""
    out = T.copy()
    out[:3, 3] += v[:3] * dt
    w = v[3:] * dt
    angle = float(np.linalg.norm(w))
    if angle > 0.0:
        k = w / angle
        K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        R = np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)
        out[:3, :3] = R @ T[:3, :3]
    return out


def all_finite(*arrays: np.ndarray) -> bool:
    """True if no array holds a NaN or an infinity."""
    return all(np.isfinite(a).all() for a in arrays)


def from_col_major(v: np.ndarray) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(4, 4).T.copy()


def is_valid_transform(T: np.ndarray) -> bool:
    """libfranka's test: last row exactly (0,0,0,1), rotation rows/columns of unit norm
    (within 1e-5), every entry finite."""
    r0, r1, r2, x, r3, r4, r5, y, r6, r7, r8, z, *last = T.ravel().tolist()
    if last != [0.0, 0.0, 0.0, 1.0] or not (
        math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
    ):
        return False
    norms = (
        math.hypot(r0, r1, r2), math.hypot(r3, r4, r5), math.hypot(r6, r7, r8),
        math.hypot(r0, r3, r6), math.hypot(r1, r4, r7), math.hypot(r2, r5, r8),
    )  # fmt: skip
    # a NaN or an infinity fails abs(n - 1) <= tol
    return all(abs(n - 1.0) <= 1e-5 for n in norms)
