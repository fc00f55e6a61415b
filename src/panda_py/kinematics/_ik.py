"""Analytical inverse kinematics of the Franka arm with joint 7 as the redundancy parameter.

The method is the geometric solver of Y. He and S. Liu, "Analytical Inverse Kinematics for
Franka Emika Panda -- a Geometrical Solver for 7-DOF Manipulators with Unconventional
Design", ICCAR 2021: given q7 the wrist point p6 follows from the target pose; the
shoulder (p2), elbow (p4) and wrist (p6) triangle gives q4; the joint-5 axis constraint
gives two q6; the shoulder gives two (q1, q2); q3 and q5 close the chain. That is four
solutions per (pose, q7), indexed here as

    row = 2 * i6 + i1,  i6 = 0: cos(q5) < 0  (q6 = pi - Theta - Phi),  1: cos(q5) >= 0,
                        i1 = 0: q2 >= 0,                             1: q2 < 0,

which is also panda-py's order in ``ik_full``. The elbow stays on the side the paper
covers (q4 below the elbow-flip angle, about -0.467 rad); configurations with a flipped
elbow are not among the four solutions.

The equations are written out here from the geometry (derivation in the comments), in a
form that is accurate to rounding everywhere away from the true singularities: angles come
from atan2 of two well-conditioned components, never from acos/asin near +-1, and the
shoulder singularity is detected on the actual geometry (|P_xy| below a length tolerance),
not on an angle threshold, so ``fk(ik(T)) == T`` holds to about 1e-12 wherever a solution
is returned.

The solver is written once, in scalar Python that numba compiles as it is (:mod:`._numba`,
the default where numba is installed) or Python runs plain (``PANDA_PY_NO_JIT=1``, or no
numba): :func:`solve` for one pose, :func:`search_q7` the walk over q7 to the nearest one
with a solution, :func:`ik_range` the loop over a batch that every kernel, single or
batched, serial or parallel, runs. Its parameters are an :class:`IKParams` read by name;
the kernels take them packed in a float64 array (:func:`pack_ik_params`), which a numba
call passes far faster than a named tuple.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from panda_py.kinematics._scalar import atan2, flip, sincos

# Status codes (mirrored by the public IKStatus enum).
OK = 0
UNREACHABLE = 1
JOINT_LIMIT = 2
SINGULAR = 3
# A pose that is not a finite rigid transform, or whose q_init or q_7 is not finite: not
# solved; the caller raises (see ``_args.raise_invalid``).
INVALID = -1

# Below this distance [m] of the shoulder point P from the joint-1 axis, q1 is undefined
# (shoulder singularity) and is taken from q_init, as in the paper.
SHOULDER_SINGULAR_TOL = 1e-10
# Below this distance [m] of the shoulder from the joint-6 axis, q6 is undefined.
WRIST_SINGULAR_TOL = 1e-10
# The q7 search's step [rad]: candidates q_7 +- k * step, nearest first.
Q7_SEARCH_STEP = 0.01
# A matrix whose rotation part is this far [-] from orthonormal (unit orthogonal x and y
# columns, z = x cross y) or whose last row is this far from (0, 0, 0, 1) is not a rigid
# transform.
ROTATION_TOL = 1e-6

TWO_PI = 2.0 * math.pi
_PIO2 = math.pi / 2
NAN7 = (math.nan,) * 7
_ZERO15 = (0.0,) * 15
_NO_ARM = (False, False, 0.0, 0.0, 0.0, 0.0, 0.0)


class IKParams(NamedTuple):
    """Geometry and limits the solver needs (all from :mod:`panda_py.robots.params`; build
    with :func:`ik_params`). The target frame is ``J7 * TransZ(d_e) * RotZ(theta_e)``."""

    d1: float
    d3: float
    d5: float
    a4: float
    a7: float
    d_e: float  # [m]
    theta_e: float  # [rad]
    l24: float  # shoulder-elbow distance [m]
    l46: float  # elbow-wrist distance [m]
    q4_offset: float  # q4 = theta_246 + q4_offset, theta_246 the elbow triangle's angle
    cos_q4_offset: float
    sin_q4_offset: float
    inv_2l24l46: float  # 1 / (2 l24 l46) [1/m^2]: the elbow triangle's sides to cos, sin
    q_min: tuple[float, ...]  # [rad]
    q_max: tuple[float, ...]


def ik_params(
    d1: float, d3: float, d5: float, a4: float, a7: float, d_e: float, theta_e: float,
    q_min: tuple[float, ...], q_max: tuple[float, ...],
) -> IKParams:  # fmt: skip
    """The solver's parameters, derived ones included."""
    l24, l46 = math.hypot(a4, d3), math.hypot(a4, d5)
    off = math.atan2(d3, a4) + math.atan2(d5, a4) - TWO_PI
    return IKParams(
        d1, d3, d5, a4, a7, d_e, theta_e, l24, l46, off, math.cos(off), math.sin(off),
        1.0 / (2.0 * l24 * l46), tuple(q_min), tuple(q_max),
    )  # fmt: skip


