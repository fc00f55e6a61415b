""":mod:`panda_py.motion.online`'s per-tick work, compiled by numba:

* :func:`sample`: the state of a trajectory ruckig calculated, at a time, from its
  profiles packed once (``online._pack``): ruckig's own sampling
  (``Trajectory::at_time``, in its arithmetic: tests hold the two equal, bit for bit),
  without a call into ruckig and the conversion of its outputs each tick;
* :func:`publish_pose`: :class:`~panda_py.motion.online.OnlinePose`'s generator's aligned
  coordinates turned into the base frame's position, orientation, twist and acceleration
  in one call of about a microsecond, where the same scalar Python
  (``OnlinePose._publish_python``, the reference) takes 8-10 us; :func:`sample_pose`, both
  in one call;
* :func:`retarget` and :func:`restart_toward`: ``OnlinePose.set_target``'s and
  ``reset_toward``'s arithmetic (the anchor, the frames, the start and the goal, through
  :func:`aim`), each in one call (the NumPy reference: ``OnlinePose._aim``).

Imported on first use unless ``PANDA_PY_NO_JIT=1`` or numba is missing; compiled once
per machine and cached on disk under a key over this file (:mod:`panda_py.jit.cache`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from panda_py.jit import cache, stack
from panda_py.jit.stack import stack_array

__all__ = [
    "ROW", "aim", "mapped_peaks", "publish_pose", "restart_toward", "retarget", "sample",
    "sample_pose",
]  # fmt: skip

# the compile cache's key: the kernels compile this file and the stack arrays' helper
# (panda_py.jit.cache)
KEY = cache.source_key([Path(__file__), Path(stack.__file__)])

# a packed profile's row (one coordinate): the brake's duration, its two phases' times,
# jerks, accelerations, velocities and positions; the profile's phase durations (7),
# jerks (7), and accelerations, velocities and positions at the phases' starts and its
# end (8 each) (online._pack writes it, sample reads it)
BRAKE_T, BRAKE_J, BRAKE_A, BRAKE_V, BRAKE_P = 1, 3, 5, 7, 9
T, J, A, V, P = 11, 18, 25, 33, 41
ROW = 49
# rotation.SMALL_ANGLE (a test holds them equal; the key covers this file only)
SMALL_ANGLE = 1e-8


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def sample(traj, duration, t, position, velocity, acceleration):  # type: ignore[no-untyped-def,unused-ignore]
    """The state at time ``t`` [s] of a one-section trajectory of ``duration`` [s] packed
    in ``traj`` (n, ROW) into ``position``, ``velocity``, ``acceleration`` (each (n,)):
    ruckig's ``Trajectory::at_time`` (its brake pre-trajectory, the profile's phase at
    ``t``, and the last phase's acceleration kept after the end), in its arithmetic."""
    ends = stack_array(7)  # (the per-tick temporaries on the stack: jit.stack)
    for d in range(traj.shape[0]):
        r = traj[d]
        brake = r[0]
        total = 0.0  # the phases' ends, summed in order as ruckig sums them
        for i in range(7):
            total += r[T + i]
            ends[i] = total
        j = 0.0
        if t >= duration:  # after the end: keep the acceleration
            tt = t - (brake + ends[6])
            p0, v0, a0 = r[P + 7], r[V + 7], r[A + 7]
        else:
            tt = t
            if brake > 0.0 and tt < brake:  # braking first
                i = 0 if tt < r[BRAKE_T] else 1
                if i > 0:
                    tt -= r[BRAKE_T]
                p0, v0, a0, j = r[BRAKE_P + i], r[BRAKE_V + i], r[BRAKE_A + i], r[BRAKE_J + i]
            else:
                if brake > 0.0:
                    tt -= brake
                if tt >= ends[6]:  # this coordinate ended before the others
                    tt -= ends[6]
                    p0, v0, a0 = r[P + 7], r[V + 7], r[A + 7]
                else:
                    i = 0  # the first phase that ends after tt (upper bound)
                    while ends[i] <= tt:
                        i += 1
                    if i > 0:
                        tt -= ends[i - 1]
                    p0, v0, a0, j = r[P + i], r[V + i], r[A + i], r[J + i]
        position[d] = p0 + tt * (v0 + tt * (a0 / 2 + tt * j / 6))
        velocity[d] = v0 + tt * (a0 + tt * j / 2)
        acceleration[d] = a0 + tt * j


