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

Two implementations share these equations: :func:`make_scalar_solver` (plain floats, for
single calls, where interpreter overhead dominates) and :func:`solve_batch` (NumPy over N
rows). Tests hold them equal.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

# Status codes (mirrored by the public IKStatus enum).
OK = 0
UNREACHABLE = 1
JOINT_LIMIT = 2
SINGULAR = 3

# Below this distance [m] of the shoulder point P from the joint-1 axis, q1 is undefined
# (shoulder singularity) and is taken from q_init, as in the paper.
SHOULDER_SINGULAR_TOL = 1e-10
# Below this distance [m] of the shoulder from the joint-6 axis, q6 is undefined.
WRIST_SINGULAR_TOL = 1e-10

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class IKParams:
    """Geometry and limits the solver needs (all from :mod:`panda_py.robots.params`).

    ``d_e`` [m] and ``theta_e`` [rad]: the target frame is ``J7 * TransZ(d_e) * RotZ(theta_e)``.
    """

    d1: float
    d3: float
    d5: float
    a4: float
    a7: float
    d_e: float
    theta_e: float
    q_min: tuple[float, ...]
    q_max: tuple[float, ...]

    @property
    def l24(self) -> float:
        return math.hypot(self.a4, self.d3)

    @property
    def l46(self) -> float:
        return math.hypot(self.a4, self.d5)

    @property
    def q4_offset(self) -> float:
        """q4 = theta_246 + q4_offset, theta_246 the triangle's angle at the elbow."""
        return math.atan2(self.d3, self.a4) + math.atan2(self.d5, self.a4) - TWO_PI

    @property
    def cos_q4_offset(self) -> float:
        return math.cos(self.q4_offset)

    @property
    def sin_q4_offset(self) -> float:
        return math.sin(self.q4_offset)

    @property
    def inv_2l24l46(self) -> float:
        """1 / (2 l24 l46) [1/m^2]: scales the elbow triangle's sides to cos and sin."""
        return 1.0 / (2.0 * self.l24 * self.l46)


# The solver's signature: (R row-major 9, p 3, q7, q1_init, branches) -> rows
ScalarSolver = Callable[..., list[tuple[int, int, tuple[float, ...]]]]


def _flip(angle: float) -> float:
    """angle + pi, wrapped to (-pi, pi] the way the shoulder flip needs it."""
    return angle - math.pi if angle > 0.0 else angle + math.pi


