"""The memory the user's process and the control process share.

One anonymous file (``memfd``, already unlinked: nothing can leak when either process
dies) holds, at fixed offsets:

* a header of int64 counters (:class:`Slot` numbers below);
* the newest robot state datagram, as a latch (two copies; the control process writes
  them once a tick, readers copy the one not being written);
* the running controller's inputs (``signals``), under a seqlock written by the user's
  process and read by the loop, which keeps its last consistent copy instead of waiting;
* the controller's outputs (its time and declared outputs), a latch written by the loop.

A seqlock's writer makes the sequence number odd, writes, and makes it even again;
aligned 8-byte stores are atomic, and a memory fence (:mod:`.fence`: a no-op on x86-64,
which keeps stores and loads in order by itself; a hardware fence on aarch64, which does
not) stands between the number and the data on both sides, so a reader that sees the same
even number before and after its copy has a consistent copy. No side ever waits for the
other, so the 1 kHz loop never takes a lock the user's process can hold.

The log ring buffer lives in its own file (:class:`LogRing`), made when logging is enabled.
"""

from __future__ import annotations

import functools
import mmap
import os
import struct
import tempfile
from collections.abc import Callable
from typing import Any

import numpy as np

from panda_py.rt.fence import memory_fence, no_fence

__all__ = [
    "HEADER",
    "LOG_FIELDS",
    "SIGNALS_MAX",
    "STATE_MAX",
    "LogRing",
    "SharedBlock",
    "anonymous_file",
]

# the RobotState fields the log keeps (panda-py's get_log keys; message_id gives "time")
LOG_FIELDS = (
    "message_id",
    "q",
    "dq",
    "tau_J",
    "O_T_EE",
    "O_F_ext_hat_K",
    "K_F_ext_hat_K",
    "tau_ext_hat_filtered",
    "elbow",
    "control_command_success_rate",
)
STATE_MAX = 4096  # [bytes] the largest state datagram of any protocol version fits
SIGNALS_MAX = 1024  # float64 values a controller may declare as inputs
OUTPUTS_MAX = 256  # float64 values of outputs (time first)
# A log snapshot the writer crossed drops the record it was writing: copy again, up to
# this many times (a long ring, whose copy outlasts a tick, keeps the last copy).
SNAPSHOT_TRIES = 3


class HEADER:
    """Indices of the int64 header counters."""

    STATE_SEQ = 0  # latch sequence of the state slot's two copies
    STATE_LEN = 1  # bytes in a state copy
    TICKS = 2  # states published so far
    RUNNING = 3  # 1 while a controller or a move runs
    EVENTS = 4  # asynchronous events (errors, log lines) posted on the channel
    IN_SEQ = 5  # seqlock of the controller inputs (writer: user's process)
    OUT_SEQ = 6  # latch sequence of the controller outputs (writer: control process)
    LOG_COUNT = 7  # states appended to the log ring so far
    REQUESTS = 8  # requests sent on the channel so far (user's process, after each send)
    COMPILED = 9  # of TICKS, those the compiled loop ran (rt.fastloop): which path ran
    COUNT = 16


_HEADER_BYTES = 8 * HEADER.COUNT
_STATE_OFF = (_HEADER_BYTES, _HEADER_BYTES + STATE_MAX)  # two copies
_IN_OFF = _HEADER_BYTES + 2 * STATE_MAX
_OUT_OFF = (_IN_OFF + 8 * SIGNALS_MAX, _IN_OFF + 8 * (SIGNALS_MAX + OUTPUTS_MAX))
_SIZE = _OUT_OFF[1] + 8 * OUTPUTS_MAX


# a copy of a state field out of one of the two state slots (SharedBlock.slot_copies)
SlotCopy = Callable[[], np.ndarray]


def _fenced(copy: SlotCopy, fence: Callable[[], None]) -> SlotCopy:
    def fenced_copy() -> np.ndarray:
        fence()
        out = copy()
        fence()
        return out

    return fenced_copy


