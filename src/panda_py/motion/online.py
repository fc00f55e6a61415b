"""Online, jerk-limited, time-optimal trajectories from any state: the control loop's
generator for what cannot be planned ahead (a move that replaces another mid-motion, a
gentle stop, targets streamed by a policy).

:class:`OnlineGenerator` advances one robot period per :meth:`~OnlineGenerator.step`
from the current position, velocity and acceleration toward a target state (or to rest),
under per-coordinate velocity, acceleration and jerk limits. It runs on ruckig (Berscheid
& Kröger, RSS 2021), a library made for exactly this: ruckig calculates the trajectory at
each new target, and the steps after it sample that trajectory compiled (numba; ruckig's
own sampling, in its arithmetic). A step on 7 joints costs 0.8 us toward an unchanged
target and 9 us toward a new one (``benchmarks/bench_online.py``, 2026-11-27; 2.6 us
toward an unchanged target through ruckig's ``update``), well under the 20 us budget.
Inputs and outputs are allocated once.

:class:`OnlinePose` runs one for a Cartesian pose: the position and the orientation as a
rotation vector ``x`` about an anchor orientation ``R0`` (``R = R0 exp(x)``), re-anchored
at every new target so the rotation vector stays small.

Cartesian limits bound the norms of the translational and rotational velocity,
acceleration and jerk; the generator bounds each coordinate, so :class:`OnlinePose` works
in frames aligned with where the motion must go (see there).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any

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
    Trajectory,
)

from panda_py import checks, jit
from panda_py.fci import PERIOD
from panda_py.motion import rotation
from panda_py.motion.errors import TrajectoryError
from panda_py.robots.params import RobotSpec

__all__ = ["OnlineGenerator", "OnlineLimits", "OnlinePose", "compiled_kernels", "warmup"]

FloatArray = NDArray[np.float64]


def compiled_kernels() -> Any:
    """The generator's compiled per-tick work (numba: ``sample_pose`` and the others of
    :mod:`._online_jit`), or None where it runs as plain Python (numba missing,
    ``PANDA_PY_NO_JIT=1``): for a compiled loop that samples an :class:`OnlinePose` itself
    (:meth:`OnlinePose.advance`, :meth:`OnlinePose.sampling`)."""
    return _compiled()


def _compiled() -> Any:
    """:mod:`._online_jit` (OnlinePose's output compiled by numba), or None (numba
    missing, or ``PANDA_PY_NO_JIT=1``): imported on first use."""
    return jit.optional("panda_py.motion._online_jit")


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
        """The robot's end-effector limits, each scaled by ``speed_factor``: the norms'
        limits of the translation ([m], x, y, z) and the rotation ([rad], x, y, z), each
        repeated for its three coordinates (:class:`OnlinePose` spreads them over its
        frame)."""
        s = _factor(speed_factor)
        c = spec.cartesian
        return OnlineLimits(
            (s * c.translation_velocity,) * 3 + (s * c.rotation_velocity,) * 3,
            (s * c.translation_acceleration,) * 3 + (s * c.rotation_acceleration,) * 3,
            (s * c.translation_jerk,) * 3 + (s * c.rotation_jerk,) * 3,
        )

    def scaled(self, velocity: float = 1.0, acceleration: float = 1.0) -> OnlineLimits:
        """These limits with the velocities and the accelerations (and jerks) scaled by
        factors > 0 (refused otherwise)."""
        if not (0.0 < velocity < math.inf and 0.0 < acceleration < math.inf):
            raise ValueError(
                f"scaled: expected factors > 0, got velocity {velocity}, acceleration "
                f"{acceleration}"
            )
        return OnlineLimits._trusted(
            tuple([velocity * v for v in self.velocity]),
            tuple([acceleration * a for a in self.acceleration]),
            tuple([acceleration * j for j in self.jerk]),
        )

    @classmethod
    def _trusted(cls, velocity: tuple[float, ...], acceleration: tuple[float, ...],
                 jerk: tuple[float, ...]) -> OnlineLimits:  # fmt: skip
        """Limits derived from checked ones by factors > 0, not checked again: a Cartesian
        move's hand-over derives two sets, whose checks took a tenth of its time."""
        limits = object.__new__(cls)
        object.__setattr__(limits, "velocity", velocity)
        object.__setattr__(limits, "acceleration", acceleration)
        object.__setattr__(limits, "jerk", jerk)
        return limits


def _factor(value: float) -> float:
    v = float(value)
    if not 0.0 < v <= 1.0:
        raise ValueError(f"speed_factor: expected a number in (0, 1], got {value!r}")
    return v


_ROW = 49  # _online_jit.ROW (a test holds them equal): importing it would load numba
_PEAK_SIZE = 8  # _online_jit.PEAK_SIZE (likewise)


