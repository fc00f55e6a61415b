"""Panda's state getters, joint limits per robot, logging and PandaContext."""

from __future__ import annotations

import time

import numpy as np
import pytest

import panda_py
from panda_py import constants
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize(
    ("robot", "version", "lower", "upper"),
    [
        ("fer", 5, constants.JOINT_LIMITS_LOWER, constants.JOINT_LIMITS_UPPER),
        ("fr3-pre-5.9", 8, constants.JOINT_LIMITS_LOWER_FR3, constants.JOINT_LIMITS_UPPER_FR3),
        ("fr3", 10, constants.JOINT_LIMITS_LOWER_FR3_5_9, constants.JOINT_LIMITS_UPPER_FR3_5_9),
    ],
)
def test_joint_limits_follow_the_robot(robot: str, version: int, lower, upper) -> None:
    from panda_py.sim.api import free_loopback_host

    with (
        Simulator(free_loopback_host(), robot=robot, versions=(version,), lockstep=True) as sim,
        panda_py.Panda(sim.host) as panda,
    ):
        np.testing.assert_array_equal(panda.get_joint_limits_lower(), lower)
        np.testing.assert_array_equal(panda.get_joint_limits_upper(), upper)
        assert panda.get_robot().server_version() == version
        assert panda.move_to_start()


def test_state_getters_agree(reset_panda: panda_py.Panda, shared_sim: Simulator) -> None:
    panda, sim = reset_panda, shared_sim
    state = panda.get_state()
    T = panda.get_pose()
    # each getter reads the newest state: the arm at rest (settled after a move, not
    # placed there) moves by rounding between two reads (1.6e-14 m seen), hence atol
    np.testing.assert_allclose(T, np.asarray(state.O_T_EE).reshape(4, 4).T, atol=1e-9)
    np.testing.assert_allclose(panda.get_position(), T[:3, 3], atol=1e-9)
    np.testing.assert_allclose(panda.q, sim.q(), atol=1e-6)
    np.testing.assert_allclose(panda_py.fk(panda.q), T, atol=1e-5)
    x, y, z, w = panda.get_orientation()
    # two reads: the arm at rest may move by rounding in between (8e-17 seen)
    np.testing.assert_allclose(panda.get_orientation(scalar_first=True), [w, x, y, z], atol=1e-9)
    R = T[:3, :3]
    assert w == pytest.approx(np.sqrt(1 + np.trace(R)) / 2, abs=1e-6) or w < 1e-3
    assert panda.name == "panda"
    assert panda.get_model().spec.name in ("fer", "fr3")
    before = panda._proc.block.header[2]
    panda.refresh_state()
    assert panda._proc.block.header[2] > before
    fresh = panda.get_robot().read_once()
    assert fresh.time.to_msec() >= state.time.to_msec()


def test_setters_reach_the_robot(reset_panda: panda_py.Panda) -> None:
    panda = reset_panda
    robot = panda.get_robot()
    robot.set_load(0.5, [0.0, 0.0, 0.05], np.eye(3) * 1e-3)
    assert panda.get_robot().read_once().m_load == pytest.approx(0.5)
    panda.set_default_behavior()
    robot.automatic_error_recovery()


def test_logging_keeps_the_newest_states(reset_panda: panda_py.Panda) -> None:
    panda = reset_panda
    panda.enable_logging(2e3)  # the paper's call: an integral float
    assert all(v == [] for v in panda.get_log().values()) or len(panda.get_log()["q"]) < 50
    deadline = time.monotonic() + 10
    while len(panda.get_log()["q"]) < 300 and time.monotonic() < deadline:
        time.sleep(0.01)
    panda.disable_logging()
    log = panda.get_log()
    n = len(log["q"])
    assert 250 <= n <= 2000
    assert all(len(v) == n for v in log.values())
    t = np.array(log["time"])[:, 0]
    assert np.all(np.diff(t) >= 1)
    assert log["O_T_EE"][0].shape == (16,) and log["elbow"][0].shape == (2,)
    assert panda.get_log()["time"][-1] == log["time"][-1]  # nothing logged after disable
    panda.enable_logging(10)
    t0 = panda.get_state().time.to_msec()
    deadline = time.monotonic() + 10
    while panda.get_state().time.to_msec() < t0 + 30 and time.monotonic() < deadline:
        time.sleep(1e-3)  # until 30 ms of the robot's time passed (not 0.1 s of ours)
    log = panda.get_log()
    assert len(log["q"]) == 10
    assert log["time"][0][0] > t0  # the newest ten: the first ones logged were dropped


def test_context_counts_and_stops(reset_panda: panda_py.Panda) -> None:
    panda = reset_panda
    with panda.create_context(frequency=200, max_iter=20) as ctx:
        n = 0
        while ctx.ok():
            n += 1
    assert n == 20 and ctx.num_ticks == 21
    assert 0.08 < ctx.time < 2.0  # 20 periods of 5 ms, on a schedule
    with panda.create_context(frequency=1000, max_runtime=0.05) as ctx:
        while ctx.ok():
            pass
    assert ctx.time >= 0.05
