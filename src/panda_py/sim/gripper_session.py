"""The gripper client's session: its Connect, Homing/Grasp/Move/Stop answered when
the hand is done, and the hand's state datagrams at 100 Hz."""

from __future__ import annotations

import logging
import selectors
import socket

import numpy as np

from panda_py import fci
from panda_py.fci import (
    GripperCommand,
    GripperStatus,
    ProtocolError,
)
from panda_py.sim.connections import GripperConnection
from panda_py.sim.parts import ServerState

log = logging.getLogger("panda_py.sim")


GRIPPER_STATE_PERIOD = 10  # [ticks] gripper state datagrams at 100 Hz


class GripperSession(ServerState):
    """The Franka Hand's side of the gripper protocol."""

    def _gripper_reply(
        self, conn: GripperConnection, command: int, cid: int, status: GripperStatus
    ) -> None:
        payload = fci.GRIPPER_RESPONSE.encode(status=int(status))
        self._send_tcp(conn, fci.encode_gripper_message(GripperCommand(command), cid, payload))

    def _handle_gripper_message(self, conn: GripperConnection, msg: fci.Message) -> None:
        g = self.gripper
        if g is None:
            return
        if not conn.connected:
            try:
                _, version, udp_port = fci.decode_gripper_connect_request(msg.raw)
            except ProtocolError as exc:
                log.warning("closing gripper connection: expected Connect: %s", exc)
                self._close_conn(conn)
                return
            if version != fci.GRIPPER_VERSION:
                log.warning(
                    "gripper client speaks v%d; the hand speaks v%d", version, fci.GRIPPER_VERSION
                )
                self._send_tcp(
                    conn,
                    fci.encode_gripper_connect_response(
                        msg.command_id,
                        fci.GripperConnectStatus.INCOMPATIBLE_LIBRARY_VERSION,
                    ),
                )
                return
            udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            udp.bind((self.config.host, 0))
            udp.setblocking(False)
            conn.udp, conn.udp_target, conn.connected = udp, (conn.addr[0], udp_port), True
            self._sel.register(udp, selectors.EVENT_READ, ("gripper-udp", conn))
            self._send_tcp(
                conn,
                fci.encode_gripper_connect_response(
                    msg.command_id, fci.GripperConnectStatus.SUCCESS
                ),
            )
            self._send_gripper_state(conn)
            return
        try:
            command = GripperCommand(msg.command)
            codec = fci.GRIPPER_REQUESTS[command]
            f = codec.decode(msg.payload)
        except (ValueError, KeyError, ProtocolError) as exc:
            log.warning("bad gripper request %d: %s", msg.command, exc)
            self._send_tcp(
                conn,
                fci.gripper.GRIPPER_HEADER.pack(msg.command, msg.command_id, 12)
                + int(GripperStatus.FAIL).to_bytes(2, "little"),
            )
            return
        self._gripper_pending[msg.command_id] = int(command)
        status: GripperStatus | None
        if command is GripperCommand.HOMING:
            g.homing(msg.command_id)
            status = None
        elif command is GripperCommand.MOVE:
            status = g.move(msg.command_id, f["width"], f["speed"])
        elif command is GripperCommand.GRASP:
            status = g.grasp_object(
                msg.command_id,
                f["width"],
                f["epsilon_inner"],
                f["epsilon_outer"],
                f["speed"],
                f["force"],
            )
        elif command is GripperCommand.STOP:
            status = g.stop()
        else:
            status = GripperStatus.FAIL
        self._flush_gripper()
        if status is not None:
            self._gripper_pending.pop(msg.command_id, None)
            self._gripper_reply(conn, int(command), msg.command_id, status)

    def _flush_gripper(self) -> None:
        conn, g = self.gripper_conn, self.gripper
        if g is None:
            return
        done, g.completed = g.completed, []
        if conn is None:
            return
        for cid, status in done:
            command = self._gripper_pending.pop(cid, int(GripperCommand.MOVE))
            self._gripper_reply(conn, command, cid, status)
        if self.tick_count % GRIPPER_STATE_PERIOD == 0:
            self._send_gripper_state(conn)

    def _send_gripper_state(self, conn: GripperConnection) -> None:
        g = self.gripper
        if g is None or conn.udp is None or conn.udp_target is None:
            return
        rec = np.zeros((), fci.GRIPPER_STATE_DTYPE)
        rec["message_id"] = self.tick_count & 0xFFFFFFFF
        rec["width"] = g.width
        rec["max_width"] = g.max_width
        rec["is_grasped"] = g.is_grasped
        rec["temperature"] = g.temperature
        try:
            conn.udp.sendto(rec.tobytes(), conn.udp_target)
        except OSError:
            pass


__all__ = ["GripperSession"]
