"""The Move lifecycle of one motion (fci-protocol.md §6), as libfranka's ``startMotion``,
``updateMotion``, ``throwOnMotionError``, ``finishMotion`` and ``cancelMotion``."""

from __future__ import annotations

import time
from collections import deque
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import (
    Command,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveRequest,
    MoveStatus,
    RobotMode,
)
from panda_py.libfranka._connection import RobotConnection, status_message
from panda_py.libfranka.errors import (
    CommandException,
    ControlException,
    FrankaException,
    InvalidOperationException,
    NetworkException,
)
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import Errors

__all__ = ["MotionSession", "motion_running"]

START_TIMEOUT = 2.0  # [s] for the robot to switch into the requested modes
STOP_TIMEOUT = 1.0  # [s] for the robot to go idle after StopMove
FINISH_TIMEOUT = 1.0  # [s] for the robot to go idle after the last command
# The TCP connection is looked at (a select) every this many states of a motion, not at
# each as libfranka does: on this project's 2-core VM each system call a tick costs the
# loop several microseconds; a robot that closed the connection also stops sending
# states, and the receive looks at the connection before it waits for one.
CLOSED_CHECK_STATES = 16

_STATE_MG = fci.STATE_GENERATOR_OF_MOVE
_IDLE_MG = (int(MotionGeneratorMode.IDLE), int(MotionGeneratorMode.NONE))
_EXTERNAL = int(ControllerMode.EXTERNAL_CONTROLLER)
_MOVE = int(RobotMode.MOVE)


def motion_running(header: tuple[int, int, int, int] | None) -> bool:
    """libfranka's ``motionGeneratorRunning() || controllerRunning()`` for a state header
    (:attr:`RobotConnection.last_header`)."""
    if header is None:
        return False
    return header[1] not in _IDLE_MG or header[2] == _EXTERNAL


def _header(conn: RobotConnection) -> tuple[int, int, int, int] | None:
    return conn.last_header if conn.last_data else None


