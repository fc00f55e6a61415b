"""The robot-side asynchronous joint position generator of protocol v10 (libfranka 0.15+
``AsyncPositionControlHandler``; the wire facts are in :mod:`panda_py.fci.move`).

With ``use_async_motion_generator`` the client no longer streams a 1 kHz trajectory: it
sends joint position *targets* whenever it likes (pylibfranka's example: 50 Hz) and the
robot moves to the newest one with its own velocity-, acceleration- and jerk-limited
trajectory; the state's ``q_d``/``dq_d``/``ddq_d`` are that trajectory (libfranka derives
its TargetStatus from them). Franka does not publish the robot's generator, so this one is
ours (a judgement, not a copy of the robot):

* per joint and independent (the joints are not time-synchronised), online: a new target
  takes effect on the next tick, from the current velocity and acceleration;
* a cascade of saturated loops, position -> velocity -> acceleration -> jerk. The velocity
  reference is the speed from which the joint can still stop within the remaining
  distance at ``BRAKE_SHARE`` of its acceleration limit with jerk-limited ramps
  (``v^2/(2A) + vA/(2J) = |e|``), capped by the Move's ``maximum_velocity`` (itself capped
  at the robot's ``dq_max``); near the target the loops are linear (gains ``K_*``), so the
  joint settles on it exponentially instead of chattering;
* discrete like the robot's own checks (:class:`~panda_py.sim.safety.JointSignal`,
  backward differences): jerk ``j`` is clipped to ``dddq_max``, then ``a += j dt``,
  ``v += a dt``, ``q += v dt``, so the differences the robot checks are exactly the
  limited quantities;
* targets are clamped into the joint range (the robot never plans past its limits).

Numpy on 7-vectors, about 20 array operations a tick: cheap enough without numba.
"""

from __future__ import annotations

import numpy as np

from panda_py.fci import MoveControllerMode, MoveMotionGeneratorMode
from panda_py.robots.params import RobotSpec
from panda_py.sim.physics import DT

# Share of ddq_max the braking profile plans with: the rest absorbs the velocity loop's lag.
BRAKE_SHARE = 0.5
# Linear gains of the cascade near the target [1/s]; each loop is ~4x faster than the
# one around it and K_A * DT < 1 keeps the innermost loop stable in discrete time.
K_P = 30.0
K_V = 150.0
K_A = 600.0
# At rest: a stopping generator ends the motion below these [rad/s], [rad/s^2].
REST_VELOCITY = 1e-4
REST_ACCELERATION = 1e-2


def async_refusal(
    controller: MoveControllerMode,
    generator: MoveMotionGeneratorMode,
    maximum_velocity: np.ndarray | None,
) -> str | None:
    """Why the robot refuses an asynchronous Move (kInvalidArgumentRejected), or None.

    Our judgement: libfranka only ever starts it as JointPosition under the robot's own
    impedance controller (``AsyncPositionControlHandler::configure``), so other modes are
    refused, as are maximum velocities that are not 7 finite positive numbers. Velocities
    above ``dq_max`` are capped at it rather than refused.
    """
    if generator != MoveMotionGeneratorMode.JOINT_POSITION:
        return f"it generates joint positions only, got motion generator {generator.name}"
    if controller == MoveControllerMode.EXTERNAL_CONTROLLER:
        return "it runs under the robot's impedance controller, got EXTERNAL_CONTROLLER"
    v = None if maximum_velocity is None else np.asarray(maximum_velocity, dtype=float)
    if v is None or v.shape != (7,) or not np.isfinite(v).all() or (v <= 0.0).any():
        given = None if v is None else v.tolist()
        return f"maximum_velocity: expected 7 finite velocities > 0 rad/s, got {given}"
    return None


class AsyncJointGenerator:
    """Online jerk-limited joint generator toward the newest target."""

    def __init__(self, spec: RobotSpec, q: np.ndarray, maximum_velocity: np.ndarray) -> None:
        j = spec.joints
        self.q_min = np.asarray(j.q_min, dtype=float)
        self.q_max = np.asarray(j.q_max, dtype=float)
        self.v_lim = np.minimum(np.asarray(maximum_velocity, dtype=float), j.dq_max)
        self.a_lim = np.asarray(j.ddq_max, dtype=float)
        self.j_lim = np.asarray(j.dddq_max, dtype=float)
        self._brake = self.a_lim * BRAKE_SHARE
        self._c = self._brake / (2.0 * self.j_lim)
        self.q = np.asarray(q, dtype=float).copy()
        self.v = np.zeros(7)
        self.a = np.zeros(7)
        self.target = self.q.copy()
        self.stopping = False

    def set_target(self, q_target: np.ndarray) -> None:
        """The newest target (finite, checked by the caller), clamped into the joint range."""
        if not self.stopping:
            self.target = np.clip(q_target, self.q_min, self.q_max)

    def stop(self) -> None:
        """Finish: come to rest wherever the jerk-limited braking ends (targets ignored)."""
        self.stopping = True

    @property
    def at_rest(self) -> bool:
        return bool(
            (np.abs(self.v) < REST_VELOCITY).all() and (np.abs(self.a) < REST_ACCELERATION).all()
        )

    def step(self) -> np.ndarray:
        """Advance one tick; returns the new desired joint positions (its own array)."""
        v, a = self.v, self.a
        if self.stopping:
            v_ref = np.zeros(7)
        else:
            e = self.target - self.q
            dist = np.abs(e)
            v_brake = self._brake * (
                np.sqrt(self._c * self._c + 2.0 * dist / self._brake) - self._c
            )
            v_ref = np.sign(e) * np.minimum(np.minimum(self.v_lim, v_brake), K_P * dist)
        # velocity still gained while the acceleration ramps to zero at full jerk
        dv = v_ref - v - a * np.abs(a) / (2.0 * self.j_lim) - a * DT
        a_ref = np.sign(dv) * np.minimum(self.a_lim, K_V * np.abs(dv))
        jerk = np.clip(K_A * (a_ref - a), -self.j_lim, self.j_lim)
        self.a = a + jerk * DT
        self.v = v + self.a * DT
        self.q = self.q + self.v * DT
        return self.q.copy()


__all__ = ["AsyncJointGenerator", "async_refusal"]
