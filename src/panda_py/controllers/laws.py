"""The math of panda-py's control laws: input filters, pose errors, the nullspace
projector, joint walls and torque saturation. Pure NumPy on small arrays, no I/O; the
control process calls them once a tick.

Conventions: quaternions (x, y, z, w); ``O_T_EE`` flat column-major (16,) as in
``RobotState``; Jacobians (6, 7) with linear rows first.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import jit, progress
from panda_py.motion.rotation import from_matrix

__all__ = [
    "DTAU_MAX_PER_TICK",
    "JointWalls",
    "cartesian_error",
    "clip_torques",
    "compiled",
    "damped_pinv",
    "ema",
    "fused",
    "nullspace_projector",
    "quat_from_matrix",
    "saturate_torque_rate",
    "slerp",
    "warmup",
]

FloatArray = NDArray[np.float64]

# panda-py's torque-rate saturation: 1 Nm per 1 ms tick (kDeltaTauMax = 1.0), i.e. the
# robot's documented 1000 Nm/s (FCI docs, "dtau_max").
DTAU_MAX_PER_TICK = 1.0  # [Nm]
# Damping of the pseudo-inverse in the nullspace projector. panda-py uses 0.2, which
# leaks the nullspace torques into the task (measured: 7 mm and 4 deg left at the end of
# a 14 cm move_to_pose with nullspace stiffness 15); 0.01 leaks nothing measurable and
# still bounds the inverse near singular configurations.
PINV_DAMPING = 0.01


KERNELS = "panda_py.controllers._kernels"
FUSED = "panda_py.controllers._fused"


def compiled() -> Any:
    """The laws compiled by numba (:mod:`._kernels`), or None (numba missing, or
    ``PANDA_PY_NO_JIT=1``): imported on first use (:func:`panda_py.jit.optional`)."""
    return jit.optional(KERNELS)


def fused() -> Any:
    """The laws compiled with their model terms (:mod:`._fused`: ``CartesianImpedance``'s
    step and the moves' and streamed targets' tracking, each in one call), or None where
    the laws, the kinematics or the dynamics run without numba: imported (and compiled or
    loaded) on first use."""
    return jit.optional(FUSED, requires=compiled)


def warmup() -> None:
    """Compile (or load from numba's cache) the compiled laws now: the control process
    calls this before its loop, whose first tick must not wait for a compiler. Each
    kernel module runs its own kernels on inputs of its own (``_kernels.warmup``,
    ``_fused.warmup``)."""
    k = compiled()
    if k is not None:
        title = "panda_py: compiling the control laws, once after installing"
        with progress.work(title, k.WARM_STEPS + 1) as w:
            k.warmup(w.advance)
            f = fused()
            if f is not None:
                f.warmup()  # the laws compiled with their model terms
            w.advance()


def ema(filtered: FloatArray, target: FloatArray, alpha: float) -> None:
    """In place: ``filtered <- alpha target + (1 - alpha) filtered`` (panda-py's first-order
    input filter; alpha = 1 follows the target at once)."""
    if alpha >= 1.0:
        filtered[:] = target
    else:
        filtered += alpha * (target - filtered)


def quat_from_matrix(O_T_EE: FloatArray) -> FloatArray:
    """Unit quaternion (x, y, z, w) of the rotation of a flat column-major transform."""
    return from_matrix(O_T_EE.reshape(4, 4, order="F"))


def slerp(q0: FloatArray, q1: FloatArray, t: float) -> FloatArray:
    """Spherical interpolation from ``q0`` (t = 0) to ``q1`` (t = 1), shortest arc."""
    if t >= 1.0:
        return q1 / math.sqrt(float(q1 @ q1))
    d = float(q0 @ q1)
    target = q1 if d >= 0.0 else -q1
    d = abs(d)
    if d > 1.0 - 1e-9:
        out = q0 + t * (target - q0)
    else:
        theta = math.acos(d)
        s = math.sin(theta)
        out = (math.sin((1.0 - t) * theta) / s) * q0 + (math.sin(t * theta) / s) * target
    return out / math.sqrt(float(out @ out))


def cartesian_error(O_T_EE: FloatArray, position_d: FloatArray, quat_d: FloatArray) -> FloatArray:
    """panda-py's Cartesian impedance error (6,): position minus desired position [m], and
    the vector part of the rotation from desired to actual, in the base frame."""
    err = np.empty(6)
    err[0] = O_T_EE[12] - position_d[0]
    err[1] = O_T_EE[13] - position_d[1]
    err[2] = O_T_EE[14] - position_d[2]
    q = quat_from_matrix(O_T_EE)
    if float(quat_d @ q) < 0.0:
        q = -q
    # e = q^-1 * q_d (vector part), then -R e in the base frame
    x, y, z, w = q
    xd, yd, zd, wd = quat_d
    ex = w * xd - x * wd - (y * zd - z * yd)
    ey = w * yd - y * wd - (z * xd - x * zd)
    ez = w * zd - z * wd - (x * yd - y * xd)
    R = O_T_EE.reshape(4, 4, order="F")[:3, :3]
    err[3:] = -(R @ np.array((ex, ey, ez)))
    return err


def damped_pinv(J: FloatArray) -> FloatArray:
    """``J^T (J J^T + lambda^2 I)^-1`` (7x6), lambda = ``PINV_DAMPING``."""
    JJt = J @ J.T
    JJt[np.diag_indices(6)] += PINV_DAMPING * PINV_DAMPING
    return np.linalg.solve(JJt, J).T  # JJt is symmetric


def nullspace_projector(J: FloatArray) -> FloatArray:
    """``I - J^T pinv(J^T)`` with a damped pseudo-inverse (lambda = ``PINV_DAMPING``)."""
    # pinv_damped(J^T) = (J J^T + lambda^2 I)^-1 J  (6x7), by the push-through identity
    return np.eye(7) - J.T @ damped_pinv(J).T


def saturate_torque_rate(tau: FloatArray, tau_J_d: FloatArray) -> FloatArray:
    """Limit the change from the last commanded torque to 1 Nm per tick (panda-py)."""
    return tau_J_d + np.clip(tau - tau_J_d, -DTAU_MAX_PER_TICK, DTAU_MAX_PER_TICK)


def clip_torques(tau: FloatArray, tau_max: FloatArray) -> FloatArray:
    return np.clip(tau, -tau_max, tau_max)


# panda-py's joint walls: PD zone and D zone widths [rad], PD stiffness [Nm/rad] and the
# dampings [Nm s/rad] per joint (panda-py include/constants.h).
WALL_PD_WIDTH = (0.12, 0.09, 0.09, 0.09, 0.0349, 0.0349, 0.0349)
WALL_D_WIDTH = (0.12, 0.09, 0.09, 0.09, 0.0349, 0.0349, 0.0349)
WALL_PD_STIFFNESS = (2000.0, 2000.0, 1000.0, 1000.0, 500.0, 200.0, 200.0)
WALL_PD_DAMPING = (30.0, 30.0, 30.0, 10.0, 5.0, 5.0, 5.0)
WALL_D_DAMPING = (30.0, 30.0, 30.0, 10.0, 5.0, 5.0, 5.0)


class JointWalls:
    """Virtual walls inside the joint limits: pure damping in a zone near each limit, a
    spring plus damping in the zone next to it (panda-py's ``VirtualWall`` per joint).

    If a joint starts inside a zone, the zone shrinks to where the joint is, so starting
    near a limit does not kick the arm; it widens back as the joint leaves.
    """

    def __init__(self, lower: Any, upper: Any) -> None:
        self.lower = [float(v) for v in lower]
        self.upper = [float(v) for v in upper]
        # per joint: lower, upper, PD width, D width, PD stiffness, PD damping, D damping
        self._table = np.array(
            [self.lower, self.upper, WALL_PD_WIDTH, WALL_D_WIDTH, WALL_PD_STIFFNESS,
             WALL_PD_DAMPING, WALL_D_DAMPING]
        ).T.copy()  # fmt: skip
        self._kernel_scale = np.ones(7)
        self._flags = np.zeros(8, dtype=np.int64)
        self.reset()

    def reset(self) -> None:
        self._scale = [1.0] * 7
        self._moving = [False] * 7
        self._initialized = False
        self._kernel_scale[:] = 1.0
        self._flags[:] = 0

    def kernel_state(self) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """What the compiled finishing takes of the walls (``_kernels.finalize_torques``):
        their table, and their state (scales, flags), updated in place by either path."""
        return self._table, self._kernel_scale, self._flags

    def finalize(self, tau: FloatArray, q: FloatArray, dq: FloatArray, tau_J_d: FloatArray,
                 tau_max: FloatArray, out: FloatArray, gain: float = 1.0) -> bool:  # fmt: skip
        """What the loop does to a law's torques ``tau`` (7,): add the walls, saturate
        the rate of change around the last command ``tau_J_d``, clip to ``tau_max``, then
        libfranka's first-order low-pass toward the result from ``tau_J_d`` with ``gain``
        (``limits.lowpass_filter``'s; 1: no filter); into ``out``. False if a torque (the
        law's or the result) is not finite. One compiled call where numba is installed
        (the walls' state is kept apart for either path: use one per loop)."""
        kernels = compiled()
        if kernels is not None:
            return bool(
                kernels.finalize_torques(
                    tau, q, dq, tau_J_d, self._table, self._kernel_scale, self._flags,
                    DTAU_MAX_PER_TICK, tau_max, gain, out,
                )
            )  # fmt: skip
        walls = self.torques(q, dq)
        out[:] = clip_torques(saturate_torque_rate(tau + walls, tau_J_d), tau_max)
        if gain != 1.0:
            out[:] = tau_J_d + gain * (out - tau_J_d)
        return bool(np.isfinite(tau).all() and np.isfinite(out).all())

    def _motion(self, i: int, q: float, dq: float) -> int:
        """0 normal, -1 penetrating/leaving the lower zone, +1 the upper (sign of dq kept
        in the second value)."""
        width = WALL_PD_WIDTH[i] + WALL_D_WIDTH[i]
        if q < self.lower[i] + width:
            return -2 if dq <= 0.0 else -1  # -2 penetrating, -1 leaving
        if q > self.upper[i] - width:
            return 2 if dq >= 0.0 else 1
        return 0

    def torques(self, q: Any, dq: Any) -> list[float]:
        out = [0.0] * 7
        for i in range(7):
            qi, dqi = float(q[i]), float(dq[i])
            width = WALL_PD_WIDTH[i] + WALL_D_WIDTH[i]
            motion = self._motion(i, qi, dqi)
            if not self._initialized:
                if motion != 0:
                    limit = self.lower[i] if motion < 0 else self.upper[i]
                    self._scale[i] = min(1.0, abs(qi - limit) / width)
                    self._moving[i] = True
            elif self._moving[i]:
                if motion == 0:
                    self._moving[i] = False
                    self._scale[i] = 1.0
                elif abs(motion) == 1:
                    limit = self.lower[i] if motion < 0 else self.upper[i]
                    self._scale[i] = min(1.0, max(self._scale[i], abs(qi - limit) / width))
            s = self._scale[i]
            d_max = self.upper[i] - s * width
            pd_max = self.upper[i] - s * WALL_PD_WIDTH[i]
            d_min = self.lower[i] + s * width
            pd_min = self.lower[i] + s * WALL_PD_WIDTH[i]
            if d_max <= qi <= pd_max or pd_min <= qi <= d_min:
                out[i] = -WALL_D_DAMPING[i] * dqi
            elif qi > pd_max:
                out[i] = -WALL_PD_DAMPING[i] * dqi + WALL_PD_STIFFNESS[i] * (pd_max - qi)
            elif qi < pd_min:
                out[i] = -WALL_PD_DAMPING[i] * dqi + WALL_PD_STIFFNESS[i] * (pd_min - qi)
        self._initialized = True
        return out
