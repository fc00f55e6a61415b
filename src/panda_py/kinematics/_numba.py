"""Optional numba kernels for the kinematics (``pip install panda-py[fast]``).

Imported lazily by :mod:`._model` on the first kinematics call that can use it, never at
``import panda_py``; without numba (ImportError) or with ``PANDA_PY_NO_JIT=1`` in the
environment the pure-NumPy paths run instead. The kernels mirror the pure code:

* forward kinematics: the modified-DH product (generic in the table, packed by
  ``_model._pack_chain``), a loop over joints on 12 scalars; frames and Jacobians from it;
* inverse kinematics: :func:`._ik.make_scalar_solver`'s equations line by line, the same
  branch indexing, status precedence and joint-limit tests (parameters packed by
  ``_model._pack_ik``), after the same input check as ``_input.check_rigid``;
* trigonometry from :mod:`._nbmath` (branch-free, within 3 ulp of libm).

One loop per problem (``_fk_range``, ``_ik_range``) serves the single-call, batch and
parallel (``prange`` over chunks, identical per-row arithmetic) kernels, so each is
compiled once. Compiled with ``cache=True`` (numba writes to ``__pycache__`` next to
this file and falls back to compiling in memory if that is not writable); a fresh
install compiles each kernel on its first use (seconds), later processes load them.
numba keys that cache on this file alone: after editing ``_nbmath.py`` or the constants
taken from ``_ik``/``_input`` in a source checkout, delete ``__pycache__/_numba*.nb[ic]``.
Tests hold every kernel equal to the pure path to 1e-12, and batched to looped.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from panda_py.kinematics import _ik
from panda_py.kinematics._input import ROTATION_TOL
from panda_py.kinematics._nbmath import atan2, sincos

_OPTS: dict[str, Any] = {"nogil": True, "error_model": "numpy"}
# The arithmetic helpers may fuse a * b + c into one multiply-add (fastmath "contract":
# one rounding instead of two, no reassociation, nothing assumed about NaN or infinity).
# Every kernel calls the same compiled loop, so batched and single calls stay equal bit
# for bit; the input test (_rigid) keeps NumPy's exact arithmetic.
_ARITH: dict[str, Any] = {**_OPTS, "forceinline": True, "fastmath": {"contract"}}


def njit(**kw: Any) -> Any:
    """numba.njit with cache=True, or without the cache where numba finds no writable
    place for it (it raises RuntimeError at decoration then)."""

    def deco(fn: Any) -> Any:
        try:
            return numba.njit(cache=True, **kw)(fn)
        except RuntimeError:
            return numba.njit(**kw)(fn)

    return deco


def single(name: str) -> Any:
    """The single-call kernel ``name`` (fk_one, ik_one, ik_full_one), compiled (or
    loaded from the cache) on first use for float64 arrays only, C-contiguous (the
    dispatcher's exact match) or of any layout (a conversion, copied in the kernel): it
    then refuses other argument types with a TypeError instead of compiling for them, so
    the callers check only the dtype (numba's TypeError costs ~100 us to word)."""
    kernel = globals()[name]
    if name not in _READY:
        for sig in _SINGLE_SIGNATURES[name]:
            kernel.compile(sig)
        kernel.disable_compile()
        _READY.add(name)
    return kernel


_READY: set[str] = set()


_f8 = numba.float64
_V, _M = _f8[::1], _f8[:, ::1]  # C-contiguous float64 vector and matrix
_VA, _MA = _f8[:], _f8[:, :]  # any layout
_SINGLE_SIGNATURES = {
    "fk_one": [numba.boolean(_V, _M, _M), numba.boolean(_VA, _M, _M)],
    "ik_one": [numba.boolean(_V, _M, _V, _f8, _V), numba.boolean(_V, _MA, _VA, _f8, _V)],
    "ik_full_one": [numba.boolean(_V, _M, _V, _f8, _M), numba.boolean(_V, _MA, _VA, _f8, _M)],
}

# ------------------------------------------------------------------------ forward kinematics


@njit(**_ARITH)
def _link(m: Any, a: float, d: float, ca: float, sa: float, q: float) -> Any:
    """M @ RotX(alpha) TransX(a) RotZ(q) TransZ(d), M the top 3x4 rows as a 12-tuple."""
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


@njit(**_ARITH)
def _tail(m: Any, fd: float, F: Any) -> Any:
    """M @ TransZ(fd) @ F (F the top 3x4 rows of a rigid transform, a 12-tuple), as a
    12-tuple."""
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


_EYE = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)

# As in the ik below, the helpers take scalars and tuples, and only the loops that own
# the arrays read and write them (an array argument costs reference counting per call).


@njit(**_OPTS)
def _fk_range(Q: Any, CF: Any, out: Any, k0: int, k1: int) -> None:
    """O_T_EE for rows k0..k1-1 of Q (N, 7) into out (N, 4, 4). CF (11, 4): per joint
    ``[a, d, cos alpha, sin alpha]``, ``[flange_d, 0, 0, 0]``, then the top 3 rows of the
    flange-to-EE transform."""
    F = (CF[8, 0], CF[8, 1], CF[8, 2], CF[8, 3], CF[9, 0], CF[9, 1], CF[9, 2], CF[9, 3],
         CF[10, 0], CF[10, 1], CF[10, 2], CF[10, 3])  # fmt: skip
    fd = CF[7, 0]
    for k in range(k0, k1):
        m = _EYE
        for i in range(7):
            m = _link(m, CF[i, 0], CF[i, 1], CF[i, 2], CF[i, 3], Q[k, i])
        v = _tail(m, fd, F)
        for i in range(3):
            for j in range(4):
                out[k, i, j] = v[4 * i + j]
        out[k, 3, 0] = 0.0
        out[k, 3, 1] = 0.0
        out[k, 3, 2] = 0.0
        out[k, 3, 3] = 1.0


@njit(**_OPTS)
def fk_one(q: Any, CF: Any, out: Any) -> bool:
    """O_T_EE of q (7,) into out (4, 4); False (out untouched) if q is not finite or not
    of shape (7,)."""
    if q.shape[0] != 7:
        return False
    s = 0.0
    for i in range(7):
        s += q[i]
    if not math.isfinite(s):
        return False
    one = np.int64(1)  # (literals would make numba compile _fk_range again)
    # (a copy only where q is not C-contiguous: decided at compile time)
    Q = np.ascontiguousarray(q).reshape((1, 7))
    _fk_range(Q, CF, out.reshape((1, 4, 4)), one - one, one)
    return True


@njit(**_OPTS)
def fk_batch(Q: Any, CF: Any, out: Any) -> None:
    """O_T_EE for each row of Q (N, 7) into out (N, 4, 4)."""
    n = Q.shape[0]
    _fk_range(Q, CF, out, n - n, n)


# Rows (poses) per parallel work item: enough to make each item's call negligible.
_PAR_CHUNK = 64


@njit(parallel=True, **_OPTS)
def fk_batch_par(Q: Any, CF: Any, out: Any) -> None:
    """:func:`fk_batch` on all cores (the same arithmetic per row)."""
    n = Q.shape[0]
    for c in numba.prange((n + _PAR_CHUNK - 1) // _PAR_CHUNK):
        k0 = np.int64(c) * _PAR_CHUNK  # prange's index is unsigned; keep the rest signed
        _fk_range(Q, CF, out, k0, min(k0 + _PAR_CHUNK, n))


@njit(**_OPTS)
def frames_batch(Q: Any, CF: Any, out: Any) -> None:
    """J1..J7, flange, EE for each row of Q into out (N, 9, 4, 4)."""
    F = (CF[8, 0], CF[8, 1], CF[8, 2], CF[8, 3], CF[9, 0], CF[9, 1], CF[9, 2], CF[9, 3],
         CF[10, 0], CF[10, 1], CF[10, 2], CF[10, 3])  # fmt: skip
    fd = CF[7, 0]
    for k in range(Q.shape[0]):
        m = _EYE
        for f in range(9):
            if f < 7:
                m = _link(m, CF[f, 0], CF[f, 1], CF[f, 2], CF[f, 3], Q[k, f])
                v = m
            else:
                v = _tail(m, fd, _EYE if f == 7 else F)
            for i in range(3):
                for j in range(4):
                    out[k, f, i, j] = v[4 * i + j]
            out[k, f, 3, 0] = 0.0
            out[k, f, 3, 1] = 0.0
            out[k, f, 3, 2] = 0.0
            out[k, f, 3, 3] = 1.0


@njit(**_OPTS)
def jacobian_batch(Q: Any, CF: Any, body: bool, out: Any) -> None:
    """Geometric EE Jacobian (rows v, w) for each row of Q into out (N, 6, 7), in the
    base frame or (body) in the EE frame."""
    F = (CF[8, 0], CF[8, 1], CF[8, 2], CF[8, 3], CF[9, 0], CF[9, 1], CF[9, 2], CF[9, 3],
         CF[10, 0], CF[10, 1], CF[10, 2], CF[10, 3])  # fmt: skip
    z = np.empty((7, 3))
    o = np.empty((7, 3))
    J = np.empty((6, 7))
    for k in range(Q.shape[0]):
        m = _EYE
        for i in range(7):
            m = _link(m, CF[i, 0], CF[i, 1], CF[i, 2], CF[i, 3], Q[k, i])
            z[i, 0], z[i, 1], z[i, 2] = m[2], m[6], m[10]
            o[i, 0], o[i, 1], o[i, 2] = m[3], m[7], m[11]
        T = _tail(m, CF[7, 0], F)
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


# ------------------------------------------------------------------------ inverse kinematics

_OK, _UNREACHABLE, _JOINT_LIMIT, _SINGULAR = _ik.OK, _ik.UNREACHABLE, _ik.JOINT_LIMIT, _ik.SINGULAR
# Status of a pose that fails the input checks (the caller raises; nothing was solved).
INVALID = -1
_SH_TOL = _ik.SHOULDER_SINGULAR_TOL
_WR_TOL2 = _ik.WRIST_SINGULAR_TOL * _ik.WRIST_SINGULAR_TOL
_TWO_PI = _ik.TWO_PI
_PI = math.pi
_PIO2 = math.pi / 2
_ROT_TOL = ROTATION_TOL


_NAN7 = (math.nan,) * 7
_ZERO15 = (0.0,) * 15
_NO_ARM = (False, False, 0.0, 0.0, 0.0, 0.0, 0.0)

# The solver below works on scalars and tuples only: a numba function that takes an
# array counts references on entry and exit (atomic operations, per pose and branch),
# so the arrays are read and written in _ik_range alone. P (see _model._pack_ik) is
# passed as a tuple.


@njit(forceinline=True, **_OPTS)
def _flip(a: float) -> float:
    return a - _PI if a > 0.0 else a + _PI


@njit(**_ARITH)
def _pose_part(
    P: Any, r00: float, r01: float, r02: float, r10: float, r11: float, r12: float,
    r20: float, r21: float, r22: float, px: float, py: float, pz: float, q7: float,
) -> Any:  # fmt: skip
    """The part of :func:`panda_py.kinematics._ik.make_scalar_solver` shared by all four
    branches: (status, (x6x, x6y, x6z, vx, vy, vz, q4, c4, s4, d26, sh3, wx, wy, irr, t)),
    the tests in the same order (a status other than OK: no branch has a solution)."""
    d1, d3, d5, a4, a7, d_e, theta_e = P[0], P[1], P[2], P[3], P[4], P[5], P[6]
    l24, l46, q4_off = P[7], P[8], P[9]
    if not (P[16] <= q7 <= P[23]):
        return _JOINT_LIMIT, _ZERO15
    sp, cp = sincos(q7 + theta_e)
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
        return _UNREACHABLE, _ZERO15
    y4 = math.sqrt(h1 * h2)
    x4 = (l24 * l24 + l46 * l46) - ll
    q4 = atan2(y4, x4) + q4_off
    if not (P[13] <= q4 <= P[20]):
        return _JOINT_LIMIT, _ZERO15
    ca, sa = x4 * P[26], y4 * P[26]
    c_off, s_off = P[24], P[25]
    c4, s4 = ca * c_off - sa * s_off, sa * c_off + ca * s_off
    d26 = a4 * s4 - d3 * c4 - d5
    wx = -(x6x * vx + x6y * vy + x6z * vz)
    wy = r02 * vx + r12 * vy + r22 * vz
    rr = wx * wx + wy * wy
    if rr < _WR_TOL2:
        return _SINGULAR, _ZERO15
    h3 = rr - d26 * d26
    if h3 < 0.0:
        return _UNREACHABLE, _ZERO15
    t = a4 * (s4 / (1.0 + c4) if c4 >= 0.0 else (1.0 - c4) / s4) - d5
    g = (x6x, x6y, x6z, vx, vy, vz, q4, c4, s4, d26, math.sqrt(h3), wx, wy, 1.0 / rr, t)
    return _OK, g


@njit(**_ARITH)
def _arm_part(P: Any, g: Any, r02: float, r12: float, r22: float, q1_init: float, i6: int) -> Any:
    """q6 branch i6 of the solver: (ok, shoulder singular, q5, q6, q1, q2, q3) with
    q1..q3 those of the q2 >= 0 row (the other row flips them, unless singular)."""
    x6x, x6y, x6z, vx, vy, vz, _q4, c4, s4, d26, sh3, wx, wy, irr, t = g
    if i6:
        cn, sn = sh3 * wx + d26 * wy, d26 * wx - sh3 * wy
    else:
        cn, sn = d26 * wy - sh3 * wx, d26 * wx + sh3 * wy
    q6 = atan2(sn, cn)
    if q6 < P[15]:
        q6 += _TWO_PI
    elif q6 > P[22]:
        q6 -= _TWO_PI
    if not (P[15] <= q6 <= P[22]):
        return _NO_ARM
    c6, s6 = cn * irr, sn * irr
    ux = vx + t * (s6 * x6x - c6 * r02)
    uy = vy + t * (s6 * x6y - c6 * r12)
    uz = vz + t * (s6 * x6z - c6 * r22)
    x5x = c6 * x6x + s6 * r02
    x5y = c6 * x6y + s6 * r12
    x5z = c6 * x6z + s6 * r22
    mx = uy * vz - uz * vy
    my = uz * vx - ux * vz
    mz = ux * vy - uy * vx
    bx = my * uz - mz * uy
    by = mz * ux - mx * uz
    bz = mx * uy - my * ux
    huu = ux * ux + uy * uy
    lu = math.sqrt(huu + uz * uz)
    mm = math.sqrt(mx * mx + my * my + mz * mz)
    hxy = math.sqrt(huu)
    q5 = atan2(
        lu * (x5x * mx + x5y * my + x5z * mz),
        c4 * (x5x * bx + x5y * by + x5z * bz) + s4 * mm * (x5x * ux + x5y * uy + x5z * uz),
    )
    if not (mm > 0.0 and P[14] <= q5 <= P[21]):
        return _NO_ARM
    if hxy < _SH_TOL:  # q1 undefined: q_init's, for both shoulder branches
        s1, c1 = sincos(q1_init)
        q2 = atan2(c1 * ux + s1 * uy, uz)
        s2, c2 = sincos(q2)
        q3 = atan2(c1 * by - s1 * bx, c2 * (c1 * bx + s1 * by) - s2 * bz)
        return True, True, q5, q6, q1_init, q2, q3
    q1 = atan2(uy, ux)
    q2 = atan2(hxy, uz)
    q3 = atan2(lu * (ux * by - uy * bx), uz * (ux * bx + uy * by) - huu * bz)
    return True, False, q5, q6, q1, q2, q3


@njit(**_ARITH)
def _row(P: Any, arm: Any, i1: int, q4: float, q7: float) -> Any:
    """(status, q (7-tuple, NaN without a solution)) of shoulder branch i1 of an arm."""
    ok, singular, q5, q6, q1, q2, q3 = arm
    if not ok:
        return _JOINT_LIMIT, _NAN7
    if i1 and not singular:
        q1, q2, q3 = _flip(q1), -q2, _flip(q3)
    if P[10] <= q1 <= P[17] and P[11] <= q2 <= P[18] and P[12] <= q3 <= P[19]:
        return _OK, (q1, q2, q3, q4, q5, q6, q7)
    return _JOINT_LIMIT, _NAN7


@njit(forceinline=True, **_OPTS)
def _case_row(q2: float, q5: float) -> int:
    """The branch of a configuration (``_model._case_row``). Within |q5| <= 3 rad,
    cos(q5) >= 0 exactly when |q5| <= pi/2 rounded down (cos(1.5707963267948966) is
    +6e-17, cos of the next float up negative): a comparison instead of a cosine."""
    a = abs(q5)
    c = a <= _PIO2 if a <= 3.0 else math.cos(q5) >= 0.0
    return (2 if c else 0) + (1 if q2 < 0.0 else 0)


@njit(forceinline=True, **_OPTS)
def _rigid(
    r00: float, r01: float, r02: float, r10: float, r11: float, r12: float, r20: float,
    r21: float, r22: float, l0: float, l1: float, l2: float, l3: float,
) -> bool:  # fmt: skip
    """The test of ``_input.check_rigid`` (unit orthogonal x and y columns, z = x cross y,
    last row 0 0 0 1, each within ROTATION_TOL) in the same arithmetic; NaN fails it.
    The comparisons are combined without branches."""
    tol = _ROT_TOL
    return (
        (abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0) <= tol)
        & (abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0) <= tol)
        & (abs(r00 * r01 + r10 * r11 + r20 * r21) <= tol)
        & (abs(r10 * r21 - r20 * r11 - r02) <= tol)
        & (abs(r20 * r01 - r00 * r21 - r12) <= tol)
        & (abs(r00 * r11 - r10 * r01 - r22) <= tol)
        & (abs(l0) <= tol)
        & (abs(l1) <= tol)
        & (abs(l2) <= tol)
        & (abs(l3 - 1.0) <= tol)
    )


