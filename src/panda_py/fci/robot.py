"""The robot ("research interface") protocol: one :class:`Dialect` per protocol version.

A server picks the dialect from the client's Connect request (whose layout is the same in
every version, see :data:`CONNECT_REQUEST`); a client picks it from the version it speaks.

States and commands are numpy records of :attr:`Dialect.state_dtype` /
:attr:`Dialect.command_dtype`: a sender fills ``dialect.new_state()`` and calls
``dialect.encode_state(record)`` (= ``record.tobytes()``); a receiver calls
``dialect.decode_state(datagram)`` (= ``numpy.frombuffer``), a few microseconds each.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from types import MappingProxyType
from typing import Any

import numpy as np

from . import layouts
from .codec import MAX_MESSAGE_SIZE, MessageReader, PayloadCodec, ProtocolError
from .enums import ERROR_NAMES, Command, ConnectStatus
from .layouts import (
    COLLISION_THRESHOLD_FIELDS,
    NEWEST_VERSION,
    SUPPORTED_VERSIONS,
    state_float_fields,
)

__all__ = [
    "COLLISION_THRESHOLD_FIELDS",
    "COMMAND_PORT",
    "CONNECT_REQUEST",
    "CONNECT_RESPONSE",
    "DEFAULT_DEVIATION",
    "HEADER",
    "MAX_REQUEST_SIZE",
    "MESSAGE_ID",
    "NEWEST_VERSION",
    "PERIOD",
    "SUPPORTED_VERSIONS",
    "Dialect",
    "RobotMessageReader",
    "decode_connect_request",
    "decode_connect_response",
    "decode_header",
    "dialect",
    "encode_connect_request",
    "encode_connect_response",
    "encode_message",
    "state_float_fields",
]

#: Robot TCP command port (``research_interface::robot::kCommandPort``).
COMMAND_PORT = 1337
#: The robot's control period: one state and one command per millisecond [s] (libfranka
#: ``kDeltaT``; FCI docs: the robot streams states and expects commands at 1 kHz).
PERIOD = 0.001
#: The ``message_id`` every state and command starts with (u64 at offset 0).
MESSAGE_ID = struct.Struct("<Q")

#: Robot TCP header: command u32, command_id u32, size u32 (total incl. header) [12 B].
HEADER = struct.Struct("<III")
#: Connect request, header + version u16 + udp_port u16 (16 B; identical in every version).
CONNECT_REQUEST = struct.Struct("<IIIHH")
#: Connect response, header + status u8 + version u16 (15 B; identical in every version).
CONNECT_RESPONSE = struct.Struct("<IIIBH")

#: The Move deviations libfranka always sends: (translation [m], rotation [rad], elbow
#: [rad]) = (10.0, 3.12, 2π) (``ControlLoop::kDefaultDeviation``), for both the path and
#: the goal pose.
DEFAULT_DEVIATION: tuple[float, float, float] = (10.0, 3.12, 2.0 * math.pi)

_CONNECT_ID = 0  # Command::kConnect is 0 in every version


@dataclass(frozen=True, eq=False)
class Dialect:
    """Everything version-specific about the robot protocol of one ``version``.

    Obtain instances with :func:`dialect`; there is exactly one per supported version.
    """

    version: int
    #: Command -> wire id, only for the commands this version has.
    command_ids: Mapping[Command, int]
    #: Packed little-endian RobotState (UDP, robot -> client).
    state_dtype: np.dtype[Any]
    #: Packed little-endian RobotCommand (UDP, client -> robot).
    command_dtype: np.dtype[Any]
    #: Names of the ``errors``/``reflex_reason`` flags in wire order.
    error_names: tuple[str, ...]
    _commands: tuple[Command, ...] = field(repr=False)
    _status_by_wire: Mapping[type, tuple[Any, ...]] = field(repr=False)
    _wire_by_status: Mapping[tuple[type, Any], int] = field(repr=False)
    _requests: Mapping[Command, PayloadCodec] = field(repr=False)
    _responses: Mapping[Command, PayloadCodec] = field(repr=False)

    # --- protocol properties ----------------------------------------------------------

    @property
    def errors_count(self) -> int:
        """Number of error flags (37 up to v4, 41 from v5)."""
        return len(self.error_names)

    @property
    def state_size(self) -> int:
        """RobotState datagram size [bytes]."""
        return self.state_dtype.itemsize

    @property
    def command_size(self) -> int:
        """RobotCommand datagram size [bytes]."""
        return self.command_dtype.itemsize

    @property
    def has_get_cartesian_limit(self) -> bool:
        """Whether this version has the GetCartesianLimit command."""
        return Command.GET_CARTESIAN_LIMIT in self.command_ids

    @property
    def has_set_filters(self) -> bool:
        """Whether this version has the SetFilters command (v3-v5 only)."""
        return Command.SET_FILTERS in self.command_ids

    @property
    def has_load_model_library(self) -> bool:
        """Whether this version has the LoadModelLibrary command (the robot serves its model
        library)."""
        return Command.LOAD_MODEL_LIBRARY in self.command_ids

    @property
    def has_get_robot_model(self) -> bool:
        """Whether this version has the GetRobotModel command (the robot serves its URDF)."""
        return Command.GET_ROBOT_MODEL in self.command_ids

    @property
    def has_motion_generator_none(self) -> bool:
        """Move/state motion generator ``NONE`` (torque-only control without a generator)."""
        return self.version >= 7

    @property
    def has_torque_command_finished(self) -> bool:
        """RobotCommand carries ``torque_command_finished`` (371 instead of 370 bytes)."""
        return self.version >= 7

    @property
    def has_async_motion_generator(self) -> bool:
        """Move request carries ``use_async_motion_generator`` + ``maximum_velocity``."""
        return self.version >= 10

    @property
    def has_O_ddP_O(self) -> bool:
        """RobotState carries the base acceleration ``O_ddP_O``."""
        return self.version >= 5

    @property
    def has_accelerometers(self) -> bool:
        """RobotState carries ``accelerometer_top``/``accelerometer_bottom``."""
        return self.version >= 10

    @property
    def has_F_T_NE(self) -> bool:
        """RobotState carries ``F_T_NE``/``NE_T_EE`` (and SetNEToEE replaces SetFToEE)."""
        return self.version >= 4

    @property
    def move_request_dtype(self) -> np.dtype[Any]:
        """Packed Move request payload (56 B up to v9, 113 B in v10)."""
        return self._requests[Command.MOVE].dtype

    # --- commands and statuses --------------------------------------------------------

    def command_for_id(self, command: int) -> Command | None:
        """The command with wire id ``command``, or None if this version has none."""
        if 0 <= command < len(self._commands):
            return self._commands[command]
        return None

    def status_type(self, command: Command) -> type[Enum]:
        """The status enum of ``command``'s responses."""
        self._check_command(command)
        return layouts.STATUS_TYPES[command]

    def encode_status(self, status: Enum) -> int:
        """Wire value of ``status`` in this version (ValueError if the version lacks it)."""
        try:
            # keyed by (type, member): IntEnum members of different enums compare equal
            return self._wire_by_status[(type(status), status)]
        except (KeyError, TypeError):
            raise ValueError(
                f"status {status!r} does not exist in robot protocol version {self.version}"
            ) from None

    def decode_status(self, enum_cls: type[Enum], value: int) -> Any:
        """The member of ``enum_cls`` that wire value ``value`` means in this version.

        Raises :class:`ProtocolError` (a ValueError) for a value the version does not define.
        """
        table = self._status_by_wire.get(enum_cls)
        if table is None:
            raise ValueError(f"enum_cls must be a status enum, got {enum_cls!r}")
        if isinstance(value, (int, np.integer)) and 0 <= value < len(table):
            return table[value]
        raise ProtocolError(
            f"{enum_cls.__name__} value in protocol version {self.version}",
            f"0..{len(table) - 1}",
            repr(value),
        )

    # --- TCP payloads -----------------------------------------------------------------

    def request_payload(self, command: Command) -> PayloadCodec:
        """Codec of ``command``'s request payload (after the 12-byte header)."""
        self._check_command(command)
        return self._requests[command]

    def response_payload(self, command: Command) -> PayloadCodec:
        """Codec of ``command``'s response payload; its ``status`` field is the raw u8."""
        self._check_command(command)
        return self._responses[command]

    def encode_request(self, command: Command, command_id: int, **fields: Any) -> bytes:
        """A complete request message (header + payload)."""
        payload = self.request_payload(command).encode(**fields)
        return encode_message(self, command, command_id, payload)

    def encode_response(
        self, command: Command, command_id: int, status: Enum, **fields: Any
    ) -> bytes:
        """A complete response message; ``status`` is a member of ``status_type(command)``."""
        expected = self.status_type(command)
        if not isinstance(status, expected):
            raise ValueError(
                f"status for {command.name} must be a {expected.__name__}, got {status!r}"
            )
        payload = self.response_payload(command).encode(status=self.encode_status(status), **fields)
        return encode_message(self, command, command_id, payload)

    def decode_request(self, command: Command, payload: bytes) -> dict[str, Any]:
        """Fields of a request payload (ProtocolError on a wrong size)."""
        return self.request_payload(command).decode(payload)

    def decode_response(self, command: Command, payload: bytes) -> tuple[Any, dict[str, Any]]:
        """``(status member, other fields)`` of a response payload."""
        fields = self.response_payload(command).decode(payload)
        status = self.decode_status(self.status_type(command), fields.pop("status"))
        return status, fields

    # --- UDP state and command --------------------------------------------------------

    def new_state(self) -> np.ndarray:
        """A zeroed, writable 0-d RobotState record (fill fields, then ``encode_state``)."""
        return np.zeros((), self.state_dtype)

    def new_command(self) -> np.ndarray:
        """A zeroed, writable 0-d RobotCommand record."""
        return np.zeros((), self.command_dtype)

    def encode_state(self, record: np.ndarray | np.void) -> bytes:
        """RobotState datagram bytes of ``record`` (a record of :attr:`state_dtype`)."""
        if record.dtype is not self.state_dtype and record.dtype != self.state_dtype:
            raise ValueError(
                f"record must have the v{self.version} state_dtype, got dtype {record.dtype}"
            )
        return record.tobytes()

    def decode_state(self, data: bytes | bytearray | memoryview) -> np.void:
        """A read-only RobotState record viewing ``data``.

        Like libfranka, a datagram *longer* than :attr:`state_size` is silently truncated
        (libfranka reads into a ``sizeof(RobotState)`` buffer); a shorter one raises
        :class:`ProtocolError` ("incorrect object size" in libfranka). The record is a view:
        copy it (``record.copy()``) before reusing a ``bytearray`` receive buffer.
        """
        if len(data) < self.state_dtype.itemsize:
            raise ProtocolError(
                f"RobotState v{self.version} size",
                f"{self.state_dtype.itemsize} bytes",
                f"{len(data)} bytes",
            )
        return np.frombuffer(data, self.state_dtype, count=1)[0]

    def encode_command(self, record: np.ndarray | np.void) -> bytes:
        """RobotCommand datagram bytes of ``record`` (a record of :attr:`command_dtype`)."""
        if record.dtype is not self.command_dtype and record.dtype != self.command_dtype:
            raise ValueError(
                f"record must have the v{self.version} command_dtype, got dtype {record.dtype}"
            )
        return record.tobytes()

    def decode_command(self, data: bytes | bytearray | memoryview) -> np.void:
        """A read-only RobotCommand record viewing ``data`` (exact size required)."""
        if len(data) != self.command_dtype.itemsize:
            raise ProtocolError(
                f"RobotCommand v{self.version} size",
                f"{self.command_dtype.itemsize} bytes",
                f"{len(data)} bytes",
            )
        return np.frombuffer(data, self.command_dtype, count=1)[0]

    def active_errors(self, flags: Any) -> tuple[str, ...]:
        """Names of the set flags of an ``errors``/``reflex_reason`` array."""
        values = np.asarray(flags)
        if values.shape != (self.errors_count,):
            raise ValueError(
                f"flags must have shape ({self.errors_count},), got shape {values.shape}"
            )
        return tuple(name for name, v in zip(self.error_names, values.tolist(), strict=True) if v)

    def _check_command(self, command: Command) -> None:
        if command not in self.command_ids:
            raise ValueError(
                f"command {command!r} does not exist in robot protocol version "
                f"{self.version}; it has {[c.name for c in self._commands]}"
            )