def _pack(traj: Trajectory, out: FloatArray, into: Any = None) -> None:
    """A one-section trajectory's profiles into ``out`` (n, _ROW), a row per coordinate,
    as ``_online_jit.sample`` reads them: the brake's duration, and its two phases'
    times, jerks, accelerations, velocities, positions; the profile's phase durations and
    jerks (7 each), accelerations, velocities and positions (8 each). ``into``: a byte
    view of ``out`` (:func:`_byte_view`), where the caller keeps one."""
    flat: list[float] = []
    for profile in traj.profiles[0]:
        brake = profile.brake
        duration = brake.duration
        flat.append(duration)
        if duration > 0.0:
            flat += [*brake.t, *brake.j, *brake.a, *brake.v, *brake.p]
        else:
            flat += _NO_BRAKE
        flat += [*profile.t, *profile.j, *profile.a, *profile.v, *profile.p]
    # struct writes the doubles as they are, at a third of the cost of NumPy's conversion
    # of a list (the most of a new target's packing)
    packer = _PACKERS.get(len(flat))
    if packer is None:
        packer = _PACKERS[len(flat)] = struct.Struct(f"={len(flat)}d")
    packer.pack_into(_byte_view(out) if into is None else into, 0, *flat)


def _byte_view(out: FloatArray) -> memoryview:
    """A writable byte view of the C-contiguous float64 array ``out`` (what :func:`_pack`
    writes through)."""
    if out.dtype != np.float64 or not out.flags.c_contiguous or not out.flags.writeable:
        raise ValueError("out: expected a writable C-contiguous float64 array")
    return out.data.cast("B")


_NO_BRAKE = [0.0] * 10
_PACKERS: dict[int, struct.Struct] = {}


# The checks and tests of a hand-over's inputs are in scalars: each NumPy call costs 20-30
# us on the cold caches the hand-overs of a caller that slept in between (a policy's) meet.
def _finite(name: str, value: Any, n: int) -> FloatArray:
    """``value`` as a new float64 array (n,), all finite, else a ValueError naming it."""
    arr = np.array(value, dtype=np.float64)
    if arr.shape != (n,) or not checks.all_finite(arr.tolist()):
        raise ValueError(f"{name}: expected {n} finite values, got {value!r}")
    return arr


def _quaternion(value: Any) -> FloatArray:
    """``value`` as a new float64 array (4,), finite and not 0, else a ValueError."""
    quat = np.array(value, dtype=np.float64)
    values = quat.tolist() if quat.shape == (4,) else [math.nan]
    if not checks.all_finite(values) or not any(values):
        raise ValueError(f"orientation: expected a unit quaternion, got {value!r}")
    return quat


