"""The laws that track a planned motion in the control process: a joint trajectory under
joint impedance, a Cartesian trajectory under Cartesian impedance (panda-py's
``move_to_joint_position`` and ``move_to_pose``).

The user's process plans the time-optimal trajectory and samples it at the robot's 1 ms
period; the loop only indexes the samples (no planning or sampling inside a tick). A move
ends when the trajectory is over and the arm has settled at the goal (at rest within
``dq_threshold`` and within the settle tolerance), or 1 s after the trajectory's end.

A move that replaces a running one (:meth:`Tracker.handover`) leads in from that one's
reference with an online, jerk-limited generator (:mod:`panda_py.motion.online`) and joins
its own plan; a cancelled move, or one whose ``until`` condition holds, comes to rest
through the same generator. Either way the reference stays continuous in position,
velocity and acceleration.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers import laws
from panda_py.controllers.condition_program import COLUMNS, compile_condition
from panda_py.controllers.finalize import FILTER_LAG, LAG_PART, LAG_TICKS, ahead_at
from panda_py.controllers.law import CompiledTicks, ControlLaw, StateView, readonly
from panda_py.controllers.model import FRICTION_SPEED, LOAD_FIELDS, ControlModel
from panda_py.controllers.plans import JointPlan, MoveResult, PosePlan, Progress, rotation_angle
from panda_py.controllers.tracking import (
    DAMPING_TICKS,
    FRICTION_ERROR_RATE,
    PoseImpedance,
    joint_impedance_torque,
)
from panda_py.fci import PERIOD
from panda_py.motion import rotation as rot
from panda_py.motion.online import LATERAL, OnlineGenerator, OnlineLimits, OnlinePose

__all__ = ["JointMove", "PoseMove", "Tracker", "joint_capped", "joint_capped_peaks", "tracker_for"]

# a move has no inputs from the user's process (its compiled ticks read none)
_NO_INPUTS = np.zeros(0)
_NO_GUARD = np.zeros((0, 2), dtype=np.int64)
# a move without an ``until`` condition: an empty program (condition_program)
_NO_PROGRAM = (np.zeros((0, COLUMNS)), np.zeros(1))
# a move that is not leading: no generator's trajectory to sample (read-only, as one is)
_NO_TRAJECTORY = readonly(np.zeros((0, 0)))

FloatArray = NDArray[np.float64]

SETTLE_JOINT = 2e-4  # [rad] at goal: every joint within this
# [1/s] integral gain per unit stiffness once a Cartesian move's trajectory ended: fast
# enough that the wrist breaks free of its dry friction within the settle time
SETTLE_INTEGRAL_POSE = 2.0
# [1/s] once a Cartesian move's trajectory ended, a push of the drives' friction level
# toward the goal (as if the joints moved there at this rate times the error), on top of
# the tracking's own cancelling of it (tracking.FRICTION_ERROR_RATE): a joint that friction
# holds breaks free at once. Measured without it: a Cartesian move and the FR3 path ran
# into SETTLE_TIMEOUT, the FER's 15 cm move settled 0.55 s after its trajectory instead of
# 0.22 s
SETTLE_RATE = 10.0
# once a joint move's trajectory ended, its friction is cancelled along the way back to
# the goal as if the joint moved there at SETTLE_RATE_JOINT [1/s] times its error, in full
# beyond SETTLE_DEADBAND [rad] and not at all within it: a joint held off the goal breaks
# free, one within half the settle tolerance stays at rest. The integral and the push on
# top of the tracking's cancelling it replaced (the friction cancelled up to twice over)
# moved joints already within 1e-4 rad at 7 mrad/s, above dq_threshold, for 20-30 ms
SETTLE_RATE_JOINT = 100.0
SETTLE_DEADBAND = 0.5 * SETTLE_JOINT
# [1/s] once a joint move's trajectory ended, an integral of the error beyond
# SETTLE_DEADBAND, per unit stiffness: what the model does not know (a grasped object's
# weight) holds a joint off its goal, which the friction's cancelling cannot move.
# Measured without it: the demo's joint moves with the cube in the hand ran into
# SETTLE_TIMEOUT, 0.53-0.57 mrad off. It holds its value within the deadband, so a joint
# at its goal gets no push that would make it creep.
SETTLE_INTEGRAL = 30.0
SETTLE_POSITION = 2e-3  # [m]
# [rad] a Cartesian move that replaced another on the FR3 came to rest 2.2-2.4 mrad off
# its orientation (40 Nm/rad against the wrist's dry friction) and, at 2 mrad, ended only
# at SETTLE_TIMEOUT, a second later; 3 mrad is 0.3 mm at 10 cm from the flange
SETTLE_ORIENTATION = 3e-3
# Once a Cartesian move's trajectory ended, its settling acts on the error beyond a band of
# half its position tolerance SETTLE_POSITION [m] and, on the error's rotation vector (the
# quaternion's vector part: half the angle), of a quarter of its orientation tolerance
# [rad], and not at all within it: there the tracking's own cancelling of the friction is
# undone too, so the friction holds an arm that reached its goal at rest. Measured before
# (the integral and the push on the whole error, on top of the tracking's cancelling):
# the friction cancelled twice over drove the joints at 2-50 mrad/s with the hand within
# 0.1 mm of its goal, and the moves ended 5-305 ms after their trajectory on the FER
# (median 88 ms over 8 random moves), 0-139 on the FR3; with the band 2-216 (median 10)
# and 0-84 (median 0).
SETTLE_BAND_POSITION = 0.5 * SETTLE_POSITION
SETTLE_BAND_ROTATION = 0.25 * SETTLE_ORIENTATION
SETTLE_TIMEOUT = 1.0  # [s] after the trajectory's end the move ends regardless
# A joint move cancels the drives' dry friction in full on a joint planned faster than
# MOVE_FRICTION_SPEED [rad/s] or behind its reference by more than that over
# MOVE_ERROR_RATE [1/s] (tanh-shaped below: tracking.joint_impedance_torque). At the
# general 1e-2 rad/s and 10/s (model.FRICTION_SPEED, tracking.FRICTION_ERROR_RATE) the
# wrist's friction held a joint up to 1 mrad behind a plan that ends slowly (0.3 mrad,
# a joint the plan hardly moves, for the whole move), which the settling then took 50-80
# ms to remove; at these it stays within 0.1 mrad. (A Cartesian move keeps the general
# ones: without the viscous feed-forward its compiled tracking lacks, these left it
# further from its goal at the trajectory's end.)
MOVE_FRICTION_SPEED = 3e-3
MOVE_ERROR_RATE = 60.0
# a move whose arm is farther than this from its plan's start at its first tick was planned
# while another move ran: it leads in from where the arm is (the plan's own start is the
# arm's state when it was planned, within the robot's joint limits)
START_JOINT = 1e-2  # [rad]
# of the joints' velocity and acceleration limits a Cartesian lead-in or stop may ask
# for: the arm tracks the online reference through impedance and overshoots it, by up to
# 1.3x from a running move (100 random preemptions, five sequences: at 0.7 the arm reached
# 0.76-0.92 of the acceleration limit, at 0.6 0.67-0.80); a sampled plan is tracked more
# closely (planning.PLAN_JOINT_SHARE)
JOINT_SHARE = 0.6
# joint_capped_peaks' tries (each one of ruckig's whole trajectories), and how far past
# the share it accepts: an arm that starts beyond it (the share judged against its own
# motion) peaks a little past its start while ruckig brakes it, whatever the limits (a
# random replacement: 1.075, 1.039, 1.018 in four tries, and then the worst case's cap)
PEAK_TRIES = 4
PEAK_TOLERANCE = 1.03
BLEND_TIME = 0.05  # [s] from one space's law to the other's (see Tracker._blend_from)
START_POSITION = 5e-3  # [m]
START_ORIENTATION = 1e-2  # [rad]


def tracker_for(plan: JointPlan | PosePlan) -> JointMove | PoseMove:
    """The law that tracks ``plan`` in the control loop."""
    if isinstance(plan, JointPlan):
        return JointMove(plan)
    if isinstance(plan, PosePlan):
        return PoseMove(plan)
    raise TypeError(f"plan: expected a JointPlan or a PosePlan, got {type(plan).__name__}")


def _smoothstep(x: float) -> float:
    """3 x^2 - 2 x^3 on [0, 1]: from 0 to 1 with no step in the rate at either end."""
    x = min(1.0, max(0.0, x))
    return x * x * (3.0 - 2.0 * x)


def _smoothstep_inverse(y: float) -> float:
    """The x in [0, 1] where :func:`_smoothstep` is y (in [0, 1])."""
    return 0.5 - math.sin(math.asin(1.0 - 2.0 * min(1.0, max(0.0, y))) / 3.0)


def beyond_band(err: FloatArray) -> FloatArray:
    """A Cartesian move's pose error (6,) [m, rad] beyond its settling's band: its position
    part shortened by SETTLE_BAND_POSITION, its rotation part by SETTLE_BAND_ROTATION, each
    zero within its band."""
    out = np.zeros(6)
    for at, band in ((0, SETTLE_BAND_POSITION), (3, SETTLE_BAND_ROTATION)):
        part = err[at : at + 3]
        n = math.sqrt(float(part @ part))
        if n > band:
            out[at : at + 3] = part * ((n - band) / n)
    return out


def joint_capped(limits: OnlineLimits, J: FloatArray, spec: Any,
                 frames: tuple[FloatArray, FloatArray] | None = None,
                 share: float = JOINT_SHARE) -> OnlineLimits:  # fmt: skip
    """Cartesian online ``limits`` (norms) scaled down where, at the Jacobian ``J``, they
    could ask a joint for more than ``share`` of its velocity or acceleration limit.
    The joint motion is ``J^+ (v, w)``; with the generator's ``frames`` (translation,
    rotation; columns) its coordinates are bounded one by one (the whole limit along the
    first axis, LATERAL of it across), so joint i's bound is the sum over the six axes of
    ``|row_i(J^+) . axis| * limit``; without them, the worst direction."""
    joints = spec.joints
    kernels = laws.compiled()
    if frames is not None and kernels is not None:  # compiled (Cholesky, not LU: equal to 1e-9)
        sv, sa = kernels.joint_scales(
            np.ascontiguousarray(J, dtype=np.float64), frames[0], frames[1], LATERAL,
            limits.velocity[0], limits.velocity[3], limits.acceleration[0],
            limits.acceleration[3], _shares(joints.dq_max, share),
            _shares(joints.ddq_max, share),
        )  # fmt: skip
        return limits if sv == 1.0 and sa == 1.0 else limits.scaled(sv, sa)
    pinv = laws.damped_pinv(J)
    if frames is None:
        excess = math.sqrt(1.0 + 2.0 * LATERAL**2)  # the aligned frames' over a norm
        t = np.linalg.norm(pinv[:, :3], axis=1) * excess
        r = np.linalg.norm(pinv[:, 3:], axis=1) * excess
    else:
        spread = np.array([1.0, LATERAL, LATERAL])
        t = np.abs(pinv[:, :3] @ frames[0]) @ spread
        r = np.abs(pinv[:, 3:] @ frames[1]) @ spread
    v = t * limits.velocity[0] + r * limits.velocity[3]
    a = t * limits.acceleration[0] + r * limits.acceleration[3]
    sv = min(1.0, float(np.min(_shares(joints.dq_max, share) / np.maximum(v, 1e-12))))
    sa = min(1.0, float(np.min(_shares(joints.ddq_max, share) / np.maximum(a, 1e-12))))
    return limits if sv == 1.0 and sa == 1.0 else limits.scaled(sv, sa)


def joint_capped_peaks(gen: OnlinePose, limits: OnlineLimits, J: FloatArray,
                       spec: Any) -> OnlineLimits:  # fmt: skip
    """:func:`joint_capped` for a lead-in whose generator ``gen`` has its state and target:
    the joints' velocities and accelerations its trajectory asks for through ``J``'s
    pseudo-inverse, along the trajectory with their signs
    (:meth:`~panda_py.motion.online.OnlineGenerator.mapped_peaks`), not every coordinate
    at its limit at once. Counting each coordinate at its own peak, at once and with the
    worst signs (as this did before), left replacing moves up to 1.6x slower than the
    trajectory the same share of the joints' limits allows (eight random replacements on
    the FER: the braking of the replaced motion is over before the new one peaks). The
    Jacobian is the hand-over's (it changes along the lead-in: JOINT_SHARE's margin). The start
    is the arm's own: where it asks for more already, the rest is judged against it.
    Falls back to joint_capped where PEAK_TRIES tries do not settle. The limits are left
    set in ``gen``."""
    worst = joint_capped(limits, J, spec, gen.frames)
    if worst is limits:  # not even every axis at its limit at once asks too much
        gen.set_limits(limits)
        return limits
    joints = spec.joints
    pinv = laws.damped_pinv(J)
    At, Ar = gen.axes()
    mix = np.hstack([pinv[:, :3] @ At, pinv[:, 3:] @ Ar])  # (7, 6): dq = mix v (signed)
    v_share, a_share = _shares(joints.dq_max, JOINT_SHARE), _shares(joints.ddq_max, JOINT_SHARE)
    start_v = max(1.0, float((np.abs(mix @ gen.gen.velocity) / v_share).max()))
    start_a = max(1.0, float((np.abs(mix @ gen.gen.acceleration) / a_share).max()))
    capped = limits
    for _ in range(PEAK_TRIES):
        gen.set_limits(capped)
        peaks = gen.gen.mapped_peaks(mix)
        if peaks is None:
            break
        over_v = float((peaks[0] / v_share).max()) / start_v
        over_a = float((peaks[1] / a_share).max()) / start_a
        if over_v <= PEAK_TOLERANCE and over_a <= PEAK_TOLERANCE:
            return capped
        capped = capped.scaled(min(1.0, 0.98 / over_v), min(1.0, 0.98 / over_a))
    gen.set_limits(worst)
    return worst


def _holding(capped: OnlineLimits, limits: OnlineLimits, gen: OnlinePose) -> OnlineLimits:
    """``capped`` (``limits`` scaled down, in effect in ``gen``) raised, up to ``limits``, to
    hold the velocity and the acceleration ``gen`` starts with. A lead-in's first tick
    runs at the worst case's cap and the next ones at its trajectory's (see
    PoseMove.published): from a start beyond the first cap, ruckig cut the acceleration
    for one tick and raised it again the next, a wobble in the torque (30 % of it where a
    move replaced one in its blend)."""
    g = gen.gen  # (its coordinates' limits: capped's, spread over the aligned frames)
    v, a, lim = g.velocity.tolist(), g.acceleration.tolist(), g.limits
    over_v = max(abs(x) / m for x, m in zip(v, lim.velocity, strict=True))
    over_a = max(abs(x) / m for x, m in zip(a, lim.acceleration, strict=True))
    if over_v <= 1.0 and over_a <= 1.0:
        return capped
    room_v = limits.velocity[0] / capped.velocity[0]
    room_a = limits.acceleration[0] / capped.acceleration[0]
    return capped.scaled(min(room_v, max(1.0, over_v)), min(room_a, max(1.0, over_a)))


@functools.lru_cache(maxsize=16)
def _shares(limits: tuple[float, ...], share: float) -> FloatArray:
    """``share`` of each joint's ``limits`` (read-only by use: cached and shared)."""
    return share * np.asarray(limits, dtype=np.float64)


