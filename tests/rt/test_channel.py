"""The request channel: small messages in band; large arrays out of band through a memfd,
so a send never waits for the reader (the control loop reads only whole requests)."""

from __future__ import annotations

import os
import socket

import numpy as np
import pytest

from panda_py.rt import channel as ch
from panda_py.rt.channel import Channel, ChannelClosed

pytestmark = pytest.mark.timeout(30)


@pytest.fixture
def pair() -> tuple[Channel, Channel]:
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    ends = Channel(a), Channel(b)
    yield ends
    for end in ends:
        end.close()


def test_a_large_message_is_sent_without_a_reader_and_arrives_whole(pair) -> None:  # type: ignore[no-untyped-def]
    sender, receiver = pair
    sender.sock.settimeout(2.0)  # a send that waits for the reader fails here
    q = np.random.default_rng(0).normal(size=(40_000, 7))  # 2.2 MB: ten socket buffers
    fortran = np.asfortranarray(q[:1000])
    for i in range(3):  # several, none read yet
        sender.send({"i": i, "q": q, "f": fortran, "name": "plan"})
    for i in range(3):
        msg, fds = receiver.recv()
        assert fds == []  # the memory file is the channel's own, not the caller's
        assert msg["i"] == i and msg["name"] == "plan"
        np.testing.assert_array_equal(msg["q"], q)
        np.testing.assert_array_equal(msg["f"], fortran)
        msg["q"][0, 0] = 1.0  # a private mapping: writable, and the sender's is unchanged
    assert q[0, 0] != 1.0


def test_a_small_message_stays_in_band_and_descriptors_travel_beside(pair) -> None:  # type: ignore[no-untyped-def]
    sender, receiver = pair
    sent: list[int] = []
    real = ch._write_memfd
    ch._write_memfd = lambda views: sent.append(1) or real(views)  # type: ignore[assignment,func-returns-value]
    try:
        r, w = os.pipe()
        sender.send({"q": np.zeros(7)}, (r,))
        sender.send({"q": np.zeros((5000, 7))}, (w,))  # out of band, with a caller's fd
    finally:
        ch._write_memfd = real  # type: ignore[assignment]
    assert sent == [1]  # only the large one used a memory file
    small, fds_small = receiver.recv()
    large, fds_large = receiver.recv()
    assert small["q"].shape == (7,) and large["q"].shape == (5000, 7)
    assert len(fds_small) == 1 and len(fds_large) == 1
    os.write(fds_large[0], b"x")  # the caller's descriptors are the pipe's ends
    assert os.read(fds_small[0], 1) == b"x"
    for fd in (r, w, *fds_small, *fds_large):
        os.close(fd)


def test_an_out_of_band_message_without_its_data_is_refused(pair) -> None:  # type: ignore[no-untyped-def]
    sender, receiver = pair
    payload = b"\x00" * 8
    sender.sock.sendall(ch._LEN.pack(len(payload) | ch._OOB_FLAG) + payload)
    with pytest.raises(ChannelClosed, match="without its data"):
        receiver.recv()


def test_without_memfd_a_temporary_file_carries_the_arrays(pair, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # macOS has no memfd_create: an unlinked temporary file does the same
    sender, receiver = pair
    monkeypatch.delattr(os, "memfd_create")
    q = np.arange(20_000.0).reshape(-1, 4)
    sender.send({"q": q})
    msg, fds = receiver.recv()
    np.testing.assert_array_equal(msg["q"], q)
    assert fds == []


def test_a_message_is_whole_once_its_last_byte_is_buffered(pair) -> None:  # type: ignore[no-untyped-def]
    sender, receiver = pair
    assert not receiver.whole()  # nothing buffered
    data = ch._LEN.pack(5) + b"\x80\x05K\x07."  # a pickle of 7, written by hand
    for cut in (1, 4, len(data) - 1):  # part of the length, the length, all but one byte
        sender.sock.sendall(data[:cut])
        assert not receiver.whole(), cut
        assert receiver.whole() is False  # and reads nothing: asked again, the same
        sender.sock.sendall(data[cut:])
        assert receiver.whole()
        assert receiver.recv() == (7, [])
    assert not receiver.whole()


def test_a_message_with_descriptors_or_out_of_band_is_whole_when_sent(pair) -> None:  # type: ignore[no-untyped-def]
    sender, receiver = pair
    r, w = os.pipe()
    try:
        sender.send({"small": 1}, (r,))
        assert receiver.whole()
        message, fds = receiver.recv()
        assert message == {"small": 1} and len(fds) == 1
        os.close(fds[0])
    finally:
        os.close(r)
        os.close(w)
    q = np.arange(70_000.0)  # out of band: its bytes in a memfd, the socket's part whole
    sender.send(q)
    assert receiver.whole()
    np.testing.assert_array_equal(receiver.recv()[0], q)


def test_a_closed_channel_is_never_whole(pair) -> None:  # type: ignore[no-untyped-def]
    sender, receiver = pair
    sender.close()
    assert not receiver.whole()
    with pytest.raises(ChannelClosed):
        receiver.recv()
