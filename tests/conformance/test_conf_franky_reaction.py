"""Conformance: franky 2.0.0's documented force reaction against the simulator. A motion
down onto the table with ``Reaction(Measure.FORCE_Z < -5.0, CartesianStopMotion())``
fires at the contact and stops the arm there: it works only if the simulator publishes
O_F_ext_hat_K with libfranka's sign (the robot's force on the environment; pressing down
reads negative). With the opposite sign it never fires and the motion ends in a reflex.
(The README sets the dynamics factor robot-wide, which slows the stop motion as much: the
commanded pose runs on into the table after the reaction fires and the robot presses
there, so the script raises the collision thresholds, as test_conf_franky_guarded
explains; the force at the firing tick is reported, not held to 5 N.)"""

from __future__ import annotations

import numpy as np
import pytest
from conf_support import PEER_TEST_TIMEOUT, peer_or_skip, run_peer, scenario

import panda_py
from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]


def test_force_reaction_stops_the_motion_at_the_table() -> None:
    python = peer_or_skip("franky")
    with Simulator(host=free_loopback_host(), robot="fr3", lockstep=True, versions=(10,)) as sim:
        pose = panda_py.fk(np.array(START_POSE))
        pose[:3, 3] = (0.45, 0.25, 0.04)  # 4 cm above the table, away from the cube
        sim.set_joint_positions(panda_py.ik(pose, np.array(START_POSE)).tolist())
        out = run_peer(python, "franky_reaction.py", [sim.host], timeout=90)
    result = scenario(out, "press_down")
    assert result["error"] is None, result
    assert result["fired"], f"the reaction never fired: {result}"
    assert result["fired"][0][2] < -5.0
    assert not result["has_errors"]
    # stopped at the table (its end effector's tip 4 cm below the start), not 10 cm down
    assert result["z_start"] - result["z_end"] < 0.06, result
    assert abs(result["O_F_ext_hat_K"][2]) < 100.0  # the reflex did not end it
