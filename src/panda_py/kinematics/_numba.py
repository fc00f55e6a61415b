"""Optional numba kernels for the kinematics (``pip install panda-py[fast]``).

Imported lazily by :mod:`._model` on the first kinematics call that can use it, never at
``import panda_py``; without numba (ImportError) or with ``PANDA_PY_NO_JIT=1`` in the
environment the pure-NumPy paths run instead. The kernels mirror the pure code:

* forward kinematics: the modified-DH product (generic in the table, packed by
  ``_model._pack_chain``), a loop over joints on 12 scalars; frames and Jacobians from it;
* inverse kinematics: :func:`._ik.make_scalar_solver`'s equations line by line, the same
  branch indexing, status precedence and joint-limit tests (parameters packed by
  ``_model._pack_ik``).

Compiled with ``cache=True`` (numba writes to ``__pycache__`` next to this file and falls
back to compiling in memory if that is not writable). Tests hold every kernel equal to the
pure path to 1e-12.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from panda_py.kinematics import _ik

_OPTS: dict[str, Any] = {"nogil": True, "error_model": "numpy"}


def njit(**kw: Any) -> Any:
    """numba.njit with cache=True, or without the cache where numba finds no writable
    place for it (it raises RuntimeError at decoration then)."""

    def deco(fn: Any) -> Any:
        try:
            return numba.njit(cache=True, **kw)(fn)
        except RuntimeError:
            return numba.njit(**kw)(fn)

    return deco


# ------------------------------------------------------------------------ forward kinematics


@njit(inline="always", **_OPTS)
def _link(m: Any, a: float, d: float, ca: float, sa: float, q: float) -> Any:
    """M @ RotX(alpha) TransX(a) RotZ(q) TransZ(d), M the top 3x4 rows as a 12-tuple."""
    c, s = math.cos(q), math.sin(q)
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


@njit(inline="always", **_OPTS)
def _tail(m: Any, fd: float, FT: Any) -> Any:
    """M @ TransZ(fd) @ FT (FT the top 3x4 rows of a rigid transform)."""
    m0, m1, m2, m3, m4, m5, m6, m7, m8, m9, m10, m11 = m
    m3 += m2 * fd
    m7 += m6 * fd
    m11 += m10 * fd
    rows = ((m0, m1, m2, m3), (m4, m5, m6, m7), (m8, m9, m10, m11))
    out = np.empty(12)
    for i in range(3):
        r = rows[i]
        for j in range(4):
            out[4 * i + j] = r[0] * FT[0, j] + r[1] * FT[1, j] + r[2] * FT[2, j]
        out[4 * i + 3] += r[3]
    return out


@njit(inline="always", **_OPTS)
def _chain(q: Any, C: Any) -> Any:
    m = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    for i in range(7):
        m = _link(m, C[i, 0], C[i, 1], C[i, 2], C[i, 3], q[i])
    return m


@njit(inline="always", **_OPTS)
def _store(out: Any, v: Any) -> None:
    """12 entries (top 3 rows) into a 4x4, last row 0 0 0 1."""
    for i in range(3):
        for j in range(4):
            out[i, j] = v[4 * i + j]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(**_OPTS)
def fk_one(q: Any, CF: Any, out: Any) -> bool:
    """O_T_EE of q (7,) into out (4, 4); False (out untouched) if q is not finite. CF
    (11, 4): per joint ``[a, d, cos alpha, sin alpha]``, ``[flange_d, 0, 0, 0]``, then the
    top 3 rows of the flange-to-EE transform."""
    s = 0.0
    for i in range(7):
        s += q[i]
    if not math.isfinite(s):
        return False
    _store(out, _tail(_chain(q, CF), CF[7, 0], CF[8:]))
    return True


@njit(**_OPTS)
def fk_batch(Q: Any, CF: Any, out: Any) -> None:
    """O_T_EE for each row of Q (N, 7) into out (N, 4, 4)."""
    C, FT = CF, CF[8:]
    for k in range(Q.shape[0]):
        _store(out[k], _tail(_chain(Q[k], C), C[7, 0], FT))


@njit(**_OPTS)
def frames_batch(Q: Any, CF: Any, out: Any) -> None:
    """J1..J7, flange, EE for each row of Q into out (N, 9, 4, 4)."""
    C, FT = CF, CF[8:]
    eye = np.zeros((3, 4))
    eye[0, 0] = 1.0
    eye[1, 1] = 1.0
    eye[2, 2] = 1.0
    for k in range(Q.shape[0]):
        m = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
        for i in range(7):
            m = _link(m, C[i, 0], C[i, 1], C[i, 2], C[i, 3], Q[k, i])
            _store(out[k, i], m)
        _store(out[k, 7], _tail(m, C[7, 0], eye))
        _store(out[k, 8], _tail(m, C[7, 0], FT))


@njit(**_OPTS)
def jacobian_batch(Q: Any, CF: Any, body: bool, out: Any) -> None:
    """Geometric EE Jacobian (rows v, w) for each row of Q into out (N, 6, 7), in the
    base frame or (body) in the EE frame."""
    C, FT = CF, CF[8:]
    z = np.empty((7, 3))
    o = np.empty((7, 3))
    J = np.empty((6, 7))
    for k in range(Q.shape[0]):
        m = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
        for i in range(7):
            m = _link(m, C[i, 0], C[i, 1], C[i, 2], C[i, 3], Q[k, i])
            z[i, 0], z[i, 1], z[i, 2] = m[2], m[6], m[10]
            o[i, 0], o[i, 1], o[i, 2] = m[3], m[7], m[11]
        T = _tail(m, C[7, 0], FT)
        px, py, pz = T[3], T[7], T[11]
        for i in range(7):
            dx, dy, dz = px - o[i, 0], py - o[i, 1], pz - o[i, 2]
            J[0, i] = z[i, 1] * dz - z[i, 2] * dy
            J[1, i] = z[i, 2] * dx - z[i, 0] * dz
            J[2, i] = z[i, 0] * dy - z[i, 1] * dx
            J[3, i] = z[i, 0]
            J[4, i] = z[i, 1]
            J[5, i] = z[i, 2]
        if body:  # R^T J, R = T[:3, :3]
            for h in (0, 3):
                for i in range(7):
                    a, b, c = J[h, i], J[h + 1, i], J[h + 2, i]
                    for r in range(3):
                        out[k, h + r, i] = T[r] * a + T[4 + r] * b + T[8 + r] * c
        else:
            out[k] = J


# ------------------------------------------------------------------------ inverse kinematics

_OK, _UNREACHABLE, _JOINT_LIMIT, _SINGULAR = _ik.OK, _ik.UNREACHABLE, _ik.JOINT_LIMIT, _ik.SINGULAR
_SH_TOL = _ik.SHOULDER_SINGULAR_TOL
_WR_TOL2 = _ik.WRIST_SINGULAR_TOL * _ik.WRIST_SINGULAR_TOL
_TWO_PI = _ik.TWO_PI


@njit(inline="always", **_OPTS)
def _fail(r0: int, r1: int, code: int, qout: Any, stout: Any) -> None:
    for row in range(r0, r1 + 1):
        stout[row - r0] = code
        for j in range(7):
            qout[row - r0, j] = np.nan


@njit(**_OPTS)
def _solve_pose(
    P: Any, T: Any, q7: float, q1_init: float, r0: int, r1: int, qout: Any, stout: Any
) -> None:
    """Branches r0..r1 of the He-Liu solution for the pose T (4x4 or 3x4 top rows) into
    qout[row - r0] (NaN without a solution) and stout[row - r0]: the equations and tests
    of :func:`panda_py.kinematics._ik.make_scalar_solver`, in the same order."""
    d1, d3, d5, a4, a7, d_e, theta_e = P[0], P[1], P[2], P[3], P[4], P[5], P[6]
    l24, l46, q4_off = P[7], P[8], P[9]
    r00, r01, r02, px = T[0, 0], T[0, 1], T[0, 2], T[0, 3]
    r10, r11, r12, py = T[1, 0], T[1, 1], T[1, 2], T[1, 3]
    r20, r21, r22, pz = T[2, 0], T[2, 1], T[2, 2], T[2, 3]
    if not (P[16] <= q7 <= P[23]):
        _fail(r0, r1, _JOINT_LIMIT, qout, stout)
        return
    psi = q7 + theta_e
    cp, sp = math.cos(psi), math.sin(psi)
    x6x = cp * r00 - sp * r01
    x6y = cp * r10 - sp * r11
    x6z = cp * r20 - sp * r21
    vx = px - d_e * r02 - a7 * x6x
    vy = py - d_e * r12 - a7 * x6y
    vz = pz - d_e * r22 - a7 * x6z - d1
    ll = vx * vx + vy * vy + vz * vz
    h1 = ll - (l24 - l46) ** 2
    h2 = (l24 + l46) ** 2 - ll
    if h1 < 0.0 or h2 < 0.0:
        _fail(r0, r1, _UNREACHABLE, qout, stout)
        return
    q4 = math.atan2(math.sqrt(h1 * h2), (l24 * l24 + l46 * l46) - ll) + q4_off
    if not (P[13] <= q4 <= P[20]):
        _fail(r0, r1, _JOINT_LIMIT, qout, stout)
        return
    c4, s4 = math.cos(q4), math.sin(q4)
    d26 = a4 * s4 - d3 * c4 - d5
    wx = -(x6x * vx + x6y * vy + x6z * vz)
    wy = r02 * vx + r12 * vy + r22 * vz
    rr = wx * wx + wy * wy
    if rr < _WR_TOL2:
        _fail(r0, r1, _SINGULAR, qout, stout)
        return
    h3 = rr - d26 * d26
    if h3 < 0.0:
        _fail(r0, r1, _UNREACHABLE, qout, stout)
        return
    theta = math.atan2(d26, math.sqrt(h3))
    phi = math.atan2(wy, wx)
    t = a4 * math.tan(0.5 * q4) - d5
    last6 = -1
    ok5 = ok6 = False
    q5 = q6 = ux = uy = uz = hxy = x3x = x3y = x3z = 0.0
    for row in range(r0, r1 + 1):
        k = row - r0
        i6 = row >> 1
        if i6 != last6:
            last6 = i6
            q6 = (theta - phi) if i6 else (math.pi - theta - phi)
            if q6 < P[15]:
                q6 += _TWO_PI
            elif q6 > P[22]:
                q6 -= _TWO_PI
            ok6 = P[15] <= q6 <= P[22]
            c6, s6 = math.cos(q6), math.sin(q6)
            z5x = s6 * x6x - c6 * r02
            z5y = s6 * x6y - c6 * r12
            z5z = s6 * x6z - c6 * r22
            ux = vx + t * z5x
            uy = vy + t * z5y
            uz = vz + t * z5z
            hxy = math.sqrt(ux * ux + uy * uy)
            lu = math.sqrt(ux * ux + uy * uy + uz * uz)
            z3x, z3y, z3z = ux / lu, uy / lu, uz / lu
            nx = z3y * vz - z3z * vy
            ny = z3z * vx - z3x * vz
            nz = z3x * vy - z3y * vx
            nn = math.sqrt(nx * nx + ny * ny + nz * nz)
            y3x, y3y, y3z = nx / nn, ny / nn, nz / nn
            x3x = y3y * z3z - y3z * z3y
            x3y = y3z * z3x - y3x * z3z
            x3z = y3x * z3y - y3y * z3x
            x4x, x4y, x4z = c4 * x3x + s4 * z3x, c4 * x3y + s4 * z3y, c4 * x3z + s4 * z3z
            x5x = c6 * x6x + s6 * r02
            x5y = c6 * x6y + s6 * r12
            x5z = c6 * x6z + s6 * r22
            q5 = math.atan2(x5x * y3x + x5y * y3y + x5z * y3z, x5x * x4x + x5y * x4y + x5z * x4z)
            ok5 = P[14] <= q5 <= P[21]
        if not (ok6 and ok5):
            _fail(row, row, _JOINT_LIMIT, qout[k:], stout[k:])
            continue
        if hxy < _SH_TOL:
            q1 = q1_init
        else:
            q1 = math.atan2(uy, ux)
            if row & 1:
                q1 = q1 - math.pi if q1 > 0.0 else q1 + math.pi
        c1, s1 = math.cos(q1), math.sin(q1)
        q2 = math.atan2(c1 * ux + s1 * uy, uz)
        c2, s2 = math.cos(q2), math.sin(q2)
        q3 = math.atan2(c1 * x3y - s1 * x3x, c2 * (c1 * x3x + s1 * x3y) - s2 * x3z)
        if P[10] <= q1 <= P[17] and P[11] <= q2 <= P[18] and P[12] <= q3 <= P[19]:
            stout[k] = _OK
            qout[k, 0] = q1
            qout[k, 1] = q2
            qout[k, 2] = q3
            qout[k, 3] = q4
            qout[k, 4] = q5
            qout[k, 5] = q6
            qout[k, 6] = q7
        else:
            _fail(row, row, _JOINT_LIMIT, qout[k:], stout[k:])


@njit(inline="always", **_OPTS)
def _case_row(q2: float, q5: float) -> int:
    return (2 if math.cos(q5) >= 0.0 else 0) + (1 if q2 < 0.0 else 0)


@njit(inline="always", **_OPTS)
def _valid(T: Any, qi: Any, q7: float) -> bool:
    """T a finite rigid transform (tolerance 1e-6 as ``_input.ROTATION_TOL``), qi and q7
    finite: the checks of the validating path, which gives the message when they fail."""
    tol = 1e-6
    r00, r01, r02 = T[0, 0], T[0, 1], T[0, 2]
    r10, r11, r12 = T[1, 0], T[1, 1], T[1, 2]
    r20, r21, r22 = T[2, 0], T[2, 1], T[2, 2]
    e = (
        abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0),
        abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0),
        abs(r00 * r01 + r10 * r11 + r20 * r21),
        abs(r10 * r21 - r20 * r11 - r02),
        abs(r20 * r01 - r00 * r21 - r12),
        abs(r00 * r11 - r10 * r01 - r22),
        abs(T[3, 0]),
        abs(T[3, 1]),
        abs(T[3, 2]),
        abs(T[3, 3] - 1.0),
    )
    for v in e:
        if not v <= tol:  # also catches NaN
            return False
    s = T[0, 3] + T[1, 3] + T[2, 3] + q7
    for j in range(7):
        s += qi[j]
    return math.isfinite(s)


@njit(**_OPTS)
def ik_one(P: Any, T: Any, qi: Any, q7: float, out: Any) -> bool:
    """One pose T (4, 4), q_init qi (7,), q7: the solution in q_init's case into out (7,)
    (NaN if none). False (nothing written) if the input does not pass :func:`_valid`."""
    if not _valid(T, qi, q7):
        return False
    st = np.empty(1, dtype=np.int8)
    row = _case_row(qi[1], qi[4])
    _solve_pose(P, T, q7, qi[0], row, row, out.reshape((1, 7)), st)
    return True


@njit(**_OPTS)
def ik_full_one(P: Any, T: Any, qi: Any, q7: float, out: Any) -> bool:
    """As :func:`ik_one`, all four branches into out (4, 7)."""
    if not _valid(T, qi, q7):
        return False
    st = np.empty(4, dtype=np.int8)
    _solve_pose(P, T, q7, qi[0], 0, 3, out, st)
    return True


@njit(**_OPTS)
def ik_batch(P: Any, T: Any, QI: Any, q7: Any, qout: Any, stout: Any) -> None:
    """For each pose T[k] (N, 4, 4) the solution in QI[k]'s case (QI (N, 7) or (1, 7)
    broadcast; q7 (N,)) into qout (N, 7), status into stout (N,)."""
    n = T.shape[0]
    bi = QI.shape[0] > 1
    for k in range(n):
        qi = QI[k] if bi else QI[0]
        row = _case_row(qi[1], qi[4])
        _solve_pose(P, T[k], q7[k], qi[0], row, row, qout[k : k + 1], stout[k : k + 1])


@njit(**_OPTS)
def ik_full_batch(P: Any, T: Any, q1_init: Any, q7: Any, qout: Any, stout: Any) -> None:
    """All four branches for each pose T[k] into qout (N, 4, 7), stout (N, 4)."""
    for k in range(T.shape[0]):
        _solve_pose(P, T[k], q7[k], q1_init[k], 0, 3, qout[k], stout[k])


@njit(**_OPTS)
def jacobian_one(q: Any, CF: Any, body: bool, out: Any) -> bool:
    """:func:`jacobian_batch` for one q (7,) into out (1, 6, 7); False if q is not
    finite."""
    s = 0.0
    for i in range(7):
        s += q[i]
    if not math.isfinite(s):
        return False
    jacobian_batch(q.reshape((1, 7)), CF, body, out)
    return True
