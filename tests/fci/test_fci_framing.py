"""The TCP framer, fed byte by byte, in odd chunks and with pipelined messages."""

from __future__ import annotations

import struct

import numpy as np
import pytest

import panda_py.fci as fci
from panda_py.fci import Command


def sample_stream(rng: np.random.Generator) -> tuple[list[bytes], bytes]:
    d = fci.dialect(10)
    messages = [
        fci.encode_connect_request(10, 5555),
        d.encode_request(
            Command.MOVE,
            1,
            controller_mode=2,
            motion_generator_mode=4,
            maximum_path_deviation=fci.DEFAULT_DEVIATION,
            maximum_goal_pose_deviation=fci.DEFAULT_DEVIATION,
        ),
        d.encode_request(Command.STOP_MOVE, 2),
        d.encode_response(
            Command.GET_ROBOT_MODEL, 3, fci.CommandBaseStatus.SUCCESS, urdf=rng.bytes(70000)
        ),
        d.encode_request(Command.SET_LOAD, 4, m_load=0.5),
        d.encode_request(Command.AUTOMATIC_ERROR_RECOVERY, 5),
    ]
    return messages, b"".join(messages)


def test_whole_stream_at_once() -> None:
    messages, stream = sample_stream(np.random.default_rng(1))
    reader = fci.RobotMessageReader()
    got = reader.feed(stream)
    assert [m.raw for m in got] == messages
    assert [m.command_id for m in got] == [0, 1, 2, 3, 4, 5]
    assert got[1].command == 1 and len(got[1].payload) == 113
    assert got[0].payload == struct.pack("<HH", 10, 5555)
    assert reader.buffered == 0


def test_byte_by_byte() -> None:
    messages, stream = sample_stream(np.random.default_rng(2))
    reader = fci.RobotMessageReader()
    got: list[fci.Message] = []
    for i in range(len(stream)):
        got += reader.feed(stream[i : i + 1])
    assert [m.raw for m in got] == messages


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_odd_chunks(seed: int) -> None:
    rng = np.random.default_rng(seed)
    messages, stream = sample_stream(rng)
    reader = fci.RobotMessageReader()
    got: list[fci.Message] = []
    pos = 0
    while pos < len(stream):
        n = int(rng.choice([1, 3, 7, 11, 12, 13, 29, 1000, 40000]))
        got += reader.feed(memoryview(stream)[pos : pos + n])
        pos += n
        assert reader.buffered < 12 + 70001
    assert [m.raw for m in got] == messages
    assert reader.buffered == 0


def test_partial_message_stays_buffered() -> None:
    messages, stream = sample_stream(np.random.default_rng(6))
    reader = fci.RobotMessageReader()
    cut = len(messages[0]) + 5
    assert [m.raw for m in reader.feed(stream[:cut])] == messages[:1]
    assert reader.buffered == 5
    assert [m.raw for m in reader.feed(stream[cut:])] == messages[1:]


@pytest.mark.parametrize("size", [0, 11, fci.MAX_MESSAGE_SIZE + 1, 2**32 - 1])
def test_bad_sizes(size: int) -> None:
    reader = fci.RobotMessageReader()
    good = fci.dialect(5).encode_request(Command.STOP_MOVE, 0)
    with pytest.raises(fci.ProtocolError, match="TCP message size"):
        reader.feed(good + struct.pack("<III", 1, 1, size))
    # the stream cannot be resynchronised: every later feed fails too
    with pytest.raises(fci.ProtocolError):
        reader.feed(good)


def test_custom_max_size_and_arguments() -> None:
    reader = fci.RobotMessageReader(max_size=100)
    with pytest.raises(fci.ProtocolError, match=r"12\.\.100"):
        reader.feed(struct.pack("<III", 0, 0, 101))
    with pytest.raises(ValueError, match="max_size"):
        fci.RobotMessageReader(max_size=5)
    with pytest.raises(ValueError, match="header"):
        fci.MessageReader(struct.Struct("<II"))


def test_decode_header() -> None:
    assert fci.decode_header(struct.pack("<III", 3, 9, 428) + b"rest") == (3, 9, 428)
    with pytest.raises(fci.ProtocolError, match="12 bytes"):
        fci.decode_header(b"\x00" * 11)
    with pytest.raises(fci.ProtocolError, match="TCP message size"):
        fci.decode_header(struct.pack("<III", 3, 9, 11))
    assert fci.HEADER.size == 12


def test_encode_message() -> None:
    d = fci.dialect(6)
    message = fci.encode_message(d, Command.SET_LOAD, 77, b"abc")
    assert message == struct.pack("<III", 9, 77, 15) + b"abc"
    with pytest.raises(ValueError, match="does not exist"):
        fci.encode_message(d, Command.SET_FILTERS, 1, b"")
