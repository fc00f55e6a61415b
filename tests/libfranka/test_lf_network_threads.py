"""Network.wait_response from several threads at once, and poll_response beside it."""

from __future__ import annotations

import concurrent.futures
import socket
import time
from collections.abc import Iterator

import pytest

from panda_py import fci
from panda_py.fci import GripperCommand
from panda_py.libfranka._network import Network
from panda_py.libfranka.errors import NetworkException
from panda_py.sim import free_loopback_host

pytestmark = pytest.mark.timeout(30)


def _response(cid: int) -> bytes:
    return fci.encode_gripper_message(GripperCommand.STOP, cid, b"\0\0")


@pytest.fixture
def pair() -> Iterator[tuple[Network, socket.socket]]:
    """A Network and the server's end of its TCP connection."""
    host = free_loopback_host()
    with socket.create_server((host, 0)) as listener:
        net = Network(
            host, listener.getsockname()[1], fci.GripperMessageReader(), udp_size=1, timeout=5.0
        )
        server, _ = listener.accept()
    with server:
        yield net, server
    net.close()


def test_each_waiting_thread_gets_its_own_response(pair):
    net, server = pair
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        waits = {cid: pool.submit(net.wait_response, cid) for cid in (1, 2, 3, 4)}
        for cid in (4, 2, 3, 1):  # in another order than asked, one segment each
            server.sendall(_response(cid))
        for cid, wait in waits.items():
            assert wait.result(timeout=5).command_id == cid


def test_polling_is_not_held_up_by_a_waiting_thread(pair):
    """A control loop polls its motion's response every tick while another thread waits
    for one: the waiter must not hold the socket's lock while it waits."""
    net, server = pair
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        wait = pool.submit(net.wait_response, 1)
        start = time.monotonic()
        polls = [net.poll_response(2) for _ in range(20)]
        took = time.monotonic() - start
        assert polls == [None] * 20 and not wait.done()
        assert took < 1.0  # 20 polls under a lock held for each wait: >= 2 s
        server.sendall(_response(2) + _response(1))
        assert wait.result(timeout=5).command_id == 1
        while (msg := net.poll_response(2)) is None:  # queued by the waiter, or read now
            pass
        assert msg.command_id == 2


def test_every_waiter_learns_the_connection_ended(pair):
    net, server = pair
    with concurrent.futures.ThreadPoolExecutor(3) as pool:
        waits = [pool.submit(net.wait_response, cid) for cid in (1, 2, 3)]
        server.close()
        for wait in waits:
            with pytest.raises(NetworkException, match="closed connection"):
                wait.result(timeout=5)


def test_a_wait_ends_at_its_timeout(pair):
    net, _ = pair
    start = time.monotonic()
    with pytest.raises(NetworkException, match="Timeout"):
        net.wait_response(1, timeout=0.2)
    assert time.monotonic() - start >= 0.2


def test_requests_from_two_threads_take_distinct_ids_and_go_out_whole() -> None:
    # libfranka lets another thread call e.g. stop() while a control loop runs: a second
    # request waits until the first is on the wire (one id each, never interleaved)
    import threading

    from panda_py.libfranka._connection import RobotConnection

    sent: list[bytes] = []
    entered, release = threading.Event(), threading.Event()

    class SlowNet:
        def send(self, data: bytes) -> None:
            if not sent and not entered.is_set():
                entered.set()
                assert release.wait(5.0)
            sent.append(data)

    class Dialect:
        def encode_request(self, command: object, cid: int, **fields: object) -> bytes:
            return f"{command}:{cid}".encode()

    conn = RobotConnection.__new__(RobotConnection)
    conn._next_id, conn._send_lock = 7, threading.Lock()
    conn.net, conn.dialect = SlowNet(), Dialect()  # type: ignore[assignment]
    ids: list[int] = []
    first = threading.Thread(target=lambda: ids.append(conn.send_request("A")))  # type: ignore[arg-type]
    first.start()
    assert entered.wait(5.0)
    second = threading.Thread(target=lambda: ids.append(conn.send_request("B")))  # type: ignore[arg-type]
    second.start()
    second.join(0.2)
    assert second.is_alive() and sent == []  # waits while the first is being sent
    release.set()
    first.join(5.0)
    second.join(5.0)
    assert sorted(ids) == [7, 8] and sent == [b"A:7", b"B:8"]