class Tracker(ControlLaw):
    """What both moves share: the reference's end, a gentle stop (cancel, or the
    ``until`` condition), a successor to continue with, and how the result says so.

    The reference is the plan's samples, or, while ``lead`` runs, the online generator's:
    leading in from the move this one replaced, or decelerating to rest."""

    def __init__(self, n: int, dq_threshold: float) -> None:
        super().__init__()
        self.last = n - 1
        self.duration = self.last * PERIOD  # [s] of the reference (known after a lead-in)
        self.t_end = self.duration  # [s] when the reference ends
        self.dq_threshold = dq_threshold
        self.k0 = 0  # the plan's sample at plan time 0
        self.t0 = 0.0  # [s] the law's time at plan time 0
        self.leading = False  # the reference is the online generator's
        self.stopping = False  # it is coming to rest (cancelled or its condition held)
        self.stop_reason = ""
        self.until: Any = None  # a condition (panda_py.controllers.conditions), or None
        self.then: JointPlan | PosePlan | None = None  # what follows when it holds
        self.condition = ""
        self.condition_time = math.nan
        self.successor: Tracker | None = None  # set when the condition hands over
        self.previous: Tracker | None = None  # the law it blends from (see _blend_from)
        self.blend_start = 0.0  # [s] where in BLEND_TIME its blend began (see _blend_from)
        self.ref: tuple[FloatArray, ...] = ()  # this tick's reference (the subclass's space)
        # the condition as the compiled ticks evaluate it: (program, stack), or None where
        # it cannot be compiled, once made (see _program)
        self._until_program: tuple[FloatArray, FloatArray] | None = None
        self._program_made = False

    replaceable = True
    # whether the compiled ticks compute the move's distance to its goal to the bit as
    # step does (condition_program.compile_condition's exact_distance)
    exact_distance = False
    # [rad/s], [1/s] the friction's cancelling: its speed and error rate (see _times)
    friction: tuple[float, float] = (FRICTION_SPEED, FRICTION_ERROR_RATE)

    def begin(self, state: StateView, model: ControlModel) -> None:
        """Planned while another move ran, which ended before it arrived: the arm is not
        where the plan starts, so lead in from where it rests."""
        if self.off_start(state):
            self.handover(None, state, model)

    def replace(self, previous: ControlLaw, state: StateView, model: ControlModel) -> None:
        if not isinstance(previous, Tracker):
            raise TypeError(f"a move takes over from a move, not from a {previous.name}")
        self.handover(previous, state, model)

    def next_law(self, state: StateView, model: ControlModel) -> ControlLaw | None:
        """Once its condition held: the move ``then`` asked for, taken over from here."""
        successor = self.successor
        if successor is None:
            return None
        successor.handover(self, state, model)
        successor.condition = self.condition
        successor.condition_time = self.condition_time
        return successor

    def sample(self) -> int:
        """The plan's sample at this tick."""
        return min(self.k0 + round((self.t - self.t0) / PERIOD), self.last)

    def cancel(self, reason: str) -> None:
        """Come to rest as fast as the limits allow (from the reference as it is), hold
        there and end; ``reason`` says why in the result."""
        if self.stopping:
            return
        self.stopping = True
        self.stop_reason = reason
        self.t_end = math.inf
        self._begin_rest()

    def _begin_rest(self) -> None:
        raise NotImplementedError

    def handover(self, prev: Tracker | None, state: StateView, model: ControlModel) -> None:
        """Take over from ``prev`` mid-motion (see the subclasses)."""
        raise NotImplementedError

    def _blend_from(self, prev: Tracker | None) -> None:
        """Across a change of space (joint <-> Cartesian) the laws' tracking terms differ
        even on one reference: blend from the previous law's torques to this one's over
        BLEND_TIME, so the torque (and the arm's acceleration) changes smoothly. Both laws
        track this move's reference (the previous one's own plan would pull the arm off it
        and the new law catch up after the blend: up to 1.4x the planned accelerations).
        A blend that ``prev`` had not finished goes on from where it stood, so the torque
        does not step when a move is replaced within BLEND_TIME of its own hand-over (a
        Cartesian move 10 ms into its blend from a joint move, replaced by another, dropped
        the joint law's 90 % share at once: joint 5 reached 0.97 of its acceleration
        limit)."""
        self.previous, self.blend_start = None, 0.0
        if prev is None:
            return
        other = prev.previous
        if other is not None and prev.t + prev.blend_start < BLEND_TIME:
            share = _smoothstep((prev.t + prev.blend_start) / BLEND_TIME)  # prev's own
            if type(prev) is type(self):  # on with prev's blend from the other space
                self.previous, other_share = other, 1.0 - share
            else:  # back toward the other space: blend from prev's part of the torque
                self.previous, other_share = prev, share
            self.blend_start = BLEND_TIME * _smoothstep_inverse(1.0 - other_share)
        elif type(prev) is not type(self):
            self.previous = prev
        prev.previous = None  # a chain of blends ends here

    def _blended(self, tau: FloatArray, state: StateView, model: ControlModel) -> FloatArray:
        prev = self.previous
        if prev is None:
            return tau
        x = (self.t + self.blend_start) / BLEND_TIME
        if x >= 1.0:
            self.previous = None
            return tau
        prev.tick(self.dt)
        s = _smoothstep(x)  # no step in the rate either
        return s * tau + (1.0 - s) * prev.torque_toward(self.ref, state, model)

    def torque_toward(
        self, ref: tuple[FloatArray, ...], state: StateView, model: ControlModel
    ) -> FloatArray:
        """This law's torques toward the other space's reference ``ref`` (a blend's)."""
        raise NotImplementedError

    def off_start(self, state: StateView) -> bool:
        """Whether the arm is away from where the plan starts (beyond what panda-py's
        planning from the current state leaves: the clip to the joint limits)."""
        raise NotImplementedError

    def joint_reference(
        self, state: StateView, model: ControlModel
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The reference of the last tick as joint positions, velocities, accelerations."""
        raise NotImplementedError

    def pose_reference(self, state: StateView, model: ControlModel) -> tuple[FloatArray, ...]:
        """The reference of the last tick as position, orientation, twist, acceleration."""
        raise NotImplementedError

    def _lead_finished(self) -> None:
        """The online generator reached its target this tick: join the plan, or (at the
        goal, or at rest after a stop) the reference ends here."""
        if self.stopping or self.k0 >= self.last:
            self.t_end = self.t
            self.duration = self.t
        else:
            self.leading = False
            self.t0 = self.t
            self.duration = self.t + (self.last - self.k0) * PERIOD
            self.t_end = self.duration

    def check_until(self, state: StateView, progress: Progress) -> None:
        """Stop gently (or hand over to ``then``) once the condition holds."""
        if self.until is None or self.stopping or self.successor is not None:
            return
        if self.until.holds(state, progress):
            which = getattr(self.until, "which", None)  # the alternative that held
            held = which(state, progress) if which is not None else None
            self.condition = repr(held if held is not None else self.until)
            self.condition_time = self.t
            if self.then is None:
                self.cancel(f"stopped after {self.t:.3f} s: {self.condition} held")
            else:
                self.successor = tracker_for(self.then)

    def finished(self, state: StateView) -> bool:
        if self.successor is not None:
            return True
        over = self.t - self.t_end
        if over <= 0.0:
            return False
        at_rest = float(np.abs(state.dq).max()) <= self.dq_threshold
        if self.stopping:
            return at_rest or over >= SETTLE_TIMEOUT
        return (at_rest and self.at_goal(state)) or over >= SETTLE_TIMEOUT

    def at_goal(self, state: StateView) -> bool:
        raise NotImplementedError

    def _program(self, state: StateView) -> tuple[FloatArray, FloatArray] | None:
        """The ``until`` condition as the compiled ticks evaluate it (a program and its
        stack: :mod:`.condition_program`), compiled at the first ask for the state's
        protocol version; empty without a condition, None where it cannot be compiled
        (a function of the state: every tick is Python's)."""
        if self.until is None:
            return _NO_PROGRAM
        if not self._program_made:
            self._program_made = True
            version = getattr(state, "version", None)
            rows = None
            if isinstance(version, int):
                rows = compile_condition(self.until, version, exact_distance=self.exact_distance)
            if rows is not None:
                self._until_program = (rows, np.zeros(max(1, len(rows))))
        return self._until_program

    def _follows_plan(self, model: ControlModel) -> bool:
        """Whether its compiled ticks can run from here: following its plan, then settling
        at the goal, or leading in or stopping where its compiled ticks run its generator
        (_lead_compiled); no blend or fired condition (those run in Python), numba running
        the laws. (Its condition, if any, the compiled ticks evaluate: see _program.)"""
        return (
            (not (self.leading or self.stopping) or (self.leading and self._lead_compiled()))
            and self.previous is None
            and self.successor is None
            and (self.t_end < math.inf or self.leading)
            and laws.fused() is not None
            and type(model) is ControlModel
        )

    def _lead_compiled(self) -> bool:
        """Whether its compiled ticks run its online generator's steps too (a lead-in, a
        stop), from here: none by default."""
        return False

    def _lead_ran(self) -> tuple[FloatArray, ...]:
        """After compiled ticks that ran its generator's steps: the generator told, and
        its reference (see _lead_compiled)."""
        raise NotImplementedError

    def _times(self) -> FloatArray:
        """The plan's clock as a compiled loop reads it: the trajectory's end, the law's
        time at plan time 0, the period, the friction's speed and error rate, and how far
        ahead of the loop's filter the acceleration is fed forward: [s], then in whole
        ticks and the part of one (finalize.ahead_at)."""
        return np.array([self.t_end, self.t0, PERIOD, *self.friction, FILTER_LAG * PERIOD,
                         LAG_TICKS, LAG_PART])  # fmt: skip

    def compiled_ran(self, time: FloatArray, in_seq: int) -> None:
        super().compiled_ran(time, in_seq)
        self.ref = self._lead_ran() if self.leading else self._sampled(self.sample())

    def _sampled(self, k: int) -> tuple[FloatArray, ...]:
        raise NotImplementedError

    def _finish(self, result: MoveResult) -> MoveResult:
        result.condition, result.condition_time = self.condition, self.condition_time
        if self.stopping and not self.condition:
            result.success, result.reason, result.cancelled = False, self.stop_reason, True
        elif self.condition:  # ended by its condition, as asked: a success
            result.success, result.reason = True, ""
        return result


class JointMove(Tracker):
    """``tau = M ddq_d + K (q_d - q) + D (dq_d - dq) + b dq_d + coriolis`` along sampled
    ``q_d``, ``dq_d``, ``ddq_d`` (the inertial, viscous ``b`` and dry friction feed-forward
    keep the arm on the planned path instead of lagging behind it: see _damped_velocity,
    MOVE_FRICTION_SPEED). Once the trajectory has ended, the dry friction is cancelled along
    the way back to the goal outside a deadband (SETTLE_RATE_JOINT), so a joint friction
    held short of it breaks free and one at it stays at rest, and an integral of the error
    beyond the deadband removes what the model does not know, such as a grasped object's
    weight (SETTLE_INTEGRAL; panda-py stops there)."""

    friction = (MOVE_FRICTION_SPEED, MOVE_ERROR_RATE)
    exact_distance = True  # (the largest joint's: no rounding to differ in)

    def __init__(self, plan: JointPlan) -> None:
        super().__init__(len(plan.q), plan.dq_threshold)
        self.q, self.dq, self.ddq = plan.q, plan.dq, plan.ddq
        self.K, self.D = plan.stiffness, plan.damping
        self.success_threshold = plan.success_threshold
        self.goal = plan.q[-1]
        self.join = plan.join % len(plan.q)
        self.integral = np.zeros(7)  # (see SETTLE_INTEGRAL)
        self.gen = OnlineGenerator(plan.limits)
        self.stop_limits = plan.stop_limits or plan.limits
        self.ref: tuple[FloatArray, FloatArray, FloatArray] = (plan.q[0], plan.dq[0], plan.ddq[0])
        self.viscous_gain: FloatArray | None = None  # (see _damped_velocity)
        self._dq_law: FloatArray | None = None  # the plan's velocities times viscous_gain
        # the compiled ticks' generator scalars and its velocity times viscous_gain
        self._lead = np.zeros(5)
        self._lead_dq = np.zeros(7)
        self._ahead = np.zeros((3, 7))  # the generator's state ahead of the filter

    def _damped_velocity(self, model: ControlModel) -> FloatArray:
        """The drives' viscous friction ``b dq_d`` fed forward through the damping:
        ``D (g dq_d - dq) = D (dq_d - dq) + b dq_d`` with ``g = 1 + b / D`` per joint (1
        where there is no damping), so the compiled tracking, which knows no viscous term,
        computes the same torques from the plan's velocities times ``g``."""
        gain = self.viscous_gain
        if gain is None:
            viscous = getattr(model, "viscous", None)
            gain = np.ones(7)
            if viscous is not None:
                D = np.asarray(self.D, dtype=np.float64)
                np.divide(viscous, D, out=gain, where=D > 0.0)
                gain[D > 0.0] += 1.0
                gain[D <= 0.0] = 1.0
            self.viscous_gain = gain
        return gain

    def handover(self, prev: Tracker | None, state: StateView, model: ControlModel) -> None:
        """Replace ``prev`` mid-motion: lead in from its reference (from the arm at rest
        where it is, without one) to this plan's sample ``join`` (its goal for a single
        target), jerk-limited, then follow the plan."""
        if prev is None:
            self.gen.reset(np.array(state.q), np.zeros(7), np.zeros(7))
        else:
            self.gen.reset(*prev.joint_reference(state, model))
        gen = self.gen
        # until its first step the reference is where it takes over, not the plan's start
        self.ref = (gen.position.copy(), gen.velocity.copy(), gen.acceleration.copy())
        j = self.join
        self.gen.set_target(self.q[j], self.dq[j], self.ddq[j])
        self.k0, self.leading = j, True
        self.t_end = self.duration = math.inf
        self._blend_from(prev)

    def off_start(self, state: StateView) -> bool:
        return float(np.abs(self.q[0] - state.q).max()) > START_JOINT

    def joint_reference(
        self, state: StateView, model: ControlModel
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The reference of the last tick: joint positions, velocities, accelerations."""
        return self.ref[0].copy(), self.ref[1].copy(), self.ref[2].copy()

    def pose_reference(self, state: StateView, model: ControlModel) -> tuple[FloatArray, ...]:
        """The pose and twist the arm has, with the reference's acceleration (as
        :meth:`PoseMove.joint_reference`: a lead-in from the reference's twist where the arm
        lags it would make the new law catch up, up to 1.3x the planned accelerations)."""
        J = model.ee_jacobian(state)
        T = state.O_T_EE
        return T[12:15].copy(), laws.quat_from_matrix(T), J @ state.dq, J @ self.ref[2]

    def torque_toward(
        self, ref: tuple[FloatArray, ...], state: StateView, model: ControlModel
    ) -> FloatArray:
        """Toward a pose reference ``(position, orientation, twist, acceleration)``: the
        joints it asks for to first order (``J^+`` of its error, twist, acceleration), the
        arm's motion in the task's nullspace kept as it is (the Cartesian law damps it
        gently; the joint damping would brake it at once)."""
        p_d, quat_d, v_d, a_d = ref
        J = model.ee_jacobian(state)
        pinv = laws.damped_pinv(J)
        err = laws.cartesian_error(state.O_T_EE, p_d, quat_d)
        err[3:] *= 2.0  # the quaternion's vector part: half the rotation, to first order
        dq = np.asarray(state.dq)
        q_d = np.asarray(state.q) - pinv @ err
        dq_d = dq + pinv @ (v_d - J @ dq)
        return joint_impedance_torque(self.K, self.D, q_d, dq_d, pinv @ a_d, state, model)

    def _begin_rest(self) -> None:
        self.gen.reset(*(r.copy() for r in self.ref))
        self.gen.set_limits(self.stop_limits)
        self.gen.set_rest()
        self.leading = True

    def _reference(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        gen = self.gen
        if self.leading:
            if not gen.finished and gen.step():
                self._lead_finished()
            return gen.position, gen.velocity, gen.acceleration
        return self._sampled(self.sample())

    def _sampled(self, k: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        return self.q[k], self.dq[k], self.ddq[k]

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Every phase of the move: its lead-in (planned while another ran, or replacing
        one), its plan, its stop and its settling: ``rt._tick_moves.joint_move_ticks``
        (Python keeps ruckig's steps and the tick the lead-in reaches its target on)."""
        program = self._program(state)
        if program is None or not self._follows_plan(model):
            return None
        chain, arm = model.kernel_arrays(state)
        gain = self._damped_velocity(model)
        if self._dq_law is None:
            self._dq_law = self.dq * gain
        gen = self.gen
        self._lead[:] = 0.0  # (rt._tick_moves.G_*)
        traj = _NO_TRAJECTORY
        if self.leading:
            sampling = gen.sampling()
            assert sampling is not None  # (_lead_compiled)
            traj = readonly(sampling[0])
            time, finished, duration = gen.clock()
            self._lead[:] = (1.0, 1.0 if self.stopping else 0.0, time, 1.0 if finished else 0.0,
                             duration)  # fmt: skip
        arrays = (
            _NO_INPUTS, _NO_GUARD, _NO_INPUTS, readonly(self.q), readonly(self._dq_law),
            readonly(self.ddq), readonly(self.K), readonly(self.D), chain, *arm,
            model.armature, model.coulomb, self._times(), np.array([self.k0, self.last]),
            self._settle(), self.integral, self._lead, traj, gen.position, gen.velocity,
            gen.acceleration, gain, self._lead_dq, self._ahead, *program,
        )  # fmt: skip
        return CompiledTicks("joint_move_ticks", arrays, ("F_T_EE", *LOAD_FIELDS),
                             np.array([self.t, self.dt]))  # fmt: skip

    def _lead_compiled(self) -> bool:
        return self.gen.sampling() is not None  # (not before ruckig's step on a new input)

    def _lead_ran(self) -> tuple[FloatArray, ...]:
        gen, lead = self.gen, self._lead
        gen.compiled_steps(float(lead[2]), lead[3] != 0.0)
        return gen.position, gen.velocity, gen.acceleration

    def _settle(self) -> FloatArray:
        """The settling's constants as ``rt._tick_moves.joint_move_ticks`` reads them (its
        ``S_*`` offsets: step's and finished's, below)."""
        scale = FRICTION_SPEED / MOVE_FRICTION_SPEED
        return np.array([self.dq_threshold, SETTLE_JOINT, SETTLE_TIMEOUT, SETTLE_DEADBAND,
                         SETTLE_INTEGRAL, SETTLE_RATE_JOINT, scale, MOVE_ERROR_RATE * scale,
                         1.0 / FRICTION_SPEED])  # fmt: skip

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        q_d, dq_d, ddq_d = self.ref = self._reference()
        # the acceleration fed forward ahead of the loop's filter: the plan's, or the
        # generator's while it leads in or comes to rest
        if self.leading:
            ddq_d = self.gen.acceleration_ahead(FILTER_LAG * PERIOD)
        else:
            ddq_d = ahead_at(self.ddq, self.sample())
        tau = joint_impedance_torque(self.K, self.D, q_d, dq_d * self._damped_velocity(model),
                                     ddq_d, state, model, MOVE_FRICTION_SPEED,
                                     MOVE_ERROR_RATE)  # fmt: skip
        if self.t > self.t_end and not self.stopping:
            # the friction's cancelling along the way back to the goal, in full outside
            # SETTLE_DEADBAND and not at all within it (in place of the tracking's own): a
            # joint friction holds off the goal breaks free, one at it stays at rest
            error = self.goal - state.q
            beyond = error - np.clip(error, -SETTLE_DEADBAND, SETTLE_DEADBAND)
            self.integral += self.dt * beyond
            tau += SETTLE_INTEGRAL * self.K * self.integral
            push = np.where(np.abs(error) > SETTLE_DEADBAND, error * SETTLE_RATE_JOINT, 0.0)
            scale = FRICTION_SPEED / MOVE_FRICTION_SPEED  # (friction_for's speed is the general)
            tau += model.friction_for(push * scale) - model.friction_for(
                error * (MOVE_ERROR_RATE * scale)
            )
        if self.until is not None:
            self.check_until(state, Progress(self.t, float(np.abs(self.goal - state.q).max())))
        return self._blended(tau, state, model)  # (the law's torque has the Coriolis')

    def at_goal(self, state: StateView) -> bool:
        return float(np.abs(self.goal - state.q).max()) <= SETTLE_JOINT

    def result(self, state: StateView) -> MoveResult:
        err = float(np.abs(self.goal - state.q).max())
        ok = err <= self.success_threshold
        reason = (
            ""
            if ok
            else (
                f"finished {err:.4f} rad from the goal, above the success threshold of "
                f"{self.success_threshold:.4f} rad; consider a higher stiffness or a lower "
                "speed_factor"
            )
        )
        return self._finish(
            MoveResult(ok, reason, joint_error=err, duration=self.duration, elapsed=self.t)
        )


class PoseMove(Tracker):
    """Cartesian impedance along sampled positions, orientations, twists and their
    derivatives, with a joint impedance toward the start configuration in the task's
    nullspace and an inertial feed-forward of the planned acceleration:
    ``tau = J^T (-K e - D (J dq - v_d)) + M J^+ (a_d - dJ dq)
    + N (k_n (q_0 - q) - 2 sqrt(k_n) dq) + coriolis``, plus the drives' dry and viscous
    friction along the planned joint velocity ``J^+ v_d`` and, once the trajectory has
    ended, an integral of the error to the goal (as :class:`JointMove`). The planned
    acceleration it feeds forward is the plan's FILTER_LAG ticks on
    (:func:`~panda_py.controllers.finalize.ahead_at`), so that the loop's low-pass
    filter delivers its torque on time."""

    def __init__(self, plan: PosePlan) -> None:
        super().__init__(len(plan.position), plan.dq_threshold)
        self.p, self.quat, self.v, self.a = plan.position, plan.orientation, plan.twist, plan.accel
        self.law = PoseImpedance(plan.impedance, plan.damping_ratio, plan.q_nullspace,
                                 plan.nullspace_stiffness, viscous_feedforward=True)  # fmt: skip
        self.success_threshold = plan.success_threshold
        self.orientation_threshold = plan.orientation_threshold
        self.join = plan.join % len(plan.position)
        self.integral = np.zeros(6)
        self.gen = OnlinePose(plan.limits)
        self.limits = plan.limits
        self.stop_limits = plan.stop_limits or plan.limits
        self.spec: Any = None  # the robot's (the model's), known from the first tick
        self.refine = False  # the lead-in's limits are the worst case's (see published)
        self.ref: tuple[FloatArray, ...] = (self.p[0], self.quat[0], self.v[0], self.a[0])
        self._lead = np.zeros(5)  # the compiled ticks' generator scalars

    def handover(self, prev: Tracker | None, state: StateView, model: ControlModel) -> None:
        """As :meth:`JointMove.handover`, in Cartesian space."""
        if prev is None:
            T = state.O_T_EE
            z = np.zeros(6)
            p, quat, v, a = T[12:15].copy(), laws.quat_from_matrix(T), z, z
        else:
            p, quat, v, a = prev.pose_reference(state, model)
        j = self.join
        g = self.gen
        g.reset_toward(p, quat, v, a, self.p[j], self.quat[j], self.v[j], self.a[j])
        self.ref = (g.position.copy(), g.orientation.copy(), g.twist.copy(), g.accel.copy())
        # within the joints' limits here (a Cartesian bound can ask a joint for more): at
        # once every axis counted at its limit, then, after the first tick's command has
        # left, at the peaks its trajectory reaches (see published)
        worst = joint_capped(self.limits, model.ee_jacobian(state), model.spec, g.frames)
        g.set_limits(worst)
        g.set_limits(_holding(worst, self.limits, g))
        self.refine = worst is not self.limits
        self.k0, self.leading = j, True
        self.t_end = self.duration = math.inf
        self._blend_from(prev)

    def published(self) -> None:
        """After a hand-over's first command: the lead-in's limits counted at the peaks its
        coordinates reach (:func:`joint_capped_peaks`, up to PEAK_TRIES of ruckig's whole
        trajectories: 0.2 ms, most of a hand-over's time, which it no longer delays), from
        the generator's state and this tick's Jacobian. Until then the lead-in ran at the
        worst case's limits (the peaks' cap is mostly higher; it is lower where the arm's
        own motion at the hand-over already asks a joint for more): the generator goes on
        from its state under the new limits, jerk-limited, with no step in its
        acceleration."""
        if not self.refine:
            return
        J = self.law.J_prev  # (this tick's, once the law has stepped)
        if J is None or self.spec is None:
            return
        self.refine = False
        if self.leading and not self.stopping and not self.gen.finished:
            joint_capped_peaks(self.gen, self.limits, J, self.spec)

    def off_start(self, state: StateView) -> bool:
        pos = float(np.linalg.norm(state.O_T_EE[12:15] - self.p[0]))
        rot = rotation_angle(laws.quat_from_matrix(state.O_T_EE), self.quat[0])
        return pos > START_POSITION or rot > START_ORIENTATION

    def pose_reference(self, state: StateView, model: ControlModel) -> tuple[FloatArray, ...]:
        """The reference of the last tick: position, orientation, twist, acceleration."""
        return tuple(r.copy() for r in self.ref)

    def joint_reference(
        self, state: StateView, model: ControlModel
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The joints where they are, with the reference's acceleration mapped to them."""
        J_pinv = laws.damped_pinv(model.ee_jacobian(state))
        return np.array(state.q), np.array(state.dq), J_pinv @ self.ref[3]

    def torque_toward(
        self, ref: tuple[FloatArray, ...], state: StateView, model: ControlModel
    ) -> FloatArray:
        """Toward a joint reference ``(q, dq, ddq)``: the pose, twist and acceleration it
        gives to first order (``J`` of its offset, velocity, acceleration)."""
        q_d, dq_d, ddq_d = ref
        J = model.ee_jacobian(state)
        dx = J @ (q_d - state.q)
        T = state.O_T_EE
        quat_d = rot.multiply(rot.exp(dx[3:]), laws.quat_from_matrix(T))
        return self.law.torque(state, model, self.dt, T[12:15] + dx[:3], quat_d, J @ dq_d,
                               J @ ddq_d)  # fmt: skip

    def _begin_rest(self) -> None:
        p, quat, v, a = (r.copy() for r in self.ref)
        self.gen.reset(p, quat, v, a)
        self.gen.set_rest()
        J_prev = self.law.J_prev
        if J_prev is not None and self.spec is not None:  # within the joints' limits
            limits = joint_capped(self.stop_limits, J_prev, self.spec, self.gen.frames)
        else:
            limits = self.stop_limits
        self.gen.set_limits(limits)
        self.leading = True

    def _reference(self) -> tuple[FloatArray, ...]:
        gen = self.gen
        if self.leading:
            if not gen.finished and gen.step():
                self._lead_finished()
            return gen.position, gen.orientation, gen.twist, gen.accel
        return self._sampled(self.sample())

    def _sampled(self, k: int) -> tuple[FloatArray, ...]:
        return self.p[k], self.quat[k], self.v[k], self.a[k]

    def compiled(self, state: StateView, model: ControlModel) -> CompiledTicks | None:
        """Every phase of the move (lead-in, plan, stop, settling), as
        :meth:`JointMove.compiled`'s: ``rt._tick_moves.pose_move_ticks``, on its tracking
        law's buffer (after that law's first tick)."""
        program = self._program(state)
        if program is None or not self._follows_plan(model):
            return None
        if self.refine or self.law.J_prev is None:
            return None
        chain, arm = model.kernel_arrays(state)
        self._samples = np.array([self.k0, self.last, self.law.damping_due, DAMPING_TICKS])
        self._lead[:] = 0.0  # (rt._tick_moves.G_*)
        if self.leading:
            time, finished, duration = self.gen.gen.clock()
            self._lead[:] = (1.0, 1.0 if self.stopping else 0.0, time, 1.0 if finished else 0.0,
                             duration)  # fmt: skip
        traj, *sampling = self.gen.sampling()
        gen = self.gen
        arrays = (
            _NO_INPUTS, _NO_GUARD, _NO_INPUTS, readonly(self.p), readonly(self.quat),
            readonly(self.v), readonly(self.a), self.law.buffer, chain, *arm, model.armature,
            model.coulomb, self._times(), self._samples, self._settle(), self.integral,
            self._lead, readonly(traj), *sampling, *gen.ahead_buffers(), *program,
        )  # fmt: skip
        return CompiledTicks("pose_move_ticks", arrays, ("F_T_EE", *LOAD_FIELDS),
                             np.array([self.t, self.dt]))  # fmt: skip

    def compiled_ran(self, time: FloatArray, in_seq: int) -> None:
        super().compiled_ran(time, in_seq)
        self.law.compiled_ran(int(self._samples[2]))

    def _lead_compiled(self) -> bool:
        # after the lead-in's limits were refined (published), not before ruckig's step
        return not self.refine and self.gen.gen.sampling() is not None

    def _lead_ran(self) -> tuple[FloatArray, ...]:
        gen, lead = self.gen, self._lead
        gen.gen.compiled_steps(float(lead[2]), lead[3] != 0.0)
        return gen.position, gen.orientation, gen.twist, gen.accel

    def _settle(self) -> FloatArray:
        """The settling's constants as ``rt._tick_moves.pose_move_ticks`` reads them (its
        ``P_*`` offsets: step's and finished's, below)."""
        return np.array([self.dq_threshold, SETTLE_POSITION, SETTLE_ORIENTATION,
                         SETTLE_TIMEOUT, SETTLE_INTEGRAL_POSE, SETTLE_RATE,
                         1.0 / FRICTION_SPEED, SETTLE_BAND_POSITION, SETTLE_BAND_ROTATION,
                         FRICTION_ERROR_RATE])  # fmt: skip

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        p_d, quat_d, v_d, a_d = self.ref = self._reference()
        # the acceleration fed forward ahead of the loop's filter: the plan's, or the
        # generator's while it leads in or comes to rest
        if self.leading:
            a_d = self.gen.accel_ahead(FILTER_LAG * PERIOD)
        else:
            a_d = ahead_at(self.a, self.sample())
        self.spec = getattr(model, "spec", None)
        tau = self.law.torque(state, model, self.dt, p_d, quat_d, v_d, a_d)
        err, J = self.law.err, self.law.J_prev  # (this tick's)
        assert J is not None  # (set by the torque's call)
        if self.t > self.t_end and not self.stopping:  # remove what friction and errors leave
            beyond = beyond_band(err)
            self.integral += self.dt * beyond
            tau -= J.T @ (SETTLE_INTEGRAL_POSE * (self.law.K @ self.integral))
            J_pinv = self.law.J_pinv
            if beyond.any():  # a push of the drives' friction level toward the goal
                tau += model.friction_for(J_pinv @ (err * -SETTLE_RATE))
            else:  # within the band the friction holds the arm (see SETTLE_BAND_POSITION)
                tau -= model.friction_for(J_pinv @ (v_d - FRICTION_ERROR_RATE * err))
        if self.until is not None:
            T = state.O_T_EE
            self.check_until(state, Progress(self.t, float(np.linalg.norm(T[12:15] - self.p[-1]))))
        return self._blended(tau, state, model)  # (the law's torque has the Coriolis')

    def _errors(self, state: StateView) -> tuple[float, float]:
        T = state.O_T_EE
        pos = float(np.linalg.norm(T[12:15] - self.p[-1]))
        return pos, rotation_angle(laws.quat_from_matrix(T), self.quat[-1])

    def at_goal(self, state: StateView) -> bool:
        pos, rot = self._errors(state)
        return pos <= SETTLE_POSITION and rot <= SETTLE_ORIENTATION

    def result(self, state: StateView) -> MoveResult:
        pos, rot = self._errors(state)
        ok = pos <= self.success_threshold and rot <= self.orientation_threshold
        reason = (
            ""
            if ok
            else (
                f"finished {pos:.4f} m and {math.degrees(rot):.2f} deg from the goal, above the "
                f"success threshold of {self.success_threshold:.4f} m and "
                f"{math.degrees(self.orientation_threshold):.2f} deg; consider a higher "
                "impedance or a lower speed_factor"
            )
        )
        return self._finish(MoveResult(
            ok, reason, position_error=pos, orientation_error=rot,
            duration=self.duration, elapsed=self.t,
        ))  # fmt: skip