# mapped_peaks' bound on the coordinates and the outputs (its scratch on the stack)
PEAK_SIZE = 8


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def mapped_peaks(traj, duration, M, v_peak, a_peak):  # type: ignore[no-untyped-def,unused-ignore]
    """The largest ``|M v(t)|`` and ``|M a(t)|`` over a trajectory (see :func:`sample`)
    into ``v_peak``, ``a_peak`` (each (m,)), ``M`` (m, n) mapping its coordinates' rates
    (n, m <= PEAK_SIZE). Exact: every coordinate's acceleration is linear between its
    phases' ends, so ``M a`` is linear between the union of those times and peaks at one
    of them; ``M v`` peaks at one of them or where ``M a`` crosses zero between two. The
    Python reference: ``online._mapped_peaks_python``."""
    m, n = M.shape
    # (stack_array takes literals: 9 PEAK_SIZE + 2 times, each coordinate's brake and phase
    # ends, and PEAK_SIZE for the rest)
    times = stack_array(74)
    p, v, a = stack_array(8), stack_array(8), stack_array(8)
    v_mid, a_mid, a_prev = stack_array(8), stack_array(8), stack_array(8)
    count = 0
    times[count] = 0.0
    count += 1
    for d in range(n):
        r = traj[d]
        brake = r[0]
        if brake > 0.0:
            times[count] = r[BRAKE_T]
            times[count + 1] = brake
            count += 2
        total = brake
        for i in range(7):
            total += r[T + i]
            times[count] = total
            count += 1
    times[count] = duration
    count += 1
    for i in range(1, count):  # sorted (insertion: a few dozen)
        x = times[i]
        j = i - 1
        while j >= 0 and times[j] > x:
            times[j + 1] = times[j]
            j -= 1
        times[j + 1] = x
    for i in range(m):
        v_peak[i] = 0.0
        a_peak[i] = 0.0
    t_prev = 0.0
    for k in range(count):
        t = min(max(times[k], 0.0), duration)
        sample(traj, duration, t, p, v, a)
        for i in range(m):
            sv = 0.0
            sa = 0.0
            for c in range(n):
                sv += M[i, c] * v[c]
                sa += M[i, c] * a[c]
            if abs(sv) > v_peak[i]:
                v_peak[i] = abs(sv)
            if abs(sa) > a_peak[i]:
                a_peak[i] = abs(sa)
            if k > 0 and t > t_prev and a_prev[i] * sa < 0.0:  # M v turns in between
                t_mid = t_prev + (t - t_prev) * a_prev[i] / (a_prev[i] - sa)
                sample(traj, duration, t_mid, p, v_mid, a_mid)  # (p: not read)
                sm = 0.0
                for c in range(n):
                    sm += M[i, c] * v_mid[c]
                if abs(sm) > v_peak[i]:
                    v_peak[i] = abs(sm)
            a_prev[i] = sa
        t_prev = t


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def sample_pose(traj, duration, t, p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel):  # type: ignore[no-untyped-def,unused-ignore]
    """:func:`sample` into the generator's ``p``, ``v``, ``a`` (6,), then
    :func:`publish_pose` from them: an OnlinePose's compiled step in one call."""
    sample(traj, duration, t, p, v, a)
    publish_pose(p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _mv(A, x, i0, out, o0):  # type: ignore[no-untyped-def,unused-ignore]
    """``out[o0:o0+3] = A x[i0:i0+3]`` for a 3x3 ``A``."""
    x0, x1, x2 = x[i0], x[i0 + 1], x[i0 + 2]
    for r in range(3):
        out[o0 + r] = A[r, 0] * x0 + A[r, 1] * x1 + A[r, 2] * x2


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _jacobian_times(x, y, sign, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``J(x) y`` for SO(3)'s left (``sign`` 1) or right (-1) Jacobian of the rotation
    vector ``x``: ``y + sign a (x × y) + b x × (x × y)`` (series expansions near 0, as the
    Python reference ``online._jacobian_times``)."""
    x0, x1, x2 = x[0], x[1], x[2]
    y0, y1, y2 = y[0], y[1], y[2]
    th2 = x0 * x0 + x1 * x1 + x2 * x2
    if th2 < 1e-8:
        a, b = 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    else:
        th = math.sqrt(th2)
        a, b = (1.0 - math.cos(th)) / th2, (th - math.sin(th)) / (th2 * th)
    a *= sign
    c0, c1, c2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
    d0, d1, d2 = x1 * c2 - x2 * c1, x2 * c0 - x0 * c2, x0 * c1 - x1 * c0
    out[0] = y0 + a * c0 + b * d0
    out[1] = y1 + a * c1 + b * d1
    out[2] = y2 + a * c2 + b * d2


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def publish_pose(p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel):  # type: ignore[no-untyped-def,unused-ignore]
    """From the generator's position ``p``, velocity ``v`` and acceleration ``a`` (6,
    translation in frame ``Ft``, rotation vector about the anchor ``q0``/``R0`` in frame
    ``Fr``): ``position`` (3,), ``orientation`` (4, x y z w), ``twist`` and ``accel``
    (6,) in the base frame, in place."""
    xs = stack_array(3)
    _mv(Fr, p, 3, xs, 0)
    x0, x1, x2 = xs[0], xs[1], xs[2]
    th2 = x0 * x0 + x1 * x1 + x2 * x2
    th = math.sqrt(th2)
    if th < 1e-4:
        k, c = 0.5 - th2 / 48.0, 1.0 - th2 / 8.0
    else:
        k, c = math.sin(0.5 * th) / th, math.cos(0.5 * th)
    ex, ey, ez, ew = k * x0, k * x1, k * x2, c
    qx, qy, qz, qw = q0[0], q0[1], q0[2], q0[3]
    orientation[0] = qw * ex + qx * ew + qy * ez - qz * ey
    orientation[1] = qw * ey - qx * ez + qy * ew + qz * ex
    orientation[2] = qw * ez + qx * ey - qy * ex + qz * ew
    orientation[3] = qw * ew - qx * ex - qy * ey - qz * ez
    _mv(Ft, p, 0, position, 0)
    scratch = stack_array(6)
    _rates(v, twist, Ft, Fr, R0, xs, scratch)
    _rates(a, accel, Ft, Fr, R0, xs, scratch)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _rates(src, dst, Ft, Fr, R0, xs, scratch):  # type: ignore[no-untyped-def,unused-ignore]
    """A velocity or acceleration ``src`` (6, aligned frames) into ``dst`` (6, base
    frame): the angular part's world rate is ``R0 J_l(x) xd`` (without the Jacobian's
    rate, small for the small ``x`` the re-anchoring keeps)."""
    _mv(Ft, src, 0, dst, 0)
    rates, world = scratch[:3], scratch[3:]
    _mv(Fr, src, 3, rates, 0)
    _jacobian_times(xs, rates, 1.0, world)
    _mv(R0, world, 0, dst, 3)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _frame(dx, dy, dz, fx, fy, fz, F):  # type: ignore[no-untyped-def,unused-ignore]
    """``OnlinePose``'s ``_frame`` into ``F`` (3x3, columns): first axis along ``d`` (or,
    where that is ~0, ``f``; the identity where both are)."""
    x, y, z = dx, dy, dz
    n = math.sqrt(x * x + y * y + z * z)
    if n < 1e-9:
        x, y, z = fx, fy, fz
        n = math.sqrt(x * x + y * y + z * z)
        if n < 1e-9:
            for r in range(3):
                for c in range(3):
                    F[r, c] = 1.0 if r == c else 0.0
            return
    x, y, z = x / n, y / n, z / n
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax <= ay and ax <= az:
        u, v, w = 0.0, z, -y
    elif ay <= az:
        u, v, w = -z, 0.0, x
    else:
        u, v, w = y, -x, 0.0
    m = math.sqrt(u * u + v * v + w * w)
    u, v, w = u / m, v / m, w / m
    F[0, 0], F[0, 1], F[0, 2] = x, u, y * w - z * v
    F[1, 0], F[1, 1], F[1, 2] = y, v, z * u - x * w
    F[2, 0], F[2, 1], F[2, 2] = z, w, x * v - y * u


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _mtv(A, x, out, o0):  # type: ignore[no-untyped-def,unused-ignore]
    """``out[o0:o0+3] = A^T x`` for a 3x3 ``A``."""
    x0, x1, x2 = x[0], x[1], x[2]
    for c in range(3):
        out[o0 + c] = A[0, c] * x0 + A[1, c] * x1 + A[2, c] * x2


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def aim(p, v, a, x, xd, xdd, q0, target, quat, Ft, Fr, start_p, start_v, start_a, goal):  # type: ignore[no-untyped-def,unused-ignore]
    """``OnlinePose._aim``'s arithmetic: from the translation's state ``p, v, a`` (base
    frame) and the rotation vector's ``x, xd, xdd`` (about the anchor ``q0``), toward the
    pose ``target`` (3,), ``quat`` (4, x y z w, any norm): the frames ``Ft``, ``Fr`` of
    the way there and the generator's start state and goal in them (each (6,)), in place."""
    nq = math.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
    bx, by, bz, bw = quat[0] / nq, quat[1] / nq, quat[2] / nq, quat[3] / nq
    ax, ay, az, aw = -q0[0], -q0[1], -q0[2], q0[3]  # the anchor's conjugate
    rx = aw * bx + ax * bw + ay * bz - az * by
    ry = aw * by - ax * bz + ay * bw + az * bx
    rz = aw * bz + ax * by - ay * bx + az * bw
    rw = aw * bw - ax * bx - ay * by - az * bz
    if rw < 0.0:  # the shortest way round
        rx, ry, rz, rw = -rx, -ry, -rz, -rw
    s = math.sqrt(rx * rx + ry * ry + rz * rz)
    k = 2.0 / rw if s < 1e-8 else 2.0 * math.atan2(s, rw) / s
    xt = np.empty(3)
    xt[0], xt[1], xt[2] = k * rx, k * ry, k * rz
    _frame(target[0] - p[0], target[1] - p[1], target[2] - p[2], v[0], v[1], v[2], Ft)
    _frame(xt[0], xt[1], xt[2], xd[0], xd[1], xd[2], Fr)
    _mtv(Ft, p, start_p, 0)
    _mtv(Fr, x, start_p, 3)
    _mtv(Ft, v, start_v, 0)
    _mtv(Fr, xd, start_v, 3)
    _mtv(Ft, a, start_a, 0)
    _mtv(Fr, xdd, start_a, 3)
    _mtv(Ft, target, goal, 0)
    _mtv(Fr, xt, goal, 3)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def retarget(gp, gv, ga, Ft, Fr, q0, target, quat, anchor, R0, Ft2, Fr2, sp, sv, sa, goal):  # type: ignore[no-untyped-def,unused-ignore]
    """``OnlinePose.set_target``'s arithmetic in one call: the generator's state ``gp``,
    ``gv``, ``ga`` (6,: the translation in frame ``Ft``, the rotation vector about the
    anchor ``q0`` in frame ``Fr``) in the base frame, the anchor moved to the current
    orientation (into ``anchor`` (4,) and ``R0`` (3, 3); the rotation vector becomes 0,
    its rates turned by its right Jacobian), then :func:`aim` toward ``target`` (3,),
    ``quat`` (4, x y z w, any norm): the new frames ``Ft2``, ``Fr2``, the generator's
    start state ``sp``, ``sv``, ``sa`` and goal in them, in place."""
    p, v, a = np.empty(3), np.empty(3), np.empty(3)
    x, xd, xdd = np.empty(3), np.empty(3), np.empty(3)
    _mv(Ft, gp, 0, p, 0)
    _mv(Ft, gv, 0, v, 0)
    _mv(Ft, ga, 0, a, 0)
    _mv(Fr, gp, 3, x, 0)
    _mv(Fr, gv, 3, xd, 0)
    _mv(Fr, ga, 3, xdd, 0)
    qx, qy, qz, qw = q0[0], q0[1], q0[2], q0[3]
    if x[0] != 0.0 or x[1] != 0.0 or x[2] != 0.0:
        th = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
        k = 0.5 - th * th / 48.0 if th < SMALL_ANGLE else math.sin(0.5 * th) / th
        ex, ey, ez, ew = k * x[0], k * x[1], k * x[2], math.cos(0.5 * th)
        anchor[0] = qw * ex + qx * ew + qy * ez - qz * ey
        anchor[1] = qw * ey - qx * ez + qy * ew + qz * ex
        anchor[2] = qw * ez + qx * ey - qy * ex + qz * ew
        anchor[3] = qw * ew - qx * ex - qy * ey - qz * ez
        rates = np.empty(3)
        _jacobian_times(x, xd, -1.0, rates)
        xd[:] = rates
        _jacobian_times(x, xdd, -1.0, rates)
        xdd[:] = rates
        x[:] = 0.0
    else:
        anchor[0], anchor[1], anchor[2], anchor[3] = qx, qy, qz, qw
    _to_matrix(anchor, R0)
    aim(p, v, a, x, xd, xdd, anchor, target, quat, Ft2, Fr2, sp, sv, sa, goal)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def restart_toward(p, quat, twist, accel, target, tquat, anchor, R0, Ft, Fr, sp, sv, sa, goal):  # type: ignore[no-untyped-def,unused-ignore]
    """``OnlinePose.reset_toward``'s arithmetic in one call (a Cartesian move's hand-over):
    the anchor at the orientation ``quat`` (4, x y z w, any norm; into ``anchor`` and
    ``R0``), the rotation vector 0 with its rates the angular ``twist`` and ``accel``
    (6,, base frame) in the anchor's frame, then :func:`aim` from the position ``p`` toward
    ``target`` (3,), ``tquat`` (4): the frames ``Ft``, ``Fr``, the generator's start state
    ``sp``, ``sv``, ``sa`` and goal in them, in place."""
    n = math.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
    for i in range(4):
        anchor[i] = quat[i] / n
    _to_matrix(anchor, R0)
    v, a = np.empty(3), np.empty(3)
    x, xd, xdd = np.zeros(3), np.empty(3), np.empty(3)
    for i in range(3):
        v[i], a[i] = twist[i], accel[i]
    _mtv(R0, twist[3:], xd, 0)
    _mtv(R0, accel[3:], xdd, 0)
    aim(p, v, a, x, xd, xdd, anchor, target, tquat, Ft, Fr, sp, sv, sa, goal)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _to_matrix(q, R):  # type: ignore[no-untyped-def,unused-ignore]
    """The rotation matrix of the unit quaternion ``q`` into ``R`` (3, 3) (as
    ``rotation.to_matrix``)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - z * w)
    R[0, 2] = 2 * (x * z + y * w)
    R[1, 0] = 2 * (x * y + z * w)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - x * w)
    R[2, 0] = 2 * (x * z - y * w)
    R[2, 1] = 2 * (y * z + x * w)
    R[2, 2] = 1 - 2 * (x * x + y * y)
