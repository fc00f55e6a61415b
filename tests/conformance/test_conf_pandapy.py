"""Conformance: panda-python 1.1.1 (libfranka 0.9.2, protocol v5), unmodified, against
the simulator. Its low-level ``libfranka`` API and its own high-level ``panda_py.Panda``
run in the peer's venv; the tests assert on what the peer saw and on ``sim.state()``."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from conf_support import (
    PEER_TEST_TIMEOUT,
    LowLevelHandlers,
    check_gripper,
    check_joint_position,
    check_reflex_recovery,
    check_setters,
    check_torque,
    col_major,
    fk,
    hand_F_T_EE,
    peer_or_skip,
    pose_error,
    run_peer,
    scenario,
    zero_jacobian,
)

from panda_py import dynamics
from panda_py.fci import RobotMode
from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]

IDLE = "kIdle"
MODES = {"idle": "kIdle", "reflex": "kReflex"}
Q_GOAL = [0.2, -0.9, 0.1, -2.2, 0.1, 1.7, 0.9]  # [rad] for move_to_joint_position
POSE_OFFSET = [0.05, 0.05, -0.05]  # [m] move_to_pose goal relative to its start


@pytest.fixture(scope="module")
def python() -> Any:
    return peer_or_skip("panda-python")


@pytest.fixture(scope="module")
def sim() -> Any:
    with Simulator(host=free_loopback_host(), robot="fer", lockstep=True, versions=(5,)) as s:
        yield s


@pytest.fixture(scope="module")
def lowlevel(python: Any, sim: Any) -> dict[str, Any]:
    sim.set_joint_positions(START_POSE)
    handlers = LowLevelHandlers(sim)
    q_initial = sim.state()["q"]
    result = run_peer(python, "pp_lowlevel.py", [sim.host], handlers.handlers(), timeout=90)
    return {"result": result, "seen": handlers.seen, "q_initial": q_initial}


@pytest.fixture(scope="module")
def highlevel(python: Any, sim: Any) -> dict[str, Any]:
    sim.set_joint_positions(START_POSE)
    seen: dict[str, Any] = {}

    def joint_move_done(_: Any) -> None:
        seen["after_joint_move"] = sim.state()

    args = [sim.host, json.dumps(Q_GOAL), json.dumps(POSE_OFFSET)]
    result = run_peer(
        python, "pp_highlevel.py", args, {"joint_move_done": joint_move_done}, timeout=90
    )
    seen["final"] = sim.state()
    return {"result": result, "seen": seen}


def test_read_once(lowlevel: dict[str, Any]) -> None:
    r = scenario(lowlevel["result"], "read_once")
    assert r["server_version"] == 5
    np.testing.assert_allclose(r["q"], lowlevel["q_initial"], atol=1e-9)  # f64 on the wire
    assert r["robot_mode"] == IDLE
    assert r["errors"] is False
    np.testing.assert_allclose(col_major(r["O_T_EE"]), fk(r["q"], hand_F_T_EE()), atol=1e-9)


def test_joint_position_motion(lowlevel: dict[str, Any]) -> None:
    check_joint_position(scenario(lowlevel["result"], "joint_position"), IDLE)


def test_torque_control(lowlevel: dict[str, Any]) -> None:
    check_torque(scenario(lowlevel["result"], "torque"), IDLE)


def test_reflex_and_recovery(lowlevel: dict[str, Any]) -> None:
    assert lowlevel["seen"]["mode_before_reflex"] == RobotMode.MOVE
    r = scenario(lowlevel["result"], "reflex_recovery")
    check_reflex_recovery(r, MODES)
    assert r["exception_type"] == "RuntimeError"  # panda-python maps ControlException so
    assert "motion aborted by reflex" in r["exception"]


def test_setters(lowlevel: dict[str, Any]) -> None:
    r = scenario(lowlevel["result"], "setters")
    check_setters(r, lowlevel["seen"]["setters_state"], IDLE, atol=1e-12)
    np.testing.assert_allclose(col_major(r["F_T_EE_restored"]), hand_F_T_EE(), atol=1e-12)


def test_gripper(lowlevel: dict[str, Any]) -> None:
    r = scenario(lowlevel["result"], "gripper")
    seen = lowlevel["seen"]
    check_gripper(r, seen["cube_before"], seen["cube_after"])


def test_panda_model_library(highlevel: dict[str, Any]) -> None:
    """panda_py.Panda's model comes from the native library the simulator compiled from
    our parameters (LoadModelLibrary): it must agree with the DH table and our dynamics."""
    r = scenario(highlevel["result"], "model")
    q, F_T_EE = np.array(r["q"]), col_major(r["F_T_EE"])
    np.testing.assert_allclose(col_major(r["pose_ee"]), fk(q, F_T_EE), atol=1e-9)
    np.testing.assert_allclose(col_major(r["pose_flange"]), fk(q), atol=1e-9)
    J = np.asarray(r["zero_jacobian_ee"]).reshape(7, 6).T  # column-major 6x7
    np.testing.assert_allclose(J, zero_jacobian(q, F_T_EE), atol=1e-6)
    load = {"m_load": r["m_total"], "F_x_Cload": r["F_x_Ctotal"]}
    np.testing.assert_allclose(r["gravity"], dynamics.gravity(q, **load), atol=1e-6)
    M = np.asarray(r["mass"]).reshape(7, 7).T
    M_ref = dynamics.mass_matrix(q, I_load=np.asarray(r["I_total"]), **load)
    np.testing.assert_allclose(M, M_ref, atol=1e-6)


def test_panda_move_to_joint_position(highlevel: dict[str, Any]) -> None:
    r = scenario(highlevel["result"], "move_to_joint_position")
    assert r["returned"] is True
    q = highlevel["seen"]["after_joint_move"]["q"]
    np.testing.assert_allclose(q, Q_GOAL, atol=0.01)  # panda-py's own success threshold
    np.testing.assert_allclose(r["q"], q, atol=1e-3)


def test_panda_move_to_pose(highlevel: dict[str, Any]) -> None:
    r = scenario(highlevel["result"], "move_to_pose")
    assert r["returned"] is True
    goal = np.array(r["goal"])
    start = highlevel["seen"]["after_joint_move"]["O_T_EE"]
    assert pose_error(col_major(start), goal)[0] == pytest.approx(
        float(np.linalg.norm(POSE_OFFSET)), abs=1e-3
    )
    dist, angle = pose_error(col_major(highlevel["seen"]["final"]["O_T_EE"]), goal)
    assert dist < 0.02 and angle < 0.1, (dist, angle)  # panda-py's own success thresholds
