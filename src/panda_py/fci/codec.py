"""Generic building blocks of the FCI wire formats: payload codecs and a TCP framer.

Everything here is pure data: no sockets, no threads. The robot (``robot.py``), gripper
(``gripper.py``) and vacuum gripper (``vacuum.py``) protocols are built from these.
All layouts are little-endian and byte-packed (libfranka-common wraps every wire type in
``#pragma pack(push, 1)``), which a packed numpy structured dtype reproduces exactly.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

__all__ = [
    "MAX_MESSAGE_SIZE",
    "FciError",
    "FieldSpec",
    "Message",
    "MessageReader",
    "PayloadCodec",
    "ProtocolError",
    "packed_dtype",
]

#: Largest TCP message a :class:`MessageReader` accepts [bytes]. Responses carry a variable
#: tail (a URDF of some 100 kB, a model shared library of a few MB); anything beyond this
#: bound is taken as a corrupt ``size`` field rather than buffered.
MAX_MESSAGE_SIZE = 16 * 1024 * 1024

#: One field of a packed layout: ``(name, numpy type string)`` or
#: ``(name, numpy type string, shape)``.
FieldSpec = tuple[str, str] | tuple[str, str, int | tuple[int, ...]]


class FciError(Exception):
    """The root of this package's errors."""


class ProtocolError(FciError):
    """Bytes on the wire do not match the protocol: a size, a status or a version.

    Deliberately not a :class:`ValueError`: corrupt or hostile wire data is not a bad
    argument of the caller, and must not be swallowed by code that validates its input.
    ``what``, ``expected`` and ``got`` are kept as attributes for structured handling
    (and survive pickling).
    """

    def __init__(self, what: str, expected: object, got: object) -> None:
        super().__init__(f"{what}: expected {expected}, got {got}")
        self.what = what
        self.expected = expected
        self.got = got

    def __reduce__(self) -> tuple[type[ProtocolError], tuple[str, object, object]]:
        return type(self), (self.what, self.expected, self.got)


def packed_dtype(fields: Sequence[FieldSpec]) -> np.dtype[Any]:
    """A byte-packed (``align=False``) structured dtype of ``fields`` in the given order."""
    spec: list[Any] = []
    for field in fields:
        if len(field) == 2:
            spec.append((field[0], field[1]))
        else:
            spec.append((field[0], field[1], field[2]))
    dtype = np.dtype(spec, align=False)
    return dtype


class PayloadCodec:
    """Encoder/decoder of one fixed-layout payload, optionally followed by a byte tail.

    ``encode(**fields)`` packs keyword arguments (omitted fields are zero, as a
    value-initialised C++ struct would be); ``decode(data)`` returns a dict of Python scalars
    and (writable copies of) numpy arrays. If the codec has a ``tail`` (LoadModelLibrary's
    shared library, GetRobotModel's URDF), everything after the fixed part is returned as
    ``bytes`` under that name, and ``encode`` appends it.
    """

    __slots__ = ("_shapes", "dtype", "name", "size", "tail")

    def __init__(self, name: str, fields: Sequence[FieldSpec], *, tail: str | None = None):
        self.name = name
        self.dtype = packed_dtype(fields)
        #: Size of the fixed part [bytes] (the whole payload unless there is a tail).
        self.size: int = self.dtype.itemsize
        self.tail = tail
        self._shapes: dict[str, tuple[int, ...]] = {
            field: self.dtype.fields[field][0].shape  # type: ignore[index]
            for field in (self.dtype.names or ())
        }

    @property
    def field_names(self) -> tuple[str, ...]:
        """The fixed fields in wire order (without the tail)."""
        return tuple(self.dtype.names or ())

    def __repr__(self) -> str:
        tail = f", tail={self.tail!r}" if self.tail else ""
        return f"PayloadCodec({self.name!r}, size={self.size}{tail})"

    def encode(self, **fields: Any) -> bytes:
        """Pack ``fields`` into payload bytes; unknown names or wrong shapes are a ValueError."""
        tail_bytes = b""
        if self.tail is not None and self.tail in fields:
            value = fields.pop(self.tail)
            if not isinstance(value, (bytes, bytearray, memoryview)):
                raise ValueError(
                    f"{self.name}: {self.tail} must be bytes, got {type(value).__name__}"
                )
            tail_bytes = bytes(value)
        if self.size == 0:
            if fields:
                raise ValueError(f"{self.name}: takes no fields, got {sorted(fields)}")
            return tail_bytes
        record = np.zeros((), self.dtype)
        for key, value in fields.items():
            shape = self._shapes.get(key)
            if shape is None:
                valid = list(self._shapes) + ([self.tail] if self.tail else [])
                raise ValueError(f"{self.name}: unknown field {key!r}; valid fields: {valid}")
            got = np.shape(value)
            if got != shape:
                raise ValueError(
                    f"{self.name}: field {key!r} must have shape {shape}, got shape {got}"
                )
            try:
                record[key] = value
            except (TypeError, ValueError, OverflowError) as exc:
                raise ValueError(
                    f"{self.name}: field {key!r} cannot hold {value!r} "
                    f"(type {self.dtype.fields[key][0]})"  # type: ignore[index]
                ) from exc
        return record.tobytes() + tail_bytes

    def decode(self, data: bytes | bytearray | memoryview) -> dict[str, Any]:
        """Unpack payload bytes; a wrong size raises :class:`ProtocolError`."""
        n = len(data)
        if self.tail is None and n != self.size:
            raise ProtocolError(f"{self.name} payload size", f"{self.size} bytes", f"{n} bytes")
        if n < self.size:
            raise ProtocolError(
                f"{self.name} payload size", f"at least {self.size} bytes", f"{n} bytes"
            )
        out: dict[str, Any] = {}
        if self.size:
            record = np.frombuffer(data, self.dtype, count=1)[0]
            for key, shape in self._shapes.items():
                value = record[key]
                out[key] = np.array(value) if shape else value.item()
        if self.tail is not None:
            out[self.tail] = bytes(data[self.size :])
        return out


