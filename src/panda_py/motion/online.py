"""Online, jerk-limited, time-optimal trajectories from any state: the control loop's
generator for what cannot be planned ahead (a move that replaces another mid-motion, a
gentle stop, targets streamed by a policy).

:class:`OnlineGenerator` advances one robot period per :meth:`~OnlineGenerator.step`
from the current position, velocity and acceleration toward a target state (or to rest),
under per-coordinate velocity, acceleration and jerk limits. It runs on ruckig (Berscheid
& Kröger, RSS 2021), a library made for exactly this: a new target costs it 2-3 us for 7
joints and a step on an unchanged target 0.3 us (``benchmarks/bench_online.py``), well under
what an own generator in Python would. Inputs and outputs are allocated once.

:class:`OnlinePose` runs one for a Cartesian pose: the position and the orientation as a
rotation vector ``x`` about an anchor orientation ``R0`` (``R = R0 exp(x)``), re-anchored
at every new target so the rotation vector stays small.

Cartesian limits bound the norm of the translational and rotational velocity,
acceleration and jerk; the generator bounds each coordinate, so each gets the norm's
limit over sqrt(3) (the norm can then never exceed it, whatever the direction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from ruckig import (
    ControlInterface,
    InputParameter,
    OutputParameter,
    Result,
    Ruckig,
    RuckigError,
    Synchronization,
)

from panda_py.fci import PERIOD
from panda_py.motion import rotation
from panda_py.motion.errors import TrajectoryError
from panda_py.robots.params import RobotSpec

__all__ = ["OnlineGenerator", "OnlineLimits", "OnlinePose"]

FloatArray = NDArray[np.float64]
_AXES = math.sqrt(3.0)  # a norm limit split over three coordinates
# A Cartesian acceleration reaches the joints through the inverse Jacobian: with the
# robot's whole Cartesian acceleration a lead-in from a joint motion drove joint 2 of an
# FER to 1.13x its acceleration limit (tests/panda/test_async_moves.py, 100 preemptions);
# with half, 0.77x.
CARTESIAN_ACCELERATION_SHARE = 0.5
# below these a velocity [unit/s] or an acceleration [unit/s^2] is rest: ruckig 0.19 fails
# to synchronize on velocities of 1e-14 (measurement noise of an arm at rest)
_REST_VELOCITY = 1e-9
_REST_ACCELERATION = 1e-7
# what ruckig is asked for, in order, if the one before fails on an input (phase
# synchronization keeps straight lines straight; the others always find a trajectory)
_SYNCHRONIZATIONS = (Synchronization.Phase, Synchronization.TimeIfNecessary, Synchronization.No)


@dataclass(frozen=True)
class OnlineLimits:
    """Per-coordinate bounds of an online trajectory: ``|v_i| <= velocity[i]``,
    ``|a_i| <= acceleration[i]``, ``|j_i| <= jerk[i]`` (units of the coordinates per s,
    s^2, s^3)."""

    velocity: tuple[float, ...]
    acceleration: tuple[float, ...]
    jerk: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.velocity)
        for name in ("velocity", "acceleration", "jerk"):
            values = getattr(self, name)
            if len(values) != n or not all(math.isfinite(v) and v > 0.0 for v in values):
                raise ValueError(f"{name}: expected {n} finite limits > 0, got {list(values)}")

    @staticmethod
    def joints(spec: RobotSpec, speed_factor: float) -> OnlineLimits:
        """The robot's joint limits, each scaled by ``speed_factor`` in (0, 1]."""
        s = _factor(speed_factor)
        j = spec.joints
        return OnlineLimits(
            tuple(s * v for v in j.dq_max),
            tuple(s * a for a in j.ddq_max),
            tuple(s * x for x in j.dddq_max),
        )

    @staticmethod
    def cartesian(spec: RobotSpec, speed_factor: float) -> OnlineLimits:
        """The robot's end-effector limits (translation x, y, z [m], rotation x, y, z
        [rad]), each scaled by ``speed_factor`` and split over the three axes; the
        accelerations also by CARTESIAN_ACCELERATION_SHARE."""
        s = _factor(speed_factor) / _AXES
        h = CARTESIAN_ACCELERATION_SHARE * s
        c = spec.cartesian
        return OnlineLimits(
            (s * c.translation_velocity,) * 3 + (s * c.rotation_velocity,) * 3,
            (h * c.translation_acceleration,) * 3 + (h * c.rotation_acceleration,) * 3,
            (s * c.translation_jerk,) * 3 + (s * c.rotation_jerk,) * 3,
        )


