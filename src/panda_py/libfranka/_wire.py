"""Byte-level access to one protocol version's RobotState and RobotCommand datagrams, for
the 1 kHz path.

A control tick should touch as little code as possible: between two ticks the process
sleeps and its caches go cold, and then every NumPy entry point (``frombuffer``, a record
field lookup, a slice assignment, ``tobytes``) costs 5-15 us instead of well under one. So
the per-tick path reads the fields it needs straight out of the received ``bytes`` with
pre-compiled :class:`struct.Struct` s, or (a control loop's ``TickState``) decodes the run
of float fields once (:meth:`Layout.decode_bulk`, a view where they are float64) and
slices it, and packs the command into one pre-allocated ``bytearray`` that is sent as is.
Offsets and formats come from the dialect's NumPy dtypes (:mod:`panda_py.fci` stays the
single source of the layouts).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py.fci import Dialect

__all__ = ["Block", "Field", "Layout", "layout"]

_CODES = {"f8": "d", "f4": "f", "u8": "Q", "u1": "B", "b1": "?"}


@dataclass(frozen=True)
class Field:
    """One state field: byte offset, element dtype, element count, array shape."""

    offset: int
    dtype: np.dtype[Any]
    count: int
    shape: tuple[int, ...]


@dataclass(frozen=True)
class Block:
    """Fields read or written together: ``struct_.unpack_from(data, offset)`` yields their
    elements in order (gaps between them skipped)."""

    struct_: struct.Struct
    offset: int

    def unpack(self, data: Any) -> tuple[Any, ...]:
        return self.struct_.unpack_from(data, self.offset)

    def pack(self, buffer: bytearray, *values: Any) -> None:
        self.struct_.pack_into(buffer, self.offset, *values)


def _block(dtype: np.dtype[Any], names: tuple[str, ...]) -> Block:
    """A Block over ``names`` (in increasing offset order) of the packed ``dtype``."""
    fmt = ["<"]
    start = position = dtype.fields[names[0]][1]  # type: ignore[index]
    for name in names:
        sub, offset = dtype.fields[name][:2]  # type: ignore[index]
        if offset < position:
            raise ValueError(f"fields {names} are not in increasing offset order")
        if offset > position:
            fmt.append(f"{offset - position}x")
        base = sub.base
        code = _CODES[f"{base.kind}{base.itemsize}"]
        count = int(np.prod(sub.shape)) if sub.shape else 1
        fmt.append(f"{count}{code}")
        position = offset + sub.itemsize
    return Block(struct.Struct("".join(fmt)), start)


class Layout:
    """Blocks and fields of one protocol version (obtain with :func:`layout`)."""

    def __init__(self, dialect: Dialect) -> None:
        sd, cd = dialect.state_dtype, dialect.command_dtype
        self.version = dialect.version
        self.fields: dict[str, Field] = {}
        self._spans: dict[tuple[str, ...], tuple[tuple[int, int], ...]] = {}
        self.scalars: dict[str, Block] = {}
        #: array field -> (unpack_from, offset, shape if not 1-D)
        self.arrays: dict[str, tuple[Any, int, tuple[int, ...] | None]] = {}
        for name in sd.names or ():
            sub, offset = sd.fields[name][:2]  # type: ignore[index]
            count = int(np.prod(sub.shape)) if sub.shape else 1
            self.fields[name] = Field(offset, sub.base, count, sub.shape)
            block = _block(sd, (name,))
            if not sub.shape:
                self.scalars[name] = block
            else:
                shape = sub.shape if len(sub.shape) > 1 else None
                self.arrays[name] = (block.struct_.unpack_from, offset, shape)
        self._find_bulk()
        # state: (message_id, motion_generator_mode, controller_mode, robot_mode)
        self.header = _block(
            sd, ("message_id", "motion_generator_mode", "controller_mode", "robot_mode")
        )
        if self.header.offset != 0 or cd.fields["message_id"][1] != 0:  # type: ignore[index]
            raise ValueError("message_id must lead the RobotState and the RobotCommand")
        self.tau_J_d = _block(sd, ("tau_J_d",))
        self.joint = _block(sd, ("q_d", "dq_d", "ddq_d"))  # 21 values
        self.elbow = _block(sd, ("elbow_c", "delbow_c", "ddelbow_c"))  # 6 values
        self.pose = _block(sd, ("O_T_EE_c", "O_dP_EE_c", "O_ddP_EE_c"))  # 28 values
        self.twist = _block(sd, ("O_dP_EE_c", "O_ddP_EE_c"))  # 12 values
        # command
        self.command_size = cd.itemsize
        self.c_message_id = _block(cd, ("message_id",))
        self.c_q = _block(cd, ("q_c",))
        self.c_dq = _block(cd, ("dq_c",))
        self.c_pose = _block(cd, ("O_T_EE_c",))
        self.c_twist = _block(cd, ("O_dP_EE_c",))
        self.c_elbow = _block(cd, ("elbow_c", "valid_elbow"))  # 2 values and a bool
        self.c_tau = _block(cd, ("tau_J_d",))

    def spans(self, names: tuple[str, ...]) -> tuple[tuple[int, int], ...]:
        """The byte ranges (start, stop) of the state's fields ``names`` in that order,
        fields that follow each other merged into one range (cached)."""
        spans = self._spans.get(names)
        if spans is None:
            fields = self.fields
            if not isinstance(names, tuple) or any(n not in fields for n in names):
                raise ValueError(
                    f"names: expected a tuple of the state's field names (e.g. ('q', 'dq')), "
                    f"got {names!r}"
                )
            merged: list[tuple[int, int]] = []
            for n in names:
                a = fields[n].offset
                b = a + fields[n].count * fields[n].dtype.itemsize
                if merged and merged[-1][1] == a:
                    merged[-1] = (merged[-1][0], b)
                else:
                    merged.append((a, b))
            spans = self._spans[names] = tuple(merged)
        return spans

    def _find_bulk(self) -> None:
        """The run of array fields after the header that share one float dtype and follow
        each other without a gap: decoded by a tick in one call (:meth:`decode_bulk`),
        each field then a slice of it (``bulk_slices``: name -> start, stop, shape)."""
        self.bulk: tuple[int, int, np.dtype[Any]] | None = None
        self.bulk_slices: dict[str, tuple[int, int, tuple[int, ...] | None]] = {}
        start = end = -1
        dtype: np.dtype[Any] | None = None
        for name, f in sorted(self.fields.items(), key=lambda item: item[1].offset):
            if dtype is None:
                if f.dtype.kind != "f":
                    continue  # the header
                dtype, start, end = f.dtype, f.offset, f.offset
            if f.dtype != dtype or f.offset != end:
                break  # the run ends at a field of another type, or a gap
            if name in self.arrays:  # (floats between the arrays, e.g. m_ee, run on)
                first = (end - start) // dtype.itemsize
                self.bulk_slices[name] = (first, first + f.count, self.arrays[name][2])
            end = f.offset + f.count * dtype.itemsize
        if dtype is not None:
            self.bulk = (start, (end - start) // dtype.itemsize, dtype)

    def decode_bulk(self, data: bytes) -> Any:
        """The bulk run of ``data`` as one read-only float64 array (a view of ``data``
        where it is float64 already, else one converted copy)."""
        assert self.bulk is not None
        offset, count, dtype = self.bulk
        out = np.frombuffer(data, dtype, count, offset)
        if dtype != _F64:
            out = out.astype(_F64)
            out.flags.writeable = False
        return out


_F64 = np.dtype("<f8")
_LAYOUTS: dict[int, Layout] = {}


def layout(dialect: Dialect) -> Layout:
    """The (cached) :class:`Layout` of ``dialect``."""
    found = _LAYOUTS.get(dialect.version)
    if found is None:
        found = _LAYOUTS[dialect.version] = Layout(dialect)
    return found