class Message(NamedTuple):
    """One complete TCP message as cut by :class:`MessageReader`."""

    command: int  #: raw command number from the header (map it with a dialect)
    command_id: int  #: the request counter the response must repeat
    payload: bytes  #: everything after the header
    raw: bytes  #: header + payload, exactly as received


class MessageReader:
    """Cuts a TCP byte stream into messages by the header's ``size`` field.

    Feed it whatever ``recv`` returned (any chunking, several pipelined messages, a
    message split across many chunks); :meth:`feed` returns the messages completed so far.
    A header whose ``size`` is smaller than the header or larger than ``max_size`` raises
    :class:`ProtocolError`; the stream cannot be resynchronised after that, so every later
    ``feed`` raises the same error.

    ``header`` is a ``struct.Struct`` of exactly three fields ``(command, command_id,
    size)``: ``'<III'`` (12 B) for the robot, ``'<HII'`` (10 B) for the grippers.
    """

    __slots__ = ("_buffer", "_error", "_header", "_max_size")

    def __init__(self, header: struct.Struct, *, max_size: int = MAX_MESSAGE_SIZE) -> None:
        if not isinstance(header, struct.Struct) or len(header.unpack(bytes(header.size))) != 3:
            raise ValueError(
                f"header must be a struct.Struct of (command, command_id, size), got {header!r}"
            )
        if not isinstance(max_size, int) or max_size < header.size:
            raise ValueError(f"max_size must be an int >= {header.size} bytes, got {max_size!r}")
        self._header = header
        self._max_size = max_size
        self._buffer = bytearray()
        self._error: ProtocolError | None = None

    @property
    def buffered(self) -> int:
        """Bytes received but not yet part of a complete message."""
        return len(self._buffer)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Message]:
        """Append ``data`` and return every message it completed, in stream order."""
        if self._error is not None:
            raise self._error
        buf = self._buffer
        buf += data
        header = self._header
        hsize = header.size
        messages: list[Message] = []
        pos = 0
        end = len(buf)
        while end - pos >= hsize:
            command, command_id, size = header.unpack_from(buf, pos)
            if size < hsize or size > self._max_size:
                self._error = ProtocolError(
                    "TCP message size", f"{hsize}..{self._max_size} bytes", f"{size} bytes"
                )
                raise self._error
            if end - pos < size:
                break
            raw = bytes(buf[pos : pos + size])
            messages.append(Message(command, command_id, raw[hsize:], raw))
            pos += size
        if pos:
            del buf[:pos]
        return messages
