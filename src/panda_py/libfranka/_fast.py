"""Allocation-light, pure-float versions of the per-tick math of :mod:`limits` (the
vectorised NumPy versions there are the reference; tests check these against them).

Seven joints or one 3x3 rotation are too small for NumPy to pay off: each ufunc call costs
about a microsecond, a float operation in Python some tens of nanoseconds. Rotations are
row-major 9-tuples here; poses arrive and leave as libfranka's column-major 16 lists.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = [
    "exp_so3",
    "is_pose",
    "joint_positions",
    "joint_velocities",
    "log_so3",
    "pose_limit",
    "pose_lowpass",
    "twist_limit",
]

DT = 1e-3  # [s]
_NORM_EPS = 2.220446049250313e-16
#: Tolerance on the norm of each rotation row and column of a commanded pose [-]
#: (``kOrthonormalThreshold`` of libfranka's ``isHomogeneousTransformation``).
ORTHONORMAL_THRESHOLD = 1e-5

Rot = tuple[float, float, float, float, float, float, float, float, float]


def joint_velocities(
    upper: Sequence[float], lower: Sequence[float], max_acc: Sequence[float],
    max_jerk: Sequence[float], v: Sequence[float], lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """Per-joint jerk/acceleration/velocity limiting (see ``limit_rate_joint_velocities``)."""
    out = []
    for i in range(len(v)):
        lvi, lai, am, jm = lv[i], la[i], max_acc[i], max_jerk[i]
        jerk = ((v[i] - lvi) / DT - lai) / DT
        acc = lai + (jm if jerk > jm else -jm if jerk < -jm else jerk) * DT
        r = jm / am
        smax = min(r * (upper[i] - lvi), am)
        smin = max(r * (lower[i] - lvi), -am)
        out.append(lvi + max(min(acc, smax), smin) * DT)
    return out


def joint_positions(
    upper: Sequence[float], lower: Sequence[float], max_acc: Sequence[float],
    max_jerk: Sequence[float], q: Sequence[float], lq: Sequence[float], lv: Sequence[float],
    la: Sequence[float],
) -> list[float]:  # fmt: skip
    """Joint positions whose finite-difference velocity is limited as above."""
    v = [(q[i] - lq[i]) / DT for i in range(len(q))]
    vl = joint_velocities(upper, lower, max_acc, max_jerk, v, lv, la)
    return [lq[i] + vl[i] * DT for i in range(len(q))]


def _vec_limit(
    max_v: float, max_a: float, max_j: float, v: Sequence[float], lv: Sequence[float],
    la: Sequence[float],
) -> list[float]:  # fmt: skip
    jx = ((v[0] - lv[0]) / DT - la[0]) / DT
    jy = ((v[1] - lv[1]) / DT - la[1]) / DT
    jz = ((v[2] - lv[2]) / DT - la[2]) / DT
    ax, ay, az = la[0], la[1], la[2]
    jn = math.sqrt(jx * jx + jy * jy + jz * jz)
    if jn > _NORM_EPS:
        k = min(jn, max_j) * DT / jn
        ax, ay, az = ax + jx * k, ay + jy * k, az + jz * k
    an = math.sqrt(ax * ax + ay * ay + az * az)
    if an <= _NORM_EPS:
        return [lv[0], lv[1], lv[2]]
    ux, uy, uz = ax / an, ay / an, az / an
    dot = ux * lv[0] + uy * lv[1] + uz * lv[2]
    lv2 = lv[0] * lv[0] + lv[1] * lv[1] + lv[2] * lv[2]
    distance = -dot + math.sqrt(max(0.0, dot * dot - lv2 + max_v * max_v))
    step = min(an, min(max_j / max_a * distance, max_a)) * DT
    return [lv[0] + ux * step, lv[1] + uy * step, lv[2] + uz * step]


def twist_limit(
    translation: Sequence[float], rotation: Sequence[float], v: Sequence[float],
    lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """A twist (6) limited as ``limit_rate_cartesian_velocity``."""
    return _vec_limit(translation[0], translation[1], translation[2], v[:3], lv[:3], la[:3]) + \
        _vec_limit(rotation[0], rotation[1], rotation[2], v[3:], lv[3:], la[3:])  # fmt: skip


def rot_of(T: Sequence[float]) -> Rot:
    """Row-major rotation of a column-major 16-list pose."""
    return (T[0], T[4], T[8], T[1], T[5], T[9], T[2], T[6], T[10])


def matmul(a: Rot, b: Rot) -> Rot:
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8], a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7], a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )  # fmt: skip


def transpose(a: Rot) -> Rot:
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


def log_so3(R: Rot) -> tuple[float, float, float]:
    """Rotation vector (axis * angle in [0, pi]) of a rotation matrix."""
    cos = min(1.0, max(-1.0, (R[0] + R[4] + R[8] - 1.0) / 2.0))
    vx, vy, vz = (R[7] - R[5]) / 2.0, (R[2] - R[6]) / 2.0, (R[3] - R[1]) / 2.0
    sin = math.sqrt(vx * vx + vy * vy + vz * vz)
    angle = math.atan2(sin, cos)
    if sin > 1e-6:
        k = angle / sin
        return (vx * k, vy * k, vz * k)
    if cos > 0.0:
        return (vx, vy, vz)
    # near pi: the axis is the dominant column of (R + 1) / 2 = a a^T
    d = ((R[0] + 1.0) / 2.0, (R[4] + 1.0) / 2.0, (R[8] + 1.0) / 2.0)
    k = d.index(max(d))
    col = ((R[k] + (k == 0)) / 2.0, (R[3 + k] + (k == 1)) / 2.0, (R[6 + k] + (k == 2)) / 2.0)
    n = math.sqrt(max(d[k], _NORM_EPS))
    ax, ay, az = col[0] / n, col[1] / n, col[2] / n
    if vx * ax + vy * ay + vz * az < 0.0:
        ax, ay, az = -ax, -ay, -az
    return (ax * angle, ay * angle, az * angle)


def exp_so3(wx: float, wy: float, wz: float) -> Rot:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    theta = math.sqrt(wx * wx + wy * wy + wz * wz)
    if theta <= _NORM_EPS:
        return (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    x, y, z = wx / theta, wy / theta, wz / theta
    s, c = math.sin(theta), math.cos(theta)
    C = 1.0 - c
    return (
        c + x * x * C, x * y * C - z * s, x * z * C + y * s,
        y * x * C + z * s, c + y * y * C, y * z * C - x * s,
        z * x * C - y * s, z * y * C + x * s, c + z * z * C,
    )  # fmt: skip


def pose_list(R: Rot, p: Sequence[float]) -> list[float]:
    """Column-major 16-list of a row-major rotation and a translation."""
    return [R[0], R[3], R[6], 0.0, R[1], R[4], R[7], 0.0, R[2], R[5], R[8], 0.0,
            p[0], p[1], p[2], 1.0]  # fmt: skip


def is_pose(T: Sequence[float]) -> bool:
    """libfranka's ``isHomogeneousTransformation`` on a column-major 16-list."""
    if T[3] != 0.0 or T[7] != 0.0 or T[11] != 0.0 or T[15] != 1.0:
        return False
    tol = ORTHONORMAL_THRESHOLD
    for j in range(3):
        a, b, c = T[4 * j], T[4 * j + 1], T[4 * j + 2]
        if abs(math.sqrt(a * a + b * b + c * c) - 1.0) > tol:
            return False
        a, b, c = T[j], T[4 + j], T[8 + j]
        if abs(math.sqrt(a * a + b * b + c * c) - 1.0) > tol:
            return False
    return True


