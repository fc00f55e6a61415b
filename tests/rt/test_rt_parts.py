"""The control process's parts on their own: the seqlocked shared block, the log ring,
pickling by value, the control laws' helpers, and PandaContext's schedule."""

from __future__ import annotations

import pickle
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

from panda_py import fci
from panda_py.controllers import laws
from panda_py.rt import byvalue
from panda_py.rt.shm import HEADER, LOG_FIELDS, LogRing, SharedBlock, anonymous_file

pytestmark = pytest.mark.timeout(60)


def test_state_slot_round_trip_and_torn_reads_never_seen() -> None:
    block, fd = SharedBlock.create()
    reader = SharedBlock(fd)
    assert reader.read_state() is None
    stop = threading.Event()
    seen: list[bytes] = []

    def write() -> None:
        i = 0
        while not stop.is_set():
            block.publish_state(bytes([i % 256]) * 2373)
            i += 1

    writer = threading.Thread(target=write)
    writer.start()
    try:
        for _ in range(3000):
            data = reader.read_state()
            if data is not None:
                seen.append(data)
    finally:
        stop.set()
        writer.join()
    assert seen
    for data in seen:  # every copy is one datagram, never two halves
        assert len(data) == 2373 and data.count(data[:1]) == 2373
    assert reader.header[HEADER.TICKS] == block.header[HEADER.TICKS] > 0


def test_a_writer_stopped_mid_write_does_not_hold_readers() -> None:
    block, fd = SharedBlock.create()
    reader = SharedBlock(fd)
    block.publish_state(b"a" * 100)
    views = reader.field_views(fci.dialect(5).state_dtype, "q")
    block.header[HEADER.STATE_SEQ] += 1  # the writer stopped inside copy 0
    block._states[0][:100] = b"b" * 100
    assert reader.read_state() == b"a" * 100  # copy 1, at once
    assert reader.read_field(views).shape == (7,)
    block.header[HEADER.STATE_SEQ] += 1  # copy 0 complete
    assert reader.read_state() == b"b" * 100


def test_signals_reader_keeps_its_copy_while_a_write_is_open() -> None:
    block, _fd = SharedBlock.create()
    out = np.zeros(4)
    block.write_signal_array(np.array([1.0, 2.0, 3.0, 4.0]))
    seq = block.read_signals(out, -1)
    assert out.tolist() == [1, 2, 3, 4]
    block.header[HEADER.IN_SEQ] += 1  # a writer in the middle of its write
    block.signals[:4] = 9.0
    assert block.read_signals(out, seq) == seq and out.tolist() == [1, 2, 3, 4]
    block.header[HEADER.IN_SEQ] += 1
    assert block.read_signals(out, seq) != seq and out.tolist() == [9, 9, 9, 9]


@pytest.mark.parametrize("version", [3, 5, 10])
def test_log_ring_keeps_the_newest_in_order(version: int) -> None:
    dialect = fci.dialect(version)
    record, spans = LogRing.layout(dialect.state_dtype, LOG_FIELDS)
    assert set(record.names) == set(LOG_FIELDS)
    size = 50
    fd = anonymous_file(LogRing.nbytes(size, record))
    ring = LogRing(fd, size, record, spans)
    header = SharedBlock(anonymous_file(SharedBlock.SIZE)).header
    rng = np.random.default_rng(1)
    states = np.zeros(120, dialect.state_dtype)
    states["message_id"] = np.arange(120) + 1000
    states["q"] = rng.normal(size=(120, 7))
    for s in states:
        ring.append(s.tobytes(), header)
    got = ring.snapshot(header)
    assert got["message_id"].tolist() == list(range(1070, 1120))
    np.testing.assert_array_equal(got["q"], states["q"][70:])


