"""One FCI client's session: Connect (where a connection is accepted as the robot's
client), the TCP commands (Move starts in :meth:`RobotCore.request_move`), the Move's
final answer, and the UDP states and commands of the 1 kHz exchange."""

from __future__ import annotations

import logging
import selectors
import socket
import time
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import (
    Command,
    ConnectStatus,
    GetterSetterStatus,
    MoveStatus,
    ProtocolError,
    RobotMode,
)
from panda_py.sim.config import DATAGRAMS_PER_PASS, LATE_THRESHOLD
from panda_py.sim.connections import RobotConnection
from panda_py.sim.desk.link import accept_fci_connect, may_start_move
from panda_py.sim.parts import ServerState
from panda_py.sim.wire import CommandWire, StateWire

log = logging.getLogger("panda_py.sim")


class FciSession(ServerState):
    """The robot side of the FCI protocol for the connected client."""

    def _handle_robot_message(self, conn: RobotConnection, msg: fci.Message) -> None:
        if conn.dialect is None:
            self._handle_connect(conn, msg)
            return
        d = conn.dialect
        command = d.command_for_id(msg.command)
        if command is None or command is Command.CONNECT:
            log.warning(
                "unknown command id %d (protocol v%d) from %s:%d",
                msg.command,
                d.version,
                *conn.addr,
            )
            # Answer with the generic "command not possible" so a waiting client fails fast.
            self._send_tcp(conn, fci.HEADER.pack(msg.command, msg.command_id, 13) + b"\x01")
            return
        try:
            fields = d.decode_request(command, msg.payload)
        except ProtocolError as exc:
            log.warning("malformed %s request: %s", command.value, exc)
            self._reply_invalid(conn, command, msg.command_id)
            return
        handler = getattr(self, f"_cmd_{command.name.lower()}")
        handler(conn, command, msg.command_id, fields)

    def _reply(
        self, conn: RobotConnection, command: Command, cid: int, status: Any, **extra: Any
    ) -> None:
        assert conn.dialect is not None
        self._send_tcp(conn, conn.dialect.encode_response(command, cid, status, **extra))

    def _reply_invalid(self, conn: RobotConnection, command: Command, cid: int) -> None:
        assert conn.dialect is not None
        status_type = conn.dialect.status_type(command)
        for name in ("INVALID_ARGUMENT_REJECTED", "COMMAND_NOT_POSSIBLE_REJECTED", "ERROR"):
            if hasattr(status_type, name):
                self._reply(conn, command, cid, getattr(status_type, name))
                return

    def _admit(self, version: int) -> tuple[ConnectStatus, int]:
        """Whether the robot takes a client speaking protocol ``version``: the one place
        where a Connect is accepted or refused -> (status, the version to answer with).
        (A second client never gets here: it hears ROBOT_BUSY from the sockets part.)"""
        accepted = self.config.accepted_versions
        if version not in accepted:
            # negotiation, not a fault: our client (and panda-py) then reconnect with it
            log.info("client speaks protocol v%d; this robot speaks %s", version, list(accepted))
            return ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION, accepted[-1]
        return ConnectStatus.SUCCESS, version

    def _handle_connect(self, conn: RobotConnection, msg: fci.Message) -> None:
        try:
            _, version, udp_port = fci.decode_connect_request(msg.raw)
        except ProtocolError as exc:
            log.warning("closing connection from %s:%d: expected Connect: %s", *conn.addr, exc)
            self._close_conn(conn)
            return
        status, answer = self._admit(version)
        if status != ConnectStatus.SUCCESS:
            self._send_tcp(conn, fci.encode_connect_response(msg.command_id, status, answer))
            return
        d = fci.dialect(version)
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind((self.config.host, 0))
        udp.setblocking(False)
        conn.udp = udp
        conn.udp_target = (conn.addr[0], udp_port)
        conn.dialect = d
        conn.state_wire = StateWire(d, self.core)
        conn.command_wire = CommandWire(d)
        if self.config.lockstep:  # it waits for the command: woken by its arrival
            self._sel.register(udp, selectors.EVENT_READ, ("robot-udp", conn))
        # on the clock, the tick reads the commands that arrived (_tick): one wake-up a
        # tick instead of two, which is most of an idle simulator's CPU
        self._send_tcp(
            conn, fci.encode_connect_response(msg.command_id, ConnectStatus.SUCCESS, version)
        )
        log.info(
            "FCI client speaks protocol v%d; streaming states to %s:%d", version, *conn.udp_target
        )
        self._send_state(conn)  # clients block for a first state right after Connect

    def _cmd_move(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        assert conn.dialect is not None
        if not may_start_move(self.desk):  # the brakes are closed
            self._reply(conn, command, cid, MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED)
            return
        deviations = np.concatenate((f["maximum_path_deviation"], f["maximum_goal_pose_deviation"]))
        status = self.core.request_move(
            f["controller_mode"],
            f["motion_generator_mode"],
            deviations,
            has_none=conn.dialect.has_motion_generator_none,
            use_async=bool(f.get("use_async_motion_generator", False)),
            maximum_velocity=f.get("maximum_velocity"),
        )
        self._reply(conn, command, cid, status)
        if status == MoveStatus.MOTION_STARTED:
            conn.move_id = cid
            conn.awaiting = False
            conn.command = None

    def _follow_desk(self) -> None:
        """The Desk's switches act on a running session as on a robot: brakes that close
        (a lock, a safety error) end a running motion, and an FCI switched off ends the
        motion and, a tick later (once a state has told the client), closes the FCI
        connection. Three loads a tick; the gripper's server is not the FCI's and keeps its
        client. Between motions, the arm is driven where the Desk asks (the pack pose)."""
        desk, conn, core = self.desk, self.robot_conn, self.core
        if desk is None:
            return
        fci_on = accept_fci_connect(desk)
        if core.robot_mode != RobotMode.MOVE:  # a new end-effector configuration
            update = desk.end_effector_update(self.desk_ee)
            if update is not None:
                self.desk_ee = update[0]
                core.configure_end_effector(*update[1:])
        request = desk.move_request()
        if request is not None:
            # The Desk moves the arm (the pack pose) between motions, on a path of the
            # robot's own; its request is done once the drive ended (there, or stopped)
            if self.desk_move != request[0]:
                if core.robot_mode != RobotMode.MOVE:
                    core.drive_to(request[1])
                    self.desk_move = request[0]
            elif not core.driving:
                desk.move_finished(request[0])
        if core.robot_mode == RobotMode.MOVE and not (fci_on and may_start_move(desk)):
            version = conn.dialect.version if conn is not None and conn.dialect else 0
            # v6 added the status for "preempted due to activated safety functions"
            # (libfranka's MoveStatus); older robots answer a plain abort.
            status = (
                MoveStatus.PREEMPTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS
                if version >= 6
                else MoveStatus.ABORTED
            )
            log.warning("motion stopped by an activated safety function (%s)", status.value)
            core.safety_stop(status)
            if conn is not None and core.pending_final is not None:
                self._send_move_final(conn, core.pending_final)
            return  # this tick's state shows the motion ended; the client reads why first
        if conn is not None and not fci_on:
            log.warning("the FCI was deactivated: closing the connection from %s:%d", *conn.addr)
            self._close_conn(conn)

    def _send_move_final(self, conn: RobotConnection, status: MoveStatus) -> None:
        self.core.pending_final = None
        if conn.move_id is not None:
            self._reply(conn, Command.MOVE, conn.move_id, status)
        conn.move_id = None
        conn.awaiting = False

    def _cmd_stop_move(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        status = self.core.request_stop_move()
        if self.core.pending_final is not None and self.robot_conn is conn:
            self._send_move_final(conn, self.core.pending_final)
        self._reply(conn, command, cid, status)

    def _cmd_automatic_error_recovery(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.request_recovery())

    def _cmd_set_collision_behavior(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_collision_behavior(f))

    def _cmd_set_joint_impedance(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_joint_impedance(f["K_theta"]))

    def _cmd_set_cartesian_impedance(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_cartesian_impedance(f["K_x"]))

    def _cmd_set_guiding_mode(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(
            conn, command, cid, self.core.set_guiding_mode(f["guiding_mode"], f["nullspace"])
        )

    def _cmd_set_ee_to_k(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_ee_to_k(f["EE_T_K"]))

    def _cmd_set_ne_to_ee(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_ne_to_ee(f["NE_T_EE"]))

    def _cmd_set_f_to_ee(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_f_to_ee(f["F_T_EE"]))

    def _cmd_set_load(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(
            conn, command, cid, self.core.set_load(f["m_load"], f["F_x_Cload"], f["I_load"])
        )

    def _cmd_set_filters(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(
            conn, command, cid, self.core.set_filters(np.array(list(f.values()), dtype=float))
        )

    def _cmd_get_cartesian_limit(
        self, conn: RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        # No virtual walls are configured on the simulated robot.
        self._reply(conn, command, cid, GetterSetterStatus.SUCCESS, object_world_size=np.zeros(3),
                    object_frame=np.eye(4).reshape(16), object_activation=False)  # fmt: skip

    def _read_robot_udp(self, conn: RobotConnection) -> None:
        wire, udp = conn.command_wire, conn.udp
        if udp is None or wire is None:
            return
        for _ in range(DATAGRAMS_PER_PASS):
            try:
                size, mid = wire.receive(udp, conn.udp_target)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return  # e.g. ICMP port unreachable from a vanished client
            self._take_datagram(conn, size, mid)

    def _take_datagram(self, conn: RobotConnection, size: int, mid: int) -> None:
        """The command datagram just received (``size`` bytes, its message id, -1: not a
        command from the client): the connection's command if it answers the newest
        state, else dropped (counted if bad)."""
        wire = conn.command_wire
        assert wire is not None
        if mid < 0 or mid > conn.last_sent_id:
            # wrong size, not from the client, or answering a state never sent
            self.stats.bad_datagrams += 1
            if self.stats.bad_datagrams <= 3 or self.stats.bad_datagrams % 1000 == 0:
                log.warning(
                    "dropping a %d-byte command datagram (protocol v%d expects %d from "
                    "%s:%d, answering a state sent)",
                    size,
                    conn.dialect.version if conn.dialect else 0,
                    wire.size,
                    *(conn.udp_target or ("?", 0)),
                )
            return
        if self.drop_commands > 0:
            self.drop_commands -= 1
            return
        if mid < conn.last_sent_id and self.core.async_gen is None:
            return  # late: answers a state older than the newest one sent
        # (an asynchronous motion's commands are targets, whatever state they answer)
        conn.command = wire.accept(mid)

    def _send_state(self, conn: RobotConnection) -> None:
        wire = conn.state_wire
        if wire is None or conn.udp is None or conn.udp_target is None:
            return
        core = self.core
        moving = core.robot_mode == RobotMode.MOVE
        mid = self.tick_count + 1  # ms since power-up; never 0, strictly increasing
        data = wire.fill(mid, core.success_rate if moving else 0.0)
        try:
            conn.udp.sendto(data, conn.udp_target)
        except OSError:
            pass  # the client's socket is gone; the TCP side will tell
        conn.state_late = time.monotonic() - self._tick_deadline > LATE_THRESHOLD
        conn.last_sent_id = mid
        # libfranka answers states only once its control loop runs: it skips the state that
        # first shows the motion's modes. Await commands (lockstep) once one has arrived.
        # An asynchronous motion's client sends targets at its own rate: nothing awaited.
        conn.awaiting = moving and not core.first_command and core.async_gen is None

    def _spin_for_command(self, conn: RobotConnection) -> None:
        """Lockstep: poll the command socket for up to ``lockstep_spin`` (the client's
        answer usually comes within it), keeping this core's caches warm."""
        end = time.monotonic() + self.config.lockstep_spin
        read = self._read_robot_udp
        while conn.command is None and conn.udp is not None and time.monotonic() < end:
            read(conn)


__all__ = ["FciSession"]
