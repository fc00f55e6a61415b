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


# The solver's signature: (R row-major 9, p 3, q7, q1_init, branches) -> rows
ScalarSolver = Callable[..., list[tuple[int, int, tuple[float, ...]]]]


def make_scalar_solver(P: IKParams) -> ScalarSolver:
    """A function ``solve(r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7,
    q1_init, rows)`` returning ``[(row, status, q), ...]`` for the requested rows (each in
    0..3), ``q`` a 7-tuple of floats (meaningful only when status is OK)."""
    d1, d3, d5, a4, a7, d_e, theta_e = P.d1, P.d3, P.d5, P.a4, P.a7, P.d_e, P.theta_e
    l24, l46 = P.l24, P.l46
    l24_sq_l46_sq = l24 * l24 + l46 * l46
    diff_sq = (l24 - l46) ** 2
    sum_sq = (l24 + l46) ** 2
    q4_off = P.q4_offset
    lo1, lo2, lo3, lo4, lo5, lo6, lo7 = P.q_min
    hi1, hi2, hi3, hi4, hi5, hi6, hi7 = P.q_max
    sin, cos, atan2, sqrt, tan, pi = math.sin, math.cos, math.atan2, math.sqrt, math.tan, math.pi

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
        # Elbow angle from the triangle (p2, p4, p6), via atan2 of a Heron-type sine.
        h1 = ll - diff_sq
        h2 = sum_sq - ll
        if h1 < 0.0 or h2 < 0.0:
            return [(r, UNREACHABLE, nan7) for r in rows]
        q4 = atan2(sqrt(h1 * h2), l24_sq_l46_sq - ll) + q4_off
        if not lo4 <= q4 <= hi4:
            return [(r, JOINT_LIMIT, nan7) for r in rows]
        c4, s4 = cos(q4), sin(q4)
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
        theta = atan2(d26, sqrt(h3))
        phi = atan2(wy, wx)
        # z6 = z7 x x6, needed for nothing but q6's frame: z5 = s6 x6 - c6 z7 and
        # x5 = c6 x6 + s6 z7 (y6 = -z7).
        t = a4 * tan(0.5 * q4) - d5  # P = p6 + t z5 lies on the joint-3 axis
        out = []
        last6 = -1
        for row in rows:
            i6 = row >> 1
            if i6 != last6:
                last6 = i6
                q6 = (theta - phi) if i6 else (pi - theta - phi)
                if q6 < lo6:
                    q6 += TWO_PI
                elif q6 > hi6:
                    q6 -= TWO_PI
                ok6 = lo6 <= q6 <= hi6
                c6, s6 = cos(q6), sin(q6)
                z5x = s6 * x6x - c6 * r02
                z5y = s6 * x6y - c6 * r12
                z5z = s6 * x6z - c6 * r22
                ux = vx + t * z5x  # V2P = P - p2
                uy = vy + t * z5y
                uz = vz + t * z5z
                hxy = sqrt(ux * ux + uy * uy)
                lu = sqrt(ux * ux + uy * uy + uz * uz)
                z3x, z3y, z3z = ux / lu, uy / lu, uz / lu
                # y3: normal of the arm plane, z3 x V26 normalised; x3 = y3 x z3.
                nx = z3y * vz - z3z * vy
                ny = z3z * vx - z3x * vz
                nz = z3x * vy - z3y * vx
                nn = sqrt(nx * nx + ny * ny + nz * nz)
                y3x, y3y, y3z = nx / nn, ny / nn, nz / nn
                x3x = y3y * z3z - y3z * z3y
                x3y = y3z * z3x - y3x * z3z
                x3z = y3x * z3y - y3y * z3x
                x4x, x4y, x4z = c4 * x3x + s4 * z3x, c4 * x3y + s4 * z3y, c4 * x3z + s4 * z3z
                x5x = c6 * x6x + s6 * r02
                x5y = c6 * x6y + s6 * r12
                x5z = c6 * x6z + s6 * r22
                q5 = atan2(x5x * y3x + x5y * y3y + x5z * y3z, x5x * x4x + x5y * x4y + x5z * x4z)
                ok5 = lo5 <= q5 <= hi5
            if not (ok6 and ok5):
                out.append((row, JOINT_LIMIT, nan7))
                continue
            # Shoulder: z3 = (c1 s2, s1 s2, c2).
            if hxy < SHOULDER_SINGULAR_TOL:
                q1 = q1_init
            else:
                q1 = atan2(uy, ux)
                if row & 1:
                    q1 = q1 - pi if q1 > 0.0 else q1 + pi
            c1, s1 = cos(q1), sin(q1)
            q2 = atan2(c1 * ux + s1 * uy, uz)
            c2, s2 = cos(q2), sin(q2)
            # x3 = c3 x2 + s3 z2 with x2 = (c1 c2, s1 c2, -s2), z2 = (-s1, c1, 0).
            q3 = atan2(c1 * x3y - s1 * x3x, c2 * (c1 * x3x + s1 * x3y) - s2 * x3z)
            if lo1 <= q1 <= hi1 and lo2 <= q2 <= hi2 and lo3 <= q3 <= hi3:
                out.append((row, OK, (q1, q2, q3, q4, q5, q6, q7)))
            else:
                out.append((row, JOINT_LIMIT, nan7))
        return out

    return solve


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
    n = q7.shape[0]
    lo = np.asarray(P.q_min)
    hi = np.asarray(P.q_max)
    status = np.zeros(n, dtype=np.int8)
    with np.errstate(invalid="ignore", divide="ignore"):
        r00, r01, r02 = R[:, 0, 0], R[:, 0, 1], R[:, 0, 2]
        r10, r11, r12 = R[:, 1, 0], R[:, 1, 1], R[:, 1, 2]
        r20, r21, r22 = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
        bad7 = ~((lo[6] <= q7) & (q7 <= hi[6]))
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
        unreach = (h1 < 0.0) | (h2 < 0.0)
        q4 = np.arctan2(np.sqrt(h1 * h2), (l24 * l24 + l46 * l46) - ll) + P.q4_offset
        bad4 = ~((lo[3] <= q4) & (q4 <= hi[3]))
        c4, s4 = np.cos(q4), np.sin(q4)
        d26 = P.a4 * s4 - P.d3 * c4 - P.d5
        wx = -(x6x * vx + x6y * vy + x6z * vz)
        wy = r02 * vx + r12 * vy + r22 * vz
        rr = wx * wx + wy * wy
        wrist_sing = rr < WRIST_SINGULAR_TOL * WRIST_SINGULAR_TOL
        h3 = rr - d26 * d26
        unreach6 = h3 < 0.0
        theta = np.arctan2(d26, np.sqrt(h3))
        phi = np.arctan2(wy, wx)
        t = P.a4 * np.tan(0.5 * q4) - P.d5
        i6 = (row >> 1).astype(bool)
        q6 = np.where(i6, theta - phi, math.pi - theta - phi)
        q6 = np.where(q6 < lo[5], q6 + TWO_PI, np.where(q6 > hi[5], q6 - TWO_PI, q6))
        c6, s6 = np.cos(q6), np.sin(q6)
        ux = vx + t * (s6 * x6x - c6 * r02)
        uy = vy + t * (s6 * x6y - c6 * r12)
        uz = vz + t * (s6 * x6z - c6 * r22)
        hxy = np.sqrt(ux * ux + uy * uy)
        lu = np.sqrt(ux * ux + uy * uy + uz * uz)
        z3x, z3y, z3z = ux / lu, uy / lu, uz / lu
        nx = z3y * vz - z3z * vy
        ny = z3z * vx - z3x * vz
        nz = z3x * vy - z3y * vx
        nn = np.sqrt(nx * nx + ny * ny + nz * nz)
        y3x, y3y, y3z = nx / nn, ny / nn, nz / nn
        x3x = y3y * z3z - y3z * z3y
        x3y = y3z * z3x - y3x * z3z
        x3z = y3x * z3y - y3y * z3x
        x4x, x4y, x4z = c4 * x3x + s4 * z3x, c4 * x3y + s4 * z3y, c4 * x3z + s4 * z3z
        x5x = c6 * x6x + s6 * r02
        x5y = c6 * x6y + s6 * r12
        x5z = c6 * x6z + s6 * r22
        q5 = np.arctan2(x5x * y3x + x5y * y3y + x5z * y3z, x5x * x4x + x5y * x4y + x5z * x4z)
        q1 = np.arctan2(uy, ux)
        flip = (row & 1).astype(bool)
        q1 = np.where(flip, np.where(q1 > 0.0, q1 - math.pi, q1 + math.pi), q1)
        q1 = np.where(hxy < SHOULDER_SINGULAR_TOL, q1_init, q1)
        c1, s1 = np.cos(q1), np.sin(q1)
        q2 = np.arctan2(c1 * ux + s1 * uy, uz)
        c2, s2 = np.cos(q2), np.sin(q2)
        q3 = np.arctan2(c1 * x3y - s1 * x3x, c2 * (c1 * x3x + s1 * x3y) - s2 * x3z)
        q = np.stack([q1, q2, q3, q4, q5, q6, q7], axis=1)
        in_limits = np.all((lo <= q) & (q <= hi), axis=1)
    # The same precedence as the scalar solver: the first failing step names the reason.
    status[~in_limits] = JOINT_LIMIT
    status[unreach6] = UNREACHABLE
    status[wrist_sing] = SINGULAR
    status[bad4] = JOINT_LIMIT
    status[unreach] = UNREACHABLE
    status[bad7] = JOINT_LIMIT
    q[status != OK] = np.nan
    return q, status
