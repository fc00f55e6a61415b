"""Turn what a control callback returns into the RobotCommand record: type and value
checks, the optional low-pass filter and rate limiter (referenced to the desired/commanded
values in the robot's last state, as libfranka's ``ControlLoop::convertMotion``).

This runs once per 1 ms tick, so it works on Python floats (:mod:`._fast`) and writes into
one pre-allocated record; :mod:`.limits` holds the NumPy reference of the same math.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py.fci import Dialect
from panda_py.libfranka import _fast
from panda_py.libfranka import limits as lim
from panda_py.libfranka.commands import (
    CartesianPose,
    CartesianVelocities,
    JointPositions,
    JointVelocities,
    Torques,
)

__all__ = ["Commander", "check_cutoff"]

_INVALID_POSE = (
    "O_T_EE: Attempt to set invalid transformation in motion generator. Has to be column major!"
)


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


def _finite(name: str, values: list[float]) -> None:
    s = sum(values)
    if s - s != 0.0:  # a NaN or an infinity makes this NaN
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
        self.gain = lim._gain(lim.DELTA_T, cutoff_frequency) if self.filter else 1.0
        self.initialized = False  # position/pose filters start from the first command
        L = limits
        self._tau_step = (L.max_torque_rate * lim.DELTA_T).tolist()
        self._acc = L.max_joint_acceleration.tolist()
        self._jerk = L.max_joint_jerk.tolist()
        self._vmax = L.max_joint_velocity.tolist()
        self._vmin = (-L.max_joint_velocity).tolist()
        self._pbvl = list(
            zip(
                (L.max_joint_velocity + L._tolerance).tolist(),
                L._tolerance.tolist(),
                L._q_min.tolist(),
                L._q_max.tolist(),
                L._offset.tolist(),
                L._decel2.tolist(),
                strict=True,
            )
        )
        f = lim.POSE_ROTATION_FACTOR
        self._pose_rotation = (f * L.rotation[0], f * L.rotation[1], f * L.rotation[2])

    def _velocity_limits(self, q_d: list[float]) -> tuple[list[float], list[float]]:
        """``RateLimits.joint_velocity_limits`` on floats."""
        if not self.limits.position_based:
            return self._vmax, self._vmin
        upper, lower = [], []
        sqrt = math.sqrt
        for i, (cap, tol, qmin, qmax, off, dec2) in enumerate(self._pbvl):
            qi = q_d[i]
            up = sqrt(dec2 * (qmax - qi)) - off if qi < qmax else -off
            lo = sqrt(dec2 * (qi - qmin)) - off if qi > qmin else -off
            upper.append(min(cap, max(0.0, up)) - tol)
            lower.append(-min(cap, max(0.0, lo)) + tol)
        return upper, lower

    # --- torques --------------------------------------------------------------------

    def torques(self, out: Any, state: np.void) -> bool:
        _expect(out, Torques)
        tau = out.tau_J.tolist()
        _finite("tau_J", tau)
        if self.filter or self.limit_rate:
            last = state["tau_J_d"].tolist()
            g = self.gain
            step = self._tau_step
            for i in range(7):
                d = g * (tau[i] - last[i])
                if self.limit_rate:
                    s = step[i]
                    d = s if d > s else -s if d < -s else d
                tau[i] = last[i] + d
            _finite("tau_J", tau)
        self._tau[:] = tau
        return bool(out.motion_finished)

    # --- motion generators ------------------------------------------------------------

    def joint_positions(self, out: Any, state: np.void) -> bool:
        _expect(out, JointPositions)
        q = out.q.tolist()
        _finite("q", q)
        if self.filter or self.limit_rate:
            q_d = state["q_d"].tolist()
            if self.filter and self.initialized:
                g = self.gain
                q = [q_d[i] + g * (q[i] - q_d[i]) for i in range(7)]
            if self.limit_rate:
                upper, lower = self._velocity_limits(q_d)
                q = _fast.joint_positions(
                    upper,
                    lower,
                    self._acc,
                    self._jerk,
                    q,
                    q_d,
                    state["dq_d"].tolist(),
                    state["ddq_d"].tolist(),
                )
            _finite("q", q)
        self.initialized = True
        self._q_c[:] = q
        return bool(out.motion_finished)

    def joint_velocities(self, out: Any, state: np.void) -> bool:
        _expect(out, JointVelocities)
        dq = out.dq.tolist()
        _finite("dq", dq)
        if self.filter or self.limit_rate:
            dq_d = state["dq_d"].tolist()
            if self.filter:
                g = self.gain
                dq = [dq_d[i] + g * (dq[i] - dq_d[i]) for i in range(7)]
            if self.limit_rate:
                upper, lower = self._velocity_limits(state["q_d"].tolist())
                dq = _fast.joint_velocities(
                    upper, lower, self._acc, self._jerk, dq, dq_d, state["ddq_d"].tolist()
                )
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
            v, a, j = self.limits.elbow
            e0 = _fast.joint_positions(
                [v],
                [-v],
                [a],
                [j],
                [e0],
                [last],
                [float(state["delbow_c"][0])],
                [float(state["ddelbow_c"][0])],
            )[0]
        if not math.isfinite(e0):
            raise ValueError("elbow: Commanding value is infinite or NaN.")
        self.record["valid_elbow"] = True
        self._elbow_c[0] = e0
        self._elbow_c[1] = sign

    def cartesian_pose(self, out: Any, state: np.void) -> bool:
        _expect(out, CartesianPose)
        T = out.O_T_EE.tolist()
        _finite("O_T_EE", T)
        if not _fast.is_pose(T):
            raise ValueError(_INVALID_POSE)
        first = not self.initialized
        self.initialized = True
        if self.filter or self.limit_rate:
            last = state["O_T_EE_c"].tolist()
            if self.filter and not first:
                T = _fast.pose_lowpass(self.gain, T, last)
            if self.limit_rate:
                T = _fast.pose_limit(
                    self.limits.translation,
                    self._pose_rotation,
                    T,
                    last,
                    state["O_dP_EE_c"].tolist(),
                    state["O_ddP_EE_c"].tolist(),
                )
            _finite("O_T_EE", T)
        self._O_T_EE_c[:] = T
        self._elbow(out.elbow, state, first)
        return bool(out.motion_finished)

    def cartesian_velocities(self, out: Any, state: np.void) -> bool:
        _expect(out, CartesianVelocities)
        v = out.O_dP_EE.tolist()
        _finite("O_dP_EE", v)
        if self.filter or self.limit_rate:
            last = state["O_dP_EE_c"].tolist()
            if self.filter:
                g = self.gain
                v = [last[i] + g * (v[i] - last[i]) for i in range(6)]
            if self.limit_rate:
                v = _fast.twist_limit(
                    self.limits.translation,
                    self.limits.rotation,
                    v,
                    last,
                    state["O_ddP_EE_c"].tolist(),
                )
            _finite("O_dP_EE", v)
        self._O_dP_EE_c[:] = v
        self._elbow(out.elbow, state, False)
        return bool(out.motion_finished)
