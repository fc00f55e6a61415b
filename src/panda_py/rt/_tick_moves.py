"""The control loop's compiled ticks of the moves (``controllers.moves``): a joint or a
Cartesian move following its plan, then settling at its goal (the integral of its error,
the push of the drives' friction): each move's part of a tick, on the skeleton of
:mod:`panda_py.rt._tick` (``loop_kernel``: its wait, decoding, finishing, sending and
publishing around it), with a guarded move's ``until`` condition compiled
(:mod:`panda_py.controllers.condition_program`).

What stays Python's (PENDING, the state unanswered): the state a move ends on (at rest at
its goal, or its settling timed out: the Python tick finishes it and makes its result),
the one on which its condition holds (``check_until`` decides there), and everything the
move's compiled form does not cover (a lead-in, a stop, a blend from another space: the
move then offers no compiled ticks).
"""

from __future__ import annotations

import math
from pathlib import Path

from panda_py.controllers import condition_program, laws, tracking
from panda_py.jit import cache
from panda_py.jit.stack import stack_array
from panda_py.motion import online, rotation
from panda_py.rt import _tick
from panda_py.rt._tick import BUF, DQ, LAW_T, PENDING, POSE, TAU, TMP, Q

_FUSED = laws.fused()
if _FUSED is None:  # plain Python: Python ticks (rt._tick refuses to load as well)
    raise ImportError("the control laws run without numba")
_joint_tracking_step = _FUSED.joint_tracking_step
_ONLINE = online.compiled_kernels()
_sample, _sample_pose = _ONLINE.sample, _ONLINE.sample_pose
_pose_tracking_step = _FUSED.pose_tracking_step
_advance, _next_time = _tick.advance, _tick.next_time

__all__ = ["joint_move_ticks", "pose_move_ticks"]

_SOURCES = [Path(__file__), Path(condition_program.__file__), Path(rotation.__file__)]
KEY = cache.source_key(_SOURCES) + _tick.KEY[:20]


# a guarded move's condition on a state (controllers.condition_program: FALSE, UNKNOWN or
# TRUE), the program's own source compiled
_condition_holds = cache.keyed_jit(KEY, nogil=True)(condition_program.evaluate)


@cache.keyed_jit(KEY, nogil=True)
def _until_holds(program, stack, buf, tmp, elapsed, goal, at, n, joints):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether a guarded move's condition ``program`` holds, or may, on the state in
    ``buf`` (already decoded: ``tmp`` is free) at the move's time ``elapsed``: its
    distance to the goal is the largest of ``|goal - at[:n]|`` (``joints``: a joint
    move's, JointMove.step) or their norm (a Cartesian move's position, PoseMove.step).
    Where it does, the tick is Python's (check_until decides)."""
    distance = 0.0
    for i in range(n):
        d = goal[i] - at[i]
        if joints:
            if math.isnan(d):  # (NumPy's max is NaN then)
                distance = d
                break
            distance = max(distance, abs(d))
        else:
            distance += d * d
    if not joints:
        distance = math.sqrt(distance)
    return _condition_holds(program, stack, buf, tmp, elapsed, distance) != 0.0


# a joint move's settling constants (controllers.moves.JointMove._settle): at rest below
# [rad/s], at the goal within [rad], the settling's time out [s], the deadband [rad], the
# integral's gain per unit stiffness [1/s], the push's rate [1/s], the friction's speed
# [rad/s] over the move's, the move's error rate times that [1/s], 1 / the friction's speed
(S_AT_REST, S_AT_GOAL, S_TIMEOUT, S_DEADBAND, S_INTEGRAL, S_RATE, S_SCALE, S_ERROR_RATE,
 S_INVERSE_SPEED) = range(9)  # fmt: skip


@cache.keyed_jit(KEY, nogil=True)
def _largest_off(a, b, n):  # type: ignore[no-untyped-def,unused-ignore]
    """``max |a[:n] - b[:n]|`` as NumPy's: NaN if any difference is."""
    m = 0.0
    for i in range(n):
        d = abs(a[i] - b[i])
        if math.isnan(d):
            return d
        m = max(m, d)
    return m