def make_scalar_solver(P: IKParams) -> ScalarSolver:
    """A function ``solve(r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7,
    q1_init, rows)`` returning ``[(row, status, q), ...]`` for the requested rows (each in
    0..3, rows of one q6 branch next to each other), ``q`` a 7-tuple of floats (meaningful
    only when status is OK)."""
    d1, d3, d5, a4, a7, d_e, theta_e = P.d1, P.d3, P.d5, P.a4, P.a7, P.d_e, P.theta_e
    l24, l46 = P.l24, P.l46
    l24_sq_l46_sq = l24 * l24 + l46 * l46
    inv_b = P.inv_2l24l46
    diff_sq = (l24 - l46) ** 2
    sum_sq = (l24 + l46) ** 2
    q4_off, c_off, s_off = P.q4_offset, P.cos_q4_offset, P.sin_q4_offset
    lo1, lo2, lo3, lo4, lo5, lo6, lo7 = P.q_min
    hi1, hi2, hi3, hi4, hi5, hi6, hi7 = P.q_max
    sin, cos, atan2, sqrt = math.sin, math.cos, math.atan2, math.sqrt

    def solve(r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7, q1_init, rows):
        nan7 = (math.nan,) * 7
        if not lo7 <= q7 <= hi7:
            return [(r, JOINT_LIMIT, nan7) for r in rows]
        # Wrist point p6: joint 7's origin lies d_e behind the target along z7 = z_EE, and
        # frame 6's x axis is the target's x axis turned back by q7 + theta_e about z7;
        # p7 = p6 + a7 x6.
        psi = q7 + theta_e
        cp, sp = cos(psi), sin(psi)
        x6x = cp * r00 - sp * r01
        x6y = cp * r10 - sp * r11
        x6z = cp * r20 - sp * r21
        vx = px - d_e * r02 - a7 * x6x  # V26 = p6 - p2, p2 = (0, 0, d1)
        vy = py - d_e * r12 - a7 * x6y
        vz = pz - d_e * r22 - a7 * x6z - d1
        ll = vx * vx + vy * vy + vz * vz
        # Elbow angle from the triangle (p2, p4, p6): law of cosines, with the sine from
        # a Heron-type product (h1 h2 = (2 l24 l46)^2 - cos_part^2), so the angle comes
        # from atan2 and its cosine and sine need no further trigonometry.
        h1 = ll - diff_sq
        h2 = sum_sq - ll
        if h1 < 0.0 or h2 < 0.0:
            return [(r, UNREACHABLE, nan7) for r in rows]
        y4 = sqrt(h1 * h2)
        x4 = l24_sq_l46_sq - ll
        q4 = atan2(y4, x4) + q4_off
        if not lo4 <= q4 <= hi4:
            return [(r, JOINT_LIMIT, nan7) for r in rows]
        ca, sa = x4 * inv_b, y4 * inv_b
        c4, s4 = ca * c_off - sa * s_off, sa * c_off + ca * s_off
        # Joint 6: the shoulder, seen from frame 6 (x6, y6 = -z7, z6 = z7 x x6), has a
        # fixed component D26 along the joint-5 axis z5 = (sin q6, cos q6, 0) in frame 6.
        d26 = a4 * s4 - d3 * c4 - d5
        wx = -(x6x * vx + x6y * vy + x6z * vz)
        wy = r02 * vx + r12 * vy + r22 * vz
        rr = wx * wx + wy * wy
        if rr < WRIST_SINGULAR_TOL * WRIST_SINGULAR_TOL:
            return [(r, SINGULAR, nan7) for r in rows]
        h3 = rr - d26 * d26
        if h3 < 0.0:
            return [(r, UNREACHABLE, nan7) for r in rows]
        sh3 = sqrt(h3)
        irr = 1.0 / rr
        # z5 = s6 x6 - c6 z7 and x5 = c6 x6 + s6 z7 (y6 = -z7); P = p6 + t z5 lies on the
        # joint-3 axis, t = a4 tan(q4 / 2) - d5 (the half-angle tangent in its stable form).
        t = a4 * (s4 / (1.0 + c4) if c4 >= 0.0 else (1.0 - c4) / s4) - d5
        out = []
        last6 = -1
        for row in rows:
            i6 = row >> 1
            if i6 != last6:
                last6 = i6
                # q6 = theta - phi (i6 = 1) or pi - theta - phi, theta = atan2(d26, sh3),
                # phi = atan2(wy, wx): its cosine and sine times |w|^2 from the sides.
                if i6:
                    cn, sn = sh3 * wx + d26 * wy, d26 * wx - sh3 * wy
                else:
                    cn, sn = d26 * wy - sh3 * wx, d26 * wx + sh3 * wy
                q6 = atan2(sn, cn)
                if q6 < lo6:
                    q6 += TWO_PI
                elif q6 > hi6:
                    q6 -= TWO_PI
                ok = lo6 <= q6 <= hi6
                c6, s6 = cn * irr, sn * irr
                ux = vx + t * (s6 * x6x - c6 * r02)  # V2P = P - p2
                uy = vy + t * (s6 * x6y - c6 * r12)
                uz = vz + t * (s6 * x6z - c6 * r22)
                x5x = c6 * x6x + s6 * r02
                x5y = c6 * x6y + s6 * r12
                x5z = c6 * x6z + s6 * r22
                # Frame 3: z3 = u / |u|, y3 = m / |m| with m = u x V26 (the arm plane's
                # normal), x3 = y3 x z3 = X / (|m| |u|) with X = m x u; x4 = c4 x3 + s4 z3.
                # Each angle below is atan2 of two components scaled by one positive
                # factor (|m| |u| and the like), so nothing needs normalising.
                mx = uy * vz - uz * vy
                my = uz * vx - ux * vz
                mz = ux * vy - uy * vx
                bx = my * uz - mz * uy
                by = mz * ux - mx * uz
                bz = mx * uy - my * ux
                huu = ux * ux + uy * uy
                lu = sqrt(huu + uz * uz)
                mm = sqrt(mx * mx + my * my + mz * mz)
                hxy = sqrt(huu)
                q5 = atan2(
                    lu * (x5x * mx + x5y * my + x5z * mz),
                    c4 * (x5x * bx + x5y * by + x5z * bz)
                    + s4 * mm * (x5x * ux + x5y * uy + x5z * uz),
                )
                ok = ok and mm > 0.0 and lo5 <= q5 <= hi5  # mm = 0: no arm plane
                if ok and hxy >= SHOULDER_SINGULAR_TOL:
                    # Shoulder: z3 = (c1 s2, s1 s2, c2), so q1 and q2 come from u; x3 =
                    # c3 x2 + s3 z2 with x2 = (c1 c2, s1 c2, -s2), z2 = (-s1, c1, 0), times
                    # |u|^2 |m| hypot(ux, uy). The other shoulder branch (q1 + pi, -q2)
                    # negates c1, s1, s2: q3 + pi.
                    q1a = atan2(uy, ux)
                    q2a = atan2(hxy, uz)
                    q3a = atan2(lu * (ux * by - uy * bx), uz * (ux * bx + uy * by) - huu * bz)
            if not ok:
                out.append((row, JOINT_LIMIT, nan7))
                continue
            if hxy < SHOULDER_SINGULAR_TOL:  # q1 undefined: take q_init's
                q1 = q1_init
                c1, s1 = cos(q1), sin(q1)
                q2 = atan2(c1 * ux + s1 * uy, uz)
                c2, s2 = cos(q2), sin(q2)
                q3 = atan2(c1 * by - s1 * bx, c2 * (c1 * bx + s1 * by) - s2 * bz)
            elif row & 1:
                q1, q2, q3 = _flip(q1a), -q2a, _flip(q3a)
            else:
                q1, q2, q3 = q1a, q2a, q3a
            if lo1 <= q1 <= hi1 and lo2 <= q2 <= hi2 and lo3 <= q3 <= hi3:
                out.append((row, OK, (q1, q2, q3, q4, q5, q6, q7)))
            else:
                out.append((row, JOINT_LIMIT, nan7))
        return out

    return solve


