"""What the Franka Hand (:class:`Gripper`) and the Cobot Pump (:class:`VacuumGripper`)
clients share: one TCP/UDP connection opened with the gripper protocol's Connect, command
ids, and blocking commands answered by a status (success, unsuccessful, fail, aborted)."""

from __future__ import annotations

import enum
from collections.abc import Callable
from typing import Any, TypeVar

from panda_py import fci
from panda_py.checks import timeout as checked_timeout
from panda_py.libfranka._network import Network, translate
from panda_py.libfranka.errors import (
    CommandException,
    IncompatibleVersionException,
    NetworkException,
)

_Hand = TypeVar("_Hand", bound="HandClient")

#: Gripper actions (homing, grasp, move, vacuum) block until done; this bounds the wait [s].
ACTION_TIMEOUT = 60.0


class HandClient:
    """A connected hand-type device; subclasses name it (``_LABEL``, ``_TITLE``)."""

    _LABEL = "gripper"  # in messages: "libfranka gripper: ..."
    _TITLE = "Gripper"  # in protocol errors: "Gripper Connect"

    def __init__(
        self, hostname: str, port: int, udp_size: int, version: int, timeout: float
    ) -> None:
        timeout = checked_timeout("timeout", timeout)
        self._net = Network(
            hostname,
            port,
            fci.GripperMessageReader(),  # the pump uses the hand's 10-byte header too
            udp_size=udp_size,
            timeout=timeout,
        )
        self._next_id = 0
        try:
            cid = self._take_id()
            self._net.send(
                fci.encode_gripper_connect_request(
                    self._net.udp_port, version=version, command_id=cid
                )
            )
            msg = self._net.wait_response(cid)
            try:
                _, status, server = fci.decode_gripper_connect_response(msg.raw)
            except fci.ProtocolError as exc:
                raise translate(exc, f"{self._TITLE} Connect") from exc
            if status == fci.GripperConnectStatus.ROBOT_BUSY:
                raise NetworkException(
                    f"libfranka {self._LABEL}: robot busy: another client is connected"
                )
            if status != fci.GripperConnectStatus.SUCCESS:
                raise IncompatibleVersionException(
                    f"libfranka {self._LABEL}: Incompatible library version (server version: "
                    f"{server}, library version: {version}).",
                    server_version=server,
                    library_version=version,
                )
            self._server_version = int(server)
        except BaseException:
            self._net.close()
            raise

    def _take_id(self) -> int:
        cid = self._next_id
        self._next_id = (cid + 1) & 0xFFFFFFFF
        return cid

    def close(self) -> None:
        self._net.close()

    def __enter__(self: _Hand) -> _Hand:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def server_version(self) -> int:
        """The device's protocol version."""
        return self._server_version

    def _run(
        self,
        name: str,
        encode: Callable[[int], bytes],
        decode_status: Callable[[Any], enum.IntEnum],
    ) -> bool:
        """Send the message ``encode(command_id)`` and wait for its status: True on
        success, False if unsuccessful; a failed or aborted command raises."""
        cid = self._take_id()
        self._net.send(encode(cid))
        msg = self._net.wait_response(cid)
        try:
            status = decode_status(msg.payload)
        except fci.ProtocolError as exc:
            raise translate(exc, f"{self._TITLE} {name} response") from exc
        # Both devices number their statuses as libfranka: 0 success, 1 fail,
        # 2 unsuccessful, 3 aborted.
        if status == fci.GripperStatus.SUCCESS:
            return True
        if status == fci.GripperStatus.UNSUCCESSFUL:
            return False
        what = "failed" if status == fci.GripperStatus.FAIL else "aborted"
        raise CommandException(
            f"libfranka {self._LABEL}: {name} command {what}!", command=name, status=status
        )