def _factor(value: float) -> float:
    v = float(value)
    if not 0.0 < v <= 1.0:
        raise ValueError(f"speed_factor: expected a number in (0, 1], got {value!r}")
    return v


class OnlineGenerator:
    """A jerk-limited, time-optimal trajectory in ``n`` coordinates, advanced one robot
    period at a time; ``position``, ``velocity``, ``acceleration`` are its state after the
    last :meth:`step` (or :meth:`reset`)."""

    def __init__(self, limits: OnlineLimits) -> None:
        n = len(limits.velocity)
        self.n = n
        self._otg = Ruckig(n, PERIOD)
        self._inp = InputParameter(n)
        self._out = OutputParameter(n)
        self._inp.synchronization = Synchronization.Phase  # straight lines where it can
        self.set_limits(limits)
        self.position = np.zeros(n)
        self.velocity = np.zeros(n)
        self.acceleration = np.zeros(n)
        self.finished = True
        self.duration = 0.0  # [s] of the trajectory computed for the newest target

    def set_limits(self, limits: OnlineLimits) -> None:
        """Bound what follows by ``limits`` (same coordinates); the current target stays."""
        if len(limits.velocity) != self.n:
            raise ValueError(f"limits: expected {self.n} coordinates, got {len(limits.velocity)}")
        self.limits = limits
        self._vmax = np.array(limits.velocity)
        self._amax = np.array(limits.acceleration)
        inp = self._inp
        inp.max_velocity = list(limits.velocity)
        inp.max_acceleration = list(limits.acceleration)
        inp.max_jerk = list(limits.jerk)

    def reset(self, position: FloatArray, velocity: FloatArray, acceleration: FloatArray) -> None:
        """Start from this state (each (n,)); the target becomes this position at rest."""
        for name, value in (("position", position), ("velocity", velocity),
                            ("acceleration", acceleration)):  # fmt: skip
            arr = np.asarray(value, dtype=np.float64)
            if arr.shape != (self.n,) or not np.isfinite(arr).all():
                raise ValueError(f"{name}: expected {self.n} finite values, got {value!r}")
        v = np.array(velocity, dtype=np.float64)
        a = np.array(acceleration, dtype=np.float64)
        v[np.abs(v) < _REST_VELOCITY] = 0.0
        a[np.abs(a) < _REST_ACCELERATION] = 0.0
        inp = self._inp
        inp.current_position = list(map(float, position))
        inp.current_velocity = v.tolist()
        inp.current_acceleration = a.tolist()
        self.position[:] = position
        self.velocity[:] = v
        self.acceleration[:] = a
        self.set_target(self.position)

    def set_target(
        self,
        position: FloatArray,
        velocity: FloatArray | None = None,
        acceleration: FloatArray | None = None,
    ) -> None:
        """Go to ``position`` and arrive with ``velocity`` and ``acceleration`` (default
        at rest), each clipped to the limits (a target state beyond them is unreachable)."""
        inp = self._inp
        inp.control_interface = ControlInterface.Position
        inp.target_position = list(map(float, position))
        v = np.zeros(self.n) if velocity is None else np.clip(velocity, -self._vmax, self._vmax)
        a = np.zeros(self.n)
        if acceleration is not None:
            a = np.clip(acceleration, -self._amax, self._amax)
            # at the velocity limit, an acceleration beyond it would leave the limits
            a[(np.abs(v) >= self._vmax) & (a * v > 0.0)] = 0.0
        inp.target_velocity = v.tolist()
        inp.target_acceleration = a.tolist()
        self.finished = False

    def _retry(self) -> Result:
        inp, out = self._inp, self._out
        error: RuckigError | None = None
        for sync in _SYNCHRONIZATIONS[1:]:
            inp.synchronization = sync
            try:
                return self._otg.update(inp, out)
            except RuckigError as exc:
                error = exc
            finally:
                inp.synchronization = Synchronization.Phase
        raise TrajectoryError(f"online trajectory: the generator failed: {error}") from error

    def set_rest(self) -> None:
        """Come to rest as fast as the limits allow, wherever that is."""
        inp = self._inp
        inp.control_interface = ControlInterface.Velocity
        inp.target_velocity = [0.0] * self.n
        inp.target_acceleration = [0.0] * self.n
        self.finished = False

    def step(self) -> bool:
        """Advance one period; True once the target (or rest) is reached."""
        out, inp = self._out, self._inp
        try:
            result = self._otg.update(inp, out)
        except RuckigError:  # a numerical corner of one synchronization: try the next
            result = self._retry()
        if result != Result.Working and result != Result.Finished:
            raise TrajectoryError(f"online trajectory: the generator failed ({result})")
        if out.new_calculation:
            self.duration = out.trajectory.duration
        self.position[:] = out.new_position
        self.velocity[:] = out.new_velocity
        self.acceleration[:] = out.new_acceleration
        out.pass_to_input(self._inp)
        self.finished = result == Result.Finished
        return self.finished


