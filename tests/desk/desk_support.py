"""Helpers of the Desk tests: a simulated robot with a Desk on a free loopback address and
a free high port (or a given one), its certificate in a given directory."""

from __future__ import annotations

from pathlib import Path

from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.desk import DeskConfig

FORCE_TIMEOUT = 1.5  # [s] the simulated Desks' tokenForceTimeout in these tests


def desk_sim(
    robot: str, cert_dir: Path, *, locked: bool = True, host: str | None = None, port: int = 0
) -> Simulator:
    config = DeskConfig(
        port=port, locked=locked, cert_dir=str(cert_dir), token_force_timeout=FORCE_TIMEOUT
    )
    return Simulator(host or free_loopback_host(), robot=robot, lockstep=True, desk=config)