def pack_ik_params(P: IKParams) -> NDArray[np.float64]:
    """The parameters as the kernels' flat float64 array (27,); :func:`unpack_ik_params`
    reverses it."""
    return np.array([*P[:13], *P.q_min, *P.q_max], dtype=np.float64)


def unpack_ik_params(A: Any) -> IKParams:
    """:func:`pack_ik_params` reversed (inside the kernels)."""
    return IKParams(
        A[0], A[1], A[2], A[3], A[4], A[5], A[6], A[7], A[8], A[9], A[10], A[11], A[12],
        (A[13], A[14], A[15], A[16], A[17], A[18], A[19]),
        (A[20], A[21], A[22], A[23], A[24], A[25], A[26]),
    )  # fmt: skip


def rigid_error(
    r00: float, r01: float, r02: float, px: float, r10: float, r11: float, r12: float,
    py: float, r20: float, r21: float, r22: float, pz: float, l0: float, l1: float,
    l2: float, l3: float,
) -> float:  # fmt: skip
    """The largest deviation [-] of a 4x4 (row-major) from a rigid transform: unit
    orthogonal x and y columns, z = x cross y, last row 0 0 0 1; NaN if an entry is not
    finite. Rigid means ``rigid_error(...) <= ROTATION_TOL``."""
    e = max(
        abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0),
        abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0),
        abs(r00 * r01 + r10 * r11 + r20 * r21),
        abs(r10 * r21 - r20 * r11 - r02),
        abs(r20 * r01 - r00 * r21 - r12),
        abs(r00 * r11 - r10 * r01 - r22),
        abs(l0),
        abs(l1),
        abs(l2),
        abs(l3 - 1.0),
    )
    s = r00 + r01 + r02 + r10 + r11 + r12 + r20 + r21 + r22 + px + py + pz + l0 + l1 + l2 + l3
    return e + (s - s)  # s - s: 0, or NaN if an entry is NaN or infinite


def case_row(q2: float, q5: float) -> int:
    """The branch of a configuration: the q6 branch follows the sign of cos(q5), the
    shoulder branch the sign of q2. Within |q5| <= 3 rad, cos(q5) >= 0 exactly when
    |q5| <= pi/2 rounded down (cos(1.5707963267948966) is +6e-17, cos of the next float up
    negative): a comparison instead of a cosine."""
    a = abs(q5)
    c = a <= _PIO2 if a <= 3.0 else math.cos(q5) >= 0.0
    return (2 if c else 0) + (1 if q2 < 0.0 else 0)


