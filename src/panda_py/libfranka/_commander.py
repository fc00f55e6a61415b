"""Turn what a control callback returns into the RobotCommand record: type and value
checks, the optional low-pass filter and rate limiter (referenced to the desired/commanded
values in the robot's last state, as libfranka's ``ControlLoop::convertMotion``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py.fci import Dialect
from panda_py.libfranka import limits as lim
from panda_py.libfranka.types import (
    CartesianPose,
    CartesianVelocities,
    JointPositions,
    JointVelocities,
    Torques,
    is_homogeneous_transformation,
)

__all__ = ["Commander", "check_cutoff"]


def check_cutoff(limit_rate: Any, cutoff_frequency: Any) -> tuple[bool, float]:
    if not isinstance(limit_rate, (bool, np.bool_)):
        raise ValueError(f"limit_rate: expected a bool, got {limit_rate!r}")
    try:
        f = float(cutoff_frequency)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"cutoff_frequency: expected a number [Hz], got {cutoff_frequency!r}"
        ) from exc
    if not (math.isfinite(f) and f > 0.0):
        raise ValueError(f"cutoff_frequency: expected a finite frequency > 0 [Hz], got {f!r}")
    return bool(limit_rate), f


def _finite(name: str, x: np.ndarray) -> None:
    s = float(x.sum())
    if s - s != 0.0:
        raise ValueError(f"{name}: Commanding value is infinite or NaN.")


def _expect(out: Any, kind: type) -> None:
    if type(out) is not kind and not isinstance(out, kind):
        raise ValueError(
            f"callback: expected it to return {kind.__name__}, got {type(out).__name__}"
        )


class Commander:
    """Holds the pre-allocated command record of one motion and fills it each tick."""

    def __init__(
        self, dialect: Dialect, limits: lim.RateLimits, limit_rate: bool, cutoff_frequency: float
    ) -> None:
        self.record = dialect.new_command()
        rec = self.record
        self._q_c = rec["q_c"]
        self._dq_c = rec["dq_c"]
        self._O_T_EE_c = rec["O_T_EE_c"]
        self._O_dP_EE_c = rec["O_dP_EE_c"]
        self._elbow_c = rec["elbow_c"]
        self._tau = rec["tau_J_d"]
        self.limits = limits
        self.limit_rate = limit_rate
        self.filter = cutoff_frequency < lim.MAX_CUTOFF_FREQUENCY
        self.cutoff = cutoff_frequency
        self.gain = lim._gain(lim.DELTA_T, cutoff_frequency) if self.filter else 1.0
        self.initialized = False  # position/pose filters start from the first command

    # --- torques --------------------------------------------------------------------

    def torques(self, out: Any, state: np.void) -> bool:
        _expect(out, Torques)
        tau = out.tau_J
        _finite("tau_J", tau)
        last = state["tau_J_d"]
        if self.filter:
            tau = last + self.gain * (tau - last)
        if self.limit_rate:
            m = self.limits.max_torque_rate
            tau = last + np.minimum(np.maximum((tau - last) / lim.DELTA_T, -m), m) * lim.DELTA_T
        _finite("tau_J", tau)
        self._tau[:] = tau
        return bool(out.motion_finished)

    # --- motion generators ------------------------------------------------------------

    def joint_positions(self, out: Any, state: np.void) -> bool:
        _expect(out, JointPositions)
        q = out.q
        _finite("q", q)
        q_d = state["q_d"]
        if self.filter and self.initialized:
            q = q_d + self.gain * (q - q_d)
        self.initialized = True
        if self.limit_rate:
            L = self.limits
            upper, lower = L.joint_velocity_limits(q_d)
            q = lim.limit_rate_joint_positions(
                upper, lower, L.max_joint_acceleration, L.max_joint_jerk, q, q_d,
                state["dq_d"], state["ddq_d"],
            )  # fmt: skip
        _finite("q", q)
        self._q_c[:] = q
        return bool(out.motion_finished)

    def joint_velocities(self, out: Any, state: np.void) -> bool:
        _expect(out, JointVelocities)
        dq = out.dq
        _finite("dq", dq)
        dq_d = state["dq_d"]
        if self.filter:
            dq = dq_d + self.gain * (dq - dq_d)
        if self.limit_rate:
            L = self.limits
            upper, lower = L.joint_velocity_limits(state["q_d"])
            dq = lim.limit_rate_joint_velocities(
                upper, lower, L.max_joint_acceleration, L.max_joint_jerk, dq, dq_d,
                state["ddq_d"],
            )  # fmt: skip
        _finite("dq", dq)
        self._dq_c[:] = dq
        return bool(out.motion_finished)

    def _elbow(self, elbow: Any, state: np.void, first: bool) -> None:
        if elbow is None:
            self.record["valid_elbow"] = False
            self._elbow_c[:] = 0.0
            return
        e0 = float(elbow[0])
        sign = float(elbow[1])
        if sign != 1.0 and sign != -1.0:
            raise ValueError(f"elbow: elbow[1] must be +1 or -1, got {sign!r}")
        last = float(state["elbow_c"][0])
        if self.filter and not first:
            e0 = last + self.gain * (e0 - last)
        if self.limit_rate:
            e0 = lim.limit_rate_position(
                self.limits.elbow, e0, last, float(state["delbow_c"][0]),
                float(state["ddelbow_c"][0]),
            )  # fmt: skip
        if not math.isfinite(e0):
            raise ValueError("elbow: Commanding value is infinite or NaN.")
        self.record["valid_elbow"] = True
        self._elbow_c[0] = e0
        self._elbow_c[1] = sign

    def cartesian_pose(self, out: Any, state: np.void) -> bool:
        _expect(out, CartesianPose)
        T = out.O_T_EE
        _finite("O_T_EE", T)
        if not is_homogeneous_transformation(T):
            raise ValueError(
                "O_T_EE: Attempt to set invalid transformation in motion generator. "
                "Has to be column major!"
            )
        first = not self.initialized
        self.initialized = True
        last = state["O_T_EE_c"]
        if self.filter and not first:
            T = lim.cartesian_lowpass_filter(lim.DELTA_T, T, last, self.cutoff)
        if self.limit_rate:
            L = self.limits
            T = lim.limit_rate_cartesian_pose(
                L.translation, L.rotation, T, last, state["O_dP_EE_c"], state["O_ddP_EE_c"]
            )
        _finite("O_T_EE", T)
        self._O_T_EE_c[:] = T
        self._elbow(out.elbow, state, first)
        return bool(out.motion_finished)

    def cartesian_velocities(self, out: Any, state: np.void) -> bool:
        _expect(out, CartesianVelocities)
        v = out.O_dP_EE
        _finite("O_dP_EE", v)
        last = state["O_dP_EE_c"]
        if self.filter:
            v = last + self.gain * (v - last)
        if self.limit_rate:
            L = self.limits
            v = lim.limit_rate_cartesian_velocity(
                L.translation, L.rotation, v, last, state["O_ddP_EE_c"]
            )
        _finite("O_dP_EE", v)
        self._O_dP_EE_c[:] = v
        self._elbow(out.elbow, state, False)
        return bool(out.motion_finished)