# ------------------------------------------------------------------ NumPy, over N poses


@dataclass
class _Pose:
    """Per-pose quantities shared by all four branches (arrays over N poses)."""

    r02: NDArray[np.float64]
    r12: NDArray[np.float64]
    r22: NDArray[np.float64]
    x6: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
    v: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
    q4: NDArray[np.float64]
    c4: NDArray[np.float64]
    s4: NDArray[np.float64]
    t: NDArray[np.float64]
    d26: NDArray[np.float64]
    sh3: NDArray[np.float64]
    wx: NDArray[np.float64]
    wy: NDArray[np.float64]
    irr: NDArray[np.float64]
    status: NDArray[np.int8]  # the pose-level failure (OK if none)


def _pose(
    P: IKParams, R: NDArray[np.float64], p: NDArray[np.float64], q7: NDArray[np.float64]
) -> _Pose:
    lo, hi = P.q_min, P.q_max
    r00, r01, r02 = R[:, 0, 0], R[:, 0, 1], R[:, 0, 2]
    r10, r11, r12 = R[:, 1, 0], R[:, 1, 1], R[:, 1, 2]
    r20, r21, r22 = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
    psi = q7 + P.theta_e
    cp, sp = np.cos(psi), np.sin(psi)
    x6x = cp * r00 - sp * r01
    x6y = cp * r10 - sp * r11
    x6z = cp * r20 - sp * r21
    vx = p[:, 0] - P.d_e * r02 - P.a7 * x6x
    vy = p[:, 1] - P.d_e * r12 - P.a7 * x6y
    vz = p[:, 2] - P.d_e * r22 - P.a7 * x6z - P.d1
    ll = vx * vx + vy * vy + vz * vz
    l24, l46 = P.l24, P.l46
    h1 = ll - (l24 - l46) ** 2
    h2 = (l24 + l46) ** 2 - ll
    y4 = np.sqrt(h1 * h2)
    x4 = (l24 * l24 + l46 * l46) - ll
    q4 = np.arctan2(y4, x4) + P.q4_offset
    ca, sa = x4 * P.inv_2l24l46, y4 * P.inv_2l24l46
    c_off, s_off = P.cos_q4_offset, P.sin_q4_offset
    c4, s4 = ca * c_off - sa * s_off, sa * c_off + ca * s_off
    d26 = P.a4 * s4 - P.d3 * c4 - P.d5
    wx = -(x6x * vx + x6y * vy + x6z * vz)
    wy = r02 * vx + r12 * vy + r22 * vz
    rr = wx * wx + wy * wy
    h3 = rr - d26 * d26
    half = np.where(c4 >= 0.0, s4 / (1.0 + c4), (1.0 - c4) / s4)
    status = np.zeros(q7.shape[0], dtype=np.int8)
    # the scalar solver's order of tests: the first failing one names the reason
    status[h3 < 0.0] = UNREACHABLE
    status[rr < WRIST_SINGULAR_TOL * WRIST_SINGULAR_TOL] = SINGULAR
    status[~((lo[3] <= q4) & (q4 <= hi[3]))] = JOINT_LIMIT
    status[(h1 < 0.0) | (h2 < 0.0)] = UNREACHABLE
    status[~((lo[6] <= q7) & (q7 <= hi[6]))] = JOINT_LIMIT
    return _Pose(
        r02, r12, r22, (x6x, x6y, x6z), (vx, vy, vz), q4, c4, s4,
        P.a4 * half - P.d5, d26, np.sqrt(h3), wx, wy, 1.0 / rr, status,
    )  # fmt: skip