@njit(**_OPTS)
def _ik_range(
    P: Any,
    T: Any,
    QI: Any,
    q7: Any,
    q7s: float,
    full: bool,
    qout: Any,
    stout: Any,
    k0: int,
    k1: int,
) -> None:
    """Poses k0..k1-1 of T (N, 4, 4), with q_init QI[k] (QI (N, 7) or (1, 7)) and q7[k]
    (q7 (N,) or (1,), or q7s if q7 is empty): all four branches (``full``) into rows
    4k..4k+3 of qout (4N, 7) and stout (4N,), or the one in q_init's case into row k of
    qout (N, 7), stout (N,). A pose that is not a finite rigid transform, or whose q_init
    or q7 is not finite, gets the status :data:`INVALID` in its first row and is not
    solved. Every kernel runs this loop, so the solver is compiled once."""
    Pt = (P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[7], P[8], P[9], P[10], P[11], P[12],
          P[13], P[14], P[15], P[16], P[17], P[18], P[19], P[20], P[21], P[22], P[23],
          P[24], P[25], P[26])  # fmt: skip
    m7 = q7.shape[0]
    for k in range(k0, k1):
        qrow = k if QI.shape[0] > 1 else 0
        q7k = q7[k] if m7 > 1 else (q7[0] if m7 == 1 else q7s)
        base = 4 * k if full else k
        r00, r01, r02, px = T[k, 0, 0], T[k, 0, 1], T[k, 0, 2], T[k, 0, 3]
        r10, r11, r12, py = T[k, 1, 0], T[k, 1, 1], T[k, 1, 2], T[k, 1, 3]
        r20, r21, r22, pz = T[k, 2, 0], T[k, 2, 1], T[k, 2, 2], T[k, 2, 3]
        q1i, q2i, q5i = QI[qrow, 0], QI[qrow, 1], QI[qrow, 4]
        finite = q7k + px + py + pz + q1i + q2i + QI[qrow, 2] + QI[qrow, 3] + q5i
        finite += QI[qrow, 5] + QI[qrow, 6]
        rigid = _rigid(
            r00, r01, r02, r10, r11, r12, r20, r21, r22, T[k, 3, 0], T[k, 3, 1], T[k, 3, 2],
            T[k, 3, 3],
        )  # fmt: skip
        if not (rigid & math.isfinite(finite)):
            stout[base] = INVALID
            continue
        status, g = _pose_part(Pt, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7k)
        first = 0 if full else _case_row(q2i, q5i)
        arm = _NO_ARM
        for r in range(4 if full else 1):
            row = first + r
            if status != _OK:
                code, qv = status, _NAN7
            else:
                if r == 0 or not row & 1:  # a new q6 branch
                    arm = _arm_part(Pt, g, r02, r12, r22, q1i, row >> 1)
                code, qv = _row(Pt, arm, row & 1, g[6], q7k)
            stout[base + r] = code
            for c in range(7):
                qout[base + r, c] = qv[c]


