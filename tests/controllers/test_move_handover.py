"""The move trackers' references across a handover (a move replacing another mid-motion),
a cancel and an ``until`` condition: continuous in position, velocity and acceleration,
within the limits, on recorded states (no simulator)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from test_law_steps import KIN, MODEL, Q0, STATE0, ctrl_quat, make_state

from panda_py.controllers import laws
from panda_py.controllers.moves import JointMove, PoseMove, Tracker, tracker_for
from panda_py.controllers.plans import Progress
from panda_py.controllers.tracking import joint_impedance_torque
from panda_py.fci import PERIOD
from panda_py.panda import move_args, planning
from panda_py.robots.params import get_robot

FER = get_robot("fer")
OFFSET = np.array([0.3, 0.2, -0.2, 0.2, 0.3, 0.3, 0.5])


def joint_law(start: np.ndarray, *targets: np.ndarray, speed: float = 0.2) -> JointMove:
    waypoints, opts = move_args.parse_joint_targets((np.array(targets),), {"speed_factor": speed})
    plan = planning.joint_move(start, waypoints, opts, FER)
    assert plan is not None
    law = tracker_for(plan)
    assert isinstance(law, JointMove)
    return law


def pose_law(start_q: np.ndarray, dp: np.ndarray) -> PoseMove:
    T = KIN.fk(start_q)
    target = T.copy()
    target[:3, 3] += dp
    positions, quats, opts = move_args.parse_pose_targets((target,), {})
    flat = T.reshape(16, order="F")
    plan = planning.pose_move(T[:3, 3], laws.quat_from_matrix(flat), positions, quats, opts,
                              start_q, FER)  # fmt: skip
    assert plan is not None
    law = tracker_for(plan)
    assert isinstance(law, PoseMove)
    return law


def follow(law: JointMove, ticks: int) -> list[np.ndarray]:
    """Step a joint move whose arm follows its reference exactly; the references."""
    refs = []
    state = make_state(law.ref[0], law.ref[1])
    for _ in range(ticks):
        law.tick(PERIOD)
        law.step(state, MODEL)
        refs.append(np.concatenate([law.ref[0], law.ref[1], law.ref[2]]))
        state = make_state(law.ref[0], law.ref[1])
        if law.finished(state):
            break
    return refs


def assert_continuous(refs: np.ndarray, speed: float = 0.2) -> None:
    j = FER.joints
    a, jerk = speed * np.array(j.ddq_max), speed * np.array(j.dddq_max)
    q, dq, ddq = refs[:, :7], refs[:, 7:14], refs[:, 14:]
    tol = 1.0 + 1e-6
    assert np.all(np.abs(np.diff(q, axis=0)) <= (np.abs(dq[1:]) + a * PERIOD) * PERIOD * tol)
    assert np.all(np.abs(np.diff(dq, axis=0)) <= a * PERIOD * tol)  # no velocity step
    assert np.all(np.abs(np.diff(ddq, axis=0)) <= jerk * PERIOD * tol)


def test_a_joint_move_takes_over_mid_motion_continuously_and_reaches_its_goal() -> None:
    first = joint_law(Q0, Q0 + OFFSET)
    before = np.array(follow(first, 400))
    state = make_state(first.ref[0], first.ref[1])
    goal = Q0 - 0.5 * OFFSET
    second = joint_law(first.ref[0], goal)
    second.handover(first, state, MODEL)
    after = np.array(follow(second, 10_000))
    refs = np.vstack([before, after])
    # across the handover the lead-in's bounds are the plan's (speed 0.2), and the plan's
    # time-optimal profile steps its acceleration only where it switches
    q, dq = refs[:, :7], refs[:, 7:14]
    a = 0.2 * np.array(FER.joints.ddq_max)
    assert np.all(np.abs(np.diff(dq[len(before) - 1 :], axis=0)) <= a * PERIOD * (1 + 1e-6))
    np.testing.assert_allclose(q[-1], goal, atol=1e-9)
    assert second.finished(make_state(goal))
    assert second.result(make_state(goal)).success


def test_a_lead_in_joins_a_multi_waypoint_plan_and_follows_its_samples() -> None:
    first = joint_law(Q0, Q0 + OFFSET)
    follow(first, 300)
    mid, goal = Q0 + 0.5 * OFFSET * np.array([1, -1, 1, -1, 1, -1, 1]), Q0 - 0.3 * OFFSET
    second = joint_law(first.ref[0], mid, goal)
    join = second.join
    assert 0 < join < second.last  # near the first waypoint, not its goal
    second.handover(first, make_state(first.ref[0], first.ref[1]), MODEL)
    refs = np.array(follow(second, 20_000))
    assert_continuous(refs[: round(second.t0 / PERIOD)])
    # after the lead-in, the reference is the plan's samples from the join on
    k = round(second.t0 / PERIOD)
    np.testing.assert_allclose(refs[k + 4, :7], second.q[join + 5], atol=1e-12)  # t0 + 5 ticks
    np.testing.assert_allclose(refs[-1, :7], goal, atol=1e-9)


def test_a_cancelled_move_decelerates_within_its_limits_and_ends_at_rest() -> None:
    law = joint_law(Q0, Q0 + OFFSET)
    before = follow(law, 400)
    speed_then = np.abs(law.ref[1]).max()
    assert speed_then > 0.1
    law.cancel("cancelled after 0.400 s")
    after = follow(law, 10_000)
    refs = np.array(before[-1:] + after)
    assert_continuous(refs, planning.STOP_SPEED_FACTOR)  # a stop brakes at least that hard
    assert np.abs(refs[-1, 7:14]).max() < 1e-9  # at rest
    rest = make_state(law.ref[0])
    assert law.finished(rest)
    result = law.result(rest)
    assert not result.success and result.cancelled and result.reason == "cancelled after 0.400 s"
    assert np.abs(law.ref[0] - Q0).max() < np.abs(OFFSET).max()  # short of the goal


def test_joint_and_cartesian_moves_take_over_from_each_other() -> None:
    first = joint_law(Q0, Q0 + OFFSET)
    follow(first, 300)
    state = make_state(first.ref[0], first.ref[1])
    pose = pose_law(first.ref[0], np.array([0.1, 0.0, -0.1]))
    pose.handover(first, state, MODEL)
    # the pose's reference starts where the arm is, moving as it moves (here: on its reference)
    T = state.O_T_EE
    np.testing.assert_allclose(pose.ref[0], T[12:15], atol=1e-12)
    np.testing.assert_allclose(pose.ref[2], MODEL.ee_jacobian(state) @ first.ref[1], atol=1e-12)
    pose.tick(PERIOD)
    pose.step(state, MODEL)
    assert np.linalg.norm(pose.ref[0] - T[12:15]) < 1e-3  # one tick's travel
    back = joint_law(first.ref[0], Q0)
    back.handover(pose, state, MODEL)
    np.testing.assert_allclose(back.ref[0], state.q)
    np.testing.assert_allclose(back.ref[1], state.dq)


def test_across_spaces_the_blend_pulls_both_laws_toward_the_new_reference() -> None:
    """During the blend the previous law tracks the new move's reference in its own space
    (not its own plan, which pulled the arm off the new one: up to 1.4x the planned
    accelerations after the blend): an arm 5 mm behind the new reference along x is pushed
    along +x by either law, an arm on it is not pushed at all."""
    first = joint_law(Q0, Q0 + OFFSET)
    follow(first, 300)
    state = make_state(first.ref[0], first.ref[1])
    J = MODEL.ee_jacobian(state)
    to_force = np.linalg.pinv(J.T)  # torques -> the end effector's wrench
    pose = pose_law(first.ref[0], np.array([0.1, 0.0, -0.1]))
    pose.handover(first, state, MODEL)
    T = state.O_T_EE
    here = (T[12:15].copy(), laws.quat_from_matrix(T), J @ state.dq, np.zeros(6))
    ahead = (here[0] + [0.005, 0.0, 0.0], *here[1:])
    on = first.torque_toward(here, state, MODEL)
    # on the reference: no pull anywhere, only what the arm's motion itself needs
    hold = joint_impedance_torque(first.K, first.D, state.q, state.dq, np.zeros(7), state, MODEL)
    np.testing.assert_allclose(on, hold, atol=1e-9)
    push = to_force @ (first.torque_toward(ahead, state, MODEL) - on)
    assert push[0] > 0.7 * np.linalg.norm(push[:3])  # toward it (the joint stiffness is
    # not the same in every direction at the end effector)
    back = joint_law(first.ref[0], Q0)
    back.handover(pose, state, MODEL)
    pose.tick(PERIOD)
    shift = np.linalg.pinv(J) @ np.array([0.005, 0.0, 0.0, 0.0, 0.0, 0.0])
    still = (state.q.copy(), state.dq.copy(), np.zeros(7))
    pose_on = pose.torque_toward(still, state, MODEL)
    pose_push = to_force @ (pose.torque_toward((still[0] + shift, *still[1:]), state, MODEL)
                            - pose_on)  # fmt: skip
    assert pose_push[0] > 0.7 * np.linalg.norm(pose_push[:3])


def test_a_move_replaced_during_its_blend_carries_the_blend_on() -> None:
    """A Cartesian move replaced by the same move 10 ms into its blend from a joint move
    (90 % of its torque still the joint law's) goes on as if it had not been: the blend
    carries on. Dropping the joint law's share at once stepped the torque and took joint
    5 to 0.97 of its acceleration limit in the random preemptions."""
    first = joint_law(Q0, Q0 + OFFSET)
    follow(first, 300)
    q, dq = first.ref[0].copy(), first.ref[1].copy()
    # an arm a little off its reference, where the two spaces' laws push differently
    state = make_state(q + 0.01 * np.sign(OFFSET), dq)
    moves = []
    for _ in range(2):
        pose = pose_law(q, np.array([0.1, 0.0, -0.1]))
        pose.handover(first, state, MODEL)
        for _ in range(10):  # as the loop runs it
            pose.tick(PERIOD)
            pose.step(state, MODEL)
            pose.published()
        moves.append(pose)
    kept, replaced = moves
    again = pose_law(q, np.array([0.1, 0.0, -0.1]))
    again.handover(replaced, state, MODEL)
    for law in (kept, again):
        law.tick(PERIOD)
    went_on, taken_over = kept.step(state, MODEL), again.step(state, MODEL)
    np.testing.assert_allclose(taken_over, went_on, atol=0.05 * np.abs(went_on).max())


def _lead_in(velocity: list[float], offset: list[float]) -> tuple[Any, Any, Any, Any]:
    """A Cartesian lead-in from the start pose moving at ``velocity`` [m/s] to the pose
    ``offset`` [m] from it, the orientation held, at 0.2 of the FER's limits: its
    generator, those limits, the start's Jacobian and the goal's position."""
    from panda_py.motion.online import OnlineLimits, OnlinePose

    J = MODEL.ee_jacobian(STATE0)
    T = STATE0.O_T_EE
    p, quat = T[12:15].copy(), laws.quat_from_matrix(T)
    limits = OnlineLimits.cartesian(FER, 0.2)
    gen = OnlinePose(limits)
    goal = p + np.array(offset)
    gen.reset_toward(p, quat, np.hstack([velocity, np.zeros(3)]), np.zeros(6), goal, quat)
    return gen, limits, J, goal


def test_a_lead_in_is_capped_by_the_peaks_its_trajectory_reaches() -> None:
    """A Cartesian lead-in that brakes a 0.5 m/s motion and turns toward a new goal, the
    orientation held: counted at the peaks its coordinates reach (the rotation: none), its
    limits stay higher than the worst case over every axis at its limit, and along the
    whole lead-in no joint is asked (through J^+) for more than JOINT_SHARE of its limits."""
    from panda_py.controllers.moves import JOINT_SHARE, joint_capped, joint_capped_peaks

    gen, limits, J, goal = _lead_in([0.5, 0.0, 0.0], [-0.15, 0.15, 0.0])
    worst = joint_capped(limits, J, FER, gen.frames)
    capped = joint_capped_peaks(gen, limits, J, FER)
    assert capped.acceleration[0] > 1.1 * worst.acceleration[0]
    assert capped.acceleration[0] <= limits.acceleration[0]
    pinv = np.linalg.pinv(J)
    ddq_max = JOINT_SHARE * np.array(FER.joints.ddq_max)
    peak = 0.0
    while not gen.step():
        peak = max(peak, float((np.abs(pinv @ gen.accel) / ddq_max).max()))
    assert 0.5 < peak <= 1.0 + 1e-3  # (pinv: undamped; the cap's is damped by 0.01)
    np.testing.assert_allclose(gen.position, goal, atol=1e-9)


def test_a_lead_in_counts_its_coordinates_as_they_combine_along_its_trajectory() -> None:
    """A lead-in that brakes a sideways motion (0.3, 0.2 m/s) while it turns toward a goal
    the other way: the braking is over before the new motion peaks, so the joints are
    asked, along the trajectory and with the signs, for most of their share. Counting
    each coordinate at its own peak at once (as the cap did before) halved its
    acceleration limit and left the joints at 0.44 of their share: 1.41 s where 0.82 s
    fit."""
    from panda_py.controllers.moves import JOINT_SHARE, joint_capped_peaks

    gen, limits, J, goal = _lead_in([0.3, 0.2, 0.0], [0.1, -0.2, 0.05])
    joint_capped_peaks(gen, limits, J, FER)
    pinv = np.linalg.pinv(J)
    dq_max = JOINT_SHARE * np.array(FER.joints.dq_max)
    ddq_max = JOINT_SHARE * np.array(FER.joints.ddq_max)
    peak_v = peak_a = 0.0
    ticks = 0
    while not gen.step():
        ticks += 1
        peak_v = max(peak_v, float((np.abs(pinv @ gen.twist) / dq_max).max()))
        peak_a = max(peak_a, float((np.abs(pinv @ gen.accel) / ddq_max).max()))
    assert 0.8 < max(peak_v, peak_a) and peak_v <= 1.0 + 1e-3 and peak_a <= 1.0 + 1e-3
    assert ticks < 1000
    np.testing.assert_allclose(gen.position, goal, atol=1e-9)


def test_a_hand_over_caps_at_the_peaks_once_its_first_command_has_left() -> None:
    """A Cartesian move taking over from one at 0.5 m/s starts its lead-in at the worst
    case's limits (every axis at its limit at once: cheap, the hand-over's time is the
    latency a replacement waits for), and once its first command has left (``published``,
    as the loop calls it) at the peaks' higher ones; along the whole lead-in no joint is
    asked for more than JOINT_SHARE of its acceleration limit."""
    from panda_py.controllers.moves import JOINT_SHARE, joint_capped

    J = MODEL.ee_jacobian(STATE0)
    T = STATE0.O_T_EE
    prev = pose_law(Q0, np.array([0.1, 0.0, 0.0]))
    prev.ref = (T[12:15].copy(), laws.quat_from_matrix(T), np.array([0.5, 0, 0, 0, 0, 0.0]),
                np.zeros(6))  # fmt: skip
    law = pose_law(Q0, np.array([-0.15, 0.15, 0.0]))
    law.handover(prev, STATE0, MODEL)
    worst = joint_capped(law.limits, J, FER, law.gen.frames)
    assert law.gen.limits.acceleration == worst.acceleration
    assert worst.acceleration[0] < law.limits.acceleration[0]
    pinv = np.linalg.pinv(J)
    ddq_max = JOINT_SHARE * np.array(FER.joints.ddq_max)
    peak = 0.0
    for k in range(5000):
        law.tick(PERIOD)
        law.step(STATE0, MODEL)
        law.published()
        if k == 0:
            assert law.gen.limits.acceleration[0] > 1.1 * worst.acceleration[0]
        peak = max(peak, float((np.abs(pinv @ law.ref[3]) / ddq_max).max()))
        if law.gen.finished:
            break
    assert law.gen.finished and 0.5 < peak <= 1.0 + 1e-3  # (pinv: undamped; the cap's: 0.01)


@dataclass(frozen=True)
class AfterTime:
    seconds: float

    def holds(self, state: Any, progress: Progress) -> bool:
        return progress.elapsed > self.seconds

    def __repr__(self) -> str:
        return f"Elapsed > {self.seconds}"


def test_a_move_whose_condition_holds_stops_gently_and_says_which_and_when() -> None:
    law = joint_law(Q0, Q0 + OFFSET)
    law.until = AfterTime(0.3)
    refs = np.array(follow(law, 10_000))
    # from where it held (the plan before steps its acceleration), at a stop's limits
    assert_continuous(refs[299:], planning.STOP_SPEED_FACTOR)
    rest = make_state(law.ref[0])
    result = law.result(rest)
    assert result.success and result.condition == "Elapsed > 0.3"
    assert 0.3 < result.condition_time < 0.3 + 2 * PERIOD


def test_a_condition_with_a_successor_hands_over_to_it() -> None:
    law = joint_law(Q0, Q0 + OFFSET)
    then = joint_law(Q0 + OFFSET, Q0)
    law.until, law.then = AfterTime(0.2), tracker_plan(then)
    follow(law, 10_000)
    assert isinstance(law.successor, Tracker) and law.finished(make_state(law.ref[0]))


def tracker_plan(law: JointMove) -> Any:
    from panda_py.controllers.plans import JointPlan

    return JointPlan(law.q, law.dq, law.ddq, law.K, law.D, 1e-3, 1e-2,
                     law.gen.limits)  # fmt: skip


def test_a_move_knows_when_the_arm_is_away_from_its_start() -> None:
    law = joint_law(Q0, Q0 + OFFSET)
    assert not law.off_start(make_state(Q0))
    assert law.off_start(make_state(Q0 + 0.05))
    pose = pose_law(Q0, np.array([0.0, 0.0, -0.1]))
    assert not pose.off_start(make_state(Q0))
    assert pose.off_start(make_state(Q0 + 0.05))
    assert ctrl_quat(KIN.fk(Q0)).shape == (4,)