class OnlinePose:
    """:class:`OnlineGenerator` for an end-effector pose: ``position`` (3,) [m],
    ``orientation`` (4,) unit quaternion (x, y, z, w), ``twist`` (6,) [m/s, rad/s] and
    ``accel`` (6,) [m/s^2, rad/s^2] in the base frame after each :meth:`step`."""

    def __init__(self, limits: OnlineLimits) -> None:
        if len(limits.velocity) != 6:
            raise ValueError(f"limits: expected 6 coordinates, got {len(limits.velocity)}")
        self.gen = OnlineGenerator(limits)
        self._q0 = np.array([0.0, 0.0, 0.0, 1.0])  # the anchor orientation
        self._R0 = np.eye(3)
        self._R0_rows = self._R0.tolist()
        self.position = np.zeros(3)
        self.orientation = self._q0.copy()
        self.twist = np.zeros(6)
        self.accel = np.zeros(6)

    @property
    def finished(self) -> bool:
        return self.gen.finished

    def reset(self, position: FloatArray, orientation: FloatArray, twist: FloatArray,
              accel: FloatArray) -> None:  # fmt: skip
        """Start from this pose, twist and acceleration, at rest on it as the target."""
        quat = np.asarray(orientation, dtype=np.float64)
        if quat.shape != (4,) or not np.isfinite(quat).all() or np.linalg.norm(quat) == 0.0:
            raise ValueError(f"orientation: expected a unit quaternion, got {orientation!r}")
        self._anchor(quat / np.linalg.norm(quat))
        R0t = self._R0.T
        tw = np.asarray(twist, dtype=np.float64)
        ac = np.asarray(accel, dtype=np.float64)
        self.gen.reset(
            np.concatenate([position, np.zeros(3)]),
            np.concatenate([tw[:3], R0t @ tw[3:]]),
            np.concatenate([ac[:3], R0t @ ac[3:]]),
        )
        self._publish()

    def _anchor(self, quat: FloatArray) -> None:
        self._q0 = quat
        self._R0 = rotation.to_matrix(quat)
        self._R0_rows = self._R0.tolist()  # read per tick: plain floats are faster

    def _reanchor(self) -> None:
        """Move the anchor to the current orientation (the rotation vector becomes 0)."""
        g = self.gen
        x, xd, xdd = g.position[3:], g.velocity[3:], g.acceleration[3:]
        if not x.any():
            return
        q = rotation.multiply(self._q0, rotation.exp(x))
        # the body rates of R0 exp(x) (J_r(x) times the coordinates' rates) are the new
        # anchor's coordinate rates at x = 0
        xs = x.tolist()
        w = _jacobian_times(xs, xd.tolist(), -1.0)
        wd = _jacobian_times(xs, xdd.tolist(), -1.0)
        self._anchor(q)
        g.reset(
            np.concatenate([g.position[:3], np.zeros(3)]),
            np.concatenate([g.velocity[:3], w]),
            np.concatenate([g.acceleration[:3], wd]),
        )

    def set_target(
        self,
        position: FloatArray,
        orientation: FloatArray,
        twist: FloatArray | None = None,
        accel: FloatArray | None = None,
    ) -> None:
        """Go to this pose (arriving at rest, or with ``twist`` and ``accel`` in the
        base frame)."""
        self._reanchor()
        quat = np.asarray(orientation, dtype=np.float64)
        rel = rotation.multiply(rotation.conjugate(self._q0), quat / np.linalg.norm(quat))
        x = rotation.log(rel)  # the shortest way round
        R0t = self._R0.T
        vel = acc = None
        if twist is not None:
            vel = np.concatenate([twist[:3], R0t @ twist[3:]])
        if accel is not None:
            acc = np.concatenate([accel[:3], R0t @ accel[3:]])
        self.gen.set_target(np.concatenate([position, x]), vel, acc)

    def set_rest(self) -> None:
        """Come to rest as fast as the limits allow."""
        self.gen.set_rest()

    def set_limits(self, limits: OnlineLimits) -> None:
        """Bound what follows by ``limits`` (6 coordinates)."""
        self.gen.set_limits(limits)

    def step(self) -> bool:
        """Advance one period; True once the target (or rest) is reached."""
        done = self.gen.step()
        self._publish()
        return done

    def _publish(self) -> None:
        # scalar arithmetic: numpy's per-call cost on 3-vectors would be most of a tick
        g = self.gen
        p, v, a = g.position, g.velocity, g.acceleration
        xs = p[3:].tolist()
        x0, x1, x2 = xs
        th2 = x0 * x0 + x1 * x1 + x2 * x2
        th = math.sqrt(th2)
        if th < 1e-4:  # series expansions
            k, c = 0.5 - th2 / 48.0, 1.0 - th2 / 8.0
        else:
            k, c = math.sin(0.5 * th) / th, math.cos(0.5 * th)
        ex, ey, ez, ew = k * x0, k * x1, k * x2, c
        qx, qy, qz, qw = self._q0.tolist()
        o = self.orientation
        o[0] = qw * ex + qx * ew + qy * ez - qz * ey
        o[1] = qw * ey - qx * ez + qy * ew + qz * ex
        o[2] = qw * ez + qx * ey - qy * ex + qz * ew
        o[3] = qw * ew - qx * ex - qy * ey - qz * ez
        # the world angular velocity of R0 exp(x) is R0 J_l(x) xd; the acceleration
        # likewise, without the Jacobian's rate (small for the small x the re-anchoring
        # keeps)
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = self._R0_rows
        tw, ac = self.twist, self.accel
        for src, dst in ((v, tw), (a, ac)):
            z0, z1, z2 = _jacobian_times(xs, src[3:].tolist(), 1.0)
            dst[:3] = src[:3]
            dst[3] = r00 * z0 + r01 * z1 + r02 * z2
            dst[4] = r10 * z0 + r11 * z1 + r12 * z2
            dst[5] = r20 * z0 + r21 * z1 + r22 * z2
        self.position[:] = p[:3]


def _jacobian_times(x: list[float], y: list[float], sign: float) -> tuple[float, float, float]:
    """``J(x) y`` for SO(3)'s left (``sign`` 1) or right (-1) Jacobian of the rotation
    vector ``x``: ``y + sign a (x × y) + b x × (x × y)``, in scalars (numpy's per-call cost
    on 3-vectors would be most of the time)."""
    x0, x1, x2 = x
    y0, y1, y2 = y
    th2 = x0 * x0 + x1 * x1 + x2 * x2
    if th2 < 1e-8:  # series expansions
        a, b = 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    else:
        th = math.sqrt(th2)
        a, b = (1.0 - math.cos(th)) / th2, (th - math.sin(th)) / (th2 * th)
    a *= sign
    c0, c1, c2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
    d0, d1, d2 = x1 * c2 - x2 * c1, x2 * c0 - x0 * c2, x0 * c1 - x1 * c0
    return y0 + a * c0 + b * d0, y1 + a * c1 + b * d1, y2 + a * c2 + b * d2
