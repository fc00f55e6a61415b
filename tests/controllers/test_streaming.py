"""Streamed targets (``JointTarget``, ``CartesianTarget``) on states made here, driven as
the loop drives them, with the user's handle writing through the same signal slot: the
reference stays continuous and within the limits through a target that jumps, it comes to
rest when targets stop arriving, and bad targets are refused where they are set."""

from __future__ import annotations

import math
import os
from typing import Any, TypeVar

import numpy as np
import pytest
from test_law_steps import KIN, MODEL, Q0, STATE0, make_state, run_once, started

from panda_py import controllers
from panda_py.controllers import streaming
from panda_py.controllers.model import ControlModel
from panda_py.controllers.plans import rotation_angle
from panda_py.libfranka.errors import InvalidOperationException
from panda_py.motion import rotation
from panda_py.panda import move_args
from panda_py.robots.params import get_robot
from panda_py.rt.shm import SharedBlock

FER = get_robot("fer")
DT = 1e-3
SLACK = 1.0 + 1e-6  # ruckig's limits hold to numerical precision


S = TypeVar("S", controllers.JointTarget, controllers.CartesianTarget)


def pair(cls: type[S], **options: Any) -> tuple[S, S]:
    """The controller as the control process runs it and the user's handle on it."""
    ctrl, user = cls(**options), cls(**options)
    block, values = started(ctrl)
    user.attach(block, values)
    return ctrl, user


def joint_pair(**options: Any) -> tuple[controllers.JointTarget, controllers.JointTarget]:
    return pair(controllers.JointTarget, **options)