def _build(version: int) -> Dialect:
    commands = tuple(layouts.command_list(version))
    tables = layouts.status_tables(version)
    wire_by_status = {(cls, m): i for cls, table in tables.items() for i, m in enumerate(table)}
    return Dialect(
        version=version,
        command_ids=MappingProxyType({c: i for i, c in enumerate(commands)}),
        state_dtype=layouts.state_dtype(version),
        command_dtype=layouts.command_dtype(version),
        error_names=ERROR_NAMES[: layouts.errors_count(version)],
        _commands=commands,
        _status_by_wire=MappingProxyType(tables),
        _wire_by_status=MappingProxyType(wire_by_status),
        _requests=MappingProxyType(layouts.request_codecs(version)),
        _responses=MappingProxyType(layouts.response_codecs(version)),
    )


_DIALECTS: dict[int, Dialect] = {v: _build(v) for v in SUPPORTED_VERSIONS}

#: The longest request of any supported version, header included [bytes]. Every request
#: is fixed-size, so a robot reads nothing longer: a larger ``size`` field means a broken
#: or hostile stream (give it to :class:`RobotMessageReader` as ``max_size``).
MAX_REQUEST_SIZE: int = HEADER.size + max(
    codec.size for d in _DIALECTS.values() for codec in d._requests.values()
)