@cache.keyed_jit(KEY, nogil=True)
def _at_rest(dq, limit):  # type: ignore[no-untyped-def,unused-ignore]
    """Tracker.finished's at rest: every joint slower than ``limit`` [rad/s] (NumPy's max:
    not with a NaN)."""
    rest = 0.0
    for i in range(7):
        d = abs(dq[i])
        if math.isnan(d):
            return False
        rest = max(rest, d)
    return rest <= limit


@cache.keyed_jit(KEY, nogil=True)
def _joint_settled(q, dq, goal, settle, over):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether a joint move ends on this state, ``over`` [s] past its trajectory's end
    (Tracker.finished with JointMove.at_goal): at rest at its goal, or timed out."""
    if _at_rest(dq, settle[S_AT_REST]) and _largest_off(goal, q, 7) <= settle[S_AT_GOAL]:
        return True
    return over >= settle[S_TIMEOUT]


@cache.keyed_jit(KEY, nogil=True)
def _joint_settling(q, goal, K, coulomb, settle, integral, dt, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """JointMove.step's terms past the trajectory's end, added to ``tau``: the integral of
    the error beyond the deadband, and the friction's cancelling along the way back to the
    goal in place of the tracking's own (the same arithmetic, in the same order)."""
    band, inverse = settle[S_DEADBAND], settle[S_INVERSE_SPEED]
    for i in range(7):
        e = goal[i] - q[i]
        integral[i] += dt * (e - min(max(e, -band), band))
        tau[i] += settle[S_INTEGRAL] * K[i] * integral[i]
        push = e * settle[S_RATE] if abs(e) > band else 0.0
        tau[i] += (coulomb[i] * math.tanh(push * settle[S_SCALE] * inverse)
                   - coulomb[i] * math.tanh(e * settle[S_ERROR_RATE] * inverse))  # fmt: skip


# a joint move's online generator as its compiled ticks run it (JointMove._lead): 1 while
# it leads (a lead-in, or coming to rest), 1 while it stops; the generator's time in its
# trajectory [s], 1 once it finished, the trajectory's duration [s]
G_LEADING, G_STOPPING, G_TIME, G_FINISHED, G_DURATION = range(5)


@cache.keyed_jit(KEY, nogil=True)
def _generator_hands_back(gs, times, dq, over, at_rest, timeout):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether a move's online generator (``gs``: G_*) hands this state to Python: it
    reaches its target on this tick (the lead-in joins the plan, or the stop's reference
    ends), or, stopping, the arm came to rest below ``at_rest`` [rad/s] (or ``timeout`` [s]
    passed) ``over`` [s] past the trajectory's end."""
    if gs[G_LEADING] != 0.0 and gs[G_FINISHED] == 0.0 and gs[G_TIME] + times[2] > gs[G_DURATION]:
        return True
    return gs[G_STOPPING] != 0.0 and over > 0.0 and (_at_rest(dq, at_rest) or over >= timeout)


@cache.keyed_jit(KEY, nogil=True)
def _plan_ahead(plan, k, last, times, out):  # type: ignore[no-untyped-def,unused-ignore]
    """The plan's sample ``times[6]`` whole ticks and ``times[7]`` of one after sample
    ``k`` (the last, ``last``, held) into ``out``: ``finalize.ahead_at``, in its
    arithmetic."""
    i = min(k + int(times[6]), last)
    j = min(i + 1, last)
    part = times[7]
    for c in range(out.shape[0]):
        out[c] = (1.0 - part) * plan[i, c] + part * plan[j, c]


