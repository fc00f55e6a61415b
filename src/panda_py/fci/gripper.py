"""Franka Hand gripper protocol, version 3 (libfranka 0.6.0 to 0.21.x, unchanged).

TCP 1338 with a 10-byte header (command u16, command_id u32, size u32) and u16 statuses;
the state comes as a 23-byte UDP datagram. Source: libfranka-common
``research_interface/gripper/types.h`` (kVersion 3 from commit 6c99ef9 to d96c221).
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from .codec import MAX_MESSAGE_SIZE, MessageReader, PayloadCodec, ProtocolError, packed_dtype

__all__ = [
    "GRIPPER_COMMAND_PORT",
    "GRIPPER_CONNECT_REQUEST",
    "GRIPPER_CONNECT_RESPONSE",
    "GRIPPER_HEADER",
    "GRIPPER_MAX_REQUEST_SIZE",
    "GRIPPER_REQUESTS",
    "GRIPPER_RESPONSE",
    "GRIPPER_STATE_DTYPE",
    "GRIPPER_VERSION",
    "GripperCommand",
    "GripperConnectStatus",
    "GripperMessageReader",
    "GripperStatus",
    "decode_gripper_connect_request",
    "decode_gripper_connect_response",
    "decode_gripper_state",
    "decode_gripper_status",
    "encode_gripper_connect_request",
    "encode_gripper_connect_response",
    "encode_gripper_message",
    "encode_gripper_state",
]

GRIPPER_VERSION = 3
"""The gripper protocol version spoken here (libfranka's ``kVersion`` of ``gripper_types.h``)."""
GRIPPER_COMMAND_PORT = 1338
"""The gripper's TCP port on the robot."""

#: Gripper TCP header: command u16, command_id u32, size u32 (total incl. header) [10 B].
GRIPPER_HEADER = struct.Struct("<HII")
#: Connect request: header + version u16 + udp_port u16 (14 B).
GRIPPER_CONNECT_REQUEST = struct.Struct("<HIIHH")
#: Connect response: header + status u16 + version u16 (14 B).
GRIPPER_CONNECT_RESPONSE = struct.Struct("<HIIHH")


class GripperCommand(enum.IntEnum):
    """The gripper protocol's command ids (libfranka's ``gripper_types.h``)."""

    CONNECT = 0
    HOMING = 1
    GRASP = 2
    MOVE = 3
    STOP = 4


class GripperStatus(enum.IntEnum):
    """Status (u16) of Homing/Grasp/Move/Stop. libfranka: SUCCESS -> True, UNSUCCESSFUL ->
    False, FAIL and ABORTED -> CommandException."""

    SUCCESS = 0
    FAIL = 1
    UNSUCCESSFUL = 2
    ABORTED = 3


class GripperConnectStatus(enum.IntEnum):
    """The gripper's answers to Connect (libfranka's ``gripper_types.h``; ``ROBOT_BUSY`` is
    panda-sim's)."""

    SUCCESS = 0
    INCOMPATIBLE_LIBRARY_VERSION = 1
    #: panda-sim only: another client holds the robot. A robot admits one client at a
    #: time but publishes no status for refusing a second one; libfranka reports any
    #: status but 0 and 1 as a protocol error, this package's client as "robot busy".
    ROBOT_BUSY = 2


#: Request payload codecs (after the 10-byte header). Widths [m], speed [m/s], force [N].
GRIPPER_REQUESTS: Mapping[GripperCommand, PayloadCodec] = MappingProxyType(
    {
        GripperCommand.CONNECT: PayloadCodec(
            "gripper Connect request", [("version", "<u2"), ("udp_port", "<u2")]
        ),
        GripperCommand.HOMING: PayloadCodec("gripper Homing request", []),
        GripperCommand.GRASP: PayloadCodec(
            "gripper Grasp request",
            [
                ("width", "<f8"),
                ("epsilon_inner", "<f8"),
                ("epsilon_outer", "<f8"),
                ("speed", "<f8"),
                ("force", "<f8"),
            ],
        ),
        GripperCommand.MOVE: PayloadCodec(
            "gripper Move request", [("width", "<f8"), ("speed", "<f8")]
        ),
        GripperCommand.STOP: PayloadCodec("gripper Stop request", []),
    }
)

#: Response payload of Homing/Grasp/Move/Stop: ``status`` u16 (a :class:`GripperStatus`).
GRIPPER_RESPONSE = PayloadCodec("gripper response", [("status", "<u2")])

#: GripperState UDP datagram (23 B): width/max_width [m], temperature [°C].
GRIPPER_STATE_DTYPE: np.dtype[Any] = packed_dtype(
    [
        ("message_id", "<u4"),
        ("width", "<f8"),
        ("max_width", "<f8"),
        ("is_grasped", "?"),
        ("temperature", "<u2"),
    ]
)


def _u32(name: str, value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFFFFFF:
        raise ValueError(f"{name} must be an int in 0..2**32-1, got {value!r}")


def _encode_small_message(command: int, command_id: int, payload: bytes) -> bytes:
    _u32("command_id", command_id)
    size = GRIPPER_HEADER.size + len(payload)
    if size > MAX_MESSAGE_SIZE:
        raise ValueError(f"payload must be at most {MAX_MESSAGE_SIZE - 10} bytes, got {size}")
    return GRIPPER_HEADER.pack(command, command_id, size) + bytes(payload)


def encode_gripper_message(command: GripperCommand, command_id: int, payload: bytes) -> bytes:
    """10-byte header + ``payload``."""
    return _encode_small_message(int(GripperCommand(command)), command_id, payload)


#: The longest gripper request, header included [bytes] (every request is fixed-size).
GRIPPER_MAX_REQUEST_SIZE: int = max(
    GRIPPER_HEADER.size + max(c.size for c in GRIPPER_REQUESTS.values()),
    GRIPPER_CONNECT_REQUEST.size,
)


class GripperMessageReader(MessageReader):
    """A :class:`MessageReader` for the gripper's 10-byte header."""

    __slots__ = ()

    def __init__(self, *, max_size: int = MAX_MESSAGE_SIZE) -> None:
        super().__init__(GRIPPER_HEADER, max_size=max_size)


def encode_gripper_state(record: np.ndarray | np.void) -> bytes:
    """GripperState datagram bytes of a record of :data:`GRIPPER_STATE_DTYPE`."""
    if record.dtype != GRIPPER_STATE_DTYPE:
        raise ValueError(f"record must have GRIPPER_STATE_DTYPE, got dtype {record.dtype}")
    return record.tobytes()


def decode_gripper_state(data: bytes | bytearray | memoryview) -> np.void:
    """A read-only GripperState record; longer datagrams are truncated like libfranka does,
    shorter ones raise :class:`ProtocolError`."""
    if len(data) < GRIPPER_STATE_DTYPE.itemsize:
        raise ProtocolError(
            "GripperState size", f"{GRIPPER_STATE_DTYPE.itemsize} bytes", f"{len(data)} bytes"
        )
    return np.frombuffer(data, GRIPPER_STATE_DTYPE, count=1)[0]


def _u16(name: str, value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
        raise ValueError(f"{name} must be an int in 0..65535, got {value!r}")


def _check_connect(what: str, data: bytes | bytearray | memoryview) -> tuple[int, int, int]:
    size = GRIPPER_CONNECT_REQUEST.size
    if len(data) != size:
        raise ProtocolError(f"{what} size", f"{size} bytes", f"{len(data)} bytes")
    command, command_id, declared, a, b = GRIPPER_CONNECT_REQUEST.unpack(data)
    if command != GripperCommand.CONNECT or declared != size:
        raise ProtocolError(
            f"{what} header", f"command 0, size {size}", f"command {command}, size {declared}"
        )
    return command_id, a, b


def encode_gripper_connect_request(
    udp_port: int, *, version: int = GRIPPER_VERSION, command_id: int = 0
) -> bytes:
    """Connect request (14 B). The vacuum gripper uses the same layout with its version."""
    _u16("udp_port", udp_port)
    _u16("version", version)
    _u32("command_id", command_id)
    return GRIPPER_CONNECT_REQUEST.pack(
        GripperCommand.CONNECT, command_id, GRIPPER_CONNECT_REQUEST.size, version, udp_port
    )


def decode_gripper_connect_request(
    data: bytes | bytearray | memoryview,
) -> tuple[int, int, int]:
    """``(command_id, version, udp_port)`` of a complete gripper Connect request."""
    return _check_connect("gripper Connect request", data)


def encode_gripper_connect_response(
    command_id: int, status: GripperConnectStatus, *, version: int = GRIPPER_VERSION
) -> bytes:
    """Connect response (14 B): status u16 + the server's version."""
    if not isinstance(status, GripperConnectStatus):
        raise ValueError(f"status must be a GripperConnectStatus, got {status!r}")
    _u16("version", version)
    _u32("command_id", command_id)
    return GRIPPER_CONNECT_RESPONSE.pack(
        GripperCommand.CONNECT, command_id, GRIPPER_CONNECT_RESPONSE.size, status, version
    )


def decode_gripper_connect_response(
    data: bytes | bytearray | memoryview,
) -> tuple[int, GripperConnectStatus, int]:
    """``(command_id, status, version)`` of a complete gripper Connect response."""
    command_id, status, version = _check_connect("gripper Connect response", data)
    try:
        return command_id, GripperConnectStatus(status), version
    except ValueError:
        raise ProtocolError("GripperConnectStatus value", "0..2", status) from None


def decode_gripper_status(payload: bytes | bytearray | memoryview) -> GripperStatus:
    """The :class:`GripperStatus` of a Homing/Grasp/Move/Stop response payload."""
    value = GRIPPER_RESPONSE.decode(payload)["status"]
    try:
        return GripperStatus(value)
    except ValueError:
        raise ProtocolError("GripperStatus value", "0..3", value) from None
