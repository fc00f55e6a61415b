"""One robot connection: Connect handshake, numbered TCP requests, newest-state reception
and status-to-exception translation (libfranka's ``Robot::Impl`` plumbing)."""

from __future__ import annotations

import threading
from enum import Enum
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import Command, ConnectStatus, Dialect, RobotMode
from panda_py.libfranka._network import TCP_TIMEOUT, Network, translate
from panda_py.libfranka._wire import layout
from panda_py.libfranka.errors import (
    CommandException,
    IncompatibleVersionException,
    NetworkException,
    ProtocolException,
)

__all__ = ["MODE_NAMES", "RobotConnection", "status_message"]

#: libfranka's printed names of the robot modes (``operator<<(RobotMode)``).
MODE_NAMES = {
    RobotMode.OTHER: "Other",
    RobotMode.IDLE: "Idle",
    RobotMode.MOVE: "Move",
    RobotMode.GUIDING: "Guiding",
    RobotMode.REFLEX: "Reflex",
    RobotMode.USER_STOPPED: "User stopped",
    RobotMode.AUTOMATIC_ERROR_RECOVERY: "Automatic error recovery",
}

_SAFETY = "due to activated safety function! Please disable all safety functions."
# Status enumerator name -> (verb, reason) of libfranka's "<Name> command <verb>: <reason>"
_STATUS_TEXT = {
    "kPreempted": ("preempted", None),
    "kPreemptedDueToActivatedSafetyFunctions": ("preempted", _SAFETY),
    "kCommandRejectedDueToActivatedSafetyFunctions": ("rejected", _SAFETY),
    "kCommandNotPossibleRejected": ("rejected", "command not possible in the current mode"),
    "kStartAtSingularPoseRejected": ("rejected", "cannot start at singular pose!"),
    "kInvalidArgumentRejected": ("rejected", "invalid argument!"),
    "kReflexAborted": ("aborted", "motion aborted by reflex!"),
    "kEmergencyAborted": ("aborted", "User Stop pressed!"),
    "kInputErrorAborted": ("aborted", "invalid input provided!"),
    "kAborted": ("aborted", "command aborted!"),
    "kManualErrorRecoveryRequiredRejected": ("rejected", "manual error recovery required!"),
    "kError": ("rejected", "error!"),
}


def status_message(command: Command, status: Enum, mode: int | None = None) -> str:
    """libfranka's exception text for a non-success ``status`` of ``command``."""
    verb, reason = _STATUS_TEXT.get(str(status.value), ("failed", f"status {status.name}"))
    if command is Command.MOVE and status.value == "kInvalidArgumentRejected":
        reason = "maximum path deviation out of range!"
    if reason is None:
        return f"libfranka: {command.value} command {verb}!"
    if reason is _SAFETY:
        return f"libfranka: {command.value} command {verb} {reason}"
    if status.value == "kCommandNotPossibleRejected" and mode is not None:
        name = MODE_NAMES.get(RobotMode(mode), "Other") if mode in MODE_NAMES else "Other"
        reason += f' ("{name}")!'
        if mode == RobotMode.OTHER:
            reason += " Did you open the brakes?"
    elif status.value == "kCommandNotPossibleRejected":
        reason += "!"
    return f"libfranka: {command.value} command {verb}: {reason}"