@cache.keyed_jit(KEY, nogil=True)
def _joint_move(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """A joint move (``controllers.moves.JointMove``). Following its plan: the sample at the
    law's time (``times``: t_end, t0, the period, the friction's speed and error rate;
    ``samples``: k0, the last), tracked by ``_fused.joint_tracking_step``; past the
    trajectory's end ``times[0]`` its settling (:func:`_joint_settling`, ``settle``'s
    constants, the error's ``integral`` kept across calls). Leading in, or coming to rest
    (``gs``: G_*), the online generator's reference instead: its trajectory ``traj``
    (packed, as ruckig calculated it) sampled into ``gen_q``, ``gen_dq``, ``gen_ddq``, its
    velocity times the viscous ``gain`` (into ``lead_dq``) tracked, its acceleration
    ``times[5]`` on (``ahead``' rows) fed forward (``OnlineGenerator.acceleration_ahead``).
    Python's, the state unanswered: the tick the generator reaches its target on (the
    lead-in joins the plan, or the stop's reference ends), the state the move ends on (at rest at
    the goal, or stopped at rest, or the settling's time out: :func:`_joint_settled`), and
    one on which its ``until`` condition (``program``, none if empty) holds while it is not
    stopping."""
    (plan_q, plan_dq, plan_ddq, K, D, _chain, origin, ca, sa, mass, h, inertia, armature,
     coulomb, times, samples, settle, integral, gs, traj, gen_q, gen_dq, gen_ddq, gain,
     lead_dq, ahead, program, stack) = law  # fmt: skip
    q, dq, law_t = view[Q], view[DQ], view[LAW_T]
    goal = plan_q[samples[1]]
    stopping, leading = gs[G_STOPPING] != 0.0, gs[G_LEADING] != 0.0
    t = _next_time(view)
    over = t - times[0]
    if _generator_hands_back(gs, times, dq, over, settle[S_AT_REST], settle[S_TIMEOUT]):
        return PENDING
    if not stopping and over > 0.0 and _joint_settled(q, dq, goal, settle, over):
        return PENDING  # it ends on this state: Python's tick finishes it
    if not stopping and program.shape[0] and _until_holds(
        program, stack, view[BUF], view[TMP], t, goal, q, 7, True
    ):  # fmt: skip
        return PENDING  # its condition holds: check_until is Python's
    _advance(view)
    if leading:
        if gs[G_FINISHED] == 0.0:  # (OnlineGenerator.step, compiled)
            gs[G_TIME] += times[2]
            _sample(traj, gs[G_DURATION], gs[G_TIME], gen_q, gen_dq, gen_ddq)
        _sample(traj, gs[G_DURATION], gs[G_TIME] + times[5], ahead[0], ahead[1], ahead[2])
        for i in range(7):
            lead_dq[i] = gen_dq[i] * gain[i]
        _joint_tracking_step(q, dq, origin, ca, sa, mass, h, inertia, armature, coulomb, K, D,
                             gen_q, lead_dq, ahead[2], times[3], times[4], view[TAU])  # fmt: skip
    else:
        k = min(samples[0] + round((law_t[0] - times[1]) / times[2]), samples[1])
        _plan_ahead(plan_ddq, k, samples[1], times, ahead[2])
        _joint_tracking_step(q, dq, origin, ca, sa, mass, h, inertia, armature, coulomb, K, D,
                             plan_q[k], plan_dq[k], ahead[2], times[3], times[4],
                             view[TAU])  # fmt: skip
    if law_t[0] > times[0] and not stopping:
        _joint_settling(q, goal, K, coulomb, settle, integral, law_t[1], view[TAU])
    return 0


joint_move_ticks = _tick.loop_kernel(_joint_move, "joint_move_ticks", 28)


# a Cartesian move's settling constants (controllers.moves.PoseMove._settle): at rest
# below [rad/s], at the goal within [m] and [rad], the settling's time out [s], the
# integral's gain per unit stiffness [1/s], the friction push's rate [1/s], 1 / the
# friction's speed
(P_AT_REST, P_POSITION, P_ORIENTATION, P_TIMEOUT, P_INTEGRAL, P_RATE, P_INVERSE_SPEED,
 P_BAND_POSITION, P_BAND_ROTATION, P_ERROR_RATE) = range(10)  # fmt: skip
# the tracking law's arrays in its buffer (tracking.LAW_LAYOUT)
_K, _ERR = tracking.LAW_LAYOUT["K"][0], tracking.LAW_LAYOUT["err"][0]
_J, _PINV = tracking.LAW_LAYOUT["J"][0], tracking.LAW_LAYOUT["J_pinv"][0]
# the rotation's quaternion as the Python step computes it (motion.rotation), compiled
_quaternion_of = cache.keyed_jit(KEY, nogil=True)(rotation.quaternion_of)


@cache.keyed_jit(KEY, nogil=True)
def _pose_settled(pose, dq, goal, goal_quat, settle, over):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether a Cartesian move ends on this state, ``over`` [s] past its trajectory's
    end (Tracker.finished with PoseMove.at_goal: its position's distance and
    plans.rotation_angle to the goal's)."""
    if _at_rest(dq, settle[P_AT_REST]):
        d = 0.0
        for i in range(3):
            d += (pose[12 + i] - goal[i]) ** 2
        if math.sqrt(d) <= settle[P_POSITION]:
            x, y, z, w = _quaternion_of(pose[0], pose[4], pose[8], pose[1], pose[5], pose[9],
                                        pose[2], pose[6], pose[10])  # fmt: skip
            g0, g1, g2, g3 = goal_quat[0], goal_quat[1], goal_quat[2], goal_quat[3]
            dot = x * g0 + y * g1 + z * g2 + w * g3
            norms = (x * x + y * y + z * z + w * w) * (g0 * g0 + g1 * g1 + g2 * g2 + g3 * g3)
            if 2.0 * math.acos(min(1.0, abs(dot) / math.sqrt(norms))) <= settle[P_ORIENTATION]:
                return True
    return over >= settle[P_TIMEOUT]


@cache.keyed_jit(KEY, nogil=True)
def _pose_settling(law, coulomb, settle, integral, v_d, dt, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """PoseMove.step's terms past the trajectory's end, added to ``tau``: the integral of
    the pose error (the tracking's, in ``law``) beyond the settling's band
    (``moves.beyond_band``), through the stiffness and the Jacobian; beyond the band a push
    of the drives' friction toward the goal along ``J^+`` of the error, within it the
    tracking's own cancelling of the friction along ``J^+`` of the reference's twist
    ``v_d`` and the error undone."""
    K = law[_K : _K + 36].reshape((6, 6))
    J = law[_J : _J + 42].reshape((6, 7))
    pinv = law[_PINV : _PINV + 42].reshape((7, 6))
    err = law[_ERR : _ERR + 6]
    beyond = stack_array(6)  # (the loop kernels allocate nothing: jit.libc.LOOP_KERNEL)
    outside = False
    for at, band in ((0, settle[P_BAND_POSITION]), (3, settle[P_BAND_ROTATION])):
        n = math.sqrt(err[at] * err[at] + err[at + 1] * err[at + 1] + err[at + 2] * err[at + 2])
        scale = (n - band) / n if n > band else 0.0
        outside = outside or n > band
        for r in range(at, at + 3):
            beyond[r] = err[r] * scale
    for r in range(6):
        integral[r] += dt * beyond[r]
    wrench = stack_array(6)
    for r in range(6):
        s = 0.0
        for c in range(6):
            s += K[r, c] * integral[c]
        wrench[r] = settle[P_INTEGRAL] * s
    for i in range(7):
        s = 0.0
        for r in range(6):
            s += J[r, i] * wrench[r]
        tau[i] -= s
    for i in range(7):
        s = 0.0
        for r in range(6):
            if outside:
                s += pinv[i, r] * (err[r] * -settle[P_RATE])
            else:
                s += pinv[i, r] * (v_d[r] - settle[P_ERROR_RATE] * err[r])
        if outside:
            tau[i] += coulomb[i] * math.tanh(s * settle[P_INVERSE_SPEED])
        else:
            tau[i] -= coulomb[i] * math.tanh(s * settle[P_INVERSE_SPEED])


@cache.keyed_jit(KEY, nogil=True)
def _pose_move(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """A Cartesian move (``controllers.moves.PoseMove``), as :func:`_joint_move`, tracked
    by ``_fused.pose_tracking_step`` on the tracking law's buffer ``tracking``
    (``tracking.PoseImpedance.compiled_inputs``' scalars set here: ``samples[2]`` counts
    the ticks until the damping's update, every ``samples[3]``); past the trajectory's end
    its settling (:func:`_pose_settling`), until the state it ends on
    (:func:`_pose_settled`). Leading in or coming to rest (``gs``), its online pose
    generator's reference (``OnlinePose.step``: ``_online_jit.sample_pose`` of the packed
    trajectory ``traj`` into the generator's state ``gen_*`` and, through its frames
    ``Ft``, ``Fr`` and anchor ``R0``, ``q0``, into ``lead_*``)."""
    (plan_p, plan_quat, plan_v, plan_a, tracking, chain, origin, ca, sa, mass, h, inertia,
     armature, coulomb, times, samples, settle, integral, gs, traj, gen_x, gen_dx, gen_ddx, Ft,
     Fr, R0, q0, lead_p, lead_quat, lead_v, lead_a, ahead_gen, ahead_p, ahead_quat, ahead_v,
     ahead_a, program, stack) = law  # fmt: skip
    q, dq, pose, law_t = view[Q], view[DQ], view[POSE], view[LAW_T]
    goal, goal_quat = plan_p[samples[1]], plan_quat[samples[1]]
    stopping, leading = gs[G_STOPPING] != 0.0, gs[G_LEADING] != 0.0
    t = _next_time(view)
    over = t - times[0]
    if _generator_hands_back(gs, times, dq, over, settle[P_AT_REST], settle[P_TIMEOUT]):
        return PENDING
    if not stopping and over > 0.0 and _pose_settled(pose, dq, goal, goal_quat, settle, over):
        return PENDING  # it ends on this state: Python's tick finishes it
    if not stopping and program.shape[0] and _until_holds(
        program, stack, view[BUF], view[TMP], t, goal, pose[12:15], 3, False
    ):  # fmt: skip
        return PENDING  # its condition holds: check_until is Python's
    _advance(view)
    samples[2] -= 1  # (PoseImpedance.compiled_inputs)
    tracking[0] = law_t[1]
    tracking[7] = 1.0  # a previous Jacobian: this law has ticked before
    if samples[2] < 0:
        tracking[6] = 1.0
        samples[2] = samples[3] - 1
    else:
        tracking[6] = 0.0
    if leading:
        if gs[G_FINISHED] == 0.0:  # (OnlinePose.step, compiled)
            gs[G_TIME] += times[2]
            _sample_pose(traj, gs[G_DURATION], gs[G_TIME], gen_x, gen_dx, gen_ddx, Ft, Fr, R0,
                         q0, lead_p, lead_quat, lead_v, lead_a)  # fmt: skip
        # its acceleration times[5] on fed forward (OnlinePose.accel_ahead)
        _sample_pose(traj, gs[G_DURATION], gs[G_TIME] + times[5], ahead_gen[0], ahead_gen[1],
                     ahead_gen[2], Ft, Fr, R0, q0, ahead_p, ahead_quat, ahead_v,
                     ahead_a)  # fmt: skip
        _pose_tracking_step(pose, q, dq, chain, origin, ca, sa, mass, h, inertia, armature,
                            coulomb, lead_p, lead_quat, lead_v, ahead_a, tracking,
                            view[TAU])  # fmt: skip
    else:
        k = min(samples[0] + round((law_t[0] - times[1]) / times[2]), samples[1])
        _plan_ahead(plan_a, k, samples[1], times, ahead_a)  # (the generator's buffer: idle)
        _pose_tracking_step(pose, q, dq, chain, origin, ca, sa, mass, h, inertia, armature,
                            coulomb, plan_p[k], plan_quat[k], plan_v[k], ahead_a, tracking,
                            view[TAU])  # fmt: skip
    if law_t[0] > times[0] and not stopping:
        _pose_settling(tracking, coulomb, settle, integral, plan_v[samples[1]], law_t[1],
                       view[TAU])  # fmt: skip
    return 0


pose_move_ticks = _tick.loop_kernel(_pose_move, "pose_move_ticks", 38)
