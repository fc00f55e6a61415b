"""``Gripper``: the Franka Hand over its own TCP/UDP protocol (v3, port 1338)."""

from __future__ import annotations

import math
from typing import Any

from panda_py import fci
from panda_py.fci import GripperCommand, GripperConnectStatus, GripperStatus
from panda_py.libfranka._network import Network, translate
from panda_py.libfranka.errors import CommandException, IncompatibleVersionException
from panda_py.libfranka.state import GripperState

__all__ = ["Gripper"]

#: Gripper actions (homing, grasp, move) block until done; this bounds the wait [s].
ACTION_TIMEOUT = 60.0

_NAMES = {
    GripperCommand.HOMING: "Homing",
    GripperCommand.GRASP: "Grasp",
    GripperCommand.MOVE: "Move",
    GripperCommand.STOP: "Stop",
}


def _number(name: str, value: Any, unit: str, *, positive: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a number {unit}, got {value!r}") from exc
    if not math.isfinite(x) or x < 0.0 or (positive and x == 0.0):
        bound = "> 0" if positive else ">= 0"
        raise ValueError(f"{name}: expected a finite value {bound} {unit}, got {value!r}")
    return x


class Gripper:
    """The Franka Hand (libfranka's ``franka::Gripper``). Commands block until the hand is
    done and return True on success, False if it was unsuccessful (e.g. nothing grasped);
    a failure raises :class:`CommandException`."""

    def __init__(self, hostname: str, *, timeout: float = ACTION_TIMEOUT) -> None:
        if not (isinstance(timeout, (int, float)) and timeout > 0):
            raise ValueError(f"timeout: expected a time > 0 [s], got {timeout!r}")
        self._net = Network(
            hostname,
            fci.GRIPPER_COMMAND_PORT,
            fci.GripperMessageReader(),
            udp_size=fci.GRIPPER_STATE_DTYPE.itemsize,
            timeout=timeout,
        )
        self._next_id = 0
        try:
            cid = self._take_id()
            self._net.send(fci.encode_gripper_connect_request(self._net.udp_port, command_id=cid))
            msg = self._net.wait_response(cid)
            try:
                _, status, version = fci.decode_gripper_connect_response(msg.raw)
            except fci.ProtocolError as exc:
                raise translate(exc, "Gripper Connect") from exc
            if status == GripperConnectStatus.INCOMPATIBLE_LIBRARY_VERSION:
                raise IncompatibleVersionException(
                    f"libfranka gripper: Incompatible library version (server version: "
                    f"{version}, library version: {fci.GRIPPER_VERSION}).",
                    server_version=version,
                    library_version=fci.GRIPPER_VERSION,
                )
            self._server_version = int(version)
        except BaseException:
            self._net.close()
            raise

    def _take_id(self) -> int:
        cid = self._next_id
        self._next_id = (cid + 1) & 0xFFFFFFFF
        return cid

    def close(self) -> None:
        self._net.close()

    def __enter__(self) -> Gripper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def server_version(self) -> int:
        """The hand's protocol version."""
        return self._server_version

    def _execute(self, command: GripperCommand, **fields: Any) -> bool:
        cid = self._take_id()
        payload = fci.GRIPPER_REQUESTS[command].encode(**fields)
        self._net.send(fci.encode_gripper_message(command, cid, payload))
        msg = self._net.wait_response(cid)
        try:
            status = fci.decode_gripper_status(msg.payload)
        except fci.ProtocolError as exc:
            raise translate(exc, f"Gripper {_NAMES[command]} response") from exc
        if status == GripperStatus.SUCCESS:
            return True
        if status == GripperStatus.UNSUCCESSFUL:
            return False
        what = "failed" if status == GripperStatus.FAIL else "aborted"
        raise CommandException(
            f"libfranka gripper: {_NAMES[command]} command {what}!",
            command=_NAMES[command],
            status=status,
        )

    def homing(self) -> bool:
        """Calibrate the fingers by moving them to the maximum width."""
        return self._execute(GripperCommand.HOMING)

    def move(self, width: float, speed: float) -> bool:
        """Move the fingers to ``width`` [m] at ``speed`` [m/s]."""
        return self._execute(
            GripperCommand.MOVE,
            width=_number("width", width, "[m]"),
            speed=_number("speed", speed, "[m/s]", positive=True),
        )

    def grasp(self, width: float, speed: float, force: float, epsilon_inner: float = 0.005,
              epsilon_outer: float = 0.005) -> bool:  # fmt: skip
        """Grasp an object of ``width`` [m] at ``speed`` [m/s] with ``force`` [N]; True if
        the final width lies within ``[width - epsilon_inner, width + epsilon_outer]``."""
        return self._execute(
            GripperCommand.GRASP,
            width=_number("width", width, "[m]"),
            speed=_number("speed", speed, "[m/s]", positive=True),
            force=_number("force", force, "[N]"),
            epsilon_inner=_number("epsilon_inner", epsilon_inner, "[m]"),
            epsilon_outer=_number("epsilon_outer", epsilon_outer, "[m]"),
        )

    def stop(self) -> bool:
        """Stop a running gripper action."""
        return self._execute(GripperCommand.STOP)

    def read_once(self) -> GripperState:
        """The newest gripper state (waits up to 1 s for one)."""
        return GripperState(fci.decode_gripper_state(self._net.receive_any()))

    readOnce = read_once
