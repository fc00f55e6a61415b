"""The external torques and wrench carry libfranka's signs (include/franka/robot_state.h),
checked against the definitions rather than against our own client:

- ``tau_ext_hat_filtered``: "the error between tau_J and the expected torques given by the
  robot model" -- for an arm at rest, tau_J minus the gravity torques (the link-side
  sensors carry what the drives push with; the table's push back acts on the links);
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
        last: dict[str, np.ndarray] = {}

        def press(state: lf.RobotState, dt: lf.Duration) -> lf.Torques:
            nonlocal ticks
            ticks += 1
            J = model.zero_jacobian(lf.Frame.kEndEffector, state).reshape(7, 6).T
            F = np.array([0.0, 0.0, -PUSH, 0.0, 0.0, 0.0])  # the robot pushes down
            tau = J.T @ F - 5.0 * np.asarray(state.dq)
            if ticks < 1500:
                return lf.Torques(tau)
            # the last tick, 1.5 s into the press: the arm rests on the table, pushing. (A
            # state read after the motion has ended sees the estimate already decaying.)
            for name in ("O_F_ext_hat_K", "K_F_ext_hat_K", "tau_ext_hat_filtered", "tau_J"):
                last[name] = np.array(getattr(state, name))
            last["dq"] = np.array(state.dq)
            last["gravity"] = np.array(model.gravity(state))
            return lf.motion_finished(lf.Torques(tau))

        robot.control(press)
    O_F, K_F, tau_ext = last["O_F_ext_hat_K"], last["K_F_ext_hat_K"], last["tau_ext_hat_filtered"]
    assert O_F[2] < -0.6 * PUSH, O_F  # the robot's force on the table points down
    assert K_F[2] > 0.6 * PUSH, K_F  # K's z points down, into the table
    # at rest the robot model expects gravity alone (M ddq + c vanish); the client's hand
    # holds the fingers' 30 g the simulated hand carries as bodies of their own
    assert np.abs(last["dq"]).max() < 1e-3
    assert np.allclose(tau_ext, last["tau_J"] - last["gravity"], atol=0.25), (
        tau_ext,
        last["tau_J"] - last["gravity"],
    )
