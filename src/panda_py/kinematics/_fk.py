"""Forward kinematics of a modified-DH chain: poses, frames and Jacobians, written once in
scalar Python that numba compiles as it is (:mod:`._numba`) or Python runs plain.

The loops read array entries through ``float()``: a no-op compiled, and plain it turns
NumPy scalars into Python floats, whose arithmetic is several times faster.

The helpers take floats and tuples and return tuples; only the ``*_range`` loops read and
write arrays (under the JIT an array argument costs reference counting per call). A pose
is the top three rows of a rigid transform as a row-major 12-tuple.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from panda_py.kinematics._scalar import sincos

# A twist constant closer than this to 0 or +-1 is taken as exact [-]: cos(pi/2) evaluates
# to 6e-17 in floating point and would otherwise leave 1e-17 residues in every pose.
SNAP_TOL = 1e-12

EYE = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)


class Chain(NamedTuple):
    """One arm with one end effector: per joint the modified-DH ``a`` [m], ``d`` [m] and
    the twist's cosine and sine; the flange offset ``flange_d`` [m] along z7; ``F`` the
    flange-to-EE transform's top three rows (row-major 12-tuple)."""

    a: tuple[float, ...]
    d: tuple[float, ...]
    cos_alpha: tuple[float, ...]
    sin_alpha: tuple[float, ...]
    flange_d: float
    F: tuple[float, ...]


def _snap(x: float) -> float:
    for exact in (0.0, 1.0, -1.0):
        if abs(x - exact) < SNAP_TOL:
            return exact
    return x


def make_chain(dh: Any, F_T_EE: NDArray[np.float64]) -> Chain:
    """The chain of a DH table (``panda_py.robots.params``) and a flange-to-EE transform."""
    return Chain(
        tuple(float(v) for v in dh.a),
        tuple(float(v) for v in dh.d),
        tuple(_snap(math.cos(v)) for v in dh.alpha),
        tuple(_snap(math.sin(v)) for v in dh.alpha),
        float(dh.flange_d),
        tuple(float(v) for v in F_T_EE[:3].ravel()),
    )


def pack_chain(c: Chain) -> NDArray[np.float64]:
    """The chain as the flat float64 array the kernels take (41,): a numba call with an
    array costs a fraction of one with a named tuple. :func:`unpack_chain` reverses it."""
    return np.array([*c.a, *c.d, *c.cos_alpha, *c.sin_alpha, c.flange_d, *c.F])


def unpack_chain(C: Any) -> Chain:
    """:func:`pack_chain` reversed (inside the kernels)."""
    return Chain(
        (C[0], C[1], C[2], C[3], C[4], C[5], C[6]),
        (C[7], C[8], C[9], C[10], C[11], C[12], C[13]),
        (C[14], C[15], C[16], C[17], C[18], C[19], C[20]),
        (C[21], C[22], C[23], C[24], C[25], C[26], C[27]),
        C[28],
        (C[29], C[30], C[31], C[32], C[33], C[34], C[35], C[36], C[37], C[38], C[39], C[40]),
    )


def link(m: Any, a: float, d: float, ca: float, sa: float, q: float) -> Any:
    """m @ RotX(alpha) TransX(a) RotZ(q) TransZ(d) (ca, sa: cos and sin of alpha)."""
    s, c = sincos(q)
    m0, m1, m2, m3, m4, m5, m6, m7, m8, m9, m10, m11 = m
    # link rows: [c, -s, 0, a], [s ca, c ca, -sa, -sa d], [s sa, c sa, ca, ca d]
    b0, b1 = s * ca, c * ca
    g0, g1 = s * sa, c * sa
    e, f = -sa * d, ca * d
    return (
        m0 * c + m1 * b0 + m2 * g0,
        -m0 * s + m1 * b1 + m2 * g1,
        -m1 * sa + m2 * ca,
        m0 * a + m1 * e + m2 * f + m3,
        m4 * c + m5 * b0 + m6 * g0,
        -m4 * s + m5 * b1 + m6 * g1,
        -m5 * sa + m6 * ca,
        m4 * a + m5 * e + m6 * f + m7,
        m8 * c + m9 * b0 + m10 * g0,
        -m8 * s + m9 * b1 + m10 * g1,
        -m9 * sa + m10 * ca,
        m8 * a + m9 * e + m10 * f + m11,
    )


def tail(m: Any, fd: float, F: Any) -> Any:
    """m @ TransZ(fd) @ F (F a pose)."""
    m0, m1, m2, m3, m4, m5, m6, m7, m8, m9, m10, m11 = m
    f00, f01, f02, f03, f10, f11, f12, f13, f20, f21, f22, f23 = F
    m3 += m2 * fd
    m7 += m6 * fd
    m11 += m10 * fd
    return (
        m0 * f00 + m1 * f10 + m2 * f20,
        m0 * f01 + m1 * f11 + m2 * f21,
        m0 * f02 + m1 * f12 + m2 * f22,
        m0 * f03 + m1 * f13 + m2 * f23 + m3,
        m4 * f00 + m5 * f10 + m6 * f20,
        m4 * f01 + m5 * f11 + m6 * f21,
        m4 * f02 + m5 * f12 + m6 * f22,
        m4 * f03 + m5 * f13 + m6 * f23 + m7,
        m8 * f00 + m9 * f10 + m10 * f20,
        m8 * f01 + m9 * f11 + m10 * f21,
        m8 * f02 + m9 * f12 + m10 * f22,
        m8 * f03 + m9 * f13 + m10 * f23 + m11,
    )