def pose_part(
    P: IKParams, r00: float, r01: float, r02: float, r10: float, r11: float, r12: float,
    r20: float, r21: float, r22: float, px: float, py: float, pz: float, q7: float,
) -> Any:  # fmt: skip
    """The part shared by all four branches: (status, (x6x, x6y, x6z, vx, vy, vz, q4, c4,
    s4, d26, sh3, wx, wy, irr, t)); a status other than OK: no branch has a solution (the
    first failing test names the reason)."""
    if not (P.q_min[6] <= q7 <= P.q_max[6]):
        return JOINT_LIMIT, _ZERO15
    # Wrist point p6: joint 7's origin lies d_e behind the target along z7 = z_EE, and
    # frame 6's x axis is the target's x axis turned back by q7 + theta_e about z7;
    # p7 = p6 + a7 x6.
    sp, cp = sincos(q7 + P.theta_e)
    x6x = cp * r00 - sp * r01
    x6y = cp * r10 - sp * r11
    x6z = cp * r20 - sp * r21
    vx = px - P.d_e * r02 - P.a7 * x6x  # V26 = p6 - p2, p2 = (0, 0, d1)
    vy = py - P.d_e * r12 - P.a7 * x6y
    vz = pz - P.d_e * r22 - P.a7 * x6z - P.d1
    ll = vx * vx + vy * vy + vz * vz
    # Elbow angle from the triangle (p2, p4, p6): law of cosines, with the sine from a
    # Heron-type product (h1 h2 = (2 l24 l46)^2 - cos_part^2), so the angle comes from
    # atan2 and its cosine and sine need no further trigonometry.
    l24, l46 = P.l24, P.l46
    h1 = ll - (l24 - l46) ** 2
    h2 = (l24 + l46) ** 2 - ll
    if h1 < 0.0 or h2 < 0.0:
        return UNREACHABLE, _ZERO15
    y4 = math.sqrt(h1 * h2)
    x4 = (l24 * l24 + l46 * l46) - ll
    q4 = atan2(y4, x4) + P.q4_offset
    if not (P.q_min[3] <= q4 <= P.q_max[3]):
        return JOINT_LIMIT, _ZERO15
    ca, sa = x4 * P.inv_2l24l46, y4 * P.inv_2l24l46
    c_off, s_off = P.cos_q4_offset, P.sin_q4_offset
    c4, s4 = ca * c_off - sa * s_off, sa * c_off + ca * s_off
    # Joint 6: the shoulder, seen from frame 6 (x6, y6 = -z7, z6 = z7 x x6), has a fixed
    # component D26 along the joint-5 axis z5 = (sin q6, cos q6, 0) in frame 6.
    d26 = P.a4 * s4 - P.d3 * c4 - P.d5
    wx = -(x6x * vx + x6y * vy + x6z * vz)
    wy = r02 * vx + r12 * vy + r22 * vz
    rr = wx * wx + wy * wy
    if rr < WRIST_SINGULAR_TOL * WRIST_SINGULAR_TOL:
        return SINGULAR, _ZERO15
    h3 = rr - d26 * d26
    if h3 < 0.0:
        return UNREACHABLE, _ZERO15
    # P = p6 + t z5 lies on the joint-3 axis, t = a4 tan(q4 / 2) - d5 (the half-angle
    # tangent in its stable form).
    t = P.a4 * (s4 / (1.0 + c4) if c4 >= 0.0 else (1.0 - c4) / s4) - P.d5
    g = (x6x, x6y, x6z, vx, vy, vz, q4, c4, s4, d26, math.sqrt(h3), wx, wy, 1.0 / rr, t)
    return OK, g


