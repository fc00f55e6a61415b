"""Streamed targets: follow the newest joint or Cartesian target, sent at any rate (a
learned policy at 10-50 Hz, a teleoperation device), smoothly, at 1 kHz.

The user's process calls ``set_target`` whenever it has a new target, from any thread; the
target is checked there and then. In the control process an online, jerk-limited,
time-optimal generator (:mod:`panda_py.motion.online`, ruckig) runs from the reference's
current state toward the newest target under the robot's velocity, acceleration and jerk
limits scaled by ``speed_factor``, and the arm tracks that reference through impedance with
the inertial and friction feed-forward of its motion (:mod:`panda_py.controllers.tracking`,
as the moves). A target that jumps far is reached on a smooth, time-optimal path; targets
that come faster than the arm can follow are followed as far as the limits allow.

Safety: a policy that dies stops sending. If no new target arrives within ``timeout``
seconds (of the robot's clock), the generator brings the reference to rest as fast as
``max(speed_factor, 0.5)`` of the limits allow (as a cancelled move stops), wherever it
is, and holds it there; the ``stale`` output says so. The next target is followed again.

The limits are the robot's as the control process knows them (its model's spec, picked
from the robot's protocol version as the loop's own limits are: FER, FR3 before or after
system 5.9); the controller publishes the joint limits and a reach bound at its start, and
``set_target`` checks against them.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from panda_py import checks
from panda_py.controllers import laws
from panda_py.controllers._base import FloatArray, TorqueController
from panda_py.controllers._builtin import JOINT_DAMPING, JOINT_STIFFNESS
from panda_py.controllers.law import CompiledTicks, StateView, readonly
from panda_py.controllers.model import FRICTION_SPEED, LOAD_FIELDS, ControlModel
from panda_py.controllers.moves import joint_capped
from panda_py.controllers.tracking import (
    DAMPING_TICKS,
    FRICTION_ERROR_RATE,
    PoseImpedance,
    joint_impedance_torque,
)
from panda_py.motion import rotation
from panda_py.motion.online import OnlineGenerator, OnlineLimits, OnlinePose

__all__ = ["CartesianTarget", "JointTarget"]

TIMEOUT = 0.5  # [s] default: no new target within this, and the arm comes to rest
SPEED_FACTOR = 0.2  # default, as the moves'
# a stop asks for at least this share of the limits (as a cancelled move's stop)
STOP_SPEED_FACTOR = 0.5
# of the joints' limits a streamed Cartesian target's generator may ask for (moves'
# lead-ins take moves.JOINT_SHARE, 0.6: their hand-overs overshoot more; a stream's
# targets, 50 ms apart, were measured within the limits at this)
STREAM_JOINT_SHARE = 0.7
# move_to_pose's defaults (panda.move_args.POSE_MOVE_DEFAULTS; a test holds them equal)
POSE_IMPEDANCE = np.diag([800.0, 800.0, 800.0, 40.0, 40.0, 40.0])  # [N/m, Nm/rad]
POSE_DAMPING_RATIO = 1.0
POSE_NULLSPACE_STIFFNESS = 15.0  # [Nm/rad]

_NEW, _STALE = 1, 2  # what arrived in a tick (_Streamed._news)


class _Streamed(TorqueController):
    """What both streamed controllers share: the speed factor and the timeout, the count of
    targets sent (a signal: the loop sees a new target even when it repeats the last one),
    and, in the control process, when the last one arrived."""

    def __init__(self, speed_factor: float, timeout: float | None) -> None:
        super().__init__()
        self.speed_factor = checks.number(
            "speed_factor", speed_factor, low=0.0, low_open=True, high=1.0
        )
        self.timeout = None if timeout is None else checks.timeout("timeout", timeout)
        self._sent = 0  # user side: targets sent

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state.pop("_gen", None)  # the control process's own (made in start)
        return state

    def _send_target(self, values: list[float]) -> None:
        """Write a checked target and the count of targets sent, together."""
        with self._lock:
            self._sent += 1
            count = float(self._sent)
        self._send(0, [*values, count])

    def _limits(self, model: ControlModel) -> tuple[OnlineLimits, OnlineLimits]:
        """Following and stopping limits (control process)."""
        raise NotImplementedError

    def _begin(self) -> None:
        """Control process, in start: nothing arrived yet; the time starts now."""
        self._count_at = self._sig_layout["count"][0]  # (read each tick: by index)
        self._seen = float(self._values[self._count_at])
        self._t_target = 0.0
        self._stale = False

    def _news(self) -> int:
        """Control process, each tick: ``_NEW`` if a target arrived, ``_STALE`` if the
        timeout just passed without one, else 0."""
        news = self._pending(self.t)
        if news == _NEW:
            self._seen = float(self._values[self._count_at])
            self._t_target = self.t
            self._stale = False
        elif news == _STALE:
            self._stale = True
        return news

    def _pending(self, t: float) -> int:
        """What :meth:`_news` would find at time ``t`` [s] (nothing changed)."""
        if float(self._values[self._count_at]) != self._seen:
            return _NEW
        timeout = self.timeout
        if not self._stale and timeout is not None and t - self._t_target > timeout:
            return _STALE
        return 0

    def compiled_news(self, dt: float, model: ControlModel) -> bool:
        """For a compiled loop that runs this controller's ticks (the fast world's): where
        the next tick brings news (a new target, or the targets gone stale), that tick's
        part of :meth:`step` before its compiled step, in Python: the clock advanced
        ``dt`` [s] (:meth:`tick`), the news taken, the generator stepped (ruckig
        calculates its trajectory) and its trajectory packed for the compiled sampling.
        True: the loop's kernel runs the rest of that tick with the generator standing
        where this step left it, and the ticks after it as usual. False, and nothing
        changed but the packing of a trajectory ruckig's step has just calculated: no
        news (or the first tick, which needs :meth:`step`)."""
        if not self._pending(self.t + dt) or not self._news_ready():
            self._generator().pack()
            return False
        self.tick(dt)
        self._take(self._news(), None, model)
        gen = self._generator()
        if not gen.finished:
            gen.step()
        gen.pack()
        return True

    def _generator(self) -> OnlineGenerator | OnlinePose:
        """The generator (control process: made in start)."""
        raise NotImplementedError

    def _compiled_parts(self, model: ControlModel, gen: OnlineGenerator,
                        extra: tuple[float, ...]) -> tuple[Any, ...] | None:  # fmt: skip
        """What both compiled loop kernels take first (``rt._tick_laws.joint_target_ticks``,
        ``cartesian_target_ticks``): the inputs, the count of targets guarded (a new target
        is the Python step's: ruckig calculates), and the scalars the kernel reads and
        advances (``rt._tick_laws.T_*``, in that order: when the last target arrived, the
        timeout, stale, the generator's clock, then ``extra``); None where the next tick
        is the Python step's (no numba, a model of the user's, a generator whose input
        changed)."""
        if laws.fused() is None or type(model) is not ControlModel or gen.sampling() is None:
            return None
        time, finished, duration = gen.clock()
        timeout = math.inf if self.timeout is None else self.timeout
        self._scalars = np.array([self._t_target, timeout, 1.0 if self._stale else 0.0, time,
                                  1.0 if finished else 0.0, duration, *extra])  # fmt: skip
        guard = np.array([[self._count_at, 1]], dtype=np.int64)
        return self._values, guard, np.array([self._seen]), self._scalars

    def _compiled_gen_ran(self, gen: OnlineGenerator) -> None:
        s = self._scalars
        gen.compiled_steps(float(s[3]), s[4] != 0.0)

    def _news_ready(self) -> bool:
        """Whether :meth:`compiled_news` can take the news without the tick's state."""
        return True

    def _take(self, news: int, state: StateView | None, model: ControlModel) -> None:
        """Take the news (``_NEW`` or ``_STALE``) into the generator: a new target, or rest
        (``state``: this tick's, where the controller needs it; None where it does not)."""
        raise NotImplementedError

    @property
    def lag(self) -> float:
        """How far the reference is from the newest target, as the loop last published
        ([rad] the largest joint's for joints, [m] for a pose)."""
        return float(self.get_output("lag")[0])

    @property
    def stale(self) -> bool:
        """Whether no target arrived within ``timeout``: the arm is brought to rest."""
        return bool(self.get_output("stale")[0])


class JointTarget(_Streamed):
    """Follow the newest joint target ``set_target(q)`` [rad] under joint impedance
    (``stiffness`` [Nm/rad], ``damping`` [Nm s/rad], ``move_to_joint_position``'s defaults)
    along a jerk-limited, time-optimal reference within the joint limits times
    ``speed_factor``; at rest after ``timeout`` [s] without a new target (None: never).

    Outputs: ``q_d``, ``dq_d``, ``ddq_d`` (the reference), ``lag`` (the largest joint's
    distance from the newest target to the reference [rad]), ``stale``, and the joint
    limits ``q_min``, ``q_max`` the targets are checked against."""

    signals: ClassVar[dict[str, int]] = {"q": 7, "count": 1}
    outputs: ClassVar[dict[str, int]] = {
        "q_d": 7, "dq_d": 7, "ddq_d": 7, "lag": 1, "stale": 1, "q_min": 7, "q_max": 7,
    }  # fmt: skip

    def __init__(
        self,
        speed_factor: float = SPEED_FACTOR,
        *,
        stiffness: Any = JOINT_STIFFNESS,
        damping: Any = JOINT_DAMPING,
        timeout: float | None = TIMEOUT,
    ) -> None:
        super().__init__(speed_factor, timeout)
        self.stiffness = np.array(checks.nonnegative("stiffness", stiffness, 7, "[Nm/rad]"))
        self.damping = np.array(checks.nonnegative("damping", damping, 7, "[Nm s/rad]"))

    def set_target(self, q: Any) -> None:
        """Follow the joint positions ``q`` [rad] from now on (within the joint limits)."""
        values = self._joint_target(q)
        self._send_target(values)

    @property
    def reference(self) -> tuple[FloatArray, FloatArray]:
        """The reference the loop last published: joint positions [rad], velocities
        [rad/s]."""
        return self.get_output("q_d"), self.get_output("dq_d")

    # --- control process ------------------------------------------------------------

    def start(self, state: StateView, model: ControlModel) -> None:
        joints = model.spec.joints
        s = self.speed_factor
        self._follow = OnlineLimits.joints(model.spec, s)
        self._stop = OnlineLimits.joints(model.spec, max(s, STOP_SPEED_FACTOR))
        gen = self._gen = OnlineGenerator(self._follow)
        gen.reset(state.q, state.dq, np.zeros(7))
        self.initial_signals(q=state.q)
        self._begin()
        self.set_output("q_min", joints.q_min)
        self.set_output("q_max", joints.q_max)
        self._publish(state.q)

    def _publish(self, target: FloatArray) -> None:
        # straight into the outputs, declared in this order (as CartesianTarget's)
        gen, out, o = self._gen, self._out, self._out_layout["q_d"][0]
        out[o : o + 7] = gen.position
        out[o + 7 : o + 14] = gen.velocity
        out[o + 14 : o + 21] = gen.acceleration
        out[o + 21] = float(np.abs(target - gen.position).max())
        out[o + 22] = float(self._stale)

    def _generator(self) -> OnlineGenerator:
        return self._gen

    def _take(self, news: int, state: StateView | None, model: ControlModel) -> None:
        gen = self._gen
        if news == _NEW:
            gen.set_limits(self._follow)
            gen.set_target(self.signal("q"))
        elif news == _STALE:
            gen.set_limits(self._stop)
            gen.set_rest()

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Between its news: ``rt._tick_laws.joint_target_ticks``."""
        gen = self._gen
        extra = (0.0, 0.0, FRICTION_SPEED, FRICTION_ERROR_RATE, float(self._sig_layout["q"][0]),
                 float(self._out_layout["q_d"][0]))  # fmt: skip
        parts = self._compiled_parts(model, gen, extra)
        sampling = gen.sampling()
        if parts is None or sampling is None:
            return None
        arm = model.kernel_arrays(state)[1]
        arrays = (*parts, readonly(sampling[0]), *sampling[1:], readonly(self.stiffness),
                  readonly(self.damping), *arm, model.armature, model.coulomb)  # fmt: skip
        return CompiledTicks("joint_target_ticks", arrays, ("F_T_EE", *LOAD_FIELDS),
                             np.array([self.t, self.dt]))  # fmt: skip

    def compiled_ran(self, time: FloatArray, in_seq: int) -> None:
        super().compiled_ran(time, in_seq)
        self._compiled_gen_ran(self._gen)

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        gen = self._gen
        target = self.signal("q")
        self._take(self._news(), state, model)
        if not gen.finished:
            gen.step()
        q_d, dq_d, ddq_d = gen.position, gen.velocity, gen.acceleration
        tau = joint_impedance_torque(self.stiffness, self.damping, q_d, dq_d, ddq_d, state, model)
        self._publish(target)
        return tau  # (with the Coriolis torques)


class CartesianTarget(_Streamed):
    """Follow the newest end-effector target ``set_target(position, orientation)`` (or a
    4x4 pose, base frame) under Cartesian impedance (``impedance`` [N/m, Nm/rad],
    ``damping_ratio``, ``nullspace_stiffness`` [Nm/rad] toward the configuration at start:
    ``move_to_pose``'s defaults) along a jerk-limited, time-optimal reference within the
    robot's Cartesian limits times ``speed_factor`` (and within its joints' where the arm
    is); at rest after ``timeout`` [s] without a new target (None: never).

    Outputs: ``position_d``, ``orientation_d``, ``twist_d`` (the reference), ``lag`` (the
    distance from the newest target's position to the reference's [m]), ``lag_angle`` [rad],
    ``stale``, and ``reach`` (the shoulder's height and a radius around it [m] no target
    may exceed: a bound the arm can surely not pass, checked as cheap as it is)."""

    signals: ClassVar[dict[str, int]] = {"position": 3, "orientation": 4, "count": 1}
    outputs: ClassVar[dict[str, int]] = {
        "position_d": 3, "orientation_d": 4, "twist_d": 6, "lag": 1, "lag_angle": 1,
        "stale": 1, "reach": 2,
    }  # fmt: skip

    def __init__(
        self,
        speed_factor: float = SPEED_FACTOR,
        *,
        impedance: Any = POSE_IMPEDANCE,
        damping_ratio: float = POSE_DAMPING_RATIO,
        nullspace_stiffness: float = POSE_NULLSPACE_STIFFNESS,
        timeout: float | None = TIMEOUT,
    ) -> None:
        super().__init__(speed_factor, timeout)
        K = checks.matrix6("impedance", impedance, "[N/m, Nm/rad]")
        self.impedance = np.array(K).reshape(6, 6)
        self.damping_ratio = checks.nonnegative_scalar("damping_ratio", damping_ratio)
        self.nullspace_stiffness = checks.nonnegative_scalar(
            "nullspace_stiffness", nullspace_stiffness, "[Nm/rad]"
        )

    def set_target(self, position: Any, orientation: Any = None) -> None:
        """Follow the end-effector ``position`` [m] and ``orientation`` (unit quaternion
        x, y, z, w) in the base frame from now on; or ``set_target(pose)``, a 4x4
        homogeneous transform."""
        if orientation is None:
            p, o = _pose("position", position)
        else:
            p = checks.fast_floats("position", position, 3, "[m]")
            o = checks.quaternion("orientation", orientation)
        shoulder, radius = self._published_bounds(("reach",))[0]
        d = math.sqrt(p[0] * p[0] + p[1] * p[1] + (p[2] - shoulder) ** 2)
        if d > radius:
            raise ValueError(
                f"position: expected a point the arm can reach, within {radius:.3f} m of its "
                f"shoulder (0, 0, {shoulder:.3f}) m; got {p}, {d:.3f} m from it"
            )
        self._send_target(p + o)

    @property
    def reference(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The reference the loop last published: position [m], orientation (x, y, z, w),
        twist [m/s, rad/s]."""
        return (self.get_output("position_d"), self.get_output("orientation_d"),
                self.get_output("twist_d"))  # fmt: skip

    # --- control process ------------------------------------------------------------

    def start(self, state: StateView, model: ControlModel) -> None:
        spec = model.spec
        s = self.speed_factor
        self._follow = OnlineLimits.cartesian(spec, s)
        self._stop = OnlineLimits.cartesian(spec, max(s, STOP_SPEED_FACTOR))
        T = state.O_T_EE
        J = model.ee_jacobian(state)
        p, quat = T[12:15].copy(), laws.quat_from_matrix(T)
        gen = self._gen = OnlinePose(self._follow)
        gen.reset(p, quat, J @ state.dq, np.zeros(6))
        gen.set_limits(joint_capped(self._follow, J, spec, gen.frames, STREAM_JOINT_SHARE))
        self._law = PoseImpedance(self.impedance, self.damping_ratio, state.q.copy(),
                                  self.nullspace_stiffness)  # fmt: skip
        self.initial_signals(position=p, orientation=quat)
        self._begin()
        # the compiled step's: its per-tick scalars (see _fused_step), the target's
        # position and orientation (declared one after the other: one view)
        o = self._out_layout["position_d"][0]
        self._tick = np.array([0.0, 0.0, 0.0, 0.0, float(o)])
        a = self._sig_layout["position"][0]
        assert self._sig_layout["orientation"][0] == a + 3
        self._target = self._values[a : a + 7]
        self.set_output("reach", reach(spec, state.F_T_EE))
        self._publish(p, quat)

    def _publish(self, p: FloatArray, quat: FloatArray) -> None:
        # straight into the outputs, declared in this order (set_output's lookups would be
        # a tenth of this controller's own cost per tick); compiled, one call
        gen, out, o = self._gen, self._out, self._out_layout["position_d"][0]
        kernels = laws.compiled()
        if kernels is not None:
            kernels.pose_target_outputs(gen.position, gen.orientation, gen.twist, p, quat,
                                        self._stale, out, o)  # fmt: skip
            return
        out[o : o + 3] = gen.position
        out[o + 3 : o + 7] = gen.orientation
        out[o + 7 : o + 13] = gen.twist
        x, y, z = p.tolist()
        px, py, pz = gen.position.tolist()
        a, b, c, d = quat.tolist()
        e, f, g, h = gen.orientation.tolist()
        out[o + 13] = math.sqrt((x - px) ** 2 + (y - py) ** 2 + (z - pz) ** 2)
        out[o + 14] = 2.0 * math.acos(min(1.0, abs(a * e + b * f + c * g + d * h)))
        out[o + 15] = 1.0 if self._stale else 0.0

    def _generator(self) -> OnlinePose:
        return self._gen

    def _news_ready(self) -> bool:
        return self._law.J_prev is not None

    def _take(self, news: int, state: StateView | None, model: ControlModel) -> None:
        gen = self._gen
        if news == _NEW:
            gen.set_target(self.signal("position"), self.signal("orientation"))
            limits = self._follow
        elif news == _STALE:
            gen.set_rest()
            limits = self._stop
        else:
            return
        # within the joints' limits where the arm is (a Cartesian bound can ask a joint
        # for more; the last tick's Jacobian, where the law has one)
        J = self._law.J_prev
        if J is None:
            assert state is not None  # (compiled_news waits for a tick's Jacobian)
            J = model.ee_jacobian(state)
        gen.set_limits(joint_capped(limits, J, model.spec, gen.frames, STREAM_JOINT_SHARE))

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Between its news, after its first tick (the tracking's Jacobian):
        ``rt._tick_laws.cartesian_target_ticks``."""
        law, gen = self._law, self._gen
        extra = (float(law.damping_due), float(DAMPING_TICKS), 0.0, 0.0, 0.0, 0.0)
        parts = self._compiled_parts(model, gen.gen, extra)
        if parts is None or law.J_prev is None:
            return None
        chain, arm = model.kernel_arrays(state)
        traj, *sampling = gen.sampling()
        arrays = (*parts, self._tick, readonly(traj), *sampling, law.buffer,
                  readonly(self._target), chain, *arm, model.armature, model.coulomb)  # fmt: skip
        return CompiledTicks("cartesian_target_ticks", arrays, ("F_T_EE", *LOAD_FIELDS),
                             np.array([self.t, self.dt]))  # fmt: skip

    def compiled_ran(self, time: FloatArray, in_seq: int) -> None:
        super().compiled_ran(time, in_seq)
        self._compiled_gen_ran(self._gen.gen)
        self._law.compiled_ran(int(self._scalars[6]))

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        gen = self._gen
        self._take(self._news(), state, model)
        fused = laws.fused()
        if fused is not None and type(model) is ControlModel:
            return self._fused_step(fused, state, model)
        if not gen.finished:
            gen.step()
        tau = self._law.torque(state, model, self.dt, gen.position, gen.orientation, gen.twist,
                               gen.accel)  # fmt: skip
        self._publish(self.signal("position"), self.signal("orientation"))
        return tau  # (with the Coriolis torques)

    def _fused_step(self, fused: Any, state: StateView, model: ControlModel) -> FloatArray:
        """The rest of :meth:`step` in one compiled call (``_fused.pose_target_step``): the
        generator's sampling, the tracking and the outputs (the same arithmetic as the
        separate calls)."""
        gen, tick = self._gen, self._tick
        t = None if gen.finished else gen.advance()
        if t is None:
            tick[0] = 0.0  # the reference stands (or ruckig's step just set it)
        else:
            tick[0], tick[1], tick[2] = 1.0, gen.duration, t
        tick[3] = 1.0 if self._stale else 0.0
        chain, arm = model.kernel_arrays(state)
        tau = np.empty(7)
        fused.pose_target_step(tick, *gen.sampling(), state.O_T_EE, state.q, state.dq, chain,
                               *arm, model.armature, model.coulomb,
                               self._law.compiled_inputs(self.dt), self._target, self._out,
                               tau)  # fmt: skip
        return tau  # (with the Coriolis torques)


def reach(spec: Any, F_T_EE: FloatArray) -> tuple[float, float]:
    """The shoulder's height [m] and a radius around it [m] the end effector cannot pass:
    the lengths of the links from the shoulder to the flange (each joint's offset
    ``hypot(a, d)``, triangle inequality) plus the end effector's offset from the flange
    (``F_T_EE``, flat column-major)."""
    dh = spec.dh
    links = sum(math.hypot(a, d) for a, d in zip(dh.a[1:], dh.d[1:], strict=True))
    ee = float(np.linalg.norm(np.asarray(F_T_EE)[12:15]))
    return float(dh.d[0]), links + dh.flange_d + ee


def _pose(name: str, pose: Any) -> tuple[list[float], list[float]]:
    """A 4x4 rigid transform as its position [m] and unit quaternion (x, y, z, w)."""
    try:
        T = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{name}: expected a 4x4 pose, or a position with an orientation, got {pose!r}"
        ) from exc
    if T.shape != (4, 4):
        raise ValueError(
            f"{name}: expected a 4x4 pose (or give the orientation too), got shape {T.shape}"
        )
    if not np.isfinite(T).all():
        raise ValueError(f"{name}: expected finite values, got {T.tolist()}")
    deviation = float(checks.rigid_errors(T))
    if deviation > checks.RIGID_TOL:
        raise ValueError(checks.rigid_message(name, deviation))
    return T[:3, 3].tolist(), rotation.from_matrix(T[:3, :3]).tolist()