def dialect(version: int) -> Dialect:
    """The :class:`Dialect` of robot protocol ``version``.

    Raises :class:`ProtocolError` (a ValueError) listing :data:`SUPPORTED_VERSIONS` if the
    version is not supported.
    """
    if isinstance(version, bool) or not isinstance(version, (int, np.integer)):
        raise ValueError(f"version must be an int in {SUPPORTED_VERSIONS}, got {version!r}")
    found = _DIALECTS.get(int(version))
    if found is None:
        raise ProtocolError("robot protocol version", f"one of {SUPPORTED_VERSIONS}", version)
    return found


# --- framing ------------------------------------------------------------------------


def _u32(name: str, value: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an int in 0..2**32-1, got {value!r}")
    if not 0 <= value <= 0xFFFFFFFF:
        raise ValueError(f"{name} must be in 0..2**32-1, got {value}")


def encode_message(d: Dialect, command: Command, command_id: int, payload: bytes) -> bytes:
    """Header + ``payload``, with ``command`` translated to ``d``'s wire id."""
    cmd = d.command_ids.get(command)
    if cmd is None:
        d._check_command(command)
    _u32("command_id", command_id)
    size = HEADER.size + len(payload)
    if size > MAX_MESSAGE_SIZE:
        raise ValueError(f"payload must be at most {MAX_MESSAGE_SIZE - 12} bytes, got {size}")
    return HEADER.pack(cmd, command_id, size) + bytes(payload)


def decode_header(data: bytes | bytearray | memoryview) -> tuple[int, int, int]:
    """``(command, command_id, size)`` from the first 12 bytes of ``data``."""
    if len(data) < HEADER.size:
        raise ProtocolError("robot TCP header", f"{HEADER.size} bytes", f"{len(data)} bytes")
    command, command_id, size = HEADER.unpack_from(data)
    if size < HEADER.size:
        raise ProtocolError("TCP message size", f">= {HEADER.size} bytes", f"{size} bytes")
    return command, command_id, size


class RobotMessageReader(MessageReader):
    """A :class:`MessageReader` for the robot's 12-byte header."""

    __slots__ = ()

    def __init__(self, *, max_size: int = MAX_MESSAGE_SIZE) -> None:
        super().__init__(HEADER, max_size=max_size)


# --- Connect (version-invariant) ----------------------------------------------------


def encode_connect_request(version: int, udp_port: int, *, command_id: int = 0) -> bytes:
    """Connect request (16 B): the client's protocol ``version`` and its UDP port."""
    for name, value in (("version", version), ("udp_port", udp_port)):
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
            raise ValueError(f"{name} must be an int in 0..65535, got {value!r}")
    _u32("command_id", command_id)
    return CONNECT_REQUEST.pack(_CONNECT_ID, command_id, CONNECT_REQUEST.size, version, udp_port)


def decode_connect_request(data: bytes | bytearray | memoryview) -> tuple[int, int, int]:
    """``(command_id, version, udp_port)`` of a complete Connect request."""
    if len(data) != CONNECT_REQUEST.size:
        raise ProtocolError(
            "Connect request size", f"{CONNECT_REQUEST.size} bytes", f"{len(data)} bytes"
        )
    command, command_id, size, version, udp_port = CONNECT_REQUEST.unpack(data)
    if command != _CONNECT_ID or size != CONNECT_REQUEST.size:
        raise ProtocolError(
            "Connect request header",
            f"command 0, size {CONNECT_REQUEST.size}",
            f"command {command}, size {size}",
        )
    return command_id, version, udp_port


def encode_connect_response(command_id: int, status: ConnectStatus, version: int) -> bytes:
    """Connect response (15 B); ``version`` is the robot's protocol version."""
    if not isinstance(status, ConnectStatus):
        raise ValueError(f"status must be a ConnectStatus, got {status!r}")
    if isinstance(version, bool) or not isinstance(version, int) or not 0 <= version <= 0xFFFF:
        raise ValueError(f"version must be an int in 0..65535, got {version!r}")
    _u32("command_id", command_id)
    return CONNECT_RESPONSE.pack(
        _CONNECT_ID, command_id, CONNECT_RESPONSE.size, int(status), version
    )


def decode_connect_response(
    data: bytes | bytearray | memoryview,
) -> tuple[int, ConnectStatus, int]:
    """``(command_id, status, version)`` of a complete Connect response."""
    if len(data) != CONNECT_RESPONSE.size:
        raise ProtocolError(
            "Connect response size", f"{CONNECT_RESPONSE.size} bytes", f"{len(data)} bytes"
        )
    command, command_id, size, status, version = CONNECT_RESPONSE.unpack(data)
    if command != _CONNECT_ID or size != CONNECT_RESPONSE.size:
        raise ProtocolError(
            "Connect response header",
            f"command 0, size {CONNECT_RESPONSE.size}",
            f"command {command}, size {size}",
        )
    try:
        connect_status = ConnectStatus(status)
    except ValueError:
        raise ProtocolError("ConnectStatus value", "0..2", status) from None
    return command_id, connect_status, version