def arm_part(
    P: IKParams, g: Any, r02: float, r12: float, r22: float, q1_init: float, i6: int
) -> Any:
    """q6 branch i6: (ok, shoulder singular, q5, q6, q1, q2, q3) with q1..q3 those of the
    q2 >= 0 row (the other row flips them, unless singular)."""
    x6x, x6y, x6z, vx, vy, vz, _q4, c4, s4, d26, sh3, wx, wy, irr, t = g
    # q6 = theta - phi (i6 = 1) or pi - theta - phi, theta = atan2(d26, sh3), phi =
    # atan2(wy, wx): its cosine and sine times |w|^2 from the sides.
    if i6:
        cn, sn = sh3 * wx + d26 * wy, d26 * wx - sh3 * wy
    else:
        cn, sn = d26 * wy - sh3 * wx, d26 * wx + sh3 * wy
    q6 = atan2(sn, cn)
    lo6, hi6 = P.q_min[5], P.q_max[5]
    if q6 < lo6:
        q6 += TWO_PI
    elif q6 > hi6:
        q6 -= TWO_PI
    if not (lo6 <= q6 <= hi6):
        return _NO_ARM
    # z5 = s6 x6 - c6 z7 and x5 = c6 x6 + s6 z7 (y6 = -z7)
    c6, s6 = cn * irr, sn * irr
    ux = vx + t * (s6 * x6x - c6 * r02)  # V2P = P - p2
    uy = vy + t * (s6 * x6y - c6 * r12)
    uz = vz + t * (s6 * x6z - c6 * r22)
    x5x = c6 * x6x + s6 * r02
    x5y = c6 * x6y + s6 * r12
    x5z = c6 * x6z + s6 * r22
    # Frame 3: z3 = u / |u|, y3 = m / |m| with m = u x V26 (the arm plane's normal),
    # x3 = y3 x z3 = X / (|m| |u|) with X = m x u; x4 = c4 x3 + s4 z3. Each angle below is
    # atan2 of two components scaled by one positive factor (|m| |u| and the like), so
    # nothing needs normalising.
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
    if not (mm > 0.0 and P.q_min[4] <= q5 <= P.q_max[4]):  # mm = 0: no arm plane
        return _NO_ARM
    if hxy < SHOULDER_SINGULAR_TOL:  # q1 undefined: q_init's, for both shoulder branches
        s1, c1 = sincos(q1_init)
        q2 = atan2(c1 * ux + s1 * uy, uz)
        s2, c2 = sincos(q2)
        q3 = atan2(c1 * by - s1 * bx, c2 * (c1 * bx + s1 * by) - s2 * bz)
        return True, True, q5, q6, q1_init, q2, q3
    # Shoulder: z3 = (c1 s2, s1 s2, c2), so q1 and q2 come from u; x3 = c3 x2 + s3 z2 with
    # x2 = (c1 c2, s1 c2, -s2), z2 = (-s1, c1, 0), times |u|^2 |m| hypot(ux, uy). The other
    # shoulder branch (q1 + pi, -q2) negates c1, s1, s2: q3 + pi.
    q1 = atan2(uy, ux)
    q2 = atan2(hxy, uz)
    q3 = atan2(lu * (ux * by - uy * bx), uz * (ux * bx + uy * by) - huu * bz)
    return True, False, q5, q6, q1, q2, q3


def branch(P: IKParams, arm: Any, i1: int, q4: float, q7: float) -> Any:
    """(status, q (7-tuple, NaN without a solution)) of shoulder branch i1 of an arm."""
    ok, singular, q5, q6, q1, q2, q3 = arm
    if not ok:
        return JOINT_LIMIT, NAN7
    if i1 and not singular:
        q1, q2, q3 = flip(q1), -q2, flip(q3)
    lo, hi = P.q_min, P.q_max
    if lo[0] <= q1 <= hi[0] and lo[1] <= q2 <= hi[1] and lo[2] <= q3 <= hi[2]:
        return OK, (q1, q2, q3, q4, q5, q6, q7)
    return JOINT_LIMIT, NAN7


def solve(
    P: IKParams, r00: float, r01: float, r02: float, r10: float, r11: float, r12: float,
    r20: float, r21: float, r22: float, px: float, py: float, pz: float, q7: float,
    q1_init: float, first: int, full: bool,
) -> Any:  # fmt: skip
    """One valid pose (rotation r, position p [m]) at q7 [rad]: four (status, q) rows,
    with ``full`` the branches 0..3, else the branch ``first`` in row 0 (and fillers)."""
    status, g = pose_part(P, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7)
    if status != OK:
        none = (status, NAN7)
        return none, none, none, none
    q4 = g[6]
    arm = arm_part(P, g, r02, r12, r22, q1_init, first >> 1)
    row0 = branch(P, arm, first & 1, q4, q7)
    if not full:
        none = (JOINT_LIMIT, NAN7)
        return row0, none, none, none
    other = arm_part(P, g, r02, r12, r22, q1_init, 1)
    return row0, branch(P, arm, 1, q4, q7), branch(P, other, 0, q4, q7), branch(P, other, 1, q4, q7)


def search_q7(
    P: IKParams, r00: float, r01: float, r02: float, r10: float, r11: float, r12: float,
    r20: float, r21: float, r22: float, px: float, py: float, pz: float, q7: float,
    q1_init: float, row: int, radius: float,
) -> float:  # fmt: skip
    """The q7 [rad] nearest ``q7`` at which branch ``row`` has a solution: ``q7`` itself,
    else ``q7 +- k * Q7_SEARCH_STEP`` for k = 1, 2, ... (+ before -) while ``k * step``
    is within ``radius`` [rad] (which may be infinite) and the candidate within joint 7's
    limits; ``q7`` if none has one. Each candidate costs one branch of :func:`solve`."""
    if radius <= 0.0:
        return q7
    lo, hi = P.q_min[6], P.q_max[6]
    # beyond this distance no candidate lies within joint 7's limits (+ a rounding margin)
    span = max(q7 - lo, hi - q7) + 1e-12
    # candidate i: q7 (i = 0), q7 + step, q7 - step, q7 + 2 step, ... (one loop, one call
    # of solve: each call site is compiled into every kernel in full)
    i = 0
    while True:
        d = ((i + 1) >> 1) * Q7_SEARCH_STEP
        if d > radius + 1e-12 or d > span:
            return q7
        c = q7 + d if i & 1 else q7 - d
        if lo <= c <= hi and solve(
            P, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, c, q1_init, row, False
        )[0][0] == OK:  # fmt: skip
            return c
        i += 1