def ee_pose(c: Chain, q: Any) -> Any:
    """O_T_EE (a pose) of the joint positions q [rad] (7 floats, indexable)."""
    m = EYE
    for i in range(7):
        m = link(m, c.a[i], c.d[i], c.cos_alpha[i], c.sin_alpha[i], q[i])
    return tail(m, c.flange_d, c.F)


def fk_range(Q: Any, C: Any, out: Any, k0: int, k1: int) -> None:
    """O_T_EE for rows k0..k1-1 of Q (N, 7) into out (N, 4, 4); C the packed chain."""
    c = unpack_chain(C)
    for k in range(k0, k1):
        q = (float(Q[k, 0]), float(Q[k, 1]), float(Q[k, 2]), float(Q[k, 3]), float(Q[k, 4]),
             float(Q[k, 5]), float(Q[k, 6]))  # fmt: skip
        v = ee_pose(c, q)
        for i in range(3):
            for j in range(4):
                out[k, i, j] = v[4 * i + j]
        out[k, 3, 0] = 0.0
        out[k, 3, 1] = 0.0
        out[k, 3, 2] = 0.0
        out[k, 3, 3] = 1.0


def frames_range(Q: Any, C: Any, out: Any, k0: int, k1: int) -> None:
    """J1..J7, flange and EE (libfranka's Frame order) for rows k0..k1-1 of Q into out
    (N, 9, 4, 4)."""
    c = unpack_chain(C)
    for k in range(k0, k1):
        m = EYE
        for f in range(9):
            if f < 7:
                m = link(m, c.a[f], c.d[f], c.cos_alpha[f], c.sin_alpha[f], float(Q[k, f]))
                v = m
            else:
                v = tail(m, c.flange_d, EYE if f == 7 else c.F)
            for i in range(3):
                for j in range(4):
                    out[k, f, i, j] = v[4 * i + j]
            out[k, f, 3, 0] = 0.0
            out[k, f, 3, 1] = 0.0
            out[k, f, 3, 2] = 0.0
            out[k, f, 3, 3] = 1.0


def _column(m: Any, T: Any, body: bool) -> Any:
    """Joint i's Jacobian column (linear velocity, angular velocity) from its frame m:
    (z_i x (p_EE - o_i), z_i), in the base frame or (``body``) the EE frame T."""
    zx, zy, zz = m[2], m[6], m[10]
    dx, dy, dz = T[3] - m[3], T[7] - m[7], T[11] - m[11]
    vx, vy, vz = zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx
    if not body:
        return vx, vy, vz, zx, zy, zz
    return (  # R^T v, R^T w, R = T[:3, :3]
        T[0] * vx + T[4] * vy + T[8] * vz,
        T[1] * vx + T[5] * vy + T[9] * vz,
        T[2] * vx + T[6] * vy + T[10] * vz,
        T[0] * zx + T[4] * zy + T[8] * zz,
        T[1] * zx + T[5] * zy + T[9] * zz,
        T[2] * zx + T[6] * zy + T[10] * zz,
    )


def jacobian_columns(c: Chain, q: Any, body: bool) -> Any:
    """The seven columns (6-tuples) of the geometric EE Jacobian at q [rad] (rows: linear
    velocity, angular velocity), in the base frame or (``body``) the EE frame."""
    a, d, ca, sa = c.a, c.d, c.cos_alpha, c.sin_alpha
    m1 = link(EYE, a[0], d[0], ca[0], sa[0], q[0])
    m2 = link(m1, a[1], d[1], ca[1], sa[1], q[1])
    m3 = link(m2, a[2], d[2], ca[2], sa[2], q[2])
    m4 = link(m3, a[3], d[3], ca[3], sa[3], q[3])
    m5 = link(m4, a[4], d[4], ca[4], sa[4], q[4])
    m6 = link(m5, a[5], d[5], ca[5], sa[5], q[5])
    m7 = link(m6, a[6], d[6], ca[6], sa[6], q[6])
    T = tail(m7, c.flange_d, c.F)
    return (
        _column(m1, T, body), _column(m2, T, body), _column(m3, T, body),
        _column(m4, T, body), _column(m5, T, body), _column(m6, T, body),
        _column(m7, T, body),
    )  # fmt: skip


def jacobian_range(Q: Any, C: Any, body: bool, out: Any, k0: int, k1: int) -> None:
    """:func:`jacobian_columns` for rows k0..k1-1 of Q into out (N, 6, 7)."""
    c = unpack_chain(C)
    for k in range(k0, k1):
        q = (float(Q[k, 0]), float(Q[k, 1]), float(Q[k, 2]), float(Q[k, 3]), float(Q[k, 4]),
             float(Q[k, 5]), float(Q[k, 6]))  # fmt: skip
        cols = jacobian_columns(c, q, body)
        for i in range(7):
            col = cols[i]
            for h in range(6):
                out[k, h, i] = col[h]
