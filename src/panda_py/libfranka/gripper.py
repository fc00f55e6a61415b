"""``Gripper``: the Franka Hand over its own TCP/UDP protocol (v3, port 1338)."""

from __future__ import annotations

import math
from typing import Any

from panda_py import fci
from panda_py.fci import GripperCommand
from panda_py.libfranka._hand import ACTION_TIMEOUT, HandClient
from panda_py.libfranka.state import GripperState

__all__ = ["ACTION_TIMEOUT", "Gripper"]

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


class Gripper(HandClient):
    """The Franka Hand (libfranka's ``franka::Gripper``). Commands block until the hand is
    done and return True on success, False if it was unsuccessful (e.g. nothing grasped);
    a failure raises :class:`CommandException`."""

    def __init__(self, hostname: str, *, timeout: float = ACTION_TIMEOUT) -> None:
        super().__init__(
            hostname,
            fci.GRIPPER_COMMAND_PORT,
            fci.GRIPPER_STATE_DTYPE.itemsize,
            fci.GRIPPER_VERSION,
            timeout,
        )

    def _execute(self, command: GripperCommand, **fields: Any) -> bool:
        payload = fci.GRIPPER_REQUESTS[command].encode(**fields)
        return self._run(
            _NAMES[command],
            lambda cid: fci.encode_gripper_message(command, cid, payload),
            fci.decode_gripper_status,
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
        """A fresh gripper state: queued ones are discarded and the next awaited (up to 1 s),
        as libfranka's ``readOnce``."""
        return GripperState(fci.decode_gripper_state(self._net.receive_fresh()))

    readOnce = read_once
