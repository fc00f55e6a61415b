"""The simulated Desk: the robot's web interface (both APIs, WSS, a page), coupled to the
simulated FCI through :mod:`panda_py.sim.desk.link`."""

from panda_py.sim.desk.link import DeskLink, accept_fci_connect, may_start_move
from panda_py.sim.desk.process import (
    DEFAULT_PASSWORD,
    DEFAULT_USER,
    DeskConfig,
    DeskProcess,
    DeskStartError,
)

__all__ = [
    "DEFAULT_PASSWORD",
    "DEFAULT_USER",
    "DeskConfig",
    "DeskLink",
    "DeskProcess",
    "DeskStartError",
    "accept_fci_connect",
    "may_start_move",
]
