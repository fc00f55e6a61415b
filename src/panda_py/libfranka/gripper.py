"""``Gripper``: the Franka Hand over its own TCP/UDP protocol (v3, port 1338)."""

from __future__ import annotations

from typing import Any, Literal, overload

from panda_py import fci
from panda_py.checks import number
from panda_py.fci import GripperCommand
from panda_py.libfranka._hand import ACTION_TIMEOUT, HandClient
from panda_py.libfranka._responses import CommandFuture
from panda_py.libfranka.state import GripperState
from panda_py.robots.params import FRANKA_HAND

__all__ = ["ACTION_TIMEOUT", "CommandFuture", "Gripper"]

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
    a failure raises :class:`CommandException`.

    ``homing``, ``move`` and ``grasp`` take ``asynchronous=True`` to return at once a
    :class:`CommandFuture` instead (``result()``, or ``await`` in a coroutine), so the arm
    can move meanwhile; ``stop()`` and ``read_once()`` work while it runs. The hand runs
    one action at a time: a new one replaces a running one, which ends as aborted (its
    future raises :class:`CommandException`), as on the real hand."""

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

    def _execute(self, command: GripperCommand, asynchronous: bool = False,
                 **fields: Any) -> bool | CommandFuture:  # fmt: skip
        """Encode (checking ``fields``) before anything is sent, then run the command:
        blocking, or returning its future at once."""
        payload = fci.GRIPPER_REQUESTS[command].encode(**fields)
        name = _NAMES[command]

        def encode(cid: int) -> bytes:
            return fci.encode_gripper_message(command, cid, payload)

        if not isinstance(asynchronous, bool):
            raise ValueError(f"asynchronous: expected True or False, got {asynchronous!r}")
        if asynchronous:
            return self._start(name, encode, fci.decode_gripper_status)
        return self._run(name, encode, fci.decode_gripper_status)

    @overload
    def homing(self, *, asynchronous: Literal[False] = False) -> bool: ...
    @overload
    def homing(self, *, asynchronous: Literal[True]) -> CommandFuture: ...
    @overload
    def homing(self, *, asynchronous: bool) -> bool | CommandFuture: ...

    def homing(self, *, asynchronous: bool = False) -> bool | CommandFuture:
        """Calibrate the fingers by moving them to the maximum width. With
        ``asynchronous``, return at once a :class:`CommandFuture` of the outcome."""
        return self._execute(GripperCommand.HOMING, asynchronous)

    @overload
    def move(self, width: float, speed: float, *,
             asynchronous: Literal[False] = False) -> bool: ...  # fmt: skip
    @overload
    def move(self, width: float, speed: float, *,
             asynchronous: Literal[True]) -> CommandFuture: ...  # fmt: skip
    @overload
    def move(self, width: float, speed: float, *,
             asynchronous: bool) -> bool | CommandFuture: ...  # fmt: skip

    def move(self, width: float, speed: float, *,
             asynchronous: bool = False) -> bool | CommandFuture:  # fmt: skip
        """Move the fingers to ``width`` [m] at ``speed`` [m/s]. With ``asynchronous``,
        check the arguments, send the command and return at once a :class:`CommandFuture`
        of what the blocking call returns (or raises), e.g. to move the arm meanwhile."""
        return self._execute(
            GripperCommand.MOVE,
            asynchronous,
            width=self._width(width),
            speed=self._speed(speed),
        )

    @overload
    def grasp(self, width: float, speed: float, force: float, epsilon_inner: float = 0.005,
              epsilon_outer: float = 0.005, *,
              asynchronous: Literal[False] = False) -> bool: ...  # fmt: skip
    @overload
    def grasp(self, width: float, speed: float, force: float, epsilon_inner: float = 0.005,
              epsilon_outer: float = 0.005, *,
              asynchronous: Literal[True]) -> CommandFuture: ...  # fmt: skip
    @overload
    def grasp(self, width: float, speed: float, force: float, epsilon_inner: float = 0.005,
              epsilon_outer: float = 0.005, *,
              asynchronous: bool) -> bool | CommandFuture: ...  # fmt: skip

    def grasp(self, width: float, speed: float, force: float, epsilon_inner: float = 0.005,
              epsilon_outer: float = 0.005, *,
              asynchronous: bool = False) -> bool | CommandFuture:  # fmt: skip
        """Grasp an object of ``width`` [m] at ``speed`` [m/s] with ``force`` [N]; True if
        the final width lies within ``[width - epsilon_inner, width + epsilon_outer]``.
        With ``asynchronous``, return at once a :class:`CommandFuture` of that outcome."""
        return self._execute(
            GripperCommand.GRASP,
            asynchronous,
            width=self._width(width),
            speed=self._speed(speed),
            force=number("force", force, "[N]", low=0.0, high=_HAND.peak_force),
            epsilon_inner=number("epsilon_inner", epsilon_inner, "[m]", low=0.0, high=_MAX_EPSILON),
            epsilon_outer=number("epsilon_outer", epsilon_outer, "[m]", low=0.0, high=_MAX_EPSILON),
        )

    def stop(self) -> bool:
        """Stop a running gripper action (which ends as aborted: its blocking call, or its
        future, raises :class:`CommandException`); True once the hand stopped."""
        return bool(self._execute(GripperCommand.STOP))

    def read_once(self) -> GripperState:
        """A fresh gripper state: queued ones are discarded and the next awaited (up to 1 s),
        as libfranka's ``readOnce``."""
        return GripperState(fci.decode_gripper_state(self._net.receive_fresh()))

    readOnce = read_once
