"""The Move lifecycle of one motion (fci-protocol.md §6), as libfranka's ``startMotion``,
``updateMotion``, ``throwOnMotionError``, ``finishMotion`` and ``cancelMotion``."""

from __future__ import annotations

import time
from collections import deque
from typing import Any

import numpy as np

from panda_py.fci import (
    DEFAULT_DEVIATION,
    Command,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
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

_STATE_MG = {
    MoveMotionGeneratorMode.JOINT_POSITION: MotionGeneratorMode.JOINT_POSITION,
    MoveMotionGeneratorMode.JOINT_VELOCITY: MotionGeneratorMode.JOINT_VELOCITY,
    MoveMotionGeneratorMode.CARTESIAN_POSITION: MotionGeneratorMode.CARTESIAN_POSITION,
    MoveMotionGeneratorMode.CARTESIAN_VELOCITY: MotionGeneratorMode.CARTESIAN_VELOCITY,
    MoveMotionGeneratorMode.NONE: MotionGeneratorMode.NONE,
}
_IDLE_MG = (int(MotionGeneratorMode.IDLE), int(MotionGeneratorMode.NONE))
_EXTERNAL = int(ControllerMode.EXTERNAL_CONTROLLER)
_MOVE = int(RobotMode.MOVE)


def motion_running(rec: np.void | None) -> bool:
    """libfranka's ``motionGeneratorRunning() || controllerRunning()`` for a state record."""
    if rec is None:
        return False
    return (
        int(rec["motion_generator_mode"]) not in _IDLE_MG
        or int(rec["controller_mode"]) == _EXTERNAL
    )


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
    ) -> None:
        if motion_running(conn.last):
            raise InvalidOperationException("libfranka: Attempted to start multiple motions!")
        self.conn = conn
        self.log = log
        self.done = False  # finished or cancelled: nothing left to clean up
        self.final_received = False  # the second Move response has been taken
        self.caller_driven = False  # an ActiveControl (the caller's thread) runs the loop
        self.expect_mg = int(_STATE_MG[generator])
        self.expect_ctrl = int(controller)
        d = conn.dialect
        fields: dict[str, Any] = {
            "controller_mode": int(controller),
            "motion_generator_mode": int(generator),
            "maximum_path_deviation": np.array(DEFAULT_DEVIATION),
            "maximum_goal_pose_deviation": np.array(DEFAULT_DEVIATION),
        }
        if d.has_async_motion_generator:
            fields["use_async_motion_generator"] = False
            fields["maximum_velocity"] = np.zeros(7)
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
                rec = conn.receive_state()
                if (
                    int(rec["robot_mode"]) == _MOVE
                    and int(rec["motion_generator_mode"]) == self.expect_mg
                    and int(rec["controller_mode"]) == self.expect_ctrl
                ):
                    break
                final = conn.poll(Command.MOVE, self.move_id)
                if final is not None:
                    self._raise_final(final[0], rec)
                if time.monotonic() > deadline:
                    raise ControlException("libfranka: the robot did not start the motion")
        except BaseException:
            self.cancel()
            raise

    def _mode(self) -> int | None:
        last = self.conn.last
        return None if last is None else int(last["robot_mode"])

    # --- per tick ---------------------------------------------------------------------

    def receive(self) -> np.void:
        """Check the TCP connection, take the newest state, raise if the motion ended."""
        conn = self.conn
        conn.net.check_closed()
        rec = conn.receive_state()
        if (
            int(rec["robot_mode"]) != _MOVE
            or int(rec["motion_generator_mode"]) != self.expect_mg
            or int(rec["controller_mode"]) != self.expect_ctrl
        ):
            self._abort(rec)
        return rec

    def send(self, record: np.ndarray) -> None:
        """Send ``record`` as the answer to the newest state."""
        record["message_id"] = self.conn.last_id
        self.conn.send_command(record)

    # --- ending -----------------------------------------------------------------------

    def _abort(self, rec: np.void) -> None:
        """The robot left the motion: collect the final Move response and raise."""
        status, _ = self.conn.response(Command.MOVE, self.move_id)
        self._raise_final(status, rec)

    def _raise_final(self, status: Any, rec: np.void) -> None:
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

    def finish(self, record: np.ndarray, *, motion: bool, control: bool) -> None:
        """Send ``record`` flagged as the last command until the robot is idle, then take
        the final Move response (raise unless success)."""
        if motion:
            record["motion_generation_finished"] = True
        if control and self.conn.dialect.has_torque_command_finished:
            record["torque_command_finished"] = True
        conn = self.conn
        rec = conn.last
        while motion_running(rec) and int(rec["robot_mode"]) == _MOVE:  # type: ignore[index]
            conn.net.check_closed()
            self.send(record)
            rec = conn.receive_state()
        status, _ = conn.response(Command.MOVE, self.move_id)
        self.final_received = True
        if status == MoveStatus.SUCCESS:
            self.done = True
            return
        if status == MoveStatus.REFLEX_ABORTED:
            errors = Errors(rec["reflex_reason"])  # type: ignore[index]
            raise ControlException(
                "libfranka: Move command aborted: Motion finished commanded, but the robot is "
                f"still moving! {errors}", log=self.log, reflex_reason=errors.active,
                status=status,
            )  # fmt: skip
        self._raise_final(status, rec)  # type: ignore[arg-type]

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
            while motion_running(conn.last) and time.monotonic() < deadline:
                conn.receive_state()
            if not self.final_received:
                self.final_received = True
                conn.response(Command.MOVE, self.move_id, timeout=STOP_TIMEOUT)
        except (NetworkException, FrankaException):
            pass
