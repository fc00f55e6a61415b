"""Vacuum gripper (Cobot Pump) protocol, version 1 (libfranka 0.8.0 to 0.21.x, unchanged).

TCP 1339 with the gripper's 10-byte header and u16 statuses; Connect messages have the
gripper's layout (use :func:`~panda_py.fci.gripper.encode_gripper_connect_request` etc.
with ``version=VACUUM_VERSION``). Source: libfranka-common
``research_interface/vacuum_gripper/types.h`` (kVersion 1 from commit af64d3e to d96c221);
``std::chrono::milliseconds`` is a signed 64-bit count on the supported platforms.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from .codec import PayloadCodec, ProtocolError, packed_dtype
from .gripper import GRIPPER_CONNECT_REQUEST, GRIPPER_HEADER, _encode_small_message

__all__ = [
    "VACUUM_COMMAND_PORT",
    "VACUUM_HEADER",
    "VACUUM_MAX_REQUEST_SIZE",
    "VACUUM_REQUESTS",
    "VACUUM_RESPONSE",
    "VACUUM_SETPOINT_UNIT",
    "VACUUM_STATE_DTYPE",
    "VACUUM_VERSION",
    "VacuumCommand",
    "VacuumDeviceStatus",
    "VacuumProfile",
    "VacuumStatus",
    "decode_vacuum_state",
    "decode_vacuum_status",
    "encode_vacuum_message",
    "encode_vacuum_state",
]

VACUUM_VERSION = 1
VACUUM_COMMAND_PORT = 1339
#: Same 10-byte header as the gripper: command u16, command_id u32, size u32.
VACUUM_HEADER = GRIPPER_HEADER


class VacuumCommand(enum.IntEnum):
    CONNECT = 0
    VACUUM = 1
    DROP_OFF = 2
    STOP = 3


class VacuumStatus(enum.IntEnum):
    SUCCESS = 0
    FAIL = 1
    UNSUCCESSFUL = 2
    ABORTED = 3


class VacuumProfile(enum.IntEnum):
    P0 = 0
    P1 = 1
    P2 = 2
    P3 = 3


class VacuumDeviceStatus(enum.IntEnum):
    GREEN = 0
    YELLOW = 1
    ORANGE = 2
    RED = 3


#: What one unit of the Vacuum request's setpoint means [mbar]: libfranka's
#: ``vacuum_gripper.h`` documents ``vacuum(vacuum, ...)``'s setpoint as "Unit: [10*mbar]";
#: the state's ``vacuum`` is in mbar (``vacuum_gripper_state.h``).
VACUUM_SETPOINT_UNIT = 10.0

#: Request payload codecs (after the 10-byte header): ``vacuum`` is the u8 setpoint that
#: libfranka's ``VacuumGripper::vacuum(vacuum, timeout, profile)`` passes through (in
#: :data:`VACUUM_SETPOINT_UNIT`), ``profile`` a :class:`VacuumProfile`, ``timeout`` [ms].
VACUUM_REQUESTS: Mapping[VacuumCommand, PayloadCodec] = MappingProxyType(
    {
        VacuumCommand.CONNECT: PayloadCodec(
            "vacuum Connect request", [("version", "<u2"), ("udp_port", "<u2")]
        ),
        VacuumCommand.VACUUM: PayloadCodec(
            "vacuum Vacuum request", [("vacuum", "u1"), ("profile", "u1"), ("timeout", "<i8")]
        ),
        VacuumCommand.DROP_OFF: PayloadCodec("vacuum DropOff request", [("timeout", "<i8")]),
        VacuumCommand.STOP: PayloadCodec("vacuum Stop request", []),
    }
)

#: Response payload of Vacuum/DropOff/Stop: ``status`` u16 (a :class:`VacuumStatus`).
VACUUM_RESPONSE = PayloadCodec("vacuum response", [("status", "<u2")])

#: The longest vacuum request, header included [bytes] (every request is fixed-size).
VACUUM_MAX_REQUEST_SIZE: int = max(
    VACUUM_HEADER.size + max(c.size for c in VACUUM_REQUESTS.values()),
    GRIPPER_CONNECT_REQUEST.size,
)

#: VacuumGripperState UDP datagram (16 B): ``vacuum`` [mbar below ambient],
#: ``actual_power`` [%] (libfranka's ``vacuum_gripper_state.h``).
VACUUM_STATE_DTYPE: np.dtype[Any] = packed_dtype(
    [
        ("message_id", "<u4"),
        ("in_control_range", "?"),
        ("part_detached", "?"),
        ("part_present", "?"),
        ("device_status", "u1"),  # VacuumDeviceStatus
        ("actual_power", "<i4"),
        ("vacuum", "<i4"),
    ]
)


def encode_vacuum_state(record: np.ndarray | np.void) -> bytes:
    """VacuumGripperState datagram bytes of a record of :data:`VACUUM_STATE_DTYPE`."""
    if record.dtype != VACUUM_STATE_DTYPE:
        raise ValueError(f"record must have VACUUM_STATE_DTYPE, got dtype {record.dtype}")
    return record.tobytes()


def decode_vacuum_state(data: bytes | bytearray | memoryview) -> np.void:
    """A read-only VacuumGripperState record (longer datagrams truncated, shorter rejected)."""
    if len(data) < VACUUM_STATE_DTYPE.itemsize:
        raise ProtocolError(
            "VacuumGripperState size", f"{VACUUM_STATE_DTYPE.itemsize} bytes", f"{len(data)} bytes"
        )
    return np.frombuffer(data, VACUUM_STATE_DTYPE, count=1)[0]


def encode_vacuum_message(command: VacuumCommand, command_id: int, payload: bytes) -> bytes:
    """10-byte header + ``payload``."""
    return _encode_small_message(int(VacuumCommand(command)), command_id, payload)


def decode_vacuum_status(payload: bytes | bytearray | memoryview) -> VacuumStatus:
    """The :class:`VacuumStatus` of a Vacuum/DropOff/Stop response payload."""
    value = VACUUM_RESPONSE.decode(payload)["status"]
    try:
        return VacuumStatus(value)
    except ValueError:
        raise ProtocolError("VacuumStatus value", "0..3", value) from None
