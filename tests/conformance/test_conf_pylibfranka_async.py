"""Conformance: pylibfranka 0.21.3's asynchronous position control
(``AsyncPositionControlHandler``, protocol v10's robot-side motion generator), unmodified,
against a simulated FR3: the behaviour its example program documents (targets at 50 Hz,
flipping every second, stop after ten seconds) and a reflex surfacing in its feedback."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest
from conf_support import PEER_TEST_TIMEOUT, peer_or_skip, run_peer, scenario

from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]

DURATION = 10.0  # [s] of the example's loop time
SWING = 0.25  # [rad] the example's target offset on every joint


@pytest.fixture(scope="module")
def run() -> dict[str, Any]:
    python = peer_or_skip("pylibfranka")
    # realtime: the example paces itself on the wall clock, the robot's generator too
    with Simulator(host=free_loopback_host(), robot="fr3", lockstep=False, versions=(10,)) as sim:
        sim.set_joint_positions(START_POSE)  # the example's initial position
        flips: list[dict[str, Any]] = []

        def flip(direction: float) -> None:
            s = sim.state()
            flips.append({"direction": direction, "q_d": s["q_d"].copy(), "q": s["q"].copy()})

        def reflex(_: Any) -> None:
            sim.inject_reflex("joint_reflex")

        result = run_peer(
            python,
            "plf_async.py",
            [sim.host, str(DURATION)],
            {"flip": flip, "reflex": reflex},
            timeout=DURATION + 60,
        )
        return {"result": result, "flips": flips, "final": sim.state()}


def test_example_loop_runs_to_its_end_without_errors(run: dict[str, Any]) -> None:
    r = scenario(run["result"], "example_loop")
    assert "configure_error" not in r, r
    assert r["feedback_errors"] == [] and r["command_errors"] == []
    assert r["unsuccessful"] == 0
    assert r["iterations"] >= DURATION / 0.020
    # stop_control finished the motion: the robot is idle, error-free and at rest
    assert r["mode_after_stop"] == "Idle"
    assert r["errors_after_stop"] is False
    assert np.abs(r["dq_after_stop"]).max() < 0.05


def test_the_arm_swings_between_the_targets(run: dict[str, Any]) -> None:
    flips = run["flips"]
    assert len(flips) >= DURATION - 1  # one a second
    q0 = np.array(START_POSE)
    first = flips[0]
    assert first["direction"] == 1.0
    # a second from rest is ample for 0.25 rad at 0.655 rad/s: there, and the arm tracks
    np.testing.assert_allclose(first["q_d"], q0 + SWING, atol=2e-3)
    np.testing.assert_allclose(first["q"], q0 + SWING, atol=5e-3)
    for before, f in itertools.pairwise(flips):
        assert f["direction"] == -before["direction"]
        # well past the middle on the commanded side, never beyond the target
        offset = f["direction"] * (f["q_d"] - q0)
        assert (offset > 0.2).all(), offset
        assert (offset < SWING + 1e-3).all(), offset


def test_reflex_surfaces_in_the_feedback(run: dict[str, Any]) -> None:
    r = scenario(run["result"], "reflex_surfaces")
    assert "configure_error" not in r, r
    assert r["before"] is None
    assert r["sent"] is True
    assert r["message"] is not None and "reflex" in r["message"].lower(), r["message"]
    assert r["mode_after_recovery"] == "Idle"
