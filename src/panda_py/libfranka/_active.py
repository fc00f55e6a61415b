"""The active-control style of libfranka >= 0.15 / pylibfranka: the caller drives the loop
with ``readOnce()`` and ``writeOnce(command)``."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

from panda_py.libfranka._commander import Commander
from panda_py.libfranka._connection import RobotConnection
from panda_py.libfranka._motion import MotionSession
from panda_py.libfranka.errors import InvalidOperationException
from panda_py.libfranka.limits import RateLimits
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import Duration, RealtimeConfig

__all__ = ["ActiveControl", "RobotBase"]


class RobotBase:
    """What the control code needs of a Robot (declared for type checking)."""

    _conn: RobotConnection
    _limits: RateLimits
    _log: deque[RobotState]
    _realtime_config: RealtimeConfig
    _session: MotionSession | None


class ActiveControl:
    """A running motion whose loop the caller drives: ``readOnce()`` -> ``(RobotState,
    Duration)``, then ``writeOnce(command)`` once per state. A command marked
    ``motion_finished`` ends the motion; so does leaving a ``with`` block (by StopMove)."""

    def __init__(
        self,
        robot: RobotBase,
        session: MotionSession,
        commander: Commander,
        convert: Callable[[Any, bytes], bool],
        *,
        control: bool,
        motion: bool,
        state_type: type[RobotState] = RobotState,
    ) -> None:
        self._robot = robot
        self._state_type = state_type
        self._session = session
        self._commander = commander
        self._convert = convert  # the Commander method for this motion's command type
        self._torque = convert == commander.torques
        self._flags = (motion, control)
        self._last_id: int | None = None
        self._last_data: bytes | None = None
        self._finished = False

    @property
    def finished(self) -> bool:
        """Whether the motion has ended (a command marked finished was sent, or it was
        cancelled); reads and writes then raise ``InvalidOperationException``."""
        return self._finished

    def _check(self) -> None:
        if self._finished:
            raise InvalidOperationException("libfranka: this motion has already finished")

    def _end(self) -> None:
        self._finished = True
        if self._robot._session is self._session:
            self._robot._session = None

    def readOnce(self) -> tuple[RobotState, Duration]:
        """The newest robot state and the time since the previous read (0 at first)."""
        self._check()
        try:
            data = self._session.receive()
        except BaseException:
            self.cancel()
            raise
        conn = self._robot._conn
        state = self._state_type(conn.dialect, data)
        self._robot._log.append(state)
        mid = conn.last_id
        dt = Duration(0 if self._last_id is None else mid - self._last_id)
        self._last_id = mid
        self._last_data = data
        return state, dt

    def writeOnce(self, command: Any) -> None:
        """Send ``command`` (of this motion's type) for the last state read."""
        self._check()
        data = self._last_data
        if data is None:
            raise InvalidOperationException("libfranka: call readOnce() before writeOnce()")
        try:
            self._send(self._convert(command, data))
        except BaseException:
            self.cancel()
            raise

    def write_torques(self, tau: list[float], motion_finished: bool = False) -> None:
        """``writeOnce(Torques(tau))`` for a loop that owns its arrays (an extension of
        ours): ``tau`` seven floats [Nm] (a list, as ``ndarray.tolist()`` gives), checked
        finite, filtered and rate-limited as ``writeOnce``; no command object is made.
        Torque control only."""
        self._check()
        data = self._last_data
        if data is None:
            raise InvalidOperationException("libfranka: call readOnce() before write_torques()")
        if not self._torque:
            raise InvalidOperationException("libfranka: write_torques() is for torque control")
        try:
            s = sum(tau)  # a builtin sum of floats: NaN or infinity anywhere shows
            ok = len(tau) == 7 and s - s == 0.0
        except TypeError:
            ok = False
        if not ok:
            raise ValueError(f"tau_J: expected 7 finite torques [Nm], got {tau!r}")
        try:
            self._commander.torque_values(tau, data)
            self._send(motion_finished)
        except BaseException:
            self.cancel()
            raise

    def _send(self, finished: bool) -> None:
        """Send the command in the commander's buffer (the last one if ``finished``)."""
        if finished:
            self._session.finish(
                self._commander.buffer, motion=self._flags[0], control=self._flags[1]
            )
            self._end()
        else:
            self._session.send(self._commander.buffer)

    read_once = readOnce
    write_once = writeOnce

    def cancel(self) -> None:
        """Stop the motion now (StopMove) if it still runs."""
        if not self._finished:
            self._session.cancel()
            self._end()

    def __enter__(self) -> ActiveControl:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()
