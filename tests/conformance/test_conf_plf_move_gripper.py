"""Conformance: pylibfranka 0.21.3's move_gripper example against the simulated Franka
Hand. Grasping with 60 N, the example checks after 3 s that the object is still grasped;
the hand's width under that force once read -5.2 mm, outside the grasp's window, and the
example printed "Object lost."."""

from __future__ import annotations

from typing import Any

import pytest
from conf_support import PEER_TEST_TIMEOUT, LowLevelHandlers, peer_or_skip, run_peer, scenario

from panda_py.robots.params import FRANKA_HAND, START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]


@pytest.fixture(scope="module")
def run() -> dict[str, Any]:
    python = peer_or_skip("pylibfranka")
    with Simulator(host=free_loopback_host(), robot="fer", lockstep=True) as sim:
        sim.set_joint_positions(START_POSE)
        handlers = LowLevelHandlers(sim)
        result = run_peer(python, "plf_move_gripper.py", [sim.host], handlers.handlers(), 120)
        return {"result": result, "seen": handlers.seen}


def _check(r: dict[str, Any], width: float) -> None:
    assert r["width_homed"] == pytest.approx(FRANKA_HAND.max_width, abs=1e-3)
    assert r["printed"][-1] == "Grasped object, will release it now.", r["printed"]
    assert r["exit"] == 0
    assert r["is_grasped"] is True
    assert width - 0.005 <= r["width_held"] <= width + 0.005
    assert 0.0 <= r["width_held"] <= r["max_width"]
    assert r["stop"] is True


def test_the_example_with_its_defaults_keeps_the_grasp(run: dict[str, Any]) -> None:
    """Nothing between the fingers: they close to 0 mm, within 5 +- 5 mm, and stay there."""
    r = scenario(run["result"], "defaults")
    _check(r, 0.005)
    assert r["width_held"] < 0.001


def test_the_example_holds_the_cube(run: dict[str, Any]) -> None:
    r = scenario(run["result"], "cube")
    _check(r, 0.04)
    assert r["width_held"] > 0.0395  # the pads do not sink into the cube
    # the cube stayed where it was grasped (the arm did not move)
    before, after = run["seen"]["cube_before"], run["seen"]["cube_after"]
    assert max(abs(a - b) for a, b in zip(before, after, strict=True)) < 0.005