@njit(forceinline=True, **_OPTS)
def _ik_single(P: Any, T: Any, qi: Any, q7: float, full: bool, out: Any) -> bool:
    if T.shape[0] != 4 or T.shape[1] != 4 or qi.shape[0] != 7:
        return False
    st = np.empty(4 if full else 1, dtype=np.int8)
    Q = out.reshape((4 if full else 1, 7))
    one = np.int64(1)  # (literal 0 and 1 would make numba compile _ik_range again)
    # (copies only where T or qi is not C-contiguous: decided at compile time)
    QI = np.ascontiguousarray(qi).reshape((1, 7))
    T3 = np.ascontiguousarray(T).reshape((1, 4, 4))
    _ik_range(P, T3, QI, QI[0, :0], q7, full, Q, st, one - one, one)
    return st[0] != INVALID


@njit(**_OPTS)
def ik_one(P: Any, T: Any, qi: Any, q7: float, out: Any) -> bool:
    """One pose T (4, 4), q_init qi (7,), q7: the solution in q_init's case into out (7,)
    (NaN if none). False if the input is not finite and rigid (see :func:`_ik_range`)
    or has the wrong shape (see :func:`single` for the types)."""
    # full computed (not the literal False): one compiled _ik_range serves every caller
    return _ik_single(P, T, qi, q7, out.size == 28, out)


