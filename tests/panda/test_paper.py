"""The paper's code blocks 2-4 (J. Elsner, "Taming the Panda with Python"), as written,
against the simulator; each checks its outcome."""

from __future__ import annotations

import numpy as np
import pytest

import panda_py
from panda_py import controllers, libfranka
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(180)


def _xy_deviation_from_line(log: dict) -> float:
    """Largest distance [m] of the logged end-effector path from the line between its
    ends."""
    p = np.array(log["O_T_EE"])[:, 12:15]
    a, b = p[0], p[-1]
    d = np.linalg.norm(np.cross(p - a, b - a), axis=1) / np.linalg.norm(b - a)
    return float(d.max())


def test_block_connect_move_grasp(sim: Simulator) -> None:
    hostname = sim.host
    panda = panda_py.Panda(hostname)
    gripper = libfranka.Gripper(hostname)
    try:
        panda.move_to_start()
        pose = panda.get_pose()
        pose[2, 3] -= 0.1
        q = panda_py.ik(pose)
        panda.move_to_joint_position(q)
        gripper.move(0.08, 0.1)

        reached = panda.get_pose()
        assert np.allclose(reached[:3, 3], pose[:3, 3], atol=2e-3)
        assert np.allclose(panda.q, q, atol=1e-2)
        assert gripper.read_once().width == pytest.approx(0.08, abs=2e-3)
    finally:
        gripper.close() if hasattr(gripper, "close") else None
        panda.close()


def test_block_logging_paths(panda: panda_py.Panda) -> None:
    panda.move_to_start()
    pose = panda.get_pose()
    pose[1, 3] -= 0.1
    q = panda_py.ik(pose)
    panda.enable_logging(2e3)
    panda.move_to_joint_position(q)
    panda.disable_logging()
    joint_log = panda.get_log()

    panda.move_to_start()
    pose = panda.get_pose()
    pose[1, 3] -= 0.1
    panda.enable_logging(2e3)
    panda.move_to_pose(pose)
    panda.disable_logging()
    pose_log = panda.get_log()

    for log in (joint_log, pose_log):
        assert 100 < len(log["q"]) <= 2000
        t = np.array(log["time"])[:, 0]
        assert (np.diff(t) > 0).all()  # in time order
        end = np.array(log["O_T_EE"])[-1]
        assert np.linalg.norm(end[12:15] - pose[:3, 3]) < 5e-3
    # the paper's figure: a straight line in Cartesian space, a curve in joint space
    assert _xy_deviation_from_line(pose_log) < 1e-3
    assert _xy_deviation_from_line(joint_log) > 3 * _xy_deviation_from_line(pose_log)
    assert set(joint_log) >= {
        "q", "dq", "tau_J", "O_T_EE", "O_F_ext_hat_K", "K_F_ext_hat_K",
        "tau_ext_hat_filtered", "elbow", "control_command_success_rate", "time",
    }  # fmt: skip


def test_block_cartesian_impedance(panda: panda_py.Panda) -> None:
    panda.move_to_start()
    ctrl = controllers.CartesianImpedance()
    x0 = panda.get_position()
    q0 = panda.get_orientation()
    runtime = np.pi * 4
    panda.enable_logging(40_000)
    panda.start_controller(ctrl)
    targets = []
    with panda.create_context(frequency=1e3, max_runtime=runtime) as ctx:
        while ctx.ok():
            x_d = x0.copy()
            x_d[1] += 0.1 * np.sin(ctrl.get_time())
            ctrl.set_control(x_d, q0)
            targets.append((ctrl.get_time(), x_d[1]))
    panda.stop_controller()
    log = panda.get_log()

    assert ctx.num_ticks > 1000
    y = np.array(log["O_T_EE"])[:, 13]
    assert y.max() - x0[1] > 0.07 and x0[1] - y.min() > 0.07  # swings +-0.1 m
    # after the first second, the arm follows the sine within a few centimetres
    t_log = (np.array(log["time"])[:, 0] - log["time"][0][0]) * 1e-3
    t_ref, y_ref = np.array(targets).T
    late = t_ref > 1.0
    follow = np.interp(t_ref[late], t_log - t_log[0] + t_ref[0], y)
    assert np.sqrt(np.mean((follow - y_ref[late]) ** 2)) < 0.03
