"""``Gripper``: the Franka Hand over its own TCP/UDP protocol (v3, port 1338)."""

from __future__ import annotations

from typing import Any

from panda_py import fci
from panda_py.checks import number
from panda_py.fci import GripperCommand
from panda_py.libfranka._hand import ACTION_TIMEOUT, HandClient
from panda_py.libfranka.state import GripperState
from panda_py.robots.params import FRANKA_HAND

__all__ = ["ACTION_TIMEOUT", "Gripper"]

_NAMES = {
    GripperCommand.HOMING: "Homing",
    GripperCommand.GRASP: "Grasp",
    GripperCommand.MOVE: "Move",
    GripperCommand.STOP: "Stop",
}


_HAND = FRANKA_HAND
#: Grasp tolerances beyond the stroke mean nothing [m].
_MAX_EPSILON = _HAND.max_width


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

    def _width(self, width: Any) -> float:
        return number("width", width, "[m]", low=0.0, high=_HAND.max_width)

    def _speed(self, speed: Any) -> float:
        """A finite speed fast enough to cross the stroke within this client's timeout (a
        slower action could never be seen to finish). Above the hand's 0.1 m/s the hand
        runs at its maximum, as a real one does: panda-py's paper calls
        ``gripper.move(0.08, 0.2)``."""
        return number("speed", speed, "[m/s]", low=_HAND.max_width / self._net.timeout)

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
            width=self._width(width),
            speed=self._speed(speed),
        )

    def grasp(self, width: float, speed: float, force: float, epsilon_inner: float = 0.005,
              epsilon_outer: float = 0.005) -> bool:  # fmt: skip
        """Grasp an object of ``width`` [m] at ``speed`` [m/s] with ``force`` [N]; True if
        the final width lies within ``[width - epsilon_inner, width + epsilon_outer]``."""
        return self._execute(
            GripperCommand.GRASP,
            width=self._width(width),
            speed=self._speed(speed),
            force=number("force", force, "[N]", low=0.0, high=_HAND.peak_force),
            epsilon_inner=number("epsilon_inner", epsilon_inner, "[m]", low=0.0, high=_MAX_EPSILON),
            epsilon_outer=number("epsilon_outer", epsilon_outer, "[m]", low=0.0, high=_MAX_EPSILON),
        )

    def stop(self) -> bool:
        """Stop a running gripper action."""
        return self._execute(GripperCommand.STOP)

    def read_once(self) -> GripperState:
        """A fresh gripper state: queued ones are discarded and the next awaited (up to 1 s),
        as libfranka's ``readOnce``."""
        return GripperState(fci.decode_gripper_state(self._net.receive_fresh()))

    readOnce = read_once
