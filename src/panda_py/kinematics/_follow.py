"""Configurations that follow a path of poses the way the arm moves along it: each the
previous one moved by damped least-squares steps toward the next pose (``q += J^T (J J^T
+ λ² I)^-1 e``), as a Cartesian law's ``J^+`` feed-forward moves the joints. Unlike the
analytical inverse kinematics (one configuration per pose, in a case, with q7 given), the
result is continuous by construction, moves q7 as the arm would, and keeps going where the
inverse kinematics' case ends or its solution splits joints 1 and 3 anew at every pose
(q2 = 0).

Scalar Python, run as it is (the plain backend) or compiled by numba (:mod:`._numba`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py.kinematics import _fk

# the smallest square of a pivot of the Cholesky factor: without damping, a singular arm
# leaves a step finite (in directions the error has next to nothing of)
MIN_PIVOT = 1e-12


def _rrt(T: Any, P: Any, a: int, b: int) -> float:
    """Element (a, b) of R_T R_P^T: T a 4x4 pose, P a 3x4 row-major one."""
    return T[a, 0] * P[4 * b] + T[a, 1] * P[4 * b + 1] + T[a, 2] * P[4 * b + 2]


def _step(c: Any, T: Any, q: Any, damping: float, A: Any, e: Any) -> None:
    """One damped least-squares step of q (7,) toward the pose T (4, 4), in place."""
    P = _fk.ee_pose(c, q)  # 3x4 row-major
    e[0] = T[0, 3] - P[3]
    e[1] = T[1, 3] - P[7]
    e[2] = T[2, 3] - P[11]
    # the rotation error's small-angle vector: vee of R_d R^T's antisymmetric part
    e[3] = 0.5 * (_rrt(T, P, 2, 1) - _rrt(T, P, 1, 2))
    e[4] = 0.5 * (_rrt(T, P, 0, 2) - _rrt(T, P, 2, 0))
    e[5] = 0.5 * (_rrt(T, P, 1, 0) - _rrt(T, P, 0, 1))
    cols = _fk.jacobian_columns(c, q, False)
    # A = J J^T + λ² I, then its Cholesky factor in the lower triangle
    for i in range(6):
        for j in range(i + 1):
            s = 0.0
            for k in range(7):
                s += cols[k][i] * cols[k][j]
            A[i, j] = s
        A[i, i] += damping * damping
    for i in range(6):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = math.sqrt(max(s, MIN_PIVOT)) if i == j else s / A[j, j]
    for i in range(6):  # L y = e
        s = e[i]
        for k in range(i):
            s -= A[i, k] * e[k]
        e[i] = s / A[i, i]
    for i in range(5, -1, -1):  # L^T x = y
        s = e[i]
        for k in range(i + 1, 6):
            s -= A[k, i] * e[k]
        e[i] = s / A[i, i]
    for k in range(7):  # q += J^T x
        col = cols[k]
        q[k] += (
            col[0] * e[0]
            + col[1] * e[1]
            + col[2] * e[2]
            + col[3] * e[3]
            + col[4] * e[4]
            + col[5] * e[5]
        )


def follow_path(P: Any, C: Any, q0: Any, damping: float, iterations: int, out: Any) -> None:
    """For each pose of P (N, 4, 4) in order, the configuration before it (``q0`` for the
    first) moved by ``iterations`` steps toward it, into out (N, 7); C the packed chain."""
    c = _fk.unpack_chain(C)
    A = np.empty((6, 6))
    e = np.empty(6)
    q = np.empty(7)
    for i in range(7):
        q[i] = q0[i]
    for k in range(P.shape[0]):
        T = P[k]
        for _ in range(iterations):
            _step(c, T, q, damping, A, e)
        for i in range(7):
            out[k, i] = q[i]
