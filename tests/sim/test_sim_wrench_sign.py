"""The external torques and wrench carry libfranka's signs (include/franka/robot_state.h),
checked against the definitions rather than against our own client:

- ``tau_ext_hat_filtered``: "the error between tau_J and the expected torques given by the
  robot model" -- at rest, tau_J minus the gravity torques;
- ``O_F_ext_hat_K`` / ``K_F_ext_hat_K``: the wrench at the stiffness frame K, "forces
  applied by the robot to the environment are positive, while forces applied by the
  environment on the robot are negative" -- an arm pressing down on the table reads a
  negative z force in the base frame (franky's documented reaction, ``FORCE_Z < -5`` on a
  downward motion, relies on it), a positive one along the downward-pointing K's z.
"""

from __future__ import annotations

import numpy as np
import pytest

import panda_py
from panda_py import libfranka as lf
from panda_py.robots.params import START_POSE

pytestmark = pytest.mark.timeout(120)
PUSH = 12.0  # [N] the force the controller makes the arm press down with


def _above_table(q_init: np.ndarray) -> np.ndarray:
    """Joint positions putting the end effector 1 cm above the table, pointing down, away
    from the cube."""
    pose = panda_py.fk(q_init)
    pose[:3, 3] = (0.45, 0.25, 0.01)
    q = panda_py.ik(pose, q_init)
    assert np.isfinite(q).all()
    return q


def test_pressing_on_the_table_reads_the_robots_force_on_it(panda_sim) -> None:
    panda_sim.set_joint_positions(_above_table(np.array(START_POSE)).tolist())
    with lf.Robot(panda_sim.host) as robot:
        model = robot.load_model()
        robot.set_collision_behavior([80.0] * 7, [80.0] * 7, [80.0] * 6, [80.0] * 6)
        ticks = 0

        def press(state: lf.RobotState, dt: lf.Duration) -> lf.Torques:
            nonlocal ticks
            ticks += 1
            J = model.zero_jacobian(lf.Frame.kEndEffector, state).reshape(7, 6).T
            F = np.array([0.0, 0.0, -PUSH, 0.0, 0.0, 0.0])  # the robot pushes down
            tau = J.T @ F - 5.0 * np.asarray(state.dq)
            torques = lf.Torques(tau)
            return lf.motion_finished(torques) if ticks >= 1500 else torques

        robot.control(press)
        state = robot.read_once()
    O_F = np.asarray(state.O_F_ext_hat_K)
    K_F = np.asarray(state.K_F_ext_hat_K)
    tau_ext = np.asarray(state.tau_ext_hat_filtered)
    assert O_F[2] < -0.6 * PUSH, O_F  # the robot's force on the table points down
    assert K_F[2] > 0.6 * PUSH, K_F  # K's z points down, into the table
    expected = np.asarray(model.gravity(state))
    # at rest the model expects gravity alone: tau_ext = tau_J - gravity, same sign
    assert np.allclose(tau_ext, np.asarray(state.tau_J) - expected, atol=0.15 * PUSH), (
        tau_ext,
        np.asarray(state.tau_J) - expected,
    )
