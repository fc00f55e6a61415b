"""Our client's AsyncPositionControlHandler (pylibfranka's API) against the simulated FR3's
protocol v10 asynchronous generator."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.robots import FR3, START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(90)

H = lf.AsyncPositionControlHandler
VELOCITY = [0.655, 0.655, 0.655, 0.655, 1.315, 1.315, 1.315]


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fr3", lockstep=True) as s:
        yield s


@pytest.fixture
def robot(sim):
    with lf.Robot(sim.host, robot="fr3") as r:
        yield r
    with lf.Robot(sim.host, robot="fr3") as cleanup:
        cleanup.automatic_error_recovery()
    sim.set_joint_positions(START_POSE)


def configure(robot: lf.Robot, tolerance: float | None = None) -> H:
    result = H.configure(robot, H.Configuration(VELOCITY, tolerance))
    assert result.error_message is None
    assert result.handler is not None
    return result.handler


def test_targets_are_reached_and_stop_leaves_the_robot_idle(robot):
    handler = configure(robot)
    assert handler.get_target_feedback().status == lf.TargetStatus.IDLE  # no target yet
    q0 = np.array(START_POSE)
    target = list(q0 + np.array([0.1, -0.1, 0.1, 0.1, -0.2, 0.2, 0.2]))
    statuses = []
    for _ in range(400):  # 20 ms apart: the robot's generator does the rest
        sent = handler.set_joint_position_target(H.JointPositionTarget(target))
        assert sent.was_successful and sent.error_message is None and sent.motion_uuid
        feedback = handler.get_target_feedback()
        assert feedback.error_message is None
        statuses.append(feedback.status)
        if feedback.status == lf.TargetStatus.TARGET_REACHED:
            break
        time.sleep(0.02)
    assert statuses[0] == lf.TargetStatus.EXECUTING
    assert statuses[-1] == lf.TargetStatus.TARGET_REACHED
    handler.stop_control()
    state = robot.read_once()
    assert state.robot_mode == lf.RobotMode.kIdle
    np.testing.assert_allclose(state.q_d, target, atol=1e-3)
    after = handler.set_joint_position_target(H.JointPositionTarget(target))
    assert not after.was_successful and "aborted" in after.error_message
    assert handler.get_target_feedback().status == lf.TargetStatus.ABORTED


def test_bad_targets_are_refused_unsent_and_control_goes_on(robot):
    handler = configure(robot)
    q = list(START_POSE)
    for bad, why in (
        ([*q[:6], float("nan")], "finite"),
        (q[:6], "7 finite"),
        ([*q[:6], FR3.joints.q_max[6] + 0.1], "outside the joint range"),
    ):
        result = handler.set_joint_position_target(H.JointPositionTarget(bad))
        assert not result.was_successful and why in result.error_message
    assert handler.set_joint_position_target(H.JointPositionTarget(q)).was_successful
    assert handler.get_target_feedback().error_message is None
    handler.stop_control()
    assert robot.read_once().robot_mode == lf.RobotMode.kIdle


@pytest.mark.parametrize(
    ("velocity", "tolerance", "why"),
    [
        (None, None, "required"),
        ([0.5] * 6, None, "7 values"),
        ([0.0] * 7, None, r"\(0, dq_max\]"),
        ([10.0] * 7, None, r"\(0, dq_max\]"),
        (VELOCITY, -1.0, "goal_tolerance"),
    ],
)
def test_configure_reports_what_it_cannot_start(robot, velocity, tolerance, why):
    result = H.configure(robot, H.Configuration(velocity, tolerance))
    assert result.handler is None
    assert result.error_message is not None
    assert re.search(why, result.error_message), result.error_message
    assert robot.read_once().robot_mode == lf.RobotMode.kIdle  # nothing started


def test_protocol_before_v10_has_no_asynchronous_generator(sim_for_version):
    with lf.Robot(sim_for_version(9).host, version=9, robot="fr3") as robot:
        result = H.configure(robot, H.Configuration(VELOCITY, None))
        assert result.handler is None
        assert "v10 or later, got v9" in result.error_message
        assert robot.read_once().robot_mode == lf.RobotMode.kIdle


def test_reflex_shows_as_aborted_feedback(robot, sim):
    handler = configure(robot)
    q = list(START_POSE)
    assert handler.set_joint_position_target(H.JointPositionTarget(q)).was_successful
    sim.inject_reflex("joint_reflex")
    feedback = handler.get_target_feedback()
    for _ in range(50):
        if feedback.status == lf.TargetStatus.ABORTED:
            break
        time.sleep(0.01)
        feedback = handler.get_target_feedback()
    assert feedback.status == lf.TargetStatus.ABORTED
    assert "reflex" in feedback.error_message.lower()
