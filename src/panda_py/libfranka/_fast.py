"""Allocation-light, pure-float versions of the per-tick math of :mod:`limits` (the
vectorised NumPy versions there are the reference; tests check these against them).

Seven joints or one 3x3 rotation are too small for NumPy to pay off: each ufunc call costs
about a microsecond (ten times that with cold caches), a float operation in Python some
tens of nanoseconds. For the same reason two-argument ``min``/``max`` are written as
conditional expressions (a builtin call costs more than the arithmetic around it); each
keeps the builtin's operand order, so results are the builtin's, bit for bit.
Rotations are row-major 9-tuples here; poses arrive and leave as libfranka's column-major
16-sequences.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from panda_py.fci import PERIOD

__all__ = [
    "exp_so3",
    "is_pose",
    "joint_positions",
    "joint_velocities",
    "log_so3",
    "pose_limit",
    "pose_lowpass",
    "pose_lowpass_limit",
    "twist_limit",
]

DT = PERIOD  # [s]
_NORM_EPS = 2.220446049250313e-16
#: Tolerance on the norm of each rotation row and column of a commanded pose [-]
#: (``kOrthonormalThreshold`` of libfranka's ``isHomogeneousTransformation``).
ORTHONORMAL_THRESHOLD = 1e-5

Rot = tuple[float, float, float, float, float, float, float, float, float]
_sqrt = math.sqrt


def joint_velocities(
    upper: Sequence[float], lower: Sequence[float], max_acc: Sequence[float],
    max_jerk: Sequence[float], v: Sequence[float], lv: Sequence[float], la: Sequence[float],
    gain: float | None = None,
) -> list[float]:  # fmt: skip
    """Per-joint jerk/acceleration/velocity limiting (see ``limit_rate_joint_velocities``),
    of ``v`` low-passed towards ``lv`` by ``gain`` first if given."""
    out = []
    for i in range(len(v)):
        lvi, lai, am, jm = lv[i], la[i], max_acc[i], max_jerk[i]
        vi = v[i] if gain is None else lvi + gain * (v[i] - lvi)
        jerk = ((vi - lvi) / DT - lai) / DT
        acc = lai + (jm if jerk > jm else -jm if jerk < -jm else jerk) * DT
        r = jm / am
        x = r * (upper[i] - lvi)
        smax = am if am < x else x  # min(x, am)
        x = r * (lower[i] - lvi)
        smin = -am if -am > x else x  # max(x, -am)
        x = smax if smax < acc else acc  # min(acc, smax)
        out.append(lvi + (smin if smin > x else x) * DT)  # max(x, smin)
    return out


def joint_positions(
    upper: Sequence[float], lower: Sequence[float], max_acc: Sequence[float],
    max_jerk: Sequence[float], q: Sequence[float], lq: Sequence[float], lv: Sequence[float],
    la: Sequence[float], gain: float | None = None,
) -> list[float]:  # fmt: skip
    """Joint positions whose finite-difference velocity is limited as above, of ``q``
    low-passed towards ``lq`` by ``gain`` first if given."""
    out = []
    for i in range(len(q)):
        lqi, lvi, lai, am, jm = lq[i], lv[i], la[i], max_acc[i], max_jerk[i]
        qi = q[i] if gain is None else lqi + gain * (q[i] - lqi)
        jerk = (((qi - lqi) / DT - lvi) / DT - lai) / DT
        acc = lai + (jm if jerk > jm else -jm if jerk < -jm else jerk) * DT
        r = jm / am
        x = r * (upper[i] - lvi)
        smax = am if am < x else x
        x = r * (lower[i] - lvi)
        smin = -am if -am > x else x
        x = smax if smax < acc else acc
        out.append(lqi + (lvi + (smin if smin > x else x) * DT) * DT)
    return out


def _vec_limit(
    max_v: float, max_a: float, max_j: float, vx: float, vy: float, vz: float, lx: float,
    ly: float, lz: float, ax: float, ay: float, az: float,
) -> tuple[float, float, float]:  # fmt: skip
    """One 3-vector of a twist limited in the norms of jerk, acceleration, velocity."""
    jx = ((vx - lx) / DT - ax) / DT
    jy = ((vy - ly) / DT - ay) / DT
    jz = ((vz - lz) / DT - az) / DT
    jn = _sqrt(jx * jx + jy * jy + jz * jz)
    if jn > _NORM_EPS:
        k = (max_j if max_j < jn else jn) * DT / jn  # min(jn, max_j)
        ax, ay, az = ax + jx * k, ay + jy * k, az + jz * k
    an = _sqrt(ax * ax + ay * ay + az * az)
    if an <= _NORM_EPS:
        return (lx, ly, lz)
    ux, uy, uz = ax / an, ay / an, az / an
    dot = ux * lx + uy * ly + uz * lz
    t = dot * dot - (lx * lx + ly * ly + lz * lz) + max_v * max_v
    distance = -dot + _sqrt(t if t > 0.0 else 0.0)  # max(0.0, t)
    s = max_j / max_a * distance
    s = max_a if max_a < s else s  # min(s, max_a)
    step = (s if s < an else an) * DT  # min(an, s)
    return (lx + ux * step, ly + uy * step, lz + uz * step)


def twist_limit(
    translation: Sequence[float], rotation: Sequence[float], v: Sequence[float],
    lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """A twist (6) limited as ``limit_rate_cartesian_velocity``."""
    tx, ty, tz = _vec_limit(
        translation[0], translation[1], translation[2], v[0], v[1], v[2], lv[0], lv[1], lv[2],
        la[0], la[1], la[2],
    )  # fmt: skip
    rx, ry, rz = _vec_limit(
        rotation[0], rotation[1], rotation[2], v[3], v[4], v[5], lv[3], lv[4], lv[5], la[3],
        la[4], la[5],
    )  # fmt: skip
    return [tx, ty, tz, rx, ry, rz]


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


def log_so3(R: Sequence[float]) -> tuple[float, float, float]:
    """Rotation vector (axis * angle in [0, pi]) of a rotation matrix (row-major 9)."""
    c = (R[0] + R[4] + R[8] - 1.0) / 2.0
    c = c if c > -1.0 else -1.0  # max(-1.0, c)
    cos = c if c < 1.0 else 1.0  # min(1.0, c)
    vx, vy, vz = (R[7] - R[5]) / 2.0, (R[2] - R[6]) / 2.0, (R[3] - R[1]) / 2.0
    sin = _sqrt(vx * vx + vy * vy + vz * vz)
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
    n = _sqrt(max(d[k], _NORM_EPS))
    ax, ay, az = col[0] / n, col[1] / n, col[2] / n
    if vx * ax + vy * ay + vz * az < 0.0:
        ax, ay, az = -ax, -ay, -az
    return (ax * angle, ay * angle, az * angle)


def exp_so3(wx: float, wy: float, wz: float) -> Rot:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    theta = _sqrt(wx * wx + wy * wy + wz * wz)
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
    a, b, c, d, e, f, g, h, i = T[0], T[1], T[2], T[4], T[5], T[6], T[8], T[9], T[10]
    # "not (... > tol)": a NaN norm passes, as in libfranka
    return not (
        abs(_sqrt(a * a + b * b + c * c) - 1.0) > tol  # column 0, row 0, column 1, ...
        or abs(_sqrt(a * a + d * d + g * g) - 1.0) > tol
        or abs(_sqrt(d * d + e * e + f * f) - 1.0) > tol
        or abs(_sqrt(b * b + e * e + h * h) - 1.0) > tol
        or abs(_sqrt(g * g + h * h + i * i) - 1.0) > tol
        or abs(_sqrt(c * c + f * f + i * i) - 1.0) > tol
    )


def pose_lowpass(gain: float, T: Sequence[float], T_last: Sequence[float]) -> list[float]:
    """Translation low-passed, orientation moved along the shortest arc by ``gain``."""
    L, N = T_last, T
    # R_last^T R: column i of T_last dotted with column j of T
    w = log_so3((
        L[0] * N[0] + L[1] * N[1] + L[2] * N[2], L[0] * N[4] + L[1] * N[5] + L[2] * N[6],
        L[0] * N[8] + L[1] * N[9] + L[2] * N[10], L[4] * N[0] + L[5] * N[1] + L[6] * N[2],
        L[4] * N[4] + L[5] * N[5] + L[6] * N[6], L[4] * N[8] + L[5] * N[9] + L[6] * N[10],
        L[8] * N[0] + L[9] * N[1] + L[10] * N[2], L[8] * N[4] + L[9] * N[5] + L[10] * N[6],
        L[8] * N[8] + L[9] * N[9] + L[10] * N[10],
    ))  # fmt: skip
    E = exp_so3(gain * w[0], gain * w[1], gain * w[2])
    g1 = 1.0 - gain
    # column-major R_last E: entry (i, j) = row i of R_last dotted with column j of E
    return [
        L[0] * E[0] + L[4] * E[3] + L[8] * E[6], L[1] * E[0] + L[5] * E[3] + L[9] * E[6],
        L[2] * E[0] + L[6] * E[3] + L[10] * E[6], 0.0,
        L[0] * E[1] + L[4] * E[4] + L[8] * E[7], L[1] * E[1] + L[5] * E[4] + L[9] * E[7],
        L[2] * E[1] + L[6] * E[4] + L[10] * E[7], 0.0,
        L[0] * E[2] + L[4] * E[5] + L[8] * E[8], L[1] * E[2] + L[5] * E[5] + L[9] * E[8],
        L[2] * E[2] + L[6] * E[5] + L[10] * E[8], 0.0,
        gain * N[12] + g1 * L[12], gain * N[13] + g1 * L[13], gain * N[14] + g1 * L[14], 1.0,
    ]  # fmt: skip


def pose_limit(
    translation: Sequence[float], rotation: Sequence[float], T: Sequence[float],
    T_last: Sequence[float], lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """A pose whose finite-difference twist is limited (``rotation`` already scaled)."""
    L, N = T_last, T
    # R R_last^T: row i of R dotted with row j of R_last
    w = log_so3((
        N[0] * L[0] + N[4] * L[4] + N[8] * L[8], N[0] * L[1] + N[4] * L[5] + N[8] * L[9],
        N[0] * L[2] + N[4] * L[6] + N[8] * L[10], N[1] * L[0] + N[5] * L[4] + N[9] * L[8],
        N[1] * L[1] + N[5] * L[5] + N[9] * L[9], N[1] * L[2] + N[5] * L[6] + N[9] * L[10],
        N[2] * L[0] + N[6] * L[4] + N[10] * L[8], N[2] * L[1] + N[6] * L[5] + N[10] * L[9],
        N[2] * L[2] + N[6] * L[6] + N[10] * L[10],
    ))  # fmt: skip
    return _limit_step(translation, rotation, L, N[12], N[13], N[14], w, lv, la)


def pose_lowpass_limit(
    gain: float, translation: Sequence[float], rotation: Sequence[float], T: Sequence[float],
    T_last: Sequence[float], lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """:func:`pose_limit` of :func:`pose_lowpass` in one pass: the low-passed rotation
    R_last exp(gain w) (w = log(R_last^T R)) is never formed, as the limiter needs only
    its rotation vector relative to R_last in the base frame, log(R_last exp(gain w)
    R_last^T) = R_last (gain w) (conjugation turns the axis; gain < 1 keeps the angle
    below pi). Equal to the two steps to float round-off."""
    L, N = T_last, T
    # R_last^T R: column i of T_last dotted with column j of T
    w = log_so3((
        L[0] * N[0] + L[1] * N[1] + L[2] * N[2], L[0] * N[4] + L[1] * N[5] + L[2] * N[6],
        L[0] * N[8] + L[1] * N[9] + L[2] * N[10], L[4] * N[0] + L[5] * N[1] + L[6] * N[2],
        L[4] * N[4] + L[5] * N[5] + L[6] * N[6], L[4] * N[8] + L[5] * N[9] + L[6] * N[10],
        L[8] * N[0] + L[9] * N[1] + L[10] * N[2], L[8] * N[4] + L[9] * N[5] + L[10] * N[6],
        L[8] * N[8] + L[9] * N[9] + L[10] * N[10],
    ))  # fmt: skip
    gx, gy, gz = gain * w[0], gain * w[1], gain * w[2]
    g1 = 1.0 - gain
    return _limit_step(
        translation, rotation, L, gain * N[12] + g1 * L[12], gain * N[13] + g1 * L[13],
        gain * N[14] + g1 * L[14],
        (L[0] * gx + L[4] * gy + L[8] * gz, L[1] * gx + L[5] * gy + L[9] * gz,
         L[2] * gx + L[6] * gy + L[10] * gz),
        lv, la,
    )  # fmt: skip


def _limit_step(
    translation: Sequence[float], rotation: Sequence[float], L: Sequence[float], x: float,
    y: float, z: float, w: Sequence[float], lv: Sequence[float], la: Sequence[float],
) -> list[float]:  # fmt: skip
    """The limited pose from T_last ``L`` towards position (x, y, z) and the base-frame
    rotation vector ``w`` relative to R_last."""
    px, py, pz = L[12], L[13], L[14]
    tx, ty, tz = _vec_limit(
        translation[0], translation[1], translation[2], (x - px) / DT, (y - py) / DT,
        (z - pz) / DT, lv[0], lv[1], lv[2], la[0], la[1], la[2],
    )  # fmt: skip
    rx, ry, rz = _vec_limit(
        rotation[0], rotation[1], rotation[2], w[0] / DT, w[1] / DT, w[2] / DT, lv[3], lv[4],
        lv[5], la[3], la[4], la[5],
    )  # fmt: skip
    E = exp_so3(rx * DT, ry * DT, rz * DT)
    # column-major E R_last: entry (i, j) = row i of E dotted with column j of R_last
    return [
        E[0] * L[0] + E[1] * L[1] + E[2] * L[2], E[3] * L[0] + E[4] * L[1] + E[5] * L[2],
        E[6] * L[0] + E[7] * L[1] + E[8] * L[2], 0.0,
        E[0] * L[4] + E[1] * L[5] + E[2] * L[6], E[3] * L[4] + E[4] * L[5] + E[5] * L[6],
        E[6] * L[4] + E[7] * L[5] + E[8] * L[6], 0.0,
        E[0] * L[8] + E[1] * L[9] + E[2] * L[10], E[3] * L[8] + E[4] * L[9] + E[5] * L[10],
        E[6] * L[8] + E[7] * L[9] + E[8] * L[10], 0.0,
        px + tx * DT, py + ty * DT, pz + tz * DT, 1.0,
    ]  # fmt: skip
