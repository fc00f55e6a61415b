"""The shared memory's seqlocks and latches on machines that reorder memory accesses: the
fence is a real hardware fence there (and free on x86-64), and every write and read
places it between the sequence number and the data (checked here by recording the order
of numbers, fences and data; the hardware reordering itself cannot be shown on x86-64)."""

from __future__ import annotations

import multiprocessing
import os
import struct
from typing import Any

import numpy as np
import pytest

from panda_py.rt import fence as fence_mod
from panda_py.rt.shm import HEADER, SharedBlock

pytestmark = pytest.mark.timeout(120)


def test_ordered_machines_need_no_fence_and_others_get_a_hardware_one() -> None:
    assert fence_mod.fence_for("x86_64") is fence_mod.fence_for("AMD64")
    fence_mod.fence_for("x86_64")()  # the no-op
    arm = fence_mod.fence_for("aarch64")
    arm()
    llvm = "\n".join(arm.inspect_llvm().values())  # type: ignore[attr-defined]
    assert "fence seq_cst" in llvm
    asm = "\n".join(arm.inspect_asm().values())  # type: ignore[attr-defined]
    # compiled for this machine: x86-64 issues a locked instruction, aarch64 a dmb
    assert "lock" in asm or "dmb" in asm or "mfence" in asm


class _Recorder:
    """Records, at each fence, the sequence number and whether the data is written."""

    def __init__(self, block: SharedBlock, seq: int, probe: Any) -> None:
        self.block, self.seq, self.probe, self.events = block, seq, probe, []

    def __call__(self) -> None:
        self.events.append((int(self.block.header[self.seq]), bool(self.probe())))


@pytest.fixture
def block() -> Any:
    b, fd = SharedBlock.create()
    yield b
    b.close()
    os.close(fd)


def test_the_state_latch_fences_each_copy_between_its_numbers(block: SharedBlock) -> None:
    data = b"\x07" * 64
    rec = _Recorder(block, HEADER.STATE_SEQ, lambda: bytes(block._states[0][:64]) == data)
    block._fence = rec
    block.publish_state(data)
    # odd before copy 0 is written; copy 0 written before the number turns even
    assert rec.events[0] == (1, False)
    assert rec.events[1] == (1, True)
    assert rec.events[2][0] == 2
    assert len(rec.events) == 4
    assert block.read_state() == data  # the reader fences twice (below)
    assert len(rec.events) == 6


def test_input_writes_fence_their_data_inside_an_odd_number(block: SharedBlock) -> None:
    rec = _Recorder(block, HEADER.IN_SEQ, lambda: block.signals[3] == 2.5)
    block._fence = rec
    block.write_packed(struct.Struct("<d"), 3, [2.5])
    assert rec.events == [(1, False), (1, True)]
    assert block.header[HEADER.IN_SEQ] == 2
    rec.events.clear()
    rec.probe = lambda: block.signals[5] == 1.0 and block.signals[7] == 2.0
    block.write_packed_many([(struct.Struct("<d"), 5, [1.0]), (struct.Struct("<d"), 7, [2.0])])
    assert rec.events == [(3, False), (3, True)]
    out = np.zeros(8)
    assert block.read_signals(out, 0) == 4 and out[3] == 2.5 and out[7] == 2.0


def _writer(fd: int, n: int) -> None:
    b = SharedBlock(fd)
    for k in range(1, n + 1):
        b.publish_state(bytes([k % 251]) * 1377)
        b.write_signal_array(np.full(64, float(k)))


def test_readers_never_see_a_torn_copy_while_another_process_writes() -> None:
    """The protocol's logic under a real concurrent writer (another process)."""
    block, fd = SharedBlock.create()
    ctx = multiprocessing.get_context("fork")
    proc = ctx.Process(target=_writer, args=(fd, 20000))
    proc.start()
    seen, last = 0, 0
    out = np.zeros(64)
    try:
        while proc.is_alive() or seen == 0:
            data = block.read_state()
            if data is not None:
                assert data == data[:1] * len(data)  # one tick's bytes, never two
                seen += 1
            last = block.read_signals(out, last)
            assert (out == out[0]).all()
    finally:
        proc.join(30)
        block.close()
        os.close(fd)
    assert seen > 0 and proc.exitcode == 0


def test_the_inline_latchs_slot_copies_are_fenced_where_the_machine_needs_it(
    block: SharedBlock,
) -> None:
    """``Panda.q`` and ``get_pose`` read the latch inline with the block's slot copies:
    bare copies where the machine keeps loads in order, each fenced before and after its
    copy where it does not (the fence replaced by one that moves a writer on: what the
    copy holds shows where between the fences it was taken)."""
    dtype = np.dtype([("q", "<f8", (7,)), ("O_T_EE", "<f8", (16,)), ("tau", "<f4", (7,))])
    record = np.zeros((), dtype)
    record["q"] = np.arange(7.0)
    record["O_T_EE"] = np.arange(16.0)
    record["tau"] = np.arange(7.0) / 2
    data = record.tobytes()
    block.publish_state(data)
    T = block.field_views(dtype, "O_T_EE")
    pose = (T[0].reshape(4, 4).T, T[1].reshape(4, 4).T)
    plain = block.slot_copies(pose)
    out = plain[1]()
    assert out.flags["F_CONTIGUOUS"] and out.dtype == np.float64
    np.testing.assert_array_equal(out, np.arange(16.0).reshape(4, 4).T)
    assert not np.shares_memory(out, pose[1])
    cast = block.slot_copies(block.field_views(dtype, "tau"))[0]()
    assert cast.dtype == np.float64 and cast.tolist() == (np.arange(7.0) / 2).tolist()
    q = block.field_views(dtype, "q")
    fences = []

    def fence() -> None:  # the writer moves on at each fence
        fences.append(True)
        q[0][:] = 10.0 * len(fences)

    block._fence = fence
    fenced = block.slot_copies(q)
    assert fenced[0]().tolist() == [10.0] * 7  # copied after one fence, before the next
    assert len(fences) == 2
