"""Turn what a control callback returns into the RobotCommand record: type and value
checks, the optional low-pass filter and rate limiter (referenced to the desired/commanded
values in the robot's last state, as libfranka's ``ControlLoop::convertMotion``).

This runs once per 1 ms tick, so it reads the state datagram with ``struct`` (:mod:`._wire`),
works on Python floats (:mod:`._fast`) and packs into one pre-allocated datagram;
:mod:`.limits` holds the NumPy reference of the same math.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from panda_py.fci import Dialect
from panda_py.libfranka import _fast
from panda_py.libfranka import limits as lim
from panda_py.libfranka._wire import layout
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


def _values(name: str, values: Any, n: int) -> list[float]:
    """``values`` (a command's NumPy array) as ``n`` floats, checked finite."""
    try:
        out = values.tolist()
        s = sum(out)
    except (AttributeError, TypeError) as exc:
        raise ValueError(f"{name}: expected {n} numbers, got {values!r}") from exc
    if len(out) != n:
        raise ValueError(f"{name}: expected {n} numbers, got {len(out)}")
    if s - s != 0.0:  # a NaN or an infinity makes this NaN
        raise ValueError(f"{name}: Commanding value is infinite or NaN.")
    return out


def _finite(name: str, values: list[float]) -> None:
    s = sum(values)
    if s - s != 0.0:
        raise ValueError(f"{name}: Commanding value is infinite or NaN.")


def _expect(out: Any, kind: type) -> None:
    if not isinstance(out, kind):
        raise ValueError(
            f"callback: expected it to return {kind.__name__}, got {type(out).__name__}"
        )


class Commander:
    """Holds the pre-allocated RobotCommand datagram of one motion and fills it each tick
    from a callback's command and the robot's last state (a datagram's ``bytes``)."""

    def __init__(
        self, dialect: Dialect, limits: lim.RateLimits, limit_rate: bool, cutoff_frequency: float
    ) -> None:
        w = layout(dialect)
        #: The RobotCommand datagram, sent as is (``message_id`` is set by the session).
        self.buffer = bytearray(w.command_size)
        #: A NumPy record viewing :attr:`buffer`.
        self.record = np.ndarray((), dialect.command_dtype, buffer=self.buffer)
        self._tau_J_d, self._joint, self._elbow_s = w.tau_J_d, w.joint, w.elbow
        self._pose, self._twist = w.pose, w.twist
        self._c_tau, self._c_q, self._c_dq = w.c_tau, w.c_q, w.c_dq
        self._c_pose, self._c_twist, self._c_elbow = w.c_pose, w.c_twist, w.c_elbow
        self.limits = limits
        self.limit_rate = limit_rate
        self.filter = cutoff_frequency < lim.MAX_CUTOFF_FREQUENCY
        self._process = self.filter or self.limit_rate
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

    @property
    def process(self) -> bool:
        """Whether commands are filtered or rate-limited before they are sent."""
        return self._process

    def _velocity_limits(self, q_d: Sequence[float]) -> tuple[list[float], list[float]]:
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

    def torques(self, out: Any, state: bytes) -> bool:
        tau = out._values if type(out) is Torques else None  # checked by the constructor
        if tau is None:
            _expect(out, Torques)
            tau = _values("tau_J", out.tau_J, 7)
        self.torque_values(tau, state)
        return bool(out.motion_finished)

    def torque_values(self, tau: list[float], state: bytes) -> None:
        """Seven finite torques [Nm] (checked by the caller) into the command, filtered
        and rate-limited as configured."""
        if self._process:
            last = self._tau_J_d.unpack(state)
            g = self.gain
            if self.limit_rate:
                step = self._tau_step
                limited = []
                for i in range(7):
                    d = g * (tau[i] - last[i])
                    s = step[i]
                    limited.append(last[i] + (s if d > s else -s if d < -s else d))
                tau = limited
            else:
                tau = [last[i] + g * (tau[i] - last[i]) for i in range(7)]
            _finite("tau_J", tau)
        self._c_tau.pack(self.buffer, *tau)

    # --- motion generators ------------------------------------------------------------

    def joint_positions(self, out: Any, state: bytes) -> bool:
        q = out._values if type(out) is JointPositions else None
        if q is None:
            _expect(out, JointPositions)
            q = _values("q", out.q, 7)
        if self._process:
            s = self._joint.unpack(state)  # q_d, dq_d, ddq_d
            q_d = s[:7]
            gain = self.gain if self.filter and self.initialized else None
            if self.limit_rate:  # the filter runs inside the limiter's loop
                upper, lower = self._velocity_limits(q_d)
                q = _fast.joint_positions(
                    upper, lower, self._acc, self._jerk, q, q_d, s[7:14], s[14:21], gain
                )
            elif gain is not None:
                q = [q_d[i] + gain * (q[i] - q_d[i]) for i in range(7)]
            _finite("q", q)
        self.initialized = True
        self._c_q.pack(self.buffer, *q)
        return bool(out.motion_finished)

    def joint_velocities(self, out: Any, state: bytes) -> bool:
        dq = out._values if type(out) is JointVelocities else None
        if dq is None:
            _expect(out, JointVelocities)
            dq = _values("dq", out.dq, 7)
        if self._process:
            s = self._joint.unpack(state)  # q_d, dq_d, ddq_d
            dq_d = s[7:14]
            gain = self.gain if self.filter else None
            if self.limit_rate:  # the filter runs inside the limiter's loop
                upper, lower = self._velocity_limits(s[:7])
                dq = _fast.joint_velocities(
                    upper, lower, self._acc, self._jerk, dq, dq_d, s[14:21], gain
                )
            elif gain is not None:
                dq = [dq_d[i] + gain * (dq[i] - dq_d[i]) for i in range(7)]
            _finite("dq", dq)
        self._c_dq.pack(self.buffer, *dq)
        return bool(out.motion_finished)

    def _elbow(self, elbow: Any, state: bytes, first: bool) -> None:
        if elbow is None:
            self._c_elbow.pack(self.buffer, 0.0, 0.0, False)
            return
        e0, sign = elbow.tolist()
        if sign != 1.0 and sign != -1.0:
            raise ValueError(f"elbow: elbow[1] must be +1 or -1, got {sign!r}")
        s = self._elbow_s.unpack(state)  # elbow_c, delbow_c, ddelbow_c
        last = s[0]
        if self.filter and not first:
            e0 = last + self.gain * (e0 - last)
        if self.limit_rate:
            v, a, j = self.limits.elbow
            e0 = _fast.joint_positions([v], [-v], [a], [j], [e0], [last], [s[2]], [s[4]])[0]
        if not math.isfinite(e0):
            raise ValueError("elbow: Commanding value is infinite or NaN.")
        self._c_elbow.pack(self.buffer, e0, sign, True)

    def cartesian_pose(self, out: Any, state: bytes) -> bool:
        T = out._values if type(out) is CartesianPose else None  # a checked pose
        if T is None:
            _expect(out, CartesianPose)
            T = _values("O_T_EE", out.O_T_EE, 16)
            if not _fast.is_pose(T):
                raise ValueError(_INVALID_POSE)
        first = not self.initialized
        self.initialized = True
        if self._process:
            s = self._pose.unpack(state)  # O_T_EE_c, O_dP_EE_c, O_ddP_EE_c
            last = s[:16]
            filtered = self.filter and not first
            if self.limit_rate and filtered:
                T = _fast.pose_lowpass_limit(
                    self.gain, self.limits.translation, self._pose_rotation, T, last,
                    s[16:22], s[22:28],
                )  # fmt: skip
            elif self.limit_rate:
                T = _fast.pose_limit(
                    self.limits.translation, self._pose_rotation, T, last, s[16:22], s[22:28]
                )
            elif filtered:
                T = _fast.pose_lowpass(self.gain, T, last)
            _finite("O_T_EE", T)
        self._c_pose.pack(self.buffer, *T)
        self._elbow(out.elbow, state, first)
        return bool(out.motion_finished)

    def cartesian_velocities(self, out: Any, state: bytes) -> bool:
        v = out._values if type(out) is CartesianVelocities else None
        if v is None:
            _expect(out, CartesianVelocities)
            v = _values("O_dP_EE", out.O_dP_EE, 6)
        if self._process:
            s = self._twist.unpack(state)  # O_dP_EE_c, O_ddP_EE_c
            last = s[:6]
            if self.filter:
                g = self.gain
                v = [last[i] + g * (v[i] - last[i]) for i in range(6)]
            if self.limit_rate:
                v = _fast.twist_limit(
                    self.limits.translation, self.limits.rotation, v, last, s[6:12]
                )
            _finite("O_dP_EE", v)
        self._c_twist.pack(self.buffer, *v)
        self._elbow(out.elbow, state, False)
        return bool(out.motion_finished)
