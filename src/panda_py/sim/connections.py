"""The simulator's view of its TCP clients: the socket, the unread answers, the parsed
but unhandled requests and, for the FCI, gripper and vacuum gripper sessions, their UDP
side."""

from __future__ import annotations

import selectors
import socket
import time
from collections import deque
from typing import Any

from panda_py import fci
from panda_py.fci import vacuum as vp
from panda_py.sim.command import Command as RobotCommand
from panda_py.sim.wire import CommandWire, StateWire


class Client:
    """What every TCP client has: its socket, its unread answers (``out``), its parsed
    but unhandled requests (``backlog``) and when it connected."""

    def __init__(self, sock: socket.socket, addr: tuple[str, int], reader: Any) -> None:
        self.sock = sock
        self.addr = addr
        self.reader = reader
        self.out = bytearray()
        self.events = selectors.EVENT_READ  # what the selector watches for (0: nothing)
        self.backlog: deque[fci.Message] = deque()
        self.opened = time.monotonic()
        self.closed = False
        self.udp: socket.socket | None = None


class RobotConnection(Client):
    def __init__(self, sock: socket.socket, addr: tuple[str, int]) -> None:
        super().__init__(sock, addr, fci.RobotMessageReader(max_size=fci.MAX_REQUEST_SIZE))
        self.dialect: fci.Dialect | None = None
        self.udp: socket.socket | None = None
        self.udp_target: tuple[str, int] | None = None
        self.state_wire: StateWire | None = None
        self.command_wire: CommandWire | None = None
        self.move_id: int | None = None
        self.last_sent_id = -1
        self.command: RobotCommand | None = None  # newest fresh command since last tick
        self.state_late = False  # the last state went out late (realtime fairness)
        self.awaiting = False  # lockstep: a command for the last state is expected


class GripperConnection(Client):
    def __init__(self, sock: socket.socket, addr: tuple[str, int]) -> None:
        super().__init__(
            sock, addr, fci.GripperMessageReader(max_size=fci.GRIPPER_MAX_REQUEST_SIZE)
        )
        self.connected = False
        self.udp: socket.socket | None = None
        self.udp_target: tuple[str, int] | None = None


class VacuumConnection(GripperConnection):
    """A Cobot Pump client: the hand's framing, the pump's requests."""

    def __init__(self, sock: socket.socket, addr: tuple[str, int]) -> None:
        super().__init__(sock, addr)
        self.reader = fci.GripperMessageReader(max_size=vp.VACUUM_MAX_REQUEST_SIZE)


__all__ = ["Client", "GripperConnection", "RobotConnection", "VacuumConnection"]
