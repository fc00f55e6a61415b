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
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
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
    """Unit quaternion of rotation matrix ``m`` (Shepperd's method: divide by the
    largest of the four candidate terms, so it is well conditioned everywhere)."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    cands = (tr, m[0, 0], m[1, 1], m[2, 2])
    i = int(np.argmax(cands))
    if i == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif i == 1:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif i == 2:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    out = np.array(q)
    return out / np.linalg.norm(out)


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