def ik_range(
    A: Any, T: Any, QI: Any, q7: Any, radius: float, full: bool, qout: Any, stout: Any,
    q7out: Any, k0: int, k1: int,
) -> None:  # fmt: skip
    """Poses k0..k1-1 of T (N, 4, 4), with q_init QI[k] (QI (N, 7) or (1, 7)) and q7[k]
    (q7 (N,) or (1,)); A the packed :class:`IKParams`: all four branches (``full``) into
    rows 4k..4k+3 of qout (4N, 7) and stout (4N,), or the one in q_init's case into row k
    of qout (N, 7), stout (N,); the q7 solved for into q7out[k] (N,). ``radius`` [rad] > 0
    first searches the q7 nearest q7[k] with a solution in q_init's case
    (:func:`search_q7`). A pose that is not a finite rigid transform, or whose q_init or q7
    is not finite, gets the status :data:`INVALID` in its first row and is not solved."""
    P = unpack_ik_params(A)
    m7 = q7.shape[0]
    mq = QI.shape[0]
    for k in range(k0, k1):
        qr = k if mq > 1 else 0
        q7k = float(q7[k] if m7 > 1 else q7[0])
        base = 4 * k if full else k
        # (float(): a no-op compiled; plain, Python floats compute faster than NumPy's)
        r00, r01, r02, px = (
            float(T[k, 0, 0]),
            float(T[k, 0, 1]),
            float(T[k, 0, 2]),
            float(T[k, 0, 3]),
        )
        r10, r11, r12, py = (
            float(T[k, 1, 0]),
            float(T[k, 1, 1]),
            float(T[k, 1, 2]),
            float(T[k, 1, 3]),
        )
        r20, r21, r22, pz = (
            float(T[k, 2, 0]),
            float(T[k, 2, 1]),
            float(T[k, 2, 2]),
            float(T[k, 2, 3]),
        )
        q1i, q2i, q5i = float(QI[qr, 0]), float(QI[qr, 1]), float(QI[qr, 4])
        s = q7k + q1i + q2i + QI[qr, 2] + QI[qr, 3] + q5i + QI[qr, 5] + QI[qr, 6]
        err = rigid_error(
            r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz,
            T[k, 3, 0], T[k, 3, 1], T[k, 3, 2], T[k, 3, 3],
        )  # fmt: skip
        if not (err <= ROTATION_TOL and s - s == 0.0):
            stout[base] = INVALID
            continue
        row = case_row(q2i, q5i)
        if radius > 0.0:
            q7k = search_q7(
                P, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7k, q1i, row, radius
            )
        q7out[k] = q7k
        first = 0 if full else row
        rows = solve(
            P, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7k, q1i, first, full
        )
        for r in range(4 if full else 1):
            code, qv = rows[r]
            stout[base + r] = code
            for c in range(7):
                qout[base + r, c] = qv[c]


def rigid_range(T: Any, err: Any, k0: int, k1: int) -> None:
    """:func:`rigid_error` of poses k0..k1-1 of T (N, 4, 4) into err (N,)."""
    for k in range(k0, k1):
        err[k] = rigid_error(
            T[k, 0, 0], T[k, 0, 1], T[k, 0, 2], T[k, 0, 3], T[k, 1, 0], T[k, 1, 1],
            T[k, 1, 2], T[k, 1, 3], T[k, 2, 0], T[k, 2, 1], T[k, 2, 2], T[k, 2, 3],
            T[k, 3, 0], T[k, 3, 1], T[k, 3, 2], T[k, 3, 3],
        )  # fmt: skip
