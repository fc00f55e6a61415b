"""``VacuumGripper``: the Cobot Pump over its TCP/UDP protocol (v1, port 1339)."""

from __future__ import annotations

import datetime
import enum
from typing import Any

import numpy as np

from panda_py.fci import vacuum as vp
from panda_py.libfranka._hand import ACTION_TIMEOUT, HandClient
from panda_py.libfranka.types import Duration

__all__ = [
    "VacuumGripper",
    "VacuumGripperDeviceStatus",
    "VacuumGripperProductionSetupProfile",
    "VacuumGripperState",
]


class VacuumGripperDeviceStatus(enum.IntEnum):
    """The Cobot Pump's device status, as libfranka's ``VacuumGripperDeviceStatus`` (green:
    fine, to red: a fault)."""

    kGreen = 0
    kYellow = 1
    kOrange = 2
    kRed = 3


class VacuumGripperProductionSetupProfile(enum.IntEnum):
    """The Cobot Pump's production setup profiles P0-P3 (libfranka's
    ``VacuumGripperProductionSetupProfile``), chosen in ``vacuum()``."""

    kP0 = 0
    kP1 = 1
    kP2 = 2
    kP3 = 3


class VacuumGripperState:
    """The pump's state: vacuum level [mbar below ambient, as reported], ``actual_power``
    [%], part flags, ``device_status``, ``time`` (:class:`Duration`)."""

    __slots__ = ("actual_power", "device_status", "in_control_range", "part_detached",
                 "part_present", "time", "vacuum")  # fmt: skip

    def __init__(self, record: np.void) -> None:
        self.in_control_range = bool(record["in_control_range"])
        self.part_detached = bool(record["part_detached"])
        self.part_present = bool(record["part_present"])
        self.device_status = VacuumGripperDeviceStatus(int(record["device_status"]))
        self.actual_power = int(record["actual_power"])
        self.vacuum = int(record["vacuum"])
        self.time = Duration(int(record["message_id"]))


def _milliseconds(timeout: Any) -> int:
    if isinstance(timeout, datetime.timedelta):
        ms = round(timeout.total_seconds() * 1000.0)
    elif isinstance(timeout, Duration):
        ms = timeout.to_msec()
    elif isinstance(timeout, (int, np.integer)) and not isinstance(timeout, bool):
        ms = int(timeout)
    else:
        raise ValueError(f"timeout: expected a timedelta, Duration or int [ms], got {timeout!r}")
    if ms < 0:
        raise ValueError(f"timeout: expected >= 0 ms, got {ms} ms")
    return ms


class VacuumGripper(HandClient):
    """The Cobot Pump (libfranka's ``franka::VacuumGripper``); commands block until done
    and return True on success, False if unsuccessful; failures raise CommandException."""

    _LABEL = "vacuum gripper"
    _TITLE = "Vacuum Gripper"

    def __init__(self, hostname: str, *, timeout: float = ACTION_TIMEOUT) -> None:
        super().__init__(
            hostname,
            vp.VACUUM_COMMAND_PORT,
            vp.VACUUM_STATE_DTYPE.itemsize,
            vp.VACUUM_VERSION,
            timeout,
        )

    def _execute(self, command: vp.VacuumCommand, name: str, **fields: Any) -> bool:
        payload = vp.VACUUM_REQUESTS[command].encode(**fields)
        return self._run(
            name,
            lambda cid: vp.encode_vacuum_message(command, cid, payload),
            vp.decode_vacuum_status,
        )

    def vacuum(self, vacuum: int, timeout: Any,
               profile: VacuumGripperProductionSetupProfile =
               VacuumGripperProductionSetupProfile.kP0) -> bool:  # fmt: skip
        """Suck until the ``vacuum`` setpoint (0..255, passed through) is reached within
        ``timeout`` (timedelta, Duration or ms), with a production setup ``profile``."""
        if isinstance(vacuum, bool) or not isinstance(vacuum, (int, np.integer)):
            raise ValueError(f"vacuum: expected an int setpoint 0..255, got {vacuum!r}")
        if not 0 <= int(vacuum) <= 255:
            raise ValueError(f"vacuum: expected 0..255, got {vacuum}")
        try:
            p = VacuumGripperProductionSetupProfile(profile)
        except ValueError:
            raise ValueError(f"profile: expected kP0..kP3, got {profile!r}") from None
        return self._execute(vp.VacuumCommand.VACUUM, "Vacuum", vacuum=int(vacuum),
                             profile=int(p), timeout=_milliseconds(timeout))  # fmt: skip

    def drop_off(self, timeout: Any) -> bool:
        """Release the part within ``timeout``."""
        return self._execute(vp.VacuumCommand.DROP_OFF, "Drop Off", timeout=_milliseconds(timeout))

    def stop(self) -> bool:
        """Stop the pump's running action (libfranka's ``stop``); True on success."""
        return self._execute(vp.VacuumCommand.STOP, "Stop")

    def read_once(self) -> VacuumGripperState:
        """A fresh pump state: queued ones are discarded and the next awaited (up to 1 s),
        as libfranka's ``readOnce`` ("Waits for a vacuum gripper state update")."""
        return VacuumGripperState(vp.decode_vacuum_state(self._net.receive_fresh()))

    readOnce = read_once