def test_log_ring_drops_records_overwritten_during_a_read() -> None:
    dialect = fci.dialect(5)
    record, spans = LogRing.layout(dialect.state_dtype, LOG_FIELDS)
    ring = LogRing(anonymous_file(LogRing.nbytes(10, record)), 10, record, spans)
    header = SharedBlock(anonymous_file(SharedBlock.SIZE)).header
    state = np.zeros(1, dialect.state_dtype)
    for _ in range(25):
        ring.append(state.tobytes(), header)

    class Moving:  # the count moves by 3 during every copy (a writer outrunning them)
        def __init__(self, moves: int) -> None:
            self.reads, self.moves = 0, moves

        def __getitem__(self, i: int) -> int:
            self.reads += 1
            return 25 + 3 * min(self.reads // 2, self.moves)

    assert len(ring.snapshot(Moving(moves=99))) == 10 - 3  # the 3 oldest may be torn
    # a writer that crossed one copy only: the next copy is whole
    assert len(ring.snapshot(Moving(moves=1))) == 10


MAIN_SCRIPT = textwrap.dedent(
    """
    import math, sys
    from panda_py.rt import byvalue
    SCALE = 2.0
    def helper(x):
        return SCALE * math.sqrt(x)
    class Law:
        def go(self, x):
            return helper(x) + self.offset
    law = Law()
    law.offset = 1.0
    sys.stdout.buffer.write(byvalue.dumps(law))
    """
)


def test_classes_of_a_script_travel_by_value() -> None:
    data = subprocess.run(
        [sys.executable, "-c", MAIN_SCRIPT], capture_output=True, check=True
    ).stdout
    law = pickle.loads(data)  # this process cannot import the script's __main__
    assert law.go(16.0) == 9.0
    assert type(law).__module__ == byvalue.MODULE_NAME


def test_importable_classes_travel_by_reference() -> None:
    from panda_py.controllers import JointPosition

    data = byvalue.dumps(JointPosition())
    assert b"panda_py.controllers._builtin" in data
    assert isinstance(pickle.loads(data), JointPosition)


def test_quaternion_helpers_and_errors() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        x, y, z, w = q
        R = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ])  # fmt: skip
        T = np.eye(4)
        T[:3, :3] = R
        got = laws.quat_from_matrix(T.reshape(16, order="F"))
        assert min(np.abs(got - q).max(), np.abs(got + q).max()) < 1e-12
        assert np.abs(laws.cartesian_error(T.reshape(16, order="F"), np.zeros(3), q)).max() < 1e-12
    half = laws.slerp(np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0, 0]), 0.5)
    np.testing.assert_allclose(half, [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-12)


def test_nullspace_projector_removes_the_task() -> None:
    J = np.random.default_rng(0).normal(size=(6, 7))
    N = laws.nullspace_projector(J)
    assert np.abs(J @ N).max() < 1e-3  # the damping leaves only a trace
    assert np.abs(N @ N - N).max() < 1e-3


def test_torque_rate_and_limits() -> None:
    out = laws.saturate_torque_rate(np.array([5.0, -5.0, 0.5, 0, 0, 0, 0]), np.zeros(7))
    assert out.tolist() == [1.0, -1.0, 0.5, 0, 0, 0, 0]
    tau_max = np.array([87.0] * 4 + [12.0] * 3)
    assert laws.clip_torques(np.full(7, 100.0), tau_max).tolist() == tau_max.tolist()


def test_joint_walls_push_back_near_the_limits() -> None:
    walls = laws.JointWalls([-2.0] * 7, [2.0] * 7)
    assert walls.torques(np.zeros(7), np.zeros(7)) == [0.0] * 7
    walls.reset()
    walls.torques(np.zeros(7), np.zeros(7))  # start in the middle: full-width zones
    t = walls.torques(np.full(7, 1.99), np.zeros(7))
    assert all(v < 0 for v in t)  # near the upper limit: pushed down
    t = walls.torques(np.full(7, -1.99), np.full(7, -0.1))
    assert all(v > 0 for v in t)


def test_control_model_answers_as_libfrankas_model() -> None:
    from panda_py.controllers.model import ControlModel
    from panda_py.libfranka import Frame, Model, RobotState

    dialect = fci.dialect(5)
    rng = np.random.default_rng(5)
    rec = np.zeros(1, dialect.state_dtype)[0]
    rec["q"] = [0.1, -0.7, 0.2, -2.2, 0.1, 1.6, 0.7]
    rec["dq"] = rng.normal(size=7) * 0.3
    F_T_EE = np.eye(4)
    F_T_EE[2, 3] = 0.1034
    rec["F_T_EE"] = F_T_EE.reshape(16, order="F")
    rec["EE_T_K"] = np.eye(4).reshape(16)
    rec["m_ee"] = 0.73  # the totals are combined from the hand and the load
    rec["F_x_Cee"] = [-0.01, 0.0, 0.03]
    rec["I_ee"] = [0.001, 0, 0, 0, 0.0025, 0, 0, 0, 0.0017]
    rec["m_load"] = 0.2
    rec["F_x_Cload"] = [0.0, 0.0, 0.05]
    rec["I_load"] = [1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-4]
    state = RobotState(dialect, rec)
    fast, slow = ControlModel("fer"), Model("fer")
    np.testing.assert_allclose(
        fast.zero_jacobian(Frame.kEndEffector, state),
        slow.zero_jacobian(Frame.kEndEffector, state),
        atol=1e-12,
    )
    np.testing.assert_allclose(fast.coriolis(state), slow.coriolis(state), atol=1e-12)
    np.testing.assert_allclose(fast.gravity(state), slow.gravity(state), atol=1e-12)
    np.testing.assert_allclose(fast.mass(state), slow.mass(state), atol=1e-12)
    g = [0.0, 0.0, -9.0]
    np.testing.assert_allclose(fast.gravity(state, g), slow.gravity(state, g), atol=1e-12)
