"""What every part of the simulator's server shares: :class:`ServerState` declares the
state the loop owns and the methods one part calls on another, so each part (sockets,
FCI session, gripper and vacuum sessions, model delivery, control RPC) lives in its own
module and
:class:`~panda_py.sim.server.SimServer` is their sum."""

from __future__ import annotations

import selectors
import socket
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

from panda_py import fci
from panda_py.fci import Command
from panda_py.robots.params import RobotSpec
from panda_py.sim.config import SimConfig, Stats
from panda_py.sim.connections import Client, GripperConnection, RobotConnection
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import Physics
from panda_py.sim.robot import RobotCore
from panda_py.sim.vacuum import VacuumCore


class ServerState:
    """Attributes of the one-threaded server; set up by ``SimServer.__init__``."""

    config: SimConfig
    spec: RobotSpec
    physics: Physics
    core: RobotCore
    # The end effector: the hand (``gripper``) or the Cobot Pump (``pump``), the other None.
    gripper: GripperCore | None
    pump: VacuumCore | None
    desk: Any  # DeskLink | None: the simulated Desk's state (brakes, FCI)
    desk_move: float  # the Desk's move request being driven (0: none yet)
    desk_ee: float  # the Desk's end-effector configuration applied (0: the mounted one's)
    stats: Stats
    tick_count: int
    drop_commands: int
    robot_conn: RobotConnection | None
    # The end effector's client: the hand's (TCP 1338), or the pump's (a VacuumConnection,
    # TCP 1339); one at a time, like the robot's.
    gripper_conn: GripperConnection | None
    _running: bool
    _sel: selectors.BaseSelector
    _robot_listener: socket.socket
    _gripper_listener: socket.socket  # the end effector's port (1338 or 1339)
    _refusing: list[Client]
    _control: Any
    _gripper_pending: dict[int, int]  # command_id -> the end effector's command
    _budget: float
    _tick_deadline: float
    _next_check: float
    _models: ThreadPoolExecutor
    _urdf: Future[bytes | str]
    _libraries: dict[tuple[int, int], Future[bytes | str]]
    _model_requests: list[tuple[RobotConnection, Command, int, Future[bytes | str]]]

    if TYPE_CHECKING:  # provided by the parts, called across them

        def _send_tcp(self, conn: Client, data: bytes) -> None: ...
        def _drop(self, conn: Client, reason: str) -> None: ...
        def _close_conn(self, conn: Client) -> None: ...
        def _handle_robot_message(self, conn: RobotConnection, msg: fci.Message) -> None: ...
        def _handle_gripper_message(self, conn: GripperConnection, msg: fci.Message) -> None: ...
        def _handle_vacuum_message(self, conn: Any, msg: fci.Message) -> None: ...
        def _reply(
            self, conn: RobotConnection, command: Command, cid: int, status: Any, **extra: Any
        ) -> None: ...
        def _answer_models(self) -> None: ...
        def _read_robot_udp(self, conn: RobotConnection) -> None: ...


__all__ = ["ServerState"]
