"""Conformance: franky-control 2.0.0 (libfranka 0.21.2, protocol v10), unmodified, against
the simulator: construction (3x GetRobotModel, SetCollisionBehavior), state, JointMotion."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from conf_support import PEER_TEST_TIMEOUT, fk, hand_F_T_EE, peer_or_skip, run_peer, scenario

from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]

Q_GOAL = [0.1, -0.7, 0.05, -2.3, 0.05, 1.6, 0.8]  # [rad]


@pytest.fixture(scope="module")
def run() -> dict[str, Any]:
    python = peer_or_skip("franky")
    with Simulator(host=free_loopback_host(), robot="fr3", lockstep=True, versions=(10,)) as sim:
        sim.set_joint_positions(START_POSE)
        q_initial = sim.state()["q"]
        result = run_peer(python, "franky_basic.py", [sim.host, json.dumps(Q_GOAL)], timeout=90)
        return {"result": result, "q_initial": q_initial, "final": sim.state()}


def test_state(run: dict[str, Any]) -> None:
    r = scenario(run["result"], "state")
    np.testing.assert_allclose(r["q"], run["q_initial"], atol=1e-6)  # float32 on the wire
    assert r["robot_mode"].endswith("Idle")
    assert r["has_errors"] is False
    np.testing.assert_allclose(r["O_T_EE"], fk(r["q"], hand_F_T_EE()), atol=1e-5)


def test_joint_motion_reaches_goal(run: dict[str, Any]) -> None:
    r = scenario(run["result"], "joint_motion")
    np.testing.assert_allclose(run["final"]["q"], Q_GOAL, atol=1e-4)
    np.testing.assert_allclose(r["q"], Q_GOAL, atol=1e-4)