@njit(**_OPTS)
def ik_full_one(P: Any, T: Any, qi: Any, q7: float, out: Any) -> bool:
    """As :func:`ik_one`, all four branches into out (4, 7)."""
    return _ik_single(P, T, qi, q7, out.size == 28, out)


@njit(**_OPTS)
def ik_batch(P: Any, T: Any, QI: Any, q7: Any, full: bool, qout: Any, stout: Any) -> None:
    """For each pose T[k] (N, 4, 4): with ``full`` all four branches into qout (N, 4, 7)
    and stout (N, 4), else the one in QI[k]'s case into qout (N, 7), stout (N,). QI
    (N, 7) or (1, 7) and q7 (N,) or (1,) broadcast. An invalid pose (see :func:`_ik_range`)
    gets the status :data:`INVALID` (in stout[k, 0] for ``full``) and is not solved."""
    n = T.shape[0]
    m = 4 * n if full else n
    _ik_range(P, T, QI, q7, 0.0, full, qout.reshape((m, 7)), stout.reshape(m), n - n, n)


@njit(parallel=True, **_OPTS)
def ik_batch_par(P: Any, T: Any, QI: Any, q7: Any, full: bool, qout: Any, stout: Any) -> None:
    """:func:`ik_batch` on all cores (the same arithmetic per pose)."""
    n = T.shape[0]
    m = 4 * n if full else n
    Q, S = qout.reshape((m, 7)), stout.reshape(m)
    for c in numba.prange((n + _PAR_CHUNK - 1) // _PAR_CHUNK):
        k0 = np.int64(c) * _PAR_CHUNK  # prange's index is unsigned; keep the rest signed
        _ik_range(P, T, QI, q7, 0.0, full, Q, S, k0, min(k0 + _PAR_CHUNK, n))
