"""A grasped cube stays in the simulated hand through a lift and the paper's moves
(move_to_start, then straight Cartesian moves of 10 cm: its code block 4) for more than
30 s of the robot's time: is_grasped true in every gripper state and the cube within a
few mm of where it sat between the fingers."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import panda_py
from panda_py import constants
from panda_py import libfranka as lf
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(300)

CUBE = np.array([0.5, 0.0, 0.02])  # [m] the scene's cube, its centre
CUBE_SIZE = 0.04  # [m]
HOLD = 30.0  # [s] of the robot's time, from the grasp
SLIP = 0.003  # [m] how far the cube may move relative to the hand


def tcp_at(position: np.ndarray) -> np.ndarray:
    T = panda_py.fk(constants.JOINT_POSITION_START)
    T[:3, 3] = position
    return T


class Watch:
    """Records, in a thread, every gripper state and where the cube sits in the hand's
    (TCP's) frame until stopped."""

    def __init__(self, sim: Simulator, gripper: lf.Gripper) -> None:
        self.sim, self.gripper = sim, gripper
        self.widths: list[float] = []
        self.grasped: list[bool] = []
        self.in_hand: list[np.ndarray] = []  # cube centre in the TCP frame [m]
        self.times: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def cube_in_hand(self) -> tuple[float, np.ndarray]:
        s = self.sim.state()
        O_T_EE = np.asarray(s["O_T_EE"]).reshape(4, 4).T  # column-major
        cube = np.asarray(s["cube_position"])
        return float(s["time"]), O_T_EE[:3, :3].T @ (cube - O_T_EE[:3, 3])

    def _run(self) -> None:
        while not self._stop.is_set():
            state = self.gripper.read_once()
            self.widths.append(state.width)
            self.grasped.append(state.is_grasped)
            t, p = self.cube_in_hand()
            self.times.append(t)
            self.in_hand.append(p)

    def __enter__(self) -> Watch:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)


def test_the_cube_stays_in_the_hand_through_the_papers_moves(
    sim: Simulator, panda: panda_py.Panda
) -> None:
    with lf.Gripper(sim.host) as gripper:
        assert gripper.homing() is True
        assert panda.move_to_start()
        assert panda.move_to_pose(tcp_at(CUBE + np.array([0, 0, 0.1])))
        assert panda.move_to_pose(tcp_at(CUBE + np.array([0, 0, 0.005])))
        assert gripper.grasp(CUBE_SIZE, 0.05, 20.0, 0.005, 0.005) is True
        watch = Watch(sim, gripper)
        t_grasp, at_grasp = watch.cube_in_hand()
        with watch:
            assert panda.move_to_pose(tcp_at(CUBE + np.array([0, 0, 0.15])))  # lift
            assert panda.move_to_start()
            while sim.state()["time"] - t_grasp < HOLD:
                pose = panda.get_pose()  # the paper's block 4: 10 cm down, and up again
                pose[2, 3] -= 0.1
                assert panda.move_to_pose(pose)
                pose[2, 3] += 0.1
                assert panda.move_to_pose(pose)
                assert panda.move_to_pose(tcp_at(pose[:3, 3] + np.array([0, 0.1, 0])))
                assert panda.move_to_start()
        t_end, at_end = watch.cube_in_hand()
    assert t_end - t_grasp >= HOLD
    assert len(watch.widths) > 100  # gripper states all along (100 Hz)
    assert all(watch.grasped), "is_grasped dropped while the cube was held"
    assert all(CUBE_SIZE - 0.005 <= w <= CUBE_SIZE + 0.005 for w in watch.widths)
    slip = max(float(np.linalg.norm(p - at_grasp)) for p in [*watch.in_hand, at_end])
    assert slip < SLIP, f"the cube moved {slip * 1000:.1f} mm in the hand"
    # and the hand carried it: at the start pose, well above the table
    assert sim.state()["cube_position"][2] > 0.3
