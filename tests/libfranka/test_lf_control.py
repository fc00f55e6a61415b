"""Each control type moves the simulated arm where it was told (lockstep simulator):
a cheap scenario in every protocol version, every control type on v5 and v10."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.robots import START_POSE

pytestmark = pytest.mark.timeout(90)

TICKS = 300  # [ms] of each motion


@pytest.fixture(params=[5, 10])
def sim(sim_for_version, request):
    """A FER speaking v5 and an FR3 speaking v10."""
    return sim_for_version(request.param)


@pytest.fixture
def robot(sim):
    with lf.Robot(sim.host) as r:
        yield r
    with lf.Robot(sim.host) as cleanup:
        cleanup.automatic_error_recovery()
    sim.set_joint_positions(START_POSE)


def _ramp(k: int) -> float:
    """0 -> 1 over TICKS with zero velocity and acceleration at both ends (quintic): a
    motion generator must start and end without a jump in acceleration."""
    t = min(k, TICKS) / TICKS
    return t**3 * (10.0 - 15.0 * t + 6.0 * t * t)


def _settle(robot: lf.Robot) -> lf.RobotState:
    robot.read(lambda s: s.robot_mode != lf.RobotMode.kIdle)
    return robot.read_once()


@pytest.mark.parametrize("version", fci.SUPPORTED_VERSIONS)
def test_torque_and_joint_position_loops_in_every_version(sim_for_version, version):
    sim = sim_for_version(version)
    with lf.Robot(sim.host, version=version) as robot:
        q0 = robot.read_once().q
        calls = []

        def torque(state, dt):
            calls.append(dt.to_msec())
            return (
                lf.Torques(np.zeros(7))
                if len(calls) < 50
                else lf.motion_finished(lf.Torques(np.zeros(7)))
            )

        robot.control(torque)
        assert len(calls) == 50 and calls[0] == 0 and set(calls[1:]) == {1}
        n = [0]

        def joint(state, dt):
            n[0] += 1
            q = q0.copy()
            q[0] += 0.05 * _ramp(n[0])
            out = lf.JointPositions(q)
            out.motion_finished = n[0] >= TICKS
            return out

        robot.control(joint, motion=lf.JointPositions)
        state = _settle(robot)
        assert state.q_d[0] - q0[0] == pytest.approx(0.05, abs=1e-5)
        assert state.q[0] - q0[0] == pytest.approx(0.05, abs=2e-3)


def test_joint_velocity_motion_integrates_to_the_commanded_distance(robot):
    q0 = robot.read_once().q
    n = [0]

    def velocity(state, dt):
        n[0] += 1
        out = lf.JointVelocities([0, 0, 0, 0.0, 0, 0, 0.4 * np.sin(np.pi * n[0] / TICKS) ** 2])
        out.motion_finished = n[0] >= TICKS
        return out

    robot.control_joint_velocity(velocity)
    moved = _settle(robot).q[6] - q0[6]
    expected = 0.4 * TICKS * 1e-3 / 2  # the integral of sin^2
    assert moved == pytest.approx(expected, abs=3e-3)


@pytest.mark.parametrize("mode", [lf.ControllerMode.kJointImpedance,
                                  lf.ControllerMode.kCartesianImpedance])  # fmt: skip
def test_cartesian_pose_motion_reaches_the_pose(robot, mode):
    T0 = robot.read_once().O_T_EE
    n = [0]

    def pose(state, dt):
        n[0] += 1
        T = T0.copy()
        T[12] += 0.02 * _ramp(n[0])
        T[14] -= 0.015 * _ramp(n[0])
        out = lf.CartesianPose(T, state.elbow_c if n[0] > 1 else state.elbow)
        out.motion_finished = n[0] >= TICKS
        return out

    robot.control_cartesian_pose(pose, mode)
    T = _settle(robot).O_T_EE
    np.testing.assert_allclose(T[12:15] - T0[12:15], [0.02, 0.0, -0.015], atol=1e-3)


def test_cartesian_velocity_motion_moves_along_z(robot):
    T0 = robot.read_once().O_T_EE
    n = [0]

    def twist(state, dt):
        n[0] += 1
        out = lf.CartesianVelocities([0, 0, 0.1 * np.sin(np.pi * n[0] / TICKS) ** 2, 0, 0, 0])
        out.motion_finished = n[0] >= TICKS
        return out

    robot.control(twist, motion=lf.CartesianVelocities)
    dz = _settle(robot).O_T_EE[14] - T0[14]
    assert dz == pytest.approx(0.1 * TICKS * 1e-3 / 2, abs=2e-3)


def test_torques_plus_a_motion_generator(robot):
    q0 = robot.read_once().q
    n = [0]
    q_d = []

    def torque(state, dt):
        return lf.Torques(np.zeros(7))

    def joint(state, dt) -> lf.JointPositions:  # the annotation tells control() the type
        n[0] += 1
        q_d.append(state.q_d[1])
        q = q0.copy()
        q[1] += 0.03 * _ramp(n[0])
        out = lf.JointPositions(q)
        out.motion_finished = n[0] >= TICKS
        return out

    robot.control(torque, joint)
    assert n[0] == TICKS
    # the robot accepted and echoed the generator's path (the torques drive the arm)
    assert q_d[-1] - q0[1] == pytest.approx(0.03 * _ramp(TICKS - 1), abs=1e-5)


def test_active_control_loops_driven_by_the_caller(robot):
    q0 = robot.read_once().q
    with robot.start_joint_position_control() as control:
        k = 0
        while not control.finished:
            _, dt = control.readOnce()
            assert dt.to_msec() == (0 if k == 0 else 1)
            k += 1
            q = q0.copy()
            q[3] += 0.05 * _ramp(k)
            cmd = lf.JointPositions(q)
            cmd.motion_finished = k >= TICKS
            control.writeOnce(cmd)
    assert _settle(robot).q_d[3] - q0[3] == pytest.approx(0.05, abs=1e-5)
    with robot.start_torque_control() as control:
        for _ in range(20):
            control.readOnce()
            control.writeOnce(lf.Torques(np.zeros(7)))
    # leaving the block stopped the motion
    assert _settle(robot).robot_mode == lf.RobotMode.kIdle
    with pytest.raises(lf.InvalidOperationException):
        control.readOnce()


def test_stop_from_a_callback_preempts_the_motion(robot):
    n = [0]

    def torque(state, dt):
        n[0] += 1
        if n[0] == 20:
            robot.stop()
        return lf.Torques(np.zeros(7))

    with pytest.raises(lf.ControlException, match="Move command preempted"):
        robot.control(torque)
    assert _settle(robot).robot_mode == lf.RobotMode.kIdle
