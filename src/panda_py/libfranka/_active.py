"""The active-control style of libfranka >= 0.15 / pylibfranka: the caller drives the loop
with ``readOnce()`` and ``writeOnce(command)``."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import fci
from panda_py.libfranka._commander import Commander
from panda_py.libfranka._connection import RobotConnection
from panda_py.libfranka._motion import MotionSession
from panda_py.libfranka._wire import Layout, layout
from panda_py.libfranka.errors import InvalidOperationException
from panda_py.libfranka.limits import RateLimits
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import Duration, RealtimeConfig

__all__ = ["ActiveControl", "RobotBase", "TorqueIO"]


@dataclass(frozen=True)
class TorqueIO:
    """What a compiled torque loop needs of a running motion
    (:meth:`ActiveControl.torque_io`)."""

    udp: int  #: the robot's UDP socket (connected to the robot), non-blocking
    command: NDArray[np.uint8]  #: the RobotCommand datagram, its bytes (shared, writable)
    last_data: bytes  #: the newest state taken (and answered)
    #: (motion generator mode, controller mode, robot mode) while the motion runs
    modes: tuple[int, int, int]
    layout: Layout  #: the fields of the states and the commands, of this protocol version

    @classmethod
    def unconnected(cls, version: int) -> TorqueIO:
        """Of protocol ``version``, with no socket (-1) and a zeroed command: what a
        compiled loop's warm-up runs on (it runs no tick)."""
        wire = layout(fci.dialect(version))
        return cls(-1, np.zeros(wire.command_size, np.uint8), b"", (0, 0, 0), wire)


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
        return self._took(data)

    def _took(self, data: bytes) -> tuple[RobotState, Duration]:
        conn = self._robot._conn
        state = self._state_type(conn.dialect, data)
        self._robot._log.append(state)
        mid = conn.last_id
        dt = Duration(0 if self._last_id is None else mid - self._last_id)
        self._last_id = mid
        self._last_data = data
        return state, dt

    # --- a compiled loop's ticks (extensions of ours, for panda_py's control process) -----

    def torque_io(self) -> TorqueIO:
        """What a compiled loop needs to run this torque motion's ticks itself, reading
        and answering states on the robot's socket: valid while the motion runs. Tell
        this object what it did with :meth:`caught_up` or :meth:`read_received`."""
        self._check()
        if not self._torque or self._commander.process:
            raise InvalidOperationException(
                "libfranka: a compiled loop runs torque control without filter or rate limit"
            )
        if self._last_data is None:
            raise InvalidOperationException("libfranka: call readOnce() before torque_io()")
        conn = self._robot._conn
        return TorqueIO(
            conn.net.state_fileno(), np.frombuffer(self._commander.buffer, np.uint8),
            self._last_data, self._session.running_modes, conn.layout,
        )  # fmt: skip

    def _check_datagram(self, data: object) -> None:
        size = self._robot._conn.dialect.state_size
        if not isinstance(data, bytes) or len(data) < size:  # (as decode_state: no shorter)
            got = f"{len(data)} bytes" if isinstance(data, bytes) else type(data).__name__
            raise ValueError(f"data: expected a state datagram of {size} bytes, got {got}")

    def caught_up(self, data: bytes) -> RobotState:
        """A compiled loop answered the states up to ``data``, the last one (it received
        them on the socket of :meth:`torque_io`): the next ``readOnce`` goes on from it.
        Returns that state."""
        self._check()
        self._check_datagram(data)
        self._robot._conn.took_state(data)
        return self._took(data)[0]

    def read_received(self, data: bytes) -> tuple[RobotState, Duration]:
        """``readOnce`` for a state a compiled loop received and left for this loop to
        answer (it raises, as ``readOnce``, if the robot left the motion)."""
        self._check()
        self._check_datagram(data)
        try:
            self._session.accept(data)
        except BaseException:
            self.cancel()
            raise
        return self._took(data)

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
