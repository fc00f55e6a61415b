"""Conformance: pylibfranka 0.21.3 (libfranka 0.21.3, protocol v10), unmodified, against
the simulator: active control (readOnce/writeOnce), torque control, setters, reflex
recovery, the Pinocchio model built from the URDF the simulator serves, and the Gripper."""

from __future__ import annotations

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
    run_peer,
    scenario,
    zero_jacobian,
)

from panda_py import dynamics
from panda_py.fci import RobotMode
from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]

IDLE = "Idle"
MODES = {"idle": "Idle", "reflex": "Reflex"}
F32 = 1e-6  # v10 states carry float32: values the client reads back are rounded
MODEL_Q = [  # [rad] configurations at which the model is compared (seeded, within limits)
    [float(x) for x in np.random.default_rng(seed).uniform(-0.5, 0.5, 7) + START_POSE]
    for seed in (1, 2, 3)
]


@pytest.fixture(scope="module")
def python() -> Any:
    return peer_or_skip("pylibfranka")


@pytest.fixture(scope="module")
def sim() -> Any:
    """An FR3 on system 5.9 or later: protocol 10, what libfranka 0.21 speaks."""
    with Simulator(host=free_loopback_host(), robot="fr3", lockstep=True, versions=(10,)) as s:
        yield s


@pytest.fixture(scope="module")
def lowlevel(python: Any, sim: Any) -> dict[str, Any]:
    sim.set_joint_positions(START_POSE)
    handlers = LowLevelHandlers(sim, MODEL_Q)
    q_initial = sim.state()["q"]
    result = run_peer(python, "plf_lowlevel.py", [sim.host], handlers.handlers(), timeout=90)
    return {
        "result": result,
        "seen": handlers.seen,
        "q_initial": q_initial,
        "robot": sim.config.robot,
    }


def test_read_once(lowlevel: dict[str, Any]) -> None:
    r = scenario(lowlevel["result"], "read_once")
    np.testing.assert_allclose(r["q"], lowlevel["q_initial"], atol=F32)
    assert r["robot_mode"] == IDLE
    assert r["errors"] is False
    np.testing.assert_allclose(col_major(r["F_T_EE"]), hand_F_T_EE(), atol=F32)
    np.testing.assert_allclose(col_major(r["O_T_EE"]), fk(r["q"], hand_F_T_EE()), atol=1e-5)


def test_joint_position_motion(lowlevel: dict[str, Any]) -> None:
    check_joint_position(scenario(lowlevel["result"], "joint_position"), IDLE)


def test_torque_control(lowlevel: dict[str, Any]) -> None:
    check_torque(scenario(lowlevel["result"], "torque"), IDLE)


def test_reflex_and_recovery(lowlevel: dict[str, Any]) -> None:
    assert lowlevel["seen"]["mode_before_reflex"] == RobotMode.MOVE
    r = scenario(lowlevel["result"], "reflex_recovery")
    check_reflex_recovery(r, MODES)
    assert r["exception_type"] == "ControlException"
    assert "motion aborted by reflex" in r["exception"]


def test_setters(lowlevel: dict[str, Any]) -> None:
    r = scenario(lowlevel["result"], "setters")
    check_setters(r, lowlevel["seen"]["setters_state"], IDLE, atol=F32)
    np.testing.assert_allclose(col_major(r["NE_T_EE_restored"]), np.eye(4), atol=F32)


def test_gripper(lowlevel: dict[str, Any]) -> None:
    r = scenario(lowlevel["result"], "gripper")
    seen = lowlevel["seen"]
    check_gripper(r, seen["cube_before"], seen["cube_after"])


@pytest.mark.parametrize("i", range(len(MODEL_Q)))
def test_model_agrees_with_parameters(lowlevel: dict[str, Any], i: int) -> None:
    """pylibfranka's Model (Pinocchio on the URDF our simulator serves) against the DH
    table and panda_py.dynamics, at the state the simulator reports at MODEL_Q[i] (its
    float32 q and the hand as load; the residue is the float32 rounding of m, F_x_C)."""
    s = scenario(lowlevel["result"], "model")["samples"][i]
    q, robot = np.array(s["q"]), lowlevel["robot"]
    np.testing.assert_allclose(q, MODEL_Q[i], atol=F32)
    F_T_EE = col_major(s["F_T_EE"])
    np.testing.assert_allclose(F_T_EE, hand_F_T_EE(), atol=F32)
    np.testing.assert_allclose(col_major(s["O_T_EE"]), fk(q, hand_F_T_EE(), robot), atol=1e-5)
    J = np.asarray(s["zero_jacobian"]).reshape(7, 6).T  # column-major 6x7
    np.testing.assert_allclose(J, zero_jacobian(q, F_T_EE, robot), atol=1e-6)
    load = {"m_load": s["m_total"], "F_x_Cload": s["F_x_Ctotal"], "robot": robot}
    np.testing.assert_allclose(s["gravity"], dynamics.gravity(q, **load), atol=1e-5)
    M = np.asarray(s["mass"]).reshape(7, 7).T
    M_ref = dynamics.mass_matrix(q, I_load=np.asarray(s["I_total"]), **load)
    np.testing.assert_allclose(M, M_ref, atol=1e-8)
