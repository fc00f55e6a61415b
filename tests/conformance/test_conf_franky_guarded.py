"""Conformance: franky 2.0.0's guarded stop onto the table, ``Reaction(Measure.FORCE_Z <
-5.0, CartesianStopMotion())`` on a motion down at 5 cm/s, with the 60 N / 60 Nm
collision thresholds of a contact task: the reaction, not the robot's reflex, ends it.

The speed is the approach's own ``relative_dynamics_factor`` (the robot's at 1) and the
stop motion brakes at 0.3 of the robot's dynamics. franky's README sets the speed
robot-wide instead, which slows its stop motion as much: at 5 cm/s the commanded pose
then runs on about 3 mm into the table after the reaction fires, the robot's joint
impedance pushes it there with well over 60 N and the reflex ends the move, on this
simulator as reported on a Panda (TimSchneider42/franky#43). benchmarks/bench_contact.py
measures both."""

from __future__ import annotations

import numpy as np
import pytest
from conf_support import PEER_TEST_TIMEOUT, peer_or_skip, run_peer, scenario

import panda_py
from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]

SPEED = 0.05  # [m/s] the approach
BRAKING = 0.3  # the stop motion's relative dynamics factor (full: joint jerk reflexes)
THRESHOLD = 60.0  # [N] the script's collision thresholds
ABOVE_TABLE = (0.45, 0.25, 0.06)  # [m] the end effector 6 cm above the table


def test_frankys_guarded_stop_ends_on_the_table_without_a_reflex() -> None:
    python = peer_or_skip("franky")
    with Simulator(host=free_loopback_host(), robot="fr3", lockstep=True, versions=(10,)) as sim:
        pose = panda_py.fk(np.array(START_POSE))
        pose[:3, 3] = ABOVE_TABLE
        q = panda_py.ik(pose, np.array(START_POSE)).tolist()

        def place(_: object) -> None:
            sim.set_joint_positions(q)

        out = run_peer(python, "franky_guarded.py", [sim.host, str(BRAKING), str(SPEED)],
                       {"place": place}, timeout=120)  # fmt: skip
    result = scenario(out, f"approach {SPEED}")
    assert result["error"] is None, result
    assert not result["has_errors"], result
    assert result["fired"], f"the reaction never fired: {result}"
    assert result["descent"] > 0.9 * SPEED, result  # it met the table at the speed asked
    assert 5.0 < result["peak"] < THRESHOLD, result
