"""The vacuum gripper client's session (TCP 1339, the Cobot Pump's protocol v1): its
Connect, Vacuum/DropOff/Stop answered when the pump is done, and the pump's state
datagrams.

The state rate: neither libfranka's sources nor its documentation give the pump's, so
it sends at the hand's 100 Hz (:data:`~panda_py.sim.gripper_session.GRIPPER_STATE_PERIOD`),
a judgement; libfranka's ``readOnce`` waits for the next one either way.
"""

from __future__ import annotations

import logging
import selectors
import socket

import numpy as np

from panda_py import fci
from panda_py.fci import ProtocolError
from panda_py.fci import vacuum as vp
from panda_py.sim.connections import VacuumConnection
from panda_py.sim.gripper_session import GRIPPER_STATE_PERIOD
from panda_py.sim.parts import ServerState

log = logging.getLogger("panda_py.sim")

VACUUM_STATE_PERIOD = GRIPPER_STATE_PERIOD  # [ticks] 100 Hz


class VacuumSession(ServerState):
    """The Cobot Pump's side of the vacuum gripper protocol."""

    def _vacuum_reply(
        self, conn: VacuumConnection, command: int, cid: int, status: vp.VacuumStatus
    ) -> None:
        payload = vp.VACUUM_RESPONSE.encode(status=int(status))
        self._send_tcp(conn, vp.encode_vacuum_message(vp.VacuumCommand(command), cid, payload))

    def _handle_vacuum_message(self, conn: VacuumConnection, msg: fci.Message) -> None:
        pump = self.pump
        if pump is None:
            return
        if not conn.connected:
            self._connect_vacuum(conn, msg)
            return
        try:
            command = vp.VacuumCommand(msg.command)
            f = vp.VACUUM_REQUESTS[command].decode(msg.payload)
        except (ValueError, KeyError, ProtocolError) as exc:
            log.warning("bad vacuum request %d: %s", msg.command, exc)
            self._send_tcp(
                conn,
                vp.VACUUM_HEADER.pack(msg.command, msg.command_id, 12)
                + int(vp.VacuumStatus.FAIL).to_bytes(2, "little"),
            )
            return
        self._gripper_pending[msg.command_id] = int(command)
        status: vp.VacuumStatus | None
        if command is vp.VacuumCommand.VACUUM:
            status = pump.vacuum_on(
                msg.command_id, int(f["vacuum"]), int(f["timeout"]), int(f["profile"])
            )
        elif command is vp.VacuumCommand.DROP_OFF:
            status = pump.drop_off(msg.command_id, int(f["timeout"]))
        elif command is vp.VacuumCommand.STOP:
            status = pump.stop()
        else:  # a second Connect
            status = vp.VacuumStatus.FAIL
        self._flush_vacuum()
        if status is not None:
            self._gripper_pending.pop(msg.command_id, None)
            self._vacuum_reply(conn, int(command), msg.command_id, status)

    def _connect_vacuum(self, conn: VacuumConnection, msg: fci.Message) -> None:
        """Connect: the pump's layout is the hand's, with the pump's version."""
        try:
            _, version, udp_port = fci.decode_gripper_connect_request(msg.raw)
        except ProtocolError as exc:
            log.warning("closing vacuum gripper connection: expected Connect: %s", exc)
            self._close_conn(conn)
            return
        if version != vp.VACUUM_VERSION:
            log.warning(
                "vacuum gripper client speaks v%d; the pump speaks v%d", version, vp.VACUUM_VERSION
            )
            self._send_tcp(
                conn,
                fci.encode_gripper_connect_response(
                    msg.command_id,
                    fci.GripperConnectStatus.INCOMPATIBLE_LIBRARY_VERSION,
                    version=vp.VACUUM_VERSION,
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
                msg.command_id, fci.GripperConnectStatus.SUCCESS, version=vp.VACUUM_VERSION
            ),
        )
        self._send_vacuum_state(conn)

    def _flush_vacuum(self) -> None:
        """Answer the commands the pump finished; a state every period."""
        pump, conn = self.pump, self.gripper_conn
        if pump is None:
            return
        done, pump.completed = pump.completed, []
        if not isinstance(conn, VacuumConnection):
            return
        for cid, status in done:
            command = self._gripper_pending.pop(cid, int(vp.VacuumCommand.VACUUM))
            self._vacuum_reply(conn, command, cid, status)
        if self.tick_count % VACUUM_STATE_PERIOD == 0:
            self._send_vacuum_state(conn)

    def _send_vacuum_state(self, conn: VacuumConnection) -> None:
        pump = self.pump
        if pump is None or conn.udp is None or conn.udp_target is None:
            return
        rec = np.zeros((), vp.VACUUM_STATE_DTYPE)
        rec["message_id"] = self.tick_count & 0xFFFFFFFF
        rec["in_control_range"] = pump.in_control_range
        rec["part_detached"] = pump.part_detached
        rec["part_present"] = pump.part_present
        rec["device_status"] = int(vp.VacuumDeviceStatus.GREEN)
        rec["actual_power"] = pump.actual_power
        rec["vacuum"] = int(pump.vacuum)  # whole mbar, as the pump reads it
        try:
            conn.udp.sendto(vp.encode_vacuum_state(rec), conn.udp_target)
        except OSError:
            pass


__all__ = ["VACUUM_STATE_PERIOD", "VacuumSession"]