def joint_reference(ctrl: controllers.JointTarget, user: controllers.JointTarget,
                    ticks: int) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Run ``ticks``; the published reference of each: positions and velocities."""
    q, dq = [], []
    for _ in range(ticks):
        run_once(ctrl, STATE0)
        q_d, dq_d = user.reference
        q.append(q_d)
        dq.append(dq_d)
    return np.array(q), np.array(dq)


def assert_within_joint_limits(q: np.ndarray, dq: np.ndarray, speed_factor: float) -> None:
    """Continuous positions (each step is the velocity's), velocities and accelerations
    within the scaled limits."""
    dq_max = speed_factor * np.array(FER.joints.dq_max)
    ddq_max = max(speed_factor, streaming.STOP_SPEED_FACTOR) * np.array(FER.joints.ddq_max)
    assert (np.abs(dq) <= dq_max * SLACK).all()
    ddq = np.diff(dq, axis=0) / DT
    assert (np.abs(ddq) <= ddq_max * SLACK).all()
    # no position step: each is what the velocities say (trapezoidal rule, within jerk)
    np.testing.assert_allclose(np.diff(q, axis=0), 0.5 * (dq[1:] + dq[:-1]) * DT, atol=1e-6)


def test_joint_target_holds_where_it_starts() -> None:
    ctrl, user = joint_pair()
    tau = run_once(ctrl, STATE0)
    np.testing.assert_allclose(tau, MODEL.coriolis_of(STATE0), atol=1e-9)  # nothing to do
    np.testing.assert_allclose(user.reference[0], Q0)
    assert user.lag == 0.0 and not user.stale


def test_joint_reference_is_continuous_through_a_target_that_jumps() -> None:
    ctrl, user = joint_pair(speed_factor=0.3, timeout=None)
    user.set_target(Q0 + np.array([0.4, 0.2, -0.3, 0.2, 0.5, 0.3, 0.6]))
    q1, dq1 = joint_reference(ctrl, user, 300)
    assert np.abs(dq1[-1]).max() > 0.2  # moving fast when the target jumps
    assert user.lag > 0.05
    goal = Q0 - np.array([0.3, 0.1, 0.2, 0.1, 0.4, 0.2, 0.3])
    user.set_target(goal)  # the other way
    q2, dq2 = joint_reference(ctrl, user, 4000)
    q, dq = np.vstack([q1, q2]), np.vstack([dq1, dq2])
    assert_within_joint_limits(q, dq, 0.3)
    np.testing.assert_allclose(q[-1], goal, atol=1e-9)  # and there, at rest
    np.testing.assert_allclose(dq[-1], 0.0, atol=1e-9)
    assert user.lag < 1e-9


def test_the_torque_pulls_toward_the_reference_with_the_stiffness() -> None:
    ctrl, user = joint_pair(stiffness=np.full(7, 100.0), damping=np.zeros(7))
    user.set_target(Q0 + 0.5)
    joint_reference(ctrl, user, 200)
    q_prev, dq_prev = user.reference
    behind = make_state(q_prev - 0.01, dq_prev)  # behind the reference, at its speed
    tau = run_once(ctrl, behind) - MODEL.coriolis_of(behind)
    q_d, dq_d = user.reference
    ff = MODEL.driven_mass_of(behind) @ ctrl.get_output("ddq_d") + MODEL.friction_for(dq_d)
    np.testing.assert_allclose(tau - ff, 100.0 * (q_d - behind.q), rtol=1e-9, atol=1e-9)
    assert (tau - ff > 0.9).all()  # forward, by about 100 Nm/rad x 0.01 rad


def test_targets_that_stop_arriving_bring_the_reference_to_rest() -> None:
    timeout = 0.1
    ctrl, user = joint_pair(speed_factor=0.5, timeout=timeout)
    far = Q0 + np.array([1.0, 0.5, 1.0, 0.5, 1.0, 1.0, 1.0])
    user.set_target(far)
    q, dq = joint_reference(ctrl, user, 100)  # 0.1 s: within the timeout
    assert not user.stale and np.abs(dq[-1]).max() > 0.4
    user.set_target(far)  # the same target again counts as alive
    q2, dq2 = joint_reference(ctrl, user, 100)
    assert not user.stale
    q3, dq3 = joint_reference(ctrl, user, 600)
    assert user.stale
    # it decelerated as soon as the timeout passed: stopped within the braking time at
    # half the limits (v / a + a / j, well under 0.4 s)
    speed = np.abs(dq3).max(axis=1)
    stopped = int(np.argmax(speed < 1e-9))
    assert 0 < stopped < 400
    peak = int(np.argmax(speed))  # (the acceleration turns round within the jerk limit)
    assert peak < 10
    assert (np.diff(speed[peak : stopped + 1]) <= 1e-12).all()  # then slowing down all the way
    assert np.abs(q3[-1] - far).max() > 0.1  # short of the target: at rest where it was
    assert_within_joint_limits(np.vstack([q, q2, q3]), np.vstack([dq, dq2, dq3]), 0.5)
    user.set_target(Q0)  # a new target: followed again
    joint_reference(ctrl, user, 10)
    assert not user.stale and np.abs(user.reference[1]).max() > 0.0


def test_no_timeout_follows_the_last_target_forever() -> None:
    ctrl, user = joint_pair(speed_factor=0.5, timeout=None)
    user.set_target(Q0 + 0.2)
    joint_reference(ctrl, user, 3000)
    assert not user.stale
    np.testing.assert_allclose(user.reference[0], Q0 + 0.2, atol=1e-9)


def test_joint_targets_are_checked_where_they_are_set() -> None:
    before = controllers.JointTarget()
    with pytest.raises(InvalidOperationException, match="not running"):
        before.set_target(Q0)
    ctrl, user = joint_pair()
    with pytest.raises(ValueError, match=r"^q: expected finite"):
        user.set_target(np.r_[Q0[:6], np.nan])
    with pytest.raises(ValueError, match=r"^q: expected 7"):
        user.set_target(Q0[:6])
    with pytest.raises(ValueError, match=r"^q: .*joint 4 is .* outside \[-3.0718, -0.0698\]"):
        user.set_target(np.r_[Q0[:3], 0.1, Q0[4:]])
    run_once(ctrl, STATE0)
    np.testing.assert_allclose(user.reference[0], Q0)  # nothing refused reached the loop
    for bad in ({"speed_factor": 0.0}, {"speed_factor": 1.5}, {"timeout": -1.0},
                {"timeout": math.inf}, {"stiffness": [-1.0] * 7}):  # fmt: skip
        name = next(iter(bad))
        with pytest.raises(ValueError, match=f"^{name}:"):
            controllers.JointTarget(**bad)  # type: ignore[arg-type]


def test_the_limits_are_the_robots_the_control_process_knows() -> None:
    ctrl, user = controllers.JointTarget(), controllers.JointTarget()
    ctrl.start(STATE0, ControlModel("fr3-pre-5.9"))  # the model the loop has on that robot
    block, fd = SharedBlock.create()
    os.close(fd)
    user.attach(block, ctrl.open_slot(block))
    spec = get_robot("fr3-pre-5.9")
    np.testing.assert_array_equal(user.get_output("q_max"), spec.joints.q_max)
    high = np.array(Q0)
    high[0] = 2.8  # within the FER's and the newer FR3's, beyond this one's 2.7437
    with pytest.raises(ValueError, match="joint 1"):
        user.set_target(high)


def test_the_defaults_are_the_moves() -> None:
    joint, pose = move_args.JOINT_MOVE_DEFAULTS, move_args.POSE_MOVE_DEFAULTS
    j, c = controllers.JointTarget(), controllers.CartesianTarget()
    np.testing.assert_array_equal(j.stiffness, joint["stiffness"])
    np.testing.assert_array_equal(j.damping, joint["damping"])
    assert j.speed_factor == c.speed_factor == joint["speed_factor"] == pose["speed_factor"]
    np.testing.assert_array_equal(c.impedance, pose["impedance"])
    assert c.damping_ratio == pose["damping_ratio"]
    assert c.nullspace_stiffness == pose["nullspace_stiffness"]


# --- Cartesian -------------------------------------------------------------------------


def pose_pair(**options: Any) -> tuple[controllers.CartesianTarget, controllers.CartesianTarget]:
    return pair(controllers.CartesianTarget, **options)


def pose_reference(ctrl: controllers.CartesianTarget, user: controllers.CartesianTarget,
                   ticks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    p, o, v = [], [], []
    for _ in range(ticks):
        run_once(ctrl, STATE0)
        pos, quat, twist = user.reference
        p.append(pos)
        o.append(quat)
        v.append(twist)
    return np.array(p), np.array(o), np.array(v)


P0 = STATE0.O_T_EE[12:15].copy()
QUAT0 = rotation.from_matrix(STATE0.O_T_EE.reshape(4, 4, order="F")[:3, :3])


def test_cartesian_reference_reaches_a_half_metre_jump_smoothly() -> None:
    sf = 0.3
    ctrl, user = pose_pair(speed_factor=sf, timeout=None)
    run_once(ctrl, STATE0)
    np.testing.assert_allclose(user.reference[0], P0)  # it starts where the arm is
    goal = P0 + np.array([0.0, 0.5, 0.0])
    turned = rotation.multiply(QUAT0, rotation.exp(np.array([0.0, 0.0, 0.3])))
    user.set_target(goal, turned)
    p, _, v = pose_reference(ctrl, user, 200)
    lag_early = user.lag
    assert 0.3 < lag_early < 0.5
    p2, o2, v2 = pose_reference(ctrl, user, 5000)
    p, v = np.vstack([p, p2]), np.vstack([v, v2])
    c = FER.cartesian
    speed = np.linalg.norm(v[:, :3], axis=1)
    assert speed.max() <= sf * c.translation_velocity * SLACK
    assert speed.max() > 0.5 * sf * c.translation_velocity  # it did go fast
    acc = np.linalg.norm(np.diff(v[:, :3], axis=0), axis=1) / DT
    assert acc.max() <= sf * c.translation_acceleration * SLACK
    np.testing.assert_allclose(np.diff(p, axis=0), 0.5 * (v[1:, :3] + v[:-1, :3]) * DT,
                               atol=1e-6)  # fmt: skip
    np.testing.assert_allclose(p[-1], goal, atol=1e-9)
    assert rotation_angle(o2[-1], turned) < 1e-6
    assert user.lag < 1e-9 and user.get_output("lag_angle")[0] < 1e-6


def test_a_4x4_pose_is_the_same_target_as_its_position_and_quaternion() -> None:
    _, user = pose_pair()
    T = np.eye(4)
    T[:3, :3] = rotation.to_matrix(QUAT0)
    T[:3, 3] = P0 + np.array([0.05, 0.0, -0.05])
    user.set_target(T)
    np.testing.assert_allclose(user.get_signal("position"), T[:3, 3])
    assert abs(float(user.get_signal("orientation") @ QUAT0)) == pytest.approx(1.0)


def test_cartesian_targets_that_stop_arriving_bring_the_reference_to_rest() -> None:
    ctrl, user = pose_pair(speed_factor=0.5, timeout=0.1)
    user.set_target(P0 + np.array([0.0, 0.4, 0.0]), QUAT0)
    p, _, v = pose_reference(ctrl, user, 600)
    speed = np.linalg.norm(v, axis=1)
    assert user.stale
    assert speed[99] > 0.1  # still going at the timeout
    stopped = int(np.argmax(speed < 1e-9))
    assert 100 < stopped < 500
    assert np.linalg.norm(p[-1] - (P0 + np.array([0.0, 0.4, 0.0]))) > 0.05  # short of it


def test_cartesian_targets_are_checked_where_they_are_set() -> None:
    before = controllers.CartesianTarget()
    with pytest.raises(InvalidOperationException, match="not running"):
        before.set_target(P0, QUAT0)
    _, user = pose_pair()
    with pytest.raises(ValueError, match=r"^position: expected finite"):
        user.set_target([0.3, np.inf, 0.4], QUAT0)
    with pytest.raises(ValueError, match=r"^orientation: expected a unit quaternion"):
        user.set_target(P0, QUAT0 * 1.01)  # beyond checks.QUATERNION_NORM_TOL
    user.set_target(P0, QUAT0 * (1.0 + 0.5e-3))  # within it: normalised
    np.testing.assert_allclose(np.linalg.norm(user.get_signal("orientation")), 1.0)
    with pytest.raises(ValueError, match=r"^orientation: expected finite"):
        user.set_target(P0, [0.0, 0.0, np.nan, 1.0])
    with pytest.raises(ValueError, match=r"^position: expected a point the arm can reach"):
        user.set_target([1.5, 0.0, 0.3], QUAT0)
    sheared = np.eye(4)
    sheared[0, 1] = 0.1
    with pytest.raises(ValueError, match=r"^position: expected a rigid transform"):
        user.set_target(sheared)
    with pytest.raises(ValueError, match=r"^position: expected a 4x4 pose"):
        user.set_target(P0)  # no orientation
    with pytest.raises(ValueError, match=r"^impedance:"):
        controllers.CartesianTarget(impedance=-np.eye(6))


def test_the_reach_bound_holds_every_reachable_point() -> None:
    """Random configurations: the end effector is always within the published bound (it
    refuses only what no configuration reaches)."""
    rng = np.random.default_rng(3)
    shoulder, radius = streaming.reach(FER, STATE0.F_T_EE)
    low, high = np.array(FER.joints.q_min), np.array(FER.joints.q_max)
    for q in rng.uniform(low, high, (2000, 7)):
        p = KIN.fk(q)[:3, 3]
        assert np.linalg.norm(p - [0.0, 0.0, shoulder]) <= radius
    assert radius < 1.1  # and a real bound: the arm's reach is about 0.86 m