class MotionSession:
    """One running Move on ``conn``. Construct to start it (blocks until the robot runs
    the requested modes); then :meth:`receive`/:meth:`send` per tick; :meth:`finish` or
    :meth:`cancel` to end it."""

    def __init__(
        self,
        conn: RobotConnection,
        controller: MoveControllerMode,
        generator: MoveMotionGeneratorMode,
        log: deque[RobotState],
        maximum_velocity: tuple[float, ...] | None = None,
    ) -> None:
        """``maximum_velocity`` [rad/s] makes it protocol v10's asynchronous motion (the
        robot's own generator moves to the targets the commands carry)."""
        if motion_running(_header(conn)):
            raise InvalidOperationException("libfranka: Attempted to start multiple motions!")
        self.conn = conn
        self.log = log
        self.done = False  # finished or cancelled: nothing left to clean up
        self.final_received = False  # the second Move response has been taken
        self.caller_driven = False  # an ActiveControl (the caller's thread) runs the loop
        self._unchecked = 0  # states until the TCP connection is looked at again
        self._pack_id = conn.layout.c_message_id.struct_.pack_into  # at offset 0
        self.expect_mg = int(_STATE_MG[generator])
        self.expect_ctrl = int(controller)
        d = conn.dialect
        request = MoveRequest(controller, generator, maximum_velocity=maximum_velocity)
        try:
            fields = request.fields(d)
        except ValueError as exc:  # asynchronous on a robot older than v10
            raise InvalidOperationException(f"libfranka: {exc}") from None
        self.move_id = conn.send_request(Command.MOVE, **fields)
        status, _ = conn.response(Command.MOVE, self.move_id)
        if status != MoveStatus.MOTION_STARTED:
            self.done = self.final_received = True
            raise CommandException(
                status_message(Command.MOVE, status, self._mode()), command="Move", status=status
            )
        deadline = time.monotonic() + START_TIMEOUT
        try:
            while True:
                data = conn.receive_state()
                _, mg, ctrl, mode = conn.last_header
                if mode == _MOVE and mg == self.expect_mg and ctrl == self.expect_ctrl:
                    break
                final = conn.poll(Command.MOVE, self.move_id)
                if final is not None:
                    self._raise_final(final[0], data)
                if time.monotonic() > deadline:
                    raise ControlException("libfranka: the robot did not start the motion")
        except BaseException:
            self.cancel()
            raise

    def _mode(self) -> int | None:
        header = _header(self.conn)
        return None if header is None else header[3]

    # --- per tick ---------------------------------------------------------------------

    def receive(self) -> bytes:
        """Take the newest state datagram (and every CLOSED_CHECK_STATES, check the TCP
        connection), raise if the motion ended."""
        conn = self.conn
        self._unchecked -= 1
        if self._unchecked <= 0:
            self._unchecked = CLOSED_CHECK_STATES
            conn.net.check_closed()
        data = conn.receive_state()
        _, mg, ctrl, mode = conn.last_header
        if mode != _MOVE or mg != self.expect_mg or ctrl != self.expect_ctrl:
            self._abort(data)
        return data

    def accept(self, data: bytes) -> None:
        """As :meth:`receive`, for a state datagram received elsewhere (a compiled loop
        on the connection's socket): take it as the newest, raise if the motion ended."""
        conn = self.conn
        conn.took_state(data)
        _, mg, ctrl, mode = conn.last_header
        if mode != _MOVE or mg != self.expect_mg or ctrl != self.expect_ctrl:
            self._abort(data)

    @property
    def running_modes(self) -> tuple[int, int, int]:
        """(motion generator mode, controller mode, robot mode) of the states while this
        motion runs."""
        return self.expect_mg, self.expect_ctrl, _MOVE

    def send(self, command: bytearray) -> None:
        """Send the RobotCommand datagram ``command`` as the answer to the newest state
        (its ``message_id`` is set here)."""
        conn = self.conn
        self._pack_id(command, 0, conn.last_id)
        conn.net.send_udp(command)

    # --- ending -----------------------------------------------------------------------

    def _abort(self, data: bytes) -> None:
        """The robot left the motion: collect the final Move response and raise."""
        status, _ = self.conn.response(Command.MOVE, self.move_id)
        self._raise_final(status, data)

    def _raise_final(self, status: Any, data: bytes) -> None:
        rec = self.conn.dialect.decode_state(data)
        self.final_received = True
        if status == MoveStatus.SUCCESS:
            raise ControlException(
                "libfranka: the robot ended the motion unexpectedly", status=status
            )
        message = status_message(Command.MOVE, status, int(rec["robot_mode"]))
        reasons: tuple[str, ...] = ()
        if status == MoveStatus.REFLEX_ABORTED:
            errors = Errors(rec["reflex_reason"])
            reasons = errors.active
            message += f" {errors}"
        rate = self.log[-1].control_command_success_rate if self.log else None
        if rate is not None:
            message += f"\ncontrol_command_success_rate: {rate:g}"
        raise ControlException(
            message, log=self.log, reflex_reason=reasons, status=status, success_rate=rate
        )

    def finish(self, command: bytearray, *, motion: bool, control: bool) -> None:
        """Send the datagram ``command`` flagged as the last command until the robot is
        idle, then take the final Move response (raise unless success)."""
        conn = self.conn
        record = np.ndarray((), conn.dialect.command_dtype, buffer=command)  # a view
        if motion:
            record["motion_generation_finished"] = True
        if control and conn.dialect.has_torque_command_finished:
            record["torque_command_finished"] = True
        header = _header(conn)
        deadline = time.monotonic() + FINISH_TIMEOUT
        while motion_running(header) and header[3] == _MOVE:  # type: ignore[index]
            if time.monotonic() > deadline:
                raise ControlException(
                    f"libfranka: the robot did not end the motion within {FINISH_TIMEOUT:g} s "
                    "of its last command", log=self.log,
                )  # fmt: skip
            conn.net.check_closed()
            self.send(command)
            conn.receive_state()
            header = conn.last_header
        status, _ = conn.response(Command.MOVE, self.move_id)
        self.final_received = True
        if status == MoveStatus.SUCCESS:
            self.done = True
            return
        rec = conn.dialect.decode_state(conn.last_data)
        if status == MoveStatus.REFLEX_ABORTED:
            errors = Errors(rec["reflex_reason"])
            raise ControlException(
                "libfranka: Move command aborted: Motion finished commanded, but the robot is "
                f"still moving! {errors}", log=self.log, reflex_reason=errors.active,
                status=status,
            )  # fmt: skip
        self._raise_final(status, conn.last_data)

    def cancel(self) -> None:
        """StopMove, wait for idle modes and swallow the pending Move response (errors
        here are ignored, as in libfranka's ``cancelMotion``)."""
        if self.done:
            return
        self.done = True
        conn = self.conn
        if conn.net.broken or conn.net.closed:
            return  # the robot is gone: nothing to stop, nothing to wait for
        try:
            conn.execute(Command.STOP_MOVE, timeout=STOP_TIMEOUT)
        except FrankaException:
            pass
        try:
            deadline = time.monotonic() + STOP_TIMEOUT
            while motion_running(_header(conn)) and time.monotonic() < deadline:
                conn.receive_state()
            if not self.final_received:
                self.final_received = True
                conn.response(Command.MOVE, self.move_id, timeout=STOP_TIMEOUT)
        except (NetworkException, FrankaException):
            pass