def _branch(
    P: IKParams,
    g: _Pose,
    i6: object,
    i1s: tuple[object, ...],
    q7: NDArray[np.float64],
    q1_init: NDArray[np.float64],
) -> list[tuple[NDArray[np.float64], NDArray[np.int8]]]:
    """The solutions (N, 7) and statuses (N,) of the branches (i6, i1) for each i1 in
    i1s (i6 and each i1 a bool or a bool array over the poses)."""
    lo, hi = np.asarray(P.q_min), np.asarray(P.q_max)
    (x6x, x6y, x6z), (vx, vy, vz) = g.x6, g.v
    r02, r12, r22, c4, s4, t = g.r02, g.r12, g.r22, g.c4, g.s4, g.t
    d26, sh3, wx, wy = g.d26, g.sh3, g.wx, g.wy
    if isinstance(i6, np.ndarray):
        cn = np.where(i6, sh3 * wx + d26 * wy, d26 * wy - sh3 * wx)
        sn = np.where(i6, d26 * wx - sh3 * wy, d26 * wx + sh3 * wy)
    elif i6:
        cn, sn = sh3 * wx + d26 * wy, d26 * wx - sh3 * wy
    else:
        cn, sn = d26 * wy - sh3 * wx, d26 * wx + sh3 * wy
    q6 = np.arctan2(sn, cn)
    q6 = np.where(q6 < lo[5], q6 + TWO_PI, np.where(q6 > hi[5], q6 - TWO_PI, q6))
    c6, s6 = cn * g.irr, sn * g.irr
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
    lu = np.sqrt(huu + uz * uz)
    mm = np.sqrt(mx * mx + my * my + mz * mz)
    hxy = np.sqrt(huu)
    q5 = np.arctan2(
        lu * (x5x * mx + x5y * my + x5z * mz),
        c4 * (x5x * bx + x5y * by + x5z * bz) + s4 * mm * (x5x * ux + x5y * uy + x5z * uz),
    )
    q5[~(mm > 0.0)] = np.nan  # no arm plane
    q1 = np.arctan2(uy, ux)
    q2 = np.arctan2(hxy, uz)
    q3 = np.arctan2(lu * (ux * by - uy * bx), uz * (ux * bx + uy * by) - huu * bz)
    sing = hxy < SHOULDER_SINGULAR_TOL
    ks = np.flatnonzero(sing) if np.any(sing) else None
    q1f = np.where(q1 > 0.0, q1 - math.pi, q1 + math.pi)
    q3f = np.where(q3 > 0.0, q3 - math.pi, q3 + math.pi)
    out = []
    for i1 in i1s:
        if isinstance(i1, np.ndarray):
            a1, a2, a3 = np.where(i1, q1f, q1), np.where(i1, -q2, q2), np.where(i1, q3f, q3)
        elif i1:
            a1, a2, a3 = q1f, -q2, q3f
        else:
            a1, a2, a3 = q1.copy(), q2.copy(), q3.copy()
        if ks is not None:  # q1 undefined: take q_init's
            k = ks
            a1[k] = q1_init[k]
            c1k, s1k = np.cos(a1[k]), np.sin(a1[k])
            a2[k] = np.arctan2(c1k * ux[k] + s1k * uy[k], uz[k])
            c2k, s2k = np.cos(a2[k]), np.sin(a2[k])
            a3[k] = np.arctan2(
                c1k * by[k] - s1k * bx[k], c2k * (c1k * bx[k] + s1k * by[k]) - s2k * bz[k]
            )
        q = np.stack([a1, a2, a3, g.q4, q5, q6, q7], axis=1)
        ok = np.all((lo <= q) & (q <= hi), axis=1)
        status = np.where(g.status != OK, g.status, np.where(ok, OK, JOINT_LIMIT)).astype(np.int8)
        q[status != OK] = np.nan
        out.append((q, status))
    return out


