"""The Cartesian impedance law compiled by numba, on the loop's arrays (no temporaries
the caller sees): panda-py's ``CartesianImpedance`` torque in one call of a few
microseconds, where the same NumPy expressions take 50-60 us. The plain version in
:mod:`.laws` stays the reference (tests hold them together).

Imported on first use unless ``PANDA_PY_NO_JIT=1`` or numba is missing; compiled once
per machine and cached on disk under a key over this file (:mod:`panda_py.jit.cache`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from panda_py.jit import cache, stack
from panda_py.jit.stack import stack_array

__all__ = [
    "cartesian_impedance_torque",
    "finalize_torques",
    "impedance_torque",
    "joint_scales",
    "mass_damping",
    "pose_filter",
    "pose_target_outputs",
    "pose_tracking_torque",
]

# the compile cache's key: the kernels compile this file and the stack arrays' helper
# (panda_py.jit.cache)
KEY = cache.source_key([Path(__file__), Path(stack.__file__)])

PINV_DAMPING = 0.01  # as laws.PINV_DAMPING


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def joint_scales(J, Ft, Fr, lateral, vt, vr, at, ar, dq_max, ddq_max):  # type: ignore[no-untyped-def,unused-ignore]
    """``controllers.moves.joint_capped``'s factors with the generator's frames: the
    largest scales (<= 1) of the Cartesian velocity (``vt``, ``vr``: the norms' limits of
    the translation and the rotation) and acceleration (``at``, ``ar``) limits under which
    ``J^+`` asks no joint for more than ``dq_max`` and ``ddq_max``; each frame's first axis
    gets the whole limit, the two others ``lateral`` of it."""
    P = stack_array(42).reshape((6, 7))
    _damped_pinv_T(J, P)  # P[k, i] = J^+[i, k]
    sv = 1.0
    sa = 1.0
    for i in range(7):
        t = 0.0
        r = 0.0
        for c in range(3):
            st = 0.0
            sr = 0.0
            for k in range(3):
                st += P[k, i] * Ft[k, c]
                sr += P[3 + k, i] * Fr[k, c]
            w = 1.0 if c == 0 else lateral
            t += abs(st) * w
            r += abs(sr) * w
        v = max(t * vt + r * vr, 1e-12)
        a = max(t * at + r * ar, 1e-12)
        sv = min(sv, dq_max[i] / v)
        sa = min(sa, ddq_max[i] / a)
    return sv, sa


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _quat_from_rotation(R, out):  # type: ignore[no-untyped-def,unused-ignore]
    """Unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0.0:
        s = 2.0 * math.sqrt(tr + 1.0)
        out[3] = 0.25 * s
        out[0] = (R[2, 1] - R[1, 2]) / s
        out[1] = (R[0, 2] - R[2, 0]) / s
        out[2] = (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        out[3] = (R[2, 1] - R[1, 2]) / s
        out[0] = 0.25 * s
        out[1] = (R[0, 1] + R[1, 0]) / s
        out[2] = (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        out[3] = (R[0, 2] - R[2, 0]) / s
        out[0] = (R[0, 1] + R[1, 0]) / s
        out[1] = 0.25 * s
        out[2] = (R[1, 2] + R[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        out[3] = (R[1, 0] - R[0, 1]) / s
        out[0] = (R[0, 2] + R[2, 0]) / s
        out[1] = (R[1, 2] + R[2, 1]) / s
        out[2] = 0.25 * s
    n = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    for k in range(4):
        out[k] /= n


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _cholesky(A, L):  # type: ignore[no-untyped-def,unused-ignore]
    """The lower triangle ``L`` (n, n; its upper part left as it is) of the symmetric
    positive definite ``A = L L^T``."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _forward_solve(L, B, Y):  # type: ignore[no-untyped-def,unused-ignore]
    """``Y = L^-1 B`` (n, m) for the lower triangular ``L`` (n, n), by forward
    substitution."""
    n = L.shape[0]
    for c in range(B.shape[1]):
        for i in range(n):
            s = B[i, c]
            for k in range(i):
                s -= L[i, k] * Y[k, c]
            Y[i, c] = s / L[i, i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _damped_gram_factor(J, L):  # type: ignore[no-untyped-def,unused-ignore]
    """The Cholesky factor ``L`` (6, 6: its lower triangle, all the solves read) of ``J J^T
    + lambda^2 I`` (symmetric positive definite). Loops: numba's @ calls BLAS, dearer
    here; the temporaries on the stack (jit.stack)."""
    A = stack_array(36).reshape((6, 6))
    for i in range(6):
        for j in range(i + 1):
            s = 0.0
            for c in range(J.shape[1]):
                s += J[i, c] * J[j, c]
            A[i, j] = s
            A[j, i] = s
        A[i, i] += PINV_DAMPING * PINV_DAMPING
    _cholesky(A, L)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _damped_pinv_T(J, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``(J J^T + lambda^2 I)^-1 J`` (6x7) into ``out``, by Cholesky (symmetric positive
    definite): the damped pseudo-inverse of J^T."""
    L = stack_array(36).reshape((6, 6))
    _damped_gram_factor(J, L)
    Y = stack_array(42).reshape((6, 7))  # solve L L^T x = J: L y = J, then L^T x = y
    _forward_solve(L, J, Y)
    for c in range(J.shape[1]):
        for i in range(5, -1, -1):
            s = Y[i, c]
            for k in range(i + 1, 6):
                s -= L[k, i] * out[k, c]
            out[i, c] = s / L[i, i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _wrench(O_T_EE, J, dq, p_d, quat_d, v_d, K, D, err, F):  # type: ignore[no-untyped-def,unused-ignore]
    """The pose error ``e`` (laws.cartesian_error) into ``err`` (6,) and the impedance's
    wrench ``-K e - D (J dq - v_d)`` into ``F`` (6,)."""
    R = stack_array(9).reshape((3, 3))
    for r in range(3):
        for c in range(3):
            R[r, c] = O_T_EE[4 * c + r]
    quat = stack_array(4)
    _quat_from_rotation(R, quat)
    if quat_d[0] * quat[0] + quat_d[1] * quat[1] + quat_d[2] * quat[2] + quat_d[3] * quat[3] < 0.0:
        for k in range(4):
            quat[k] = -quat[k]
    x, y, z, w = quat[0], quat[1], quat[2], quat[3]
    xd, yd, zd, wd = quat_d[0], quat_d[1], quat_d[2], quat_d[3]
    ex = w * xd - x * wd - (y * zd - z * yd)
    ey = w * yd - y * wd - (z * xd - x * zd)
    ez = w * zd - z * wd - (x * yd - y * xd)
    err[0] = O_T_EE[12] - p_d[0]
    err[1] = O_T_EE[13] - p_d[1]
    err[2] = O_T_EE[14] - p_d[2]
    for r in range(3):
        err[3 + r] = -(R[r, 0] * ex + R[r, 1] * ey + R[r, 2] * ez)
    v = stack_array(6)
    for k in range(6):
        acc = -v_d[k]
        for c in range(7):
            acc += J[k, c] * dq[c]
        v[k] = acc
    for k in range(6):
        acc = 0.0
        for c in range(6):
            acc -= K[k, c] * err[c] + D[k, c] * v[c]
        F[k] = acc


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def impedance_torque(O_T_EE, J, q, dq, p_d, quat_d, v_d, K, D, q_n, k_n, tau, err, J_pinv):  # type: ignore[no-untyped-def,unused-ignore]
    """``tau = J^T (-K e - D (J dq - v_d)) + N (k_n (q_n - q) - 2 sqrt(k_n) dq)`` into
    ``tau`` (7,), with ``e`` (panda-py's Cartesian error, laws.cartesian_error) into ``err``
    (6,) and the damped pseudo-inverse of J (laws.damped_pinv) into ``J_pinv`` (7, 6); ``N``
    is the damped nullspace projector (laws.nullspace_projector). No Coriolis term (the
    caller adds it). ``O_T_EE`` flat column-major (16,)."""
    F = stack_array(6)
    _wrench(O_T_EE, J, dq, p_d, quat_d, v_d, K, D, err, F)
    P = stack_array(42).reshape((6, 7))
    _damped_pinv_T(J, P)
    for i in range(7):
        for k in range(6):
            J_pinv[i, k] = P[k, i]
    s = 2.0 * math.sqrt(k_n)
    u = stack_array(7)
    for i in range(7):
        u[i] = k_n * (q_n[i] - q[i]) - s * dq[i]
    Pu = stack_array(6)
    for k in range(6):
        acc = 0.0
        for c in range(7):
            acc += P[k, c] * u[c]
        Pu[k] = acc
    for i in range(7):  # J^T F + u - (J^T pinv(J^T)) u
        acc = u[i]
        for k in range(6):
            acc += J[k, i] * (F[k] - Pu[k])
        tau[i] = acc


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def cartesian_impedance_torque(O_T_EE, J, q, dq, p_d, quat_d, K, Kd, q_n, k_n, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """:func:`impedance_torque` toward a pose at rest (panda-py's ``CartesianImpedance``),
    without the pseudo-inverse itself: its product with the nullspace torque ``u`` is
    ``(J J^T + lambda^2 I)^-1 (J u)``, one solve where the pseudo-inverse takes seven."""
    v_d = stack_array(6)
    for k in range(6):
        v_d[k] = 0.0
    err = stack_array(6)
    F = stack_array(6)
    _wrench(O_T_EE, J, dq, p_d, quat_d, v_d, K, Kd, err, F)
    s = 2.0 * math.sqrt(k_n)
    u = stack_array(7)
    for i in range(7):
        u[i] = k_n * (q_n[i] - q[i]) - s * dq[i]
    L = stack_array(36).reshape((6, 6))
    _damped_gram_factor(J, L)
    y = stack_array(6)  # L y = J u, then L^T Pu = y
    for i in range(6):
        acc = 0.0
        for c in range(7):
            acc += J[i, c] * u[c]
        for k in range(i):
            acc -= L[i, k] * y[k]
        y[i] = acc / L[i, i]
    Pu = stack_array(6)
    for i in range(5, -1, -1):
        acc = y[i]
        for k in range(i + 1, 6):
            acc -= L[k, i] * Pu[k]
        Pu[i] = acc / L[i, i]
    for i in range(7):  # J^T F + u - (J^T pinv(J^T)) u
        acc = u[i]
        for k in range(6):
            acc += J[k, i] * (F[k] - Pu[k])
        tau[i] = acc


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def finalize_torques(tau, q, dq, tau_J_d, walls, scale, flags, dtau_max, tau_max, gain, out):  # type: ignore[no-untyped-def,unused-ignore]
    """What the loop does to every law's torques, in one call: panda-py's joint walls
    (``laws.JointWalls.torques``, the reference: ``walls`` holds per joint lower, upper,
    PD width, D width, PD stiffness, PD damping, D damping; ``scale`` and ``flags``, the
    walls' state, are updated in place: flags[i] = 1 while joint i moves in a shrunken
    zone, flags[7] = 1 once initialised), the torque-rate saturation around ``tau_J_d``
    (``dtau_max`` per tick), the torque limits and libfranka's low-pass filter from
    ``tau_J_d`` with ``gain`` (1: none). Writes ``out``; False if a torque, the law's or
    the result, is not finite."""
    init = flags[7] != 0
    finite = True
    for i in range(7):
        qi, dqi = q[i], dq[i]
        lower, upper = walls[i, 0], walls[i, 1]
        pd_w, d_w = walls[i, 2], walls[i, 3]
        width = pd_w + d_w
        motion = 0
        if qi < lower + width:
            motion = -2 if dqi <= 0.0 else -1
        elif qi > upper - width:
            motion = 2 if dqi >= 0.0 else 1
        if not init:
            if motion != 0:
                limit = lower if motion < 0 else upper
                scale[i] = min(1.0, abs(qi - limit) / width)
                flags[i] = 1
        elif flags[i] != 0:
            if motion == 0:
                flags[i] = 0
                scale[i] = 1.0
            elif motion == 1 or motion == -1:
                limit = lower if motion < 0 else upper
                scale[i] = min(1.0, max(scale[i], abs(qi - limit) / width))
        s = scale[i]
        d_max = upper - s * width
        pd_max = upper - s * pd_w
        d_min = lower + s * width
        pd_min = lower + s * pd_w
        wall = 0.0
        if d_max <= qi <= pd_max or pd_min <= qi <= d_min:
            wall = -walls[i, 6] * dqi
        elif qi > pd_max:
            wall = -walls[i, 5] * dqi + walls[i, 4] * (pd_max - qi)
        elif qi < pd_min:
            wall = -walls[i, 5] * dqi + walls[i, 4] * (pd_min - qi)
        if not math.isfinite(tau[i]):  # the law's own torque: saturating it would hide it
            finite = False
        v = tau[i] + wall
        d = v - tau_J_d[i]
        if d > dtau_max:
            d = dtau_max
        elif d < -dtau_max:
            d = -dtau_max
        v = tau_J_d[i] + d
        m = tau_max[i]
        if v > m:
            v = m
        elif v < -m:
            v = -m
        if gain != 1.0:
            v = tau_J_d[i] + gain * (v - tau_J_d[i])
        out[i] = v
        if not math.isfinite(v):
            finite = False
    flags[7] = 1
    return finite


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def pose_tracking_torque(  # type: ignore[no-untyped-def,unused-ignore]
    O_T_EE, J, J_prev, q, dq, dt, p_d, quat_d, v_d, a_d, K, D, q_n, k_n, M, armature,
    coulomb, viscous, friction_speed, error_rate, tau, err, J_pinv,
):  # fmt: skip
    """A Cartesian reference's tracking torque in one call (the reference:
    ``tracking.PoseImpedance.torque``'s NumPy branch): :func:`impedance_torque` toward the
    reference pose ``p_d``, ``quat_d`` moving at ``v_d``, plus its feed-forward: ``(M +
    diag(armature)) J^+ (a_d - dJ dq)``, the links' mass matrix ``M`` and the drives'
    reflected rotor inertia, with ``dJ = (J - J_prev) / dt`` (left out when ``dt`` is 0),
    and the drives' dry friction along the joint velocity that follows the reference and
    closes the error at ``error_rate`` [1/s], ``coulomb tanh(J^+ (v_d - error_rate err) /
    friction_speed)``, and their viscous friction along the reference's joint velocities,
    ``viscous J^+ v_d``. Into ``tau`` (7,), ``err`` (6,) and ``J_pinv`` (7, 6)."""
    impedance_torque(O_T_EE, J, q, dq, p_d, quat_d, v_d, K, D, q_n, k_n, tau, err, J_pinv)
    a = stack_array(6)
    for r in range(6):
        s = a_d[r]
        if dt > 0.0:
            d = 0.0
            for c in range(7):
                d += (J[r, c] - J_prev[r, c]) * dq[c]
            s -= d / dt
        a[r] = s
    ddq = stack_array(7)
    dq_d = stack_array(7)
    dq_v = stack_array(7)
    for i in range(7):
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        for k in range(6):
            s1 += J_pinv[i, k] * a[k]
            s2 += J_pinv[i, k] * (v_d[k] - error_rate * err[k])
            s3 += J_pinv[i, k] * v_d[k]
        ddq[i] = s1
        dq_d[i] = s2
        dq_v[i] = s3
    for i in range(7):
        f = armature[i] * ddq[i]
        for c in range(7):
            f += M[i, c] * ddq[c]
        tau[i] += f + coulomb[i] * math.tanh(dq_d[i] / friction_speed) + viscous[i] * dq_v[i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _ema(filtered, target, alpha):  # type: ignore[no-untyped-def,unused-ignore]
    f = filtered.reshape(-1)
    t = target.reshape(-1)
    if alpha >= 1.0:
        for i in range(f.size):
            f[i] = t[i]
    else:
        for i in range(f.size):
            f[i] += alpha * (t[i] - f[i])


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def pose_filter(alpha, K, K_t, Kd, Kd_t, p, p_t, q_n, q_n_t, quat, quat_t):  # type: ignore[no-untyped-def,unused-ignore]
    """``CartesianImpedance``'s input filter in place (the reference: laws.ema on the
    stiffness, damping, position and nullspace pose, laws.slerp on the orientation)."""
    _ema(K, K_t, alpha)
    _ema(Kd, Kd_t, alpha)
    _ema(p, p_t, alpha)
    _ema(q_n, q_n_t, alpha)
    x0, y0, z0, w0 = quat[0], quat[1], quat[2], quat[3]
    x1, y1, z1, w1 = quat_t[0], quat_t[1], quat_t[2], quat_t[3]
    if alpha >= 1.0:
        o0, o1, o2, o3 = x1, y1, z1, w1
    else:
        d = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
        if d < 0.0:
            x1, y1, z1, w1, d = -x1, -y1, -z1, -w1, -d
        if d > 1.0 - 1e-9:
            a0, a1 = 1.0 - alpha, alpha
        else:
            theta = math.acos(d)
            st = math.sin(theta)
            a0, a1 = math.sin((1.0 - alpha) * theta) / st, math.sin(alpha * theta) / st
        o0, o1 = a0 * x0 + a1 * x1, a0 * y0 + a1 * y1
        o2, o3 = a0 * z0 + a1 * z1, a0 * w0 + a1 * w1
    n = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2 + o3 * o3)
    quat[0], quat[1], quat[2], quat[3] = o0 / n, o1 / n, o2 / n, o3 / n


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _symmetric_eigen(A, w, V):  # type: ignore[no-untyped-def,unused-ignore]
    """Eigenvalues into ``w`` (n,) and eigenvectors (columns) into ``V`` (n, n) of the
    symmetric ``A`` (n, n; overwritten), by cyclic Jacobi rotations until the off-diagonal
    is below 1e-15 of the diagonal (a few sweeps for the 6x6 matrices here: loops, where
    LAPACK's eigh through numba cost several calls and allocations)."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            V[i, j] = 1.0 if i == j else 0.0
    for _ in range(50):
        off = 0.0
        diag = 0.0
        for i in range(n):
            diag += A[i, i] * A[i, i]
            for j in range(i + 1, n):
                off += A[i, j] * A[i, j]
        if off <= 1e-30 * diag or off == 0.0:
            break
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                if abs(theta) > 1e150:  # theta squared would overflow
                    t = 0.5 / theta
                else:
                    t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                    if theta < 0.0:
                        t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(n):  # A J (columns p, q)
                    akp, akq = A[k, p], A[k, q]
                    A[k, p] = c * akp - sn * akq
                    A[k, q] = sn * akp + c * akq
                for k in range(n):  # J^T (A J) (rows p, q)
                    apk, aqk = A[p, k], A[q, k]
                    A[p, k] = c * apk - sn * aqk
                    A[q, k] = sn * apk + c * aqk
                for k in range(n):  # V J
                    vkp, vkq = V[k, p], V[k, q]
                    V[k, p] = c * vkp - sn * vkq
                    V[k, q] = sn * vkp + c * vkq
    for i in range(n):
        w[i] = A[i, i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _product(A, B, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``out = A B`` (written out: numba's ``@`` calls BLAS, dearer for these sizes)."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            acc = 0.0
            for k in range(A.shape[1]):
                acc += A[i, k] * B[k, j]
            out[i, j] = acc


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _sandwich(A, B, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``out = A B A`` for 6x6 ``A``, ``B``."""
    T = stack_array(36).reshape((6, 6))
    _product(B, A, T)
    _product(A, T, out)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def mass_damping(K, zeta, M, armature, J, min_eig, D):  # type: ignore[no-untyped-def,unused-ignore]
    """Into ``D`` (6, 6): the Cartesian damping that gives the stiffness ``K`` the damping
    ratio ``zeta`` on the end effector's inertia ``Lambda = (J (M + diag(armature))^-1
    J^T)^-1``: ``D = 2 zeta S (S^-1 K S^-1)^(1/2) S`` with ``S = Lambda^(1/2)`` (for one
    axis ``2 zeta sqrt(K Lambda)``; positive semi-definite by construction). The
    eigenvalues of ``Lambda^-1`` are kept >= ``min_eig``, so a singular configuration's
    unbounded inertia stays bounded (the reference: ``tracking.mass_damping``). In loops:
    a Cholesky solve and Jacobi's eigenvalues (:func:`_symmetric_eigen`), no BLAS or
    LAPACK call (each cost the loop's tick more than this arithmetic)."""
    Md = stack_array(49).reshape((7, 7))  # the driven inertia M + diag(armature) = L L^T
    for i in range(7):
        for j in range(7):
            Md[i, j] = M[i, j]
        Md[i, i] += armature[i]
    L = stack_array(49).reshape((7, 7))  # (its lower triangle, all the solve reads)
    _cholesky(Md, L)
    Y = stack_array(42).reshape((7, 6))  # L^-1 J^T: then J M^-1 J^T = Y^T Y
    _forward_solve(L, J.T, Y)
    A = stack_array(36).reshape((6, 6))
    for i in range(6):
        for j in range(i + 1):
            acc = 0.0
            for k in range(7):
                acc += Y[k, i] * Y[k, j]
            A[i, j] = acc
            A[j, i] = acc
    w = stack_array(6)
    V = stack_array(36).reshape((6, 6))
    _symmetric_eigen(A, w, V)
    S = stack_array(36).reshape((6, 6))
    S_inv = stack_array(36).reshape((6, 6))
    for i in range(6):
        for j in range(6):
            S[i, j] = 0.0
            S_inv[i, j] = 0.0
    for k in range(6):
        e = max(w[k], min_eig)
        r = math.sqrt(e)
        for i in range(6):
            for j in range(6):
                vv = V[i, k] * V[j, k]
                S[i, j] += vv / r
                S_inv[i, j] += vv * r
    Kt = stack_array(36).reshape((6, 6))
    _sandwich(S_inv, K, Kt)
    for i in range(6):
        for j in range(i):
            m = 0.5 * (Kt[i, j] + Kt[j, i])
            Kt[i, j] = m
            Kt[j, i] = m
    _symmetric_eigen(Kt, w, V)
    R = stack_array(36).reshape((6, 6))
    for i in range(6):
        for j in range(6):
            R[i, j] = 0.0
    for k in range(6):
        r = math.sqrt(max(w[k], 0.0))
        for i in range(6):
            for j in range(6):
                R[i, j] += V[i, k] * V[j, k] * r
    out = stack_array(36).reshape((6, 6))
    _sandwich(S, R, out)
    for i in range(6):
        for j in range(6):
            D[i, j] = zeta * (out[i, j] + out[j, i])


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def pose_target_outputs(p_d, quat_d, v_d, p, quat, stale, out, o):  # type: ignore[no-untyped-def,unused-ignore]
    """``CartesianTarget``'s outputs from offset ``o`` of ``out``: the reference's position,
    orientation and twist, its distance [m] and angle [rad] to the target ``p``, ``quat``,
    and 1 if the targets went stale (else 0)."""
    for i in range(3):
        out[o + i] = p_d[i]
    for i in range(4):
        out[o + 3 + i] = quat_d[i]
    for i in range(6):
        out[o + 7 + i] = v_d[i]
    dx, dy, dz = p[0] - p_d[0], p[1] - p_d[1], p[2] - p_d[2]
    out[o + 13] = math.sqrt(dx * dx + dy * dy + dz * dz)
    d = abs(quat[0] * quat_d[0] + quat[1] * quat_d[1] + quat[2] * quat_d[2] + quat[3] * quat_d[3])
    out[o + 14] = 2.0 * math.acos(min(1.0, d))
    out[o + 15] = 1.0 if stale else 0.0


WARM_STEPS = 6  # the steps :func:`warmup` reports


def warmup(advance: Callable[[], object] = lambda: None) -> None:
    """Run every kernel of this module once (compiled, or loaded from the cache), on
    inputs of the types the laws pass; ``advance`` after each of :data:`WARM_STEPS`."""
    J = np.zeros((6, 7))
    J[:6, :6] = np.eye(6)
    z7, K = np.zeros(7), np.eye(6)
    T = np.eye(4).reshape(16)
    z3, quat = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    cartesian_impedance_torque(T, J, z7, z7, z3, quat, K, K, z7, 1.0, np.empty(7))
    advance()
    pose_filter(0.5, K, K, K, K, z3, z3, z7, z7, quat.copy(), quat)
    advance()
    # the joint walls, the rate and torque limits and the filter (laws.JointWalls):
    # per joint lower, upper, PD width, D width, PD stiffness, PD damping, D damping
    walls = np.tile([-1.0, 1.0, 0.1, 0.1, 1.0, 1.0, 1.0], (7, 1))
    finalize_torques(z7, z7, z7, z7, walls, np.ones(7), np.zeros(8, dtype=np.int64), 1.0,
                     z7 + 1.0, 1.0, np.empty(7))  # fmt: skip
    advance()
    # the Cartesian moves' and CartesianTarget's tracking (tracking.PoseImpedance)
    pose_tracking_torque(T, J, J, z7, z7, 1e-3, z3, quat, np.zeros(6), np.zeros(6), K, K, z7,
                         1.0, np.eye(7), z7, z7, z7, 0.01, 10.0, np.empty(7), np.empty(6),
                         np.empty((7, 6)))  # fmt: skip
    advance()
    # their damping from the arm's inertia (tracking.mass_damping)
    mass_damping(K, 1.0, np.eye(7), z7, J, 1e-2, np.empty((6, 6)))
    advance()
    # the Cartesian moves' and CartesianTarget's limits at a new target, and its outputs
    joint_scales(J, np.eye(3), np.eye(3), 0.5, 1.0, 1.0, 1.0, 1.0, z7 + 1.0, z7 + 1.0)
    pose_target_outputs(z3, quat, np.zeros(6), z3, quat, False, np.zeros(16), 0)
    advance()