def _zero(value: FloatArray | None) -> bool:
    """Whether ``value`` is None or all zeros."""
    return value is None or not any(np.asarray(value).tolist())


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
        # compiled (see step): the trajectory ruckig calculated at the last change of its
        # input, packed here and sampled each tick at _time [s] since; _changed: the input
        # changed since; _fresh: ruckig's step calculated it, not packed yet; _moved: the
        # state advanced since the input last had it
        self._packed = np.zeros((n, _ROW))
        self._packed_bytes = _byte_view(self._packed)
        self._time = 0.0
        self._changed = True
        self._fresh = False
        self._moved = False
        self._apply_limits(limits)
        self.position = np.zeros(n)
        self.velocity = np.zeros(n)
        self.acceleration = np.zeros(n)
        self._ahead = np.zeros((3, n))  # (acceleration_ahead's state ahead)
        self.finished = True
        self.duration = 0.0  # [s] of the trajectory computed for the newest target

    def set_limits(self, limits: OnlineLimits) -> None:
        """Bound what follows by ``limits`` (same coordinates); the current target stays."""
        if limits is not self.limits:  # (the same: in effect already)
            self._apply_limits(limits)

    def _apply_limits(self, limits: OnlineLimits) -> None:
        if len(limits.velocity) != self.n:
            raise ValueError(f"limits: expected {self.n} coordinates, got {len(limits.velocity)}")
        self.limits = limits
        self._vmax = np.array(limits.velocity)
        self._amax = np.array(limits.acceleration)
        inp = self._input()
        inp.max_velocity = list(limits.velocity)
        inp.max_acceleration = list(limits.acceleration)
        inp.max_jerk = list(limits.jerk)

    def reset(self, position: FloatArray, velocity: FloatArray, acceleration: FloatArray) -> None:
        """Start from this state (each (n,)); the target becomes this position at rest."""
        n = self.n
        self._start_from(_finite("position", position, n), _finite("velocity", velocity, n),
                         _finite("acceleration", acceleration, n))  # fmt: skip
        self.set_target(self.position)

    def _start_from(
        self, position: FloatArray, velocity: FloatArray, acceleration: FloatArray
    ) -> None:
        """:meth:`reset` for a caller whose state is this generator's own kind: float64
        arrays of shape (n,), finite, left unmodified (the state takes a velocity or an
        acceleration below its rest threshold as 0); the target is left for the caller to
        set (:class:`OnlinePose` restarts in new frames at each target: the checks and the
        interim target were a fifth of its cost)."""
        # (in scalars: a hand-over's path, where each NumPy call costs 20-30 us on the
        # cold caches the hand-overs of a caller that slept in between meet)
        rest_v, rest_a = _REST_VELOCITY, _REST_ACCELERATION
        v = [0.0 if -rest_v < x < rest_v else x for x in velocity.tolist()]
        a = [0.0 if -rest_a < x < rest_a else x for x in acceleration.tolist()]
        inp = self._inp
        inp.current_position = p = position.tolist()
        inp.current_velocity = v
        inp.current_acceleration = a
        self.position[:] = p
        self.velocity[:] = v
        self.acceleration[:] = a
        self._changed, self._moved = True, False

    def set_target(
        self,
        position: FloatArray,
        velocity: FloatArray | None = None,
        acceleration: FloatArray | None = None,
    ) -> None:
        """Go to ``position`` and arrive with ``velocity`` and ``acceleration`` (default
        at rest), each clipped to the limits (a target state beyond them is unreachable)."""
        inp = self._input()
        inp.control_interface = ControlInterface.Position
        inp.target_position = list(map(float, position))
        self.finished = False
        if _zero(velocity) and _zero(acceleration):  # at rest (a goal's: a hand-over's path)
            inp.target_velocity = [0.0] * self.n
            inp.target_acceleration = [0.0] * self.n
            return
        v = np.zeros(self.n) if velocity is None else np.clip(velocity, -self._vmax, self._vmax)
        a = np.zeros(self.n)
        if acceleration is not None:
            a = np.clip(acceleration, -self._amax, self._amax)
            # at the velocity limit, an acceleration beyond it would leave the limits
            a[(np.abs(v) >= self._vmax) & (a * v > 0.0)] = 0.0
        inp.target_velocity = v.tolist()
        inp.target_acceleration = a.tolist()

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
        inp = self._input()
        inp.control_interface = ControlInterface.Velocity
        inp.target_velocity = [0.0] * self.n
        inp.target_acceleration = [0.0] * self.n
        self.finished = False

    def mapped_peaks(self, M: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """The largest ``|M v(t)|`` and ``|M a(t)|`` (each (m,)) along the trajectory from
        the current state to the target, ``M`` (m, n) mapping the coordinates' rates to
        another space's (a Jacobian's pseudo-inverse: the joints' velocities and
        accelerations), with their signs: coordinates that peak at different times, or
        cancel, are counted as they combine. Exact (at the phases' ends and where the
        mapped acceleration crosses zero) on ruckig's whole trajectory, computed without
        stepping (the generator's state is unchanged); None where ruckig cannot."""
        traj = Trajectory(self.n)
        try:
            result = self._otg.calculate(self._input(change=False), traj)
        except RuckigError:
            return None
        if result != Result.Working:
            return None
        M = np.ascontiguousarray(M, dtype=np.float64)
        if (M.ndim != 2 or M.shape[1] != self.n or not 0 < len(M) <= _PEAK_SIZE
                or self.n > _PEAK_SIZE):  # fmt: skip
            raise ValueError(
                f"M: expected 1 to {_PEAK_SIZE} rows of this generator's {self.n} "
                f"coordinates (at most {_PEAK_SIZE}), got shape {M.shape}"
            )
        kernels = _compiled()
        if kernels is None:
            return _mapped_peaks_python(traj, M)
        v_peak, a_peak = np.zeros(len(M)), np.zeros(len(M))
        packed = np.zeros((self.n, _ROW))
        _pack(traj, packed)
        kernels.mapped_peaks(packed, traj.duration, M, v_peak, a_peak)
        return v_peak, a_peak

    def _input(self, change: bool = True) -> InputParameter:
        """ruckig's input, its current state made the generator's where the compiled steps
        advanced past it (ruckig's own steps keep it so); ``change``: about to be changed
        (the next compiled step calculates anew)."""
        inp = self._inp
        if self._moved:
            inp.current_position = self.position.tolist()
            inp.current_velocity = self.velocity.tolist()
            inp.current_acceleration = self.acceleration.tolist()
            self._moved = False
        if change:
            self._changed = True
        return inp

    def step(self) -> bool:
        """Advance one period; True once the target (or rest) is reached.

        Compiled (numba), ruckig steps once after each change of its input (it calculates
        the trajectory), and the steps after it sample that trajectory
        (``_online_jit.sample``: ruckig's own sampling, in its arithmetic), where ruckig's
        ``update`` cost a call and the conversion of its outputs each tick (packing the
        trajectory costs about as much as a dozen of those: a target changed every tick is
        never packed)."""
        kernels = _compiled()
        if kernels is None or self._changed:
            return self._step_ruckig()
        t = self._advance()
        kernels.sample(self._packed, self.duration, t, self.position, self.velocity,
                       self.acceleration)  # fmt: skip
        return self.finished

    def acceleration_ahead(self, dt: float) -> FloatArray:
        """The trajectory's acceleration ``dt`` [s] after its last step (the last phase's
        kept after its end, as ruckig's), a buffer the next call rewrites: what a torque
        fed forward through a filter that trails it by ``dt`` should aim at
        (``controllers.finalize.FILTER_LAG``)."""
        if not dt >= 0.0:
            raise ValueError(f"dt: expected a time >= 0 [s], got {dt!r}")
        kernels = _compiled()
        if self._changed:  # reset, no step yet: where it is
            return self.acceleration
        if kernels is None:  # every step is ruckig's, whose output has the time
            _, _, acceleration = self._out.trajectory.at_time(self._out.time + dt)
            self._ahead[2] = acceleration
            return self._ahead[2]
        self.pack()
        ahead = self._ahead
        kernels.sample(self._packed, self.duration, self._time + dt, ahead[0], ahead[1],
                       ahead[2])  # fmt: skip
        return ahead[2]

    def _advance(self) -> float:
        """A compiled step's bookkeeping (the input unchanged since ruckig's step): the
        trajectory packed if ruckig's step just calculated it, the time advanced one period
        (returned: when to sample), ``finished`` (as ruckig's: once the time passed the
        duration)."""
        self.pack()
        self._time += PERIOD
        self._moved = True
        self.finished = self._time > self.duration
        return self._time

    def pack(self) -> None:
        """Where ruckig's step has just calculated a trajectory, pack it for the compiled
        steps that sample it (the next compiled step would; a compiled loop that samples
        it itself packs it first)."""
        if self._fresh:
            out = self._out
            _pack(out.trajectory, self._packed, self._packed_bytes)
            self._time = out.time
            self._fresh = False

    def sampling(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
        """For a compiled loop that runs this generator's steps itself (``_online_jit.sample``
        at its own :meth:`clock`): the packed trajectory and the state it samples into (the
        arrays themselves: they are written), the trajectory packed first; None where the
        next step is ruckig's (its input changed)."""
        if self._changed:
            return None
        self.pack()
        return self._packed, self.position, self.velocity, self.acceleration

    def clock(self) -> tuple[float, bool, float]:
        """The time [s] in the trajectory of the last step, whether it finished, and the
        trajectory's duration [s] (what a compiled loop's steps advance)."""
        return self._time, self.finished, self.duration

    def compiled_steps(self, time: float, finished: bool) -> None:
        """A compiled loop stepped this generator (sampling its packed trajectory, see
        :meth:`sampling`) to ``time`` [s] in it, finished or not."""
        if time != self._time:
            self._time = time
            self._moved = True
        self.finished = finished

    def _step_ruckig(self) -> bool:
        """:meth:`step` by ruckig's ``update``."""
        out, inp = self._out, self._inp
        if self._changed:  # its own copy of the input may be stale (compiled steps): anew
            self._otg.reset()
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
        self._fresh = out.new_calculation or self._fresh
        self._changed = False
        return self.finished


class OnlinePose:
    """:class:`OnlineGenerator` for an end-effector pose: ``position`` (3,) [m],
    ``orientation`` (4,) unit quaternion (x, y, z, w), ``twist`` (6,) [m/s, rad/s] and
    ``accel`` (6,) [m/s^2, rad/s^2] in the base frame after each :meth:`step`.

    The generator bounds each coordinate, the robot the norms of the translational and
    rotational motion. Each is generated in a frame whose first axis points where it must
    go (at a new target: toward it; at a stop: along the motion), which gets the whole
    norm limit, and the two others LATERAL of it: a straight motion gets all the robot
    allows, and the norm exceeds it only while a sideways velocity left from before is
    braked, by at most sqrt(1 + 2 LATERAL^2)."""

    def __init__(self, limits: OnlineLimits) -> None:
        if len(limits.velocity) != 6:
            raise ValueError(f"limits: expected 6 coordinates, got {len(limits.velocity)}")
        self.gen = OnlineGenerator(_aligned(limits))
        self.limits = limits
        self._q0 = np.array([0.0, 0.0, 0.0, 1.0])  # the anchor orientation
        self._R0 = np.eye(3)
        self._R0_rows = self._R0.tolist()
        # the frames of the translation's and the rotation vector's coordinates (columns)
        self._Ft = np.eye(3)
        self._Fr = np.eye(3)
        self._Ft_rows = self._Ft.tolist()
        self._Fr_rows = self._Fr.tolist()
        self.position = np.zeros(3)
        self.orientation = self._q0.copy()
        self.twist = np.zeros(6)
        self.accel = np.zeros(6)
        # accel_ahead's state ahead: the generator's (3, 6), then the pose's outputs
        self._ahead_gen = np.zeros((3, 6))
        self._ahead_out = (np.zeros(3), np.zeros(4), np.zeros(6), np.zeros(6))

    @property
    def finished(self) -> bool:
        return self.gen.finished

    def ahead_buffers(self) -> tuple[FloatArray, ...]:
        """:meth:`accel_ahead`'s buffers, for a compiled loop that samples ahead itself:
        the generator's state (3, 6), then the position, orientation, twist and
        acceleration (the arrays themselves: they are written)."""
        return (self._ahead_gen, *self._ahead_out)

    def accel_ahead(self, dt: float) -> FloatArray:
        """:attr:`accel` ``dt`` [s] after the last step (as
        :meth:`OnlineGenerator.acceleration_ahead`), a buffer the next call rewrites."""
        if not dt >= 0.0:
            raise ValueError(f"dt: expected a time >= 0 [s], got {dt!r}")
        g = self.gen
        if g._changed:  # reset, no step yet
            return self.accel
        kernels = _compiled()
        if kernels is None:  # the generator's, in the base frame at the pose now
            a = g.acceleration_ahead(dt).tolist()
            xs = _times(self._Fr_rows, g.position.tolist()[3:])
            out = self._ahead_out[3]
            out[:3] = _times(self._Ft_rows, a[:3])
            out[3:] = _times(self._R0_rows,
                             _jacobian_times(xs, _times(self._Fr_rows, a[3:]), 1.0))  # fmt: skip
            return out
        g.pack()
        ahead = self._ahead_gen
        kernels.sample_pose(g._packed, g.duration, g._time + dt, ahead[0], ahead[1], ahead[2],
                            self._Ft, self._Fr, self._R0, self._q0, *self._ahead_out)  # fmt: skip
        return self._ahead_out[3]

    @property
    def frames(self) -> tuple[FloatArray, FloatArray]:
        """The frames (columns) of the translation's and the rotation vector's
        coordinates: their first axes get the whole limit, the others LATERAL of it."""
        return self._Ft, self._Fr

    def axes(self) -> tuple[FloatArray, FloatArray]:
        """The generator's six coordinates' axes in the base frame (columns): the
        translation's, and the rotation's (about the anchor, where the rotation vector
        stays small)."""
        return self._Ft, self._R0 @ self._Fr

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
        self._restart(
            np.asarray(position, dtype=np.float64), tw[:3], ac[:3],
            np.zeros(3), R0t @ tw[3:], R0t @ ac[3:], np.eye(3), np.eye(3), checked=True,
        )  # fmt: skip
        self._publish()

    def reset_toward(
        self, position: FloatArray, orientation: FloatArray, twist: FloatArray,
        accel: FloatArray, target_position: FloatArray, target_orientation: FloatArray,
        target_twist: FloatArray | None = None, target_accel: FloatArray | None = None,
    ) -> None:  # fmt: skip
        """:meth:`reset` to this state, then :meth:`set_target`, in one restart of the
        generator (a move's hand-over: the two restarts were a third of it)."""
        quat = _quaternion(orientation)  # (fresh copies: one kernel signature)
        p = _finite("position", position, 3)
        tw = _finite("twist", twist, 6)
        ac = _finite("accel", accel, 6)
        kernels = _compiled()
        if kernels is not None:  # the same, compiled in one call (a hand-over's path)
            anchor, R0 = np.empty(4), np.empty((3, 3))
            Ft, Fr = np.empty((3, 3)), np.empty((3, 3))
            sp, sv, sa, goal = np.empty(6), np.empty(6), np.empty(6), np.empty(6)
            kernels.restart_toward(p, quat, tw, ac, np.array(target_position, dtype=np.float64),
                                   np.array(target_orientation, dtype=np.float64), anchor, R0,
                                   Ft, Fr, sp, sv, sa, goal)  # fmt: skip
            self._q0, self._R0, self._R0_rows = anchor, R0, R0.tolist()
            self._use_frames(Ft, Fr)
            self.gen._start_from(sp, sv, sa)
            self._set_goal(goal, target_twist, target_accel)
        else:
            self._anchor(quat / np.linalg.norm(quat))
            R0t = self._R0.T
            self._aim(p, tw[:3].copy(), ac[:3].copy(), np.zeros(3), R0t @ tw[3:],
                      R0t @ ac[3:], target_position, target_orientation, target_twist,
                      target_accel)  # fmt: skip
        self._publish()

    def _anchor(self, quat: FloatArray) -> None:
        self._q0 = np.ascontiguousarray(quat, dtype=np.float64)
        self._R0 = np.ascontiguousarray(rotation.to_matrix(quat), dtype=np.float64)
        self._R0_rows = self._R0.tolist()  # read per tick: plain floats are faster

    def _restart(
        self, p: FloatArray, v: FloatArray, a: FloatArray,
        x: FloatArray, xd: FloatArray, xdd: FloatArray, Ft: FloatArray, Fr: FloatArray,
        checked: bool = False,
    ) -> None:  # fmt: skip
        """Restart the generator from this state (translation in the base frame, rotation
        vector about the anchor) in the frames ``Ft``, ``Fr``; ``checked``: a state from
        the caller (checked, and at rest on it as the target), else the generator's own
        (the caller sets the target)."""
        self._use_frames(np.ascontiguousarray(Ft, dtype=np.float64),
                         np.ascontiguousarray(Fr, dtype=np.float64))  # fmt: skip
        start = self.gen.reset if checked else self.gen._start_from
        start(
            np.concatenate([Ft.T @ p, Fr.T @ x]),
            np.concatenate([Ft.T @ v, Fr.T @ xd]),
            np.concatenate([Ft.T @ a, Fr.T @ xdd]),
        )

    def _use_frames(self, Ft: FloatArray, Fr: FloatArray) -> None:
        """The coordinates' frames from now on (C-contiguous float64, columns)."""
        self._Ft, self._Fr = Ft, Fr
        self._Ft_rows, self._Fr_rows = Ft.tolist(), Fr.tolist()

    def _world(self) -> tuple[FloatArray, ...]:
        """The translation (base frame) and the rotation vector's state (anchor frame):
        p, v, a, x, xd, xdd."""
        g, Ft, Fr = self.gen, self._Ft, self._Fr
        return (Ft @ g.position[:3], Ft @ g.velocity[:3], Ft @ g.acceleration[:3],
                Fr @ g.position[3:], Fr @ g.velocity[3:], Fr @ g.acceleration[3:])  # fmt: skip

    def _state_at_new_anchor(self) -> tuple[FloatArray, ...]:
        """The state with the anchor moved to the current orientation (the rotation
        vector becomes 0; its rates, J_r(x) times the old ones, are the body rates)."""
        p, v, a, x, xd, xdd = self._world()
        if x.any():
            self._anchor(rotation.multiply(self._q0, rotation.exp(x)))
            xs = x.tolist()
            xd = np.array(_jacobian_times(xs, xd.tolist(), -1.0))
            xdd = np.array(_jacobian_times(xs, xdd.tolist(), -1.0))
        return p, v, a, np.zeros(3), xd, xdd

    def set_target(
        self,
        position: FloatArray,
        orientation: FloatArray,
        twist: FloatArray | None = None,
        accel: FloatArray | None = None,
    ) -> None:
        """Go to this pose (arriving at rest, or with ``twist`` and ``accel`` in the
        base frame)."""
        kernels = _compiled()
        if kernels is None:
            p, v, a, x, xd, xdd = self._state_at_new_anchor()
            self._aim(p, v, a, x, xd, xdd, position, orientation, twist, accel)
            return
        # the same, compiled in one call (a streamed target's path: 45 us in NumPy and
        # Python, most of it the re-anchoring); fresh writable copies: one signature
        g = self.gen
        anchor, R0 = np.empty(4), np.empty((3, 3))
        Ft, Fr = np.empty((3, 3)), np.empty((3, 3))
        sp, sv, sa, goal = np.empty(6), np.empty(6), np.empty(6), np.empty(6)
        kernels.retarget(g.position, g.velocity, g.acceleration, self._Ft, self._Fr, self._q0,
                         np.array(position, dtype=np.float64),
                         np.array(orientation, dtype=np.float64), anchor, R0, Ft, Fr, sp, sv,
                         sa, goal)  # fmt: skip
        self._q0, self._R0, self._R0_rows = anchor, R0, R0.tolist()
        self._use_frames(Ft, Fr)
        g._start_from(sp, sv, sa)
        self._set_goal(goal, twist, accel)

    def _aim(
        self, p: FloatArray, v: FloatArray, a: FloatArray, x: FloatArray, xd: FloatArray,
        xdd: FloatArray, position: FloatArray, orientation: FloatArray,
        twist: FloatArray | None, accel: FloatArray | None,
    ) -> None:  # fmt: skip
        """Restart from this state (as :meth:`_restart`'s) toward the target pose, in the
        frames of the way there (in NumPy: compiled, :meth:`set_target` and
        :meth:`reset_toward` call ``_online_jit.retarget`` and ``restart_toward``)."""
        goal = self._aim_python(p, v, a, x, xd, xdd, position, orientation)
        self._set_goal(goal, twist, accel)

    def _set_goal(self, goal: FloatArray, twist: FloatArray | None,
                  accel: FloatArray | None) -> None:  # fmt: skip
        """The generator's target: ``goal`` (6,, in its frames), arriving at rest or with
        ``twist`` and ``accel`` (base frame)."""
        Ft, Fr, R0t = self._Ft, self._Fr, self._R0.T
        vel = acc = None
        if _zero(twist) and _zero(accel):  # at rest (a goal's)
            twist = accel = None
        if twist is not None:
            vel = np.concatenate([Ft.T @ twist[:3], Fr.T @ (R0t @ twist[3:])])
        if accel is not None:
            acc = np.concatenate([Ft.T @ accel[:3], Fr.T @ (R0t @ accel[3:])])
        self.gen.set_target(goal, vel, acc)

    def _aim_python(
        self, p: FloatArray, v: FloatArray, a: FloatArray, x: FloatArray, xd: FloatArray,
        xdd: FloatArray, position: FloatArray, orientation: FloatArray,
    ) -> FloatArray:  # fmt: skip
        """:meth:`_aim`'s restart in NumPy (the reference the compiled ``aim`` equals):
        the generator restarted in the new frames; returns the goal in them."""
        quat = np.asarray(orientation, dtype=np.float64)
        rel = rotation.multiply(rotation.conjugate(self._q0), quat / np.linalg.norm(quat))
        x_t = rotation.log(rel)  # the shortest way round
        target = np.asarray(position, dtype=np.float64)
        Ft, Fr = _frame(target - p, v), _frame(x_t, xd)
        self._restart(p, v, a, x, xd, xdd, Ft, Fr)
        return np.concatenate([Ft.T @ target, Fr.T @ x_t])

    def set_rest(self) -> None:
        """Come to rest as fast as the limits allow (braking along the motion)."""
        p, v, a, x, xd, xdd = self._state_at_new_anchor()
        self._restart(p, v, a, x, xd, xdd, _frame(v, a), _frame(xd, xdd))
        self.gen.set_rest()

    def set_limits(self, limits: OnlineLimits) -> None:
        """Bound what follows by ``limits`` (the norms' limits, 6 coordinates)."""
        if limits is self.limits:  # in effect already (a joints' cap that did not bind)
            return
        if len(limits.velocity) != 6:
            raise ValueError(f"limits: expected 6 coordinates, got {len(limits.velocity)}")
        self.limits = limits
        self.gen.set_limits(_aligned(limits))

    def step(self) -> bool:
        """Advance one period; True once the target (or rest) is reached."""
        kernels = _compiled()
        if kernels is None:
            done = self.gen.step()
            self._publish_python()
            return done
        g = self.gen
        if g._changed:  # ruckig's step (it calculates), then the output
            done = g.step()
            self._publish()
            return done
        t = g._advance()  # the generator's compiled step and the output in one call
        kernels.sample_pose(g._packed, g.duration, t, g.position, g.velocity, g.acceleration,
                            self._Ft, self._Fr, self._R0, self._q0, self.position,
                            self.orientation, self.twist, self.accel)  # fmt: skip
        return g.finished

    def advance(self) -> float | None:
        """:meth:`step` for a caller that samples in its own compiled call: the time to
        sample the trajectory at (:meth:`sampling` gives what ``_online_jit.sample_pose``
        takes besides), or None where this call stepped in full (ruckig steps after a
        change of its input, or nothing is compiled)."""
        g = self.gen
        if g._changed or _compiled() is None:
            self.step()
            return None
        return g._advance()

    def pack(self) -> None:
        """:meth:`OnlineGenerator.pack` of its generator."""
        self.gen.pack()

    def sampling(self) -> tuple[Any, ...]:
        """What ``_online_jit.sample_pose`` takes after the time (see :meth:`advance`): the
        packed trajectory, the generator's state, the frames and the anchor, and this
        generator's outputs (the arrays themselves: they are written)."""
        g = self.gen
        return (g._packed, g.position, g.velocity, g.acceleration, self._Ft, self._Fr, self._R0,
                self._q0, self.position, self.orientation, self.twist, self.accel)  # fmt: skip

    @property
    def duration(self) -> float:
        """[s] of the trajectory toward the newest target (from its change)."""
        return self.gen.duration

    def _publish(self) -> None:
        kernels = _compiled()
        if kernels is None:
            self._publish_python()
        else:  # the same, compiled (about 1 us instead of 8-10)
            g = self.gen
            kernels.publish_pose(g.position, g.velocity, g.acceleration, self._Ft, self._Fr,
                                 self._R0, self._q0, self.position, self.orientation,
                                 self.twist, self.accel)  # fmt: skip

    def _publish_python(self) -> None:
        # scalar arithmetic: numpy's per-call cost on 3-vectors would be most of a tick
        g = self.gen
        ct, cr = self._Ft_rows, self._Fr_rows
        p, v, a = g.position.tolist(), g.velocity.tolist(), g.acceleration.tolist()
        xs = _times(cr, p[3:])
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
        self.position[:] = _times(ct, p[:3])
        # the world angular velocity of R0 exp(x) is R0 J_l(x) xd; the acceleration
        # likewise, without the Jacobian's rate (small for the small x the re-anchoring
        # keeps)
        r0 = self._R0_rows
        for src, dst in ((v, self.twist), (a, self.accel)):
            dst[:3] = _times(ct, src[:3])
            dst[3:] = _times(r0, _jacobian_times(xs, _times(cr, src[3:]), 1.0))


LATERAL = 0.5  # of a norm's limit for the two coordinates across the motion (OnlinePose)


def _aligned(limits: OnlineLimits) -> OnlineLimits:
    """Per-coordinate limits of an aligned frame from the norms' limits (OnlinePose)."""

    def spread(values: tuple[float, ...]) -> tuple[float, ...]:
        t, r = values[0], values[3]
        return (t, LATERAL * t, LATERAL * t, r, LATERAL * r, LATERAL * r)

    return OnlineLimits._trusted(
        spread(limits.velocity), spread(limits.acceleration), spread(limits.jerk)
    )


def _frame(direction: FloatArray, fallback: FloatArray) -> FloatArray:
    """A right-handed frame (columns) whose first axis is ``direction`` (or, where that
    is ~0, ``fallback``; the identity where both are). In scalars: numpy's cross on
    3-vectors cost most of a new target."""
    x, y, z = (float(c) for c in direction)
    n = math.sqrt(x * x + y * y + z * z)
    if n < 1e-9:
        x, y, z = (float(c) for c in fallback)
        n = math.sqrt(x * x + y * y + z * z)
        if n < 1e-9:
            return np.eye(3)
    x, y, z = x / n, y / n, z / n
    # e2 = e1 x (the base axis least along e1), normalized; e3 = e1 x e2
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax <= ay and ax <= az:
        u, v, w = 0.0, z, -y  # e1 x (1, 0, 0)
    elif ay <= az:
        u, v, w = -z, 0.0, x  # e1 x (0, 1, 0)
    else:
        u, v, w = y, -x, 0.0  # e1 x (0, 0, 1)
    m = math.sqrt(u * u + v * v + w * w)
    u, v, w = u / m, v / m, w / m
    return np.array([
        [x, u, y * w - z * v],
        [y, v, z * u - x * w],
        [z, w, x * v - y * u],
    ])  # fmt: skip


def _times(rows: list[list[float]], v: list[float]) -> list[float]:
    """The 3x3 ``rows`` times ``v``, in scalars."""
    (a, b, c), (d, e, f), (g, h, i) = rows
    x, y, z = v
    return [a * x + b * y + c * z, d * x + e * y + f * z, g * x + h * y + i * z]


def _jacobian_times(x: list[float], y: list[float], sign: float) -> list[float]:
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
    return [y0 + a * c0 + b * d0, y1 + a * c1 + b * d1, y2 + a * c2 + b * d2]


def _mapped_peaks_python(traj: Trajectory, M: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:meth:`OnlineGenerator.mapped_peaks` through ruckig's own profiles and sampling (the
    compiled ``_online_jit.mapped_peaks``' reference)."""
    duration = traj.duration
    times = [0.0, duration]
    for profile in traj.profiles[0]:
        brake = profile.brake.duration
        if brake > 0.0:
            times += [profile.brake.t[0], brake]
        times += list(brake + np.cumsum(profile.t))
    times = sorted(min(max(t, 0.0), duration) for t in times)
    v_peak, a_peak = np.zeros(len(M)), np.zeros(len(M))
    t_prev, a_prev = 0.0, np.zeros(len(M))
    for k, t in enumerate(times):
        _, v, a = traj.at_time(t)[:3]
        mv, ma = M @ np.asarray(v), M @ np.asarray(a)
        v_peak, a_peak = np.maximum(v_peak, np.abs(mv)), np.maximum(a_peak, np.abs(ma))
        for i in np.nonzero((a_prev * ma < 0.0) & (k > 0) & (t > t_prev))[0]:
            t_mid = t_prev + (t - t_prev) * a_prev[i] / (a_prev[i] - ma[i])
            v_peak[i] = max(v_peak[i], abs(float(M[i] @ np.asarray(traj.at_time(t_mid)[1]))))
        t_prev, a_prev = t, ma
    return v_peak, a_peak


def warmup() -> None:
    """Compile (or load from numba's cache) the generators' compiled steps now: a loop
    calls this before its first tick, which must not wait for a compiler."""
    if _compiled() is None:
        return
    one = (1.0,) * 6
    pose = OnlinePose(OnlineLimits(one, one, one))
    z3, z6, quat = np.zeros(3), np.zeros(6), np.array([0.0, 0.0, 0.0, 1.0])
    pose.reset(z3, quat, z6, z6)  # (publish_pose)
    pose.set_target(z3 + 0.1, quat)  # (retarget)
    pose.step()  # ruckig's step
    pose.step()  # (sample_pose)
    pose.reset_toward(z3, quat, z6, z6, z3 + 0.1, quat)  # (restart_toward)
    seven = (1.0,) * 7
    joints = OnlineGenerator(OnlineLimits(seven, seven, seven))
    joints.reset(np.zeros(7), np.zeros(7), np.zeros(7))
    joints.set_target(np.full(7, 0.1))
    joints.step()
    joints.step()  # (sample)
    joints.mapped_peaks(np.eye(7))  # (mapped_peaks)
