"""Unit quaternions in panda-py's (and Eigen's coeffs()) order: x, y, z, w (scalar last).

Small private helpers for the Cartesian trajectory; rotation vectors are axis * angle [rad].
"""

from __future__ import annotations

import math

import numpy as np

from panda_py.motion._path import Array

SMALL_ANGLE = 1e-8  # [rad] below this the series expansions are used


def multiply(a: Array, b: Array) -> Array:
    """Hamilton product ``a ⊗ b``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def left_matrix(a: Array) -> Array:
    """The 4x4 matrix ``L`` with ``a ⊗ e = L @ e``."""
    x, y, z, w = a
    return np.array([[w, -z, y, x], [z, w, -x, y], [-y, x, w, z], [-x, -y, -z, w]])


def conjugate(q: Array) -> Array:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def log(q: Array) -> Array:
    """Rotation vector of unit quaternion ``q``, angle in [0, π] (shortest way round)."""
    v, w = q[:3], q[3]
    if w < 0.0:
        v, w = -v, -w
    s = float(np.linalg.norm(v))
    if s < SMALL_ANGLE:
        return 2.0 * v / w
    return (2.0 * math.atan2(s, w) / s) * v


def exp(r: Array) -> Array:
    """Unit quaternion of rotation vector ``r`` [rad]."""
    th = float(np.linalg.norm(r))
    k = 0.5 - th * th / 48.0 if th < SMALL_ANGLE else math.sin(0.5 * th) / th
    return np.array([k * r[0], k * r[1], k * r[2], math.cos(0.5 * th)])


def exp_many(r: Array) -> Array:
    """:func:`exp` of each row of ``r`` (shape (N, 3)) -> (N, 4)."""
    th = np.linalg.norm(r, axis=-1)
    small = th < SMALL_ANGLE
    k = np.where(small, 0.5 - th * th / 48.0, np.sin(0.5 * th) / np.where(small, 1.0, th))
    return np.concatenate([r * k[:, None], np.cos(0.5 * th)[:, None]], axis=1)


def to_matrix(q: Array) -> Array:
    """Rotation matrix of unit quaternion ``q``."""
    return np.array(matrix_rows(*q))


def matrix_rows(x: float, y: float, z: float, w: float) -> tuple[tuple[float, ...], ...]:
    """The rows of the rotation matrix of unit quaternion (x, y, z, w), in scalars."""
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)),
    )


def to_matrix_many(q: Array) -> Array:
    """:func:`to_matrix` of each row of ``q`` (shape (N, 4)) -> (N, 3, 3)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    m = np.empty((len(q), 3, 3))
    m[:, 0, 0] = 1 - 2 * (y * y + z * z)
    m[:, 0, 1] = 2 * (x * y - z * w)
    m[:, 0, 2] = 2 * (x * z + y * w)
    m[:, 1, 0] = 2 * (x * y + z * w)
    m[:, 1, 1] = 1 - 2 * (x * x + z * z)
    m[:, 1, 2] = 2 * (y * z - x * w)
    m[:, 2, 0] = 2 * (x * z - y * w)
    m[:, 2, 1] = 2 * (y * z + x * w)
    m[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def transforms(positions: Array, quats: Array) -> Array:
    """4x4 homogeneous transforms (N, 4, 4) of positions (N, 3) and unit quaternions
    (N, 4)."""
    poses = np.zeros((len(positions), 4, 4))
    poses[:, :3, :3] = to_matrix_many(quats)
    poses[:, :3, 3] = positions
    poses[:, 3, 3] = 1.0
    return poses


def from_matrix(m: Array) -> Array:
    """Unit quaternion of rotation matrix ``m`` (3x3, or the rotation of a 4x4)."""
    (a, b, c), (d, e, f), (g, h, i) = (row[:3] for row in m[:3].tolist())
    return np.array(quaternion_of(a, b, c, d, e, f, g, h, i))


def quaternion_of(
    m00: float, m01: float, m02: float, m10: float, m11: float, m12: float,
    m20: float, m21: float, m22: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """Unit quaternion (x, y, z, w) of the rotation matrix with these entries (Shepperd's
    method: divide by the largest of the four candidate terms, so it is well conditioned
    everywhere; on a tie the first of trace, m00, m11, m22). In scalars: a single pose
    costs a tenth of the same in NumPy calls, and far less on cold caches."""
    tr = m00 + m11 + m22
    if tr >= m00 and tr >= m11 and tr >= m22:
        s = 2.0 * math.sqrt(1.0 + tr)
        x, y, z, w = (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s
    elif m00 >= m11 and m00 >= m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        x, y, z, w = 0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s
    elif m11 >= m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        x, y, z, w = (m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        x, y, z, w = (m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


def rotate_many(q: Array, v: Array) -> Array:
    """Rotate each row of ``v`` (N, 3) by the matching unit quaternion row of ``q`` (N, 4)."""
    u, w = q[:, :3], q[:, 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def right_jacobian_times(x: Array, xd: Array) -> Array:
    """``J_r(x) @ xd`` row-wise: the body angular velocity of ``R0 exp(x(t))`` [rad/s]."""
    th = np.linalg.norm(x, axis=-1)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th * th / 24.0, (1.0 - np.cos(th)) / ths**2)
    b = np.where(small, 1.0 / 6.0 - th * th / 120.0, (th - np.sin(th)) / ths**3)
    c = np.cross(x, xd)
    return xd - a[:, None] * c + b[:, None] * np.cross(x, c)
