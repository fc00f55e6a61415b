"""``VacuumGripper``: the Cobot Pump over its TCP/UDP protocol (v1, port 1339)."""

from __future__ import annotations

import datetime
import enum
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import vacuum as vp
from panda_py.libfranka._network import Network, translate
from panda_py.libfranka.errors import CommandException, IncompatibleVersionException
from panda_py.libfranka.gripper import ACTION_TIMEOUT
from panda_py.libfranka.types import Duration

__all__ = [
    "VacuumGripper",
    "VacuumGripperDeviceStatus",
    "VacuumGripperProductionSetupProfile",
    "VacuumGripperState",
]


class VacuumGripperDeviceStatus(enum.IntEnum):
    kGreen = 0
    kYellow = 1
    kOrange = 2
    kRed = 3


class VacuumGripperProductionSetupProfile(enum.IntEnum):
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


class VacuumGripper:
    """The Cobot Pump (libfranka's ``franka::VacuumGripper``); commands block until done
    and return True on success, False if unsuccessful; failures raise CommandException."""

    def __init__(self, hostname: str, *, timeout: float = ACTION_TIMEOUT) -> None:
        self._net = Network(
            hostname,
            vp.VACUUM_COMMAND_PORT,
            fci.GripperMessageReader(),  # the same 10-byte header as the hand
            udp_size=vp.VACUUM_STATE_DTYPE.itemsize,
            timeout=timeout,
        )
        self._next_id = 0
        try:
            request = fci.encode_gripper_connect_request(
                self._net.udp_port, version=vp.VACUUM_VERSION, command_id=self._take_id()
            )
            self._net.send(request)
            msg = self._net.wait_response(0)
            try:
                _, status, version = fci.decode_gripper_connect_response(msg.raw)
            except fci.ProtocolError as exc:
                raise translate(exc, "Vacuum Gripper Connect") from exc
            if status != fci.GripperConnectStatus.SUCCESS:
                raise IncompatibleVersionException(
                    f"libfranka vacuum gripper: Incompatible library version (server version: "
                    f"{version}, library version: {vp.VACUUM_VERSION}).",
                    server_version=version,
                    library_version=vp.VACUUM_VERSION,
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

    def __enter__(self) -> VacuumGripper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def server_version(self) -> int:
        return self._server_version

    def _execute(self, command: vp.VacuumCommand, name: str, **fields: Any) -> bool:
        cid = self._take_id()
        payload = vp.VACUUM_REQUESTS[command].encode(**fields)
        self._net.send(vp.encode_vacuum_message(command, cid, payload))
        msg = self._net.wait_response(cid)
        try:
            status = vp.decode_vacuum_status(msg.payload)
        except fci.ProtocolError as exc:
            raise translate(exc, f"Vacuum Gripper {name} response") from exc
        if status == vp.VacuumStatus.SUCCESS:
            return True
        if status == vp.VacuumStatus.UNSUCCESSFUL:
            return False
        what = "failed" if status == vp.VacuumStatus.FAIL else "aborted"
        raise CommandException(
            f"libfranka vacuum gripper: {name} command {what}!", command=name, status=status
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
        return self._execute(vp.VacuumCommand.STOP, "Stop")

    def read_once(self) -> VacuumGripperState:
        """The newest pump state (waits up to 1 s)."""
        return VacuumGripperState(vp.decode_vacuum_state(self._net.receive_any()))