def pose_lowpass(gain: float, T: Sequence[float], T_last: Sequence[float]) -> list[float]:
    """Translation low-passed, orientation moved along the shortest arc by ``gain``."""
    R_last = rot_of(T_last)
    w = log_so3(matmul(transpose(R_last), rot_of(T)))
    R = matmul(R_last, exp_so3(gain * w[0], gain * w[1], gain * w[2]))
    g1 = 1.0 - gain
    p = [gain * T[12] + g1 * T_last[12], gain * T[13] + g1 * T_last[13],
         gain * T[14] + g1 * T_last[14]]  # fmt: skip
    return pose_list(R, p)


def pose_limit(
    translation: Sequence[float], rotation: Sequence[float], T: Sequence[float],
    T_last: Sequence[float], lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """A pose whose finite-difference twist is limited (``rotation`` already scaled)."""
    R_last = rot_of(T_last)
    w = log_so3(matmul(rot_of(T), transpose(R_last)))
    twist = [(T[12] - T_last[12]) / DT, (T[13] - T_last[13]) / DT, (T[14] - T_last[14]) / DT,
             w[0] / DT, w[1] / DT, w[2] / DT]  # fmt: skip
    dx = twist_limit(translation, rotation, twist, lv, la)
    R = matmul(exp_so3(dx[3] * DT, dx[4] * DT, dx[5] * DT), R_last)
    p = [T_last[12] + dx[0] * DT, T_last[13] + dx[1] * DT, T_last[14] + dx[2] * DT]
    return pose_list(R, p)
