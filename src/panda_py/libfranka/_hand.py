"""What the Franka Hand (:class:`Gripper`) and the Cobot Pump (:class:`VacuumGripper`)
clients share: one TCP/UDP connection opened with the gripper protocol's Connect, command
ids, and commands answered by a status (success, unsuccessful, fail, aborted) when the
action ends: waited for (blocking), or as a :class:`CommandFuture` (``asynchronous``).

The device runs one action at a time: a command sent while another one runs replaces it,
and the earlier one ends as aborted (its call raises :class:`CommandException`), as the
real hand and the simulated one do; Stop aborts the running action and succeeds."""

from __future__ import annotations

import enum
import threading
import weakref
from collections.abc import Callable
from typing import Any, TypeVar

from panda_py import fci
from panda_py.checks import timeout as checked_timeout
from panda_py.libfranka._network import Network, translate
from panda_py.libfranka._responses import CommandFuture, Responses
from panda_py.libfranka.errors import (
    CommandException,
    IncompatibleVersionException,
    NetworkException,
)

_Hand = TypeVar("_Hand", bound="HandClient")

#: Gripper actions (homing, grasp, move, vacuum) block until done; this bounds the wait [s].
ACTION_TIMEOUT = 60.0


def _close(responses: Responses, net: Network) -> None:
    responses.close()
    net.close()


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
        self._id_lock = threading.Lock()
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
            # from here on, one thread reads the responses (see _responses); it holds the
            # connection, not this client: one dropped unclosed is closed when collected
            self._responses = Responses(self._net, self._LABEL)
            self._closer = weakref.finalize(self, _close, self._responses, self._net)
        except BaseException:
            self._net.close()
            raise

    def _take_id(self) -> int:
        with self._id_lock:
            cid = self._next_id
            self._next_id = (cid + 1) & 0xFFFFFFFF
        return cid

    def close(self) -> None:
        """Close the connection; a command still pending fails with NetworkException."""
        self._closer()

    def __enter__(self: _Hand) -> _Hand:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def server_version(self) -> int:
        """The device's protocol version."""
        return self._server_version

    def _start(
        self,
        name: str,
        encode: Callable[[int], bytes],
        decode_status: Callable[[Any], enum.IntEnum],
    ) -> CommandFuture:
        """Send the message ``encode(command_id)`` and return at once the future of its
        outcome (see :meth:`_run`)."""
        cid = self._take_id()

        def finish(msg: fci.Message) -> bool:
            return self._outcome(name, decode_status, msg)

        return self._responses.submit(cid, name, finish, lambda: self._net.send(encode(cid)))

    def _run(
        self,
        name: str,
        encode: Callable[[int], bytes],
        decode_status: Callable[[Any], enum.IntEnum],
    ) -> bool:
        """Send the message ``encode(command_id)`` and wait for its status: True on
        success, False if unsuccessful; a failed or aborted command raises."""
        self._check_blocking(name)
        return self._start(name, encode, decode_status).result()

    def _check_blocking(self, name: str) -> None:
        """A blocking call waits for the reader thread, which resolves every future by the
        connection's timeout or when the client is closed; in that thread (a future's
        done-callback) it would wait for itself, so it is refused before anything is sent."""
        if self._responses.in_reader():
            raise RuntimeError(
                f"libfranka {self._LABEL}: a blocking {name} in a future's done-callback "
                "would wait for the thread that runs it; use asynchronous=True there"
            )

    def _outcome(
        self, name: str, decode_status: Callable[[Any], enum.IntEnum], msg: fci.Message
    ) -> bool:
        """The call's return value from its response, or the exception it raises."""
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