class RobotConnection:
    """A connected robot speaking protocol ``version`` (raises
    :class:`IncompatibleVersionException` carrying the robot's version if it refuses)."""

    def __init__(self, host: str, version: int, *, timeout: float = TCP_TIMEOUT) -> None:
        self.dialect: Dialect = fci.dialect(version)
        self.net = Network(
            host,
            fci.COMMAND_PORT,
            fci.RobotMessageReader(),
            udp_size=self.dialect.state_size,
            timeout=timeout,
        )
        self.layout = layout(self.dialect)
        self._header = self.layout.header.struct_.unpack_from  # the header is at offset 0
        self._next_id = 0
        # ids and requests from several threads (a Robot's stop() beside its control loop,
        # as libfranka allows) stay unique and whole
        self._send_lock = threading.Lock()
        self.last_data = b""  # newest RobotState datagram (empty before the first)
        #: (message_id, motion_generator_mode, controller_mode, robot_mode) of last_data
        self.last_header: tuple[int, int, int, int] = (0, 0, 0, 0)
        self.last_id = 0
        try:
            self._connect(version)
            self.receive_state()  # the robot streams right after Connect (1 s timeout)
        except BaseException:
            self.net.close()
            raise

    def _connect(self, version: int) -> None:
        with self._send_lock:
            cid = self._take_id()
            self.net.send(fci.encode_connect_request(version, self.net.udp_port, command_id=cid))
        msg = self.net.wait_response(cid)
        try:
            _, status, server_version = fci.decode_connect_response(msg.raw)
        except fci.ProtocolError as exc:
            raise translate(exc, "Connect") from exc
        if status == ConnectStatus.ROBOT_BUSY:
            raise NetworkException("libfranka: robot busy: another client is connected")
        if status == ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION:
            raise IncompatibleVersionException(
                f"libfranka: Incompatible library version (server version: {server_version}, "
                f"library version: {version}).",
                server_version=server_version,
                library_version=version,
            )
        self.server_version = server_version

    def close(self) -> None:
        self.net.close()

    def _take_id(self) -> int:
        """The next command id (caller holds ``_send_lock``)."""
        cid = self._next_id
        self._next_id = (cid + 1) & 0xFFFFFFFF
        return cid

    # --- TCP requests -------------------------------------------------------------------

    def send_request(self, command: Command, **fields: Any) -> int:
        """Send ``command`` and return its command id (the caller collects responses)."""
        with self._send_lock:
            cid = self._take_id()
            self.net.send(self.dialect.encode_request(command, cid, **fields))
        return cid

    def _decode(self, command: Command, msg: fci.Message) -> tuple[Any, dict[str, Any]]:
        try:
            return self.dialect.decode_response(command, msg.payload)
        except (fci.ProtocolError, ValueError) as exc:
            raise ProtocolException(f"libfranka: {command.value} response: {exc}") from exc

    def response(
        self, command: Command, cid: int, timeout: float | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Block for the next response to request ``cid`` -> (status member, fields)."""
        return self._decode(command, self.net.wait_response(cid, timeout))

    def poll(self, command: Command, cid: int) -> tuple[Any, dict[str, Any]] | None:
        msg = self.net.poll_response(cid)
        return None if msg is None else self._decode(command, msg)

    def execute(
        self, command: Command, *, timeout: float | None = None, **fields: Any
    ) -> dict[str, Any]:
        """Send ``command``, wait for its response, raise CommandException unless success."""
        cid = self.send_request(command, **fields)
        status, out = self.response(command, cid, timeout)
        if status.value != "kSuccess":
            mode = self.last_header[3] if self.last_data else None
            raise CommandException(
                status_message(command, status, mode), command=command.value, status=status
            )
        return out

    # --- UDP ----------------------------------------------------------------------------

    def receive_state(self) -> bytes:
        """The newest RobotState datagram newer than the last one (waits up to 1 s); its
        header is in :attr:`last_header`."""
        data = self.net.receive_newest(self.last_id)
        self.took_state(data)
        return data

    def took_state(self, data: bytes) -> None:
        """``data`` is the newest RobotState datagram (received here, or by a compiled
        loop on this connection's socket): remember it and its header."""
        header = self._header(data)
        self.last_data = data
        self.last_header = header
        self.last_id = header[0]

    def receive_fresh_state(self) -> bytes:
        """The first RobotState sent after this call (libfranka's ``readOnce``: queued
        states, sent before whatever the caller just did, are discarded first)."""
        self.net.discard_queued()
        return self.receive_state()

    @property
    def last(self) -> np.void | None:
        """The newest RobotState as a record (None before the first)."""
        data = self.last_data
        return self.dialect.decode_state(data) if data else None
