"""Conformance: ``print(state)`` of ours is panda-python 1.1.1's (libfranka 0.9.2's
``operator<<``) character for character, on the same simulated robot (the tick aside)."""

from __future__ import annotations

import re
import subprocess

import pytest
from conf_support import PEER_TEST_TIMEOUT, peer_or_skip

from panda_py import libfranka
from panda_py.sim import Simulator, free_loopback_host

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]
PRINT = (
    "import sys; from panda_py import libfranka; print(libfranka.Robot(sys.argv[1]).read_once())"
)


def _untimed(text: str) -> str:
    return re.sub(r'"time": \d+', '"time": T', text.strip())


def test_state_prints_as_panda_pythons() -> None:
    python = peer_or_skip("panda-python")
    with Simulator(host=free_loopback_host(), robot="fer", lockstep=True, versions=(5,)) as sim:
        with libfranka.Robot(sim.host) as robot:
            ours = str(robot.read_once())
        theirs = subprocess.run(
            [str(python), "-c", PRINT, sim.host], capture_output=True, text=True, timeout=60
        ).stdout
    assert _untimed(ours) == _untimed(theirs)