def solve_batch(
    P: IKParams,
    R: NDArray[np.float64],
    p: NDArray[np.float64],
    q7: NDArray[np.float64],
    q1_init: NDArray[np.float64],
    row: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.int8]]:
    """Vectorised solver: R (N, 3, 3), p (N, 3), q7, q1_init, row (N,) -> q (N, 7) with NaN
    rows where there is no solution, status (N,) int8."""
    with np.errstate(invalid="ignore", divide="ignore"):
        g = _pose(P, R, p, q7)
        ((q, status),) = _branch(
            P, g, (row >> 1).astype(bool), ((row & 1).astype(bool),), q7, q1_init
        )
    return q, status


def solve_batch_full(
    P: IKParams,
    R: NDArray[np.float64],
    p: NDArray[np.float64],
    q7: NDArray[np.float64],
    q1_init: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.int8]]:
    """All four branches: q (N, 4, 7) (NaN rows without a solution), status (N, 4) int8.
    The per-pose part is computed once."""
    n = q7.shape[0]
    q = np.empty((n, 4, 7))
    status = np.empty((n, 4), dtype=np.int8)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = _pose(P, R, p, q7)
        for i6 in (False, True):
            for i1, (qb, sb) in enumerate(_branch(P, g, i6, (False, True), q7, q1_init)):
                q[:, 2 * i6 + i1], status[:, 2 * i6 + i1] = qb, sb
    return q, status