def anonymous_file(size: int, name: str = "panda_py") -> int:
    """A file descriptor of ``size`` zero bytes that no path names (memfd where the
    platform has it, else an unlinked temporary file)."""
    if hasattr(os, "memfd_create"):
        fd = os.memfd_create(name, 0)
    else:  # pragma: no cover - non-Linux
        fd, path = tempfile.mkstemp(prefix=name)
        os.unlink(path)
    try:
        os.ftruncate(fd, size)
    except OSError:
        os.close(fd)
        raise
    return fd


class SharedBlock:
    """The header, state and controller slots over one shared file ``fd``.

    The state and the outputs, written by the control process, are latches: two copies,
    the writer bumps the sequence number before each copy it writes, and readers read
    the copy the sequence's parity names (the one not being written). A reader retries
    only if the writer moved on during its read, so it never waits on a writer that the
    scheduler stopped mid-write.
    """

    SIZE = _SIZE

    def __init__(self, fd: int) -> None:
        self._mm = mmap.mmap(fd, _SIZE)
        self._mv = memoryview(self._mm)
        self.header = self._mv[:_HEADER_BYTES].cast("q")
        self._states = tuple(self._mv[o : o + STATE_MAX] for o in _STATE_OFF)
        self.signals = np.frombuffer(self._mm, np.float64, SIGNALS_MAX, _IN_OFF)
        self._outputs = tuple(np.frombuffer(self._mm, np.float64, OUTPUTS_MAX, o) for o in _OUT_OFF)
        self._in = self._mv[_IN_OFF : _IN_OFF + 8 * SIGNALS_MAX]
        self._fence = memory_fence()

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For a compiled loop (:mod:`panda_py.rt._tick`): NumPy views of the header
        (int64), the state slot's two copies (uint8, ``2 * STATE_MAX``), the controller
        inputs (float64) and the outputs' two copies (float64, ``(2, OUTPUTS_MAX)``)."""
        header = np.frombuffer(self._mm, np.int64, HEADER.COUNT, 0)
        states = np.frombuffer(self._mm, np.uint8, 2 * STATE_MAX, _STATE_OFF[0])
        outputs = np.frombuffer(self._mm, np.float64, 2 * OUTPUTS_MAX, _OUT_OFF[0])
        return header, states, self.signals, outputs.reshape(2, OUTPUTS_MAX)

    @classmethod
    def create(cls) -> tuple[SharedBlock, int]:
        """A new zeroed block and the descriptor to hand to the other process."""
        fd = anonymous_file(_SIZE)
        return cls(fd), fd

    def close(self) -> None:
        for view in (self.header, *self._states, self._in, self._mv):
            view.release()
        self.signals = np.zeros(0)
        self._outputs = (np.zeros(0), np.zeros(0))
        try:
            self._mm.close()
        except BufferError:  # a caller still holds a view; the mapping goes with it
            pass

    # --- the state slot (writer: control process) ---------------------------------------

    def publish_state(self, data: bytes) -> None:
        h, fence = self.header, self._fence
        n = len(data)
        first, second = self._states
        h[HEADER.STATE_SEQ] += 1  # odd: readers take copy 1 while copy 0 is written
        fence()
        first[:n] = data
        h[HEADER.STATE_LEN] = n
        fence()
        h[HEADER.STATE_SEQ] += 1  # even: readers take copy 0
        fence()
        second[:n] = data
        fence()
        h[HEADER.TICKS] += 1

    def field_views(self, state_dtype: np.dtype, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Live views of one field in both state copies, for :meth:`read_field`."""
        fields = state_dtype.fields
        assert fields is not None
        sub, offset = fields[name][0], fields[name][1]
        count = int(np.prod(sub.shape)) if sub.shape else 1
        views = [np.frombuffer(self._mm, sub.base, count, o + offset) for o in _STATE_OFF]
        return views[0], views[1]

    def slot_copies(self, views: tuple[np.ndarray, np.ndarray]) -> tuple[SlotCopy, SlotCopy]:
        """For a reader that takes the state latch inline (``Panda.q``, ``get_pose``: a
        user's hot path, 0.39 us a call here against 0.46 through a reader function of
        the block's): per state copy, a function returning a float64 copy of the field in
        ``views``, its memory order kept, fenced before and after where the machine
        reorders loads. The reader keeps :meth:`read_field`'s order: the number, the copy
        of the slot it names (``seq & 1``), the number again, until they agree."""
        copies: list[SlotCopy] = [
            view.__copy__
            if view.dtype == np.float64
            else functools.partial(view.astype, np.float64)
            for view in views
        ]
        fence = self._fence
        if fence is not no_fence:
            copies = [_fenced(copy, fence) for copy in copies]
        return copies[0], copies[1]

    def read_field(self, views: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """A consistent float64 copy of a state field (``views`` from :meth:`field_views`)."""
        h, fence = self.header, self._fence
        while True:
            seq = h[0]  # HEADER.STATE_SEQ
            fence()
            out = views[seq & 1].astype(np.float64)
            fence()
            if seq == h[0]:
                return out

    def read_state(self) -> bytes | None:
        """A consistent copy of the newest state datagram (None before the first)."""
        h, fence = self.header, self._fence
        states = self._states
        while True:
            seq = h[HEADER.STATE_SEQ]
            fence()
            n = h[HEADER.STATE_LEN]
            data = bytes(states[seq & 1][:n])
            fence()
            if h[HEADER.STATE_SEQ] == seq:
                return data if n else None

    # --- controller inputs (writer: user's process) -------------------------------------

    def write_packed(self, packer: struct.Struct, offset: int, values: Any) -> None:
        """Write ``values`` (a sequence of floats, packed by ``packer``) at float64 index
        ``offset`` of the inputs, as one seqlock write."""
        h, fence = self.header, self._fence
        h[5] += 1  # HEADER.IN_SEQ: odd while writing
        fence()
        packer.pack_into(self._in, 8 * offset, *values)
        fence()
        h[5] += 1

    def write_packed_many(self, pieces: Any) -> None:
        """Write several ``(packer, offset, values)`` pieces as one seqlock write."""
        h, fence = self.header, self._fence
        h[HEADER.IN_SEQ] += 1
        fence()
        try:
            for packer, offset, values in pieces:
                packer.pack_into(self._in, 8 * offset, *values)
        finally:
            fence()
            h[HEADER.IN_SEQ] += 1

    def write_signal_array(self, values: np.ndarray, offset: int = 0) -> None:
        h, fence = self.header, self._fence
        h[HEADER.IN_SEQ] += 1
        fence()
        self.signals[offset : offset + len(values)] = values
        fence()
        h[HEADER.IN_SEQ] += 1

    def read_signals(self, out: np.ndarray, last_seq: int) -> int:
        """Copy the inputs into ``out`` if they changed since ``last_seq`` and are
        consistent; returns the sequence number ``out`` now holds (``last_seq`` if the
        copy was skipped or torn: the caller keeps its previous values, never waits)."""
        h, fence = self.header, self._fence
        seq = h[HEADER.IN_SEQ]
        if seq == last_seq or seq & 1:
            return last_seq
        fence()
        n = len(out)
        scratch = self.signals[:n].copy()
        fence()
        if h[HEADER.IN_SEQ] != seq:
            return last_seq
        out[:] = scratch
        return int(seq)

    # --- controller outputs (writer: control process) -----------------------------------

    def write_outputs(self, values: np.ndarray) -> None:
        h, fence = self.header, self._fence
        n = len(values)
        first, second = self._outputs
        h[HEADER.OUT_SEQ] += 1
        fence()
        first[:n] = values
        fence()
        h[HEADER.OUT_SEQ] += 1
        fence()
        second[:n] = values

    def read_outputs(self, n: int) -> np.ndarray:
        h, fence = self.header, self._fence
        outputs = self._outputs
        while True:
            seq = h[HEADER.OUT_SEQ]
            fence()
            out = outputs[seq & 1][:n].copy()
            fence()
            if h[HEADER.OUT_SEQ] == seq:
                return out


class LogRing:
    """The last ``size`` states' logged fields, one packed record per tick.

    The record holds the byte ranges of the logged fields of one state datagram, so a
    tick's append is a few slice copies; :meth:`snapshot` decodes them into arrays with the
    dialect's own field types. The ring has one slot more than it keeps: the writer fills
    slot ``count % (size + 1)`` and then counts, so the slot it may be inside is never one
    of the ``size`` newest. A reader copies the ring between two reads of the count and
    drops the records the writer reached meanwhile.
    """

    def __init__(self, fd: int, size: int, record: np.dtype, spans: list[tuple[int, int, int]]):
        self.size = size
        self.slots = size + 1
        self.record = record
        self.spans = spans  # (source offset, record offset, length) in bytes
        self._mm = mmap.mmap(fd, LogRing.nbytes(size, record))
        self._mv = memoryview(self._mm)
        self._fence = memory_fence()

    @staticmethod
    def layout(state_dtype: np.dtype, names: tuple[str, ...]) -> tuple[np.dtype, list]:
        """The packed record dtype of ``names`` (those ``state_dtype`` has) and the copy
        spans from a datagram, adjacent fields merged into one copy."""
        all_fields = state_dtype.fields
        assert all_fields is not None
        fields = sorted((all_fields[n][1], n) for n in names if n in all_fields)
        names_out: list[str] = []
        formats: list[np.dtype] = []
        offsets: list[int] = []
        spans: list[tuple[int, int, int]] = []
        pos = 0
        for src, name in fields:
            sub = all_fields[name][0]
            names_out.append(name)
            formats.append(sub)
            offsets.append(pos)
            if spans and spans[-1][0] + spans[-1][2] == src and spans[-1][1] + spans[-1][2] == pos:
                s, d, n = spans[-1]
                spans[-1] = (s, d, n + sub.itemsize)
            else:
                spans.append((src, pos, sub.itemsize))
            pos += sub.itemsize
        record = np.dtype({"names": names_out, "formats": formats, "offsets": offsets})
        return record, spans

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """For a compiled loop (:mod:`panda_py.rt._tick`): the ring's bytes (uint8) and
        the copy spans (int64, one row of source offset, record offset, length each)."""
        ring = np.frombuffer(self._mm, np.uint8)
        spans = np.array(self.spans, dtype=np.int64).reshape(-1, 3)
        return ring, spans

    @staticmethod
    def nbytes(size: int, record: np.dtype) -> int:
        return (size + 1) * record.itemsize

    def close(self) -> None:
        self._mv.release()
        try:
            self._mm.close()
        except BufferError:
            pass

    def append(self, data: bytes, header: Any) -> None:
        """Append one state datagram (control process)."""
        count = header[HEADER.LOG_COUNT]
        base = (count % self.slots) * self.record.itemsize
        mv = self._mv
        for src, dst, n in self.spans:
            mv[base + dst : base + dst + n] = data[src : src + n]
        self._fence()  # the record before the count that publishes it
        header[HEADER.LOG_COUNT] = count + 1

    def snapshot(self, header: Any) -> np.ndarray:
        """The logged records, oldest first (user's process)."""
        for _ in range(SNAPSHOT_TRIES):  # a copy the writer did not cross: every record
            before = header[HEADER.LOG_COUNT]
            self._fence()
            raw = np.frombuffer(self._mm, self.record, self.slots).copy()
            self._fence()
            after = header[HEADER.LOG_COUNT]
            if after == before:
                break
        # a record is intact if the writer has not reached its slot again: logical index
        # i with i >= after + 1 - slots (the writer may be inside slot ``after``'s now)
        start = max(before - min(before, self.size), after + 1 - self.slots)
        if start >= before:
            return raw[:0]
        idx = np.arange(start, before) % self.slots
        return raw[idx]
