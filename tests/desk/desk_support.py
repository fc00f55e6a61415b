"""Helpers of the Desk tests: a simulated robot with a Desk on a free loopback address and
a free high port (or a given one), its certificate in a given directory."""

from __future__ import annotations

import threading
import time
from pathlib import Path

from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.desk import DeskConfig

FORCE_TIMEOUT = 1.5  # [s] the simulated Desks' tokenForceTimeout in these tests
HEADER_TIMEOUT = 1.0  # [s] their patience with a slow request head
SELF_TEST_DURATION = 0.3  # [s] their safety self-test


def desk_sim(
    robot: str, cert_dir: Path, *, locked: bool = True, host: str | None = None, port: int = 0
) -> Simulator:
    config = DeskConfig(
        port=port,
        locked=locked,
        cert_dir=str(cert_dir),
        token_force_timeout=FORCE_TIMEOUT,
        header_timeout=HEADER_TIMEOUT,
        self_test_duration=SELF_TEST_DURATION,
    )
    return Simulator(host or free_loopback_host(), robot=robot, lockstep=True, desk=config)


def press_when_requested(sim: Simulator, button: str) -> threading.Thread:
    """A thread pressing ``button`` on the Pilot once a take of control waits for it
    (a person at the robot confirming it), within 10 s."""

    def run() -> None:
        assert sim.desk is not None
        deadline = time.monotonic() + 10
        while sim.desk.status()["pendingControlRequests"] == 0:
            if time.monotonic() > deadline:
                return
            time.sleep(0.02)
        sim.press_pilot_button(button)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread
