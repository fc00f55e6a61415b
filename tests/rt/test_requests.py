"""The typed seam between the user's process and the control process: every request kind
has its dataclass and its handler, requests and replies survive the channel, and the
control process answers a request it does not know, or one it must refuse while a law
runs, with an error naming it (no robot, no simulator: the server's dispatch alone)."""

from __future__ import annotations

import dataclasses
import os
import pickle
import socket
import threading
import time
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from panda_py.controllers.moves import JointMove, tracker_for
from panda_py.controllers.plans import JointPlan
from panda_py.libfranka import InvalidOperationException
from panda_py.motion.online import OnlineLimits
from panda_py.robots.params import get_robot
from panda_py.rt import requests as rq
from panda_py.rt.channel import Channel
from panda_py.rt.child import STATE_WAIT, ControlServer
from panda_py.rt.shm import HEADER, SharedBlock

pytestmark = pytest.mark.timeout(30)

REQUESTS = [
    rq.Connect("172.16.0.2", 0, 5.0),
    rq.StartController(b"payload"),
    rq.Move(
        JointPlan(
            np.zeros((2, 7)),
            np.zeros((2, 7)),
            np.zeros((2, 7)),
            np.ones(7),
            np.ones(7),
            1e-3,
            1e-2,
            OnlineLimits.joints(get_robot("fer"), 1.0),
        )
    ),
    rq.Cancel(7),
    rq.Stop(),
    rq.RobotCall("set_load", (0.5, [0.0, 0.0, 0.1], [0.0] * 9)),
    rq.Recover(),
    rq.EnableLog(100),
    rq.DisableLog(),
    rq.Close(),
]


def test_every_kind_has_one_request_and_every_request_a_kind() -> None:
    assert sorted(r.kind.value for r in REQUESTS) == sorted(k.value for k in rq.Kind)


@pytest.fixture
def server():  # type: ignore[no-untyped-def]
    mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    block, fd = SharedBlock.create()
    os.close(fd)
    srv = ControlServer(Channel(theirs), block, os.getppid())
    user = Channel(mine)
    yield srv, user
    user.close()
    srv.chan.close()
    block.close()


def test_the_server_has_a_handler_for_every_kind_but_connect(server) -> None:  # type: ignore[no-untyped-def]
    srv, _ = server
    assert set(srv._handlers) == set(rq.Kind) - {rq.Kind.CONNECT}


@pytest.mark.parametrize("request_", REQUESTS, ids=lambda r: r.kind.value)
def test_requests_survive_the_channel(server, request_) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    user.send(rq.Call(7, request_))
    msg, fds = srv.chan.recv()
    assert fds == [] and isinstance(msg, rq.Call) and msg.rid == 7
    got = msg.request
    assert type(got) is type(request_)
    for field in dataclasses.fields(request_):
        a, b = getattr(got, field.name), getattr(request_, field.name)
        if isinstance(a, JointPlan):
            np.testing.assert_array_equal(a.q, b.q)
        else:
            assert a == b


def test_an_unknown_request_is_refused_by_name(server) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    user.send(rq.Call(3, ("start", 3, b"old-style tuple")))  # type: ignore[arg-type]
    srv._receive(running=False)
    reply, _ = user.recv()
    assert isinstance(reply, rq.Reply) and reply.rid == 3 and not reply.ok
    assert isinstance(reply.value, ValueError)
    assert "request: expected one of" in str(reply.value) and "start_controller" in str(reply.value)


def test_requests_that_need_the_loop_idle_are_refused_while_it_runs(server) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    for rid, request in enumerate([rq.Recover(), rq.RobotCall("set_load"), REQUESTS[1]]):
        user.send(rq.Call(rid, request))
        srv._receive(running=True)
        reply, _ = user.recv()
        assert reply.rid == rid and not reply.ok
        assert isinstance(reply.value, InvalidOperationException)
        assert "not while a controller or a move runs" in str(reply.value)


def test_a_robot_method_outside_the_list_is_refused(server) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    user.send(rq.Call(1, rq.RobotCall("__del__")))
    srv._receive(running=False)
    reply, _ = user.recv()
    assert not reply.ok and "method: expected one of" in str(reply.value)


def test_replies_and_events_pickle() -> None:
    for msg in (rq.Reply(1, True, rq.Connected(10, "fr3", "fr3")), rq.LogLine(30, "x"),
                rq.LoopError(InvalidOperationException("y"))):  # fmt: skip
        back = pickle.loads(pickle.dumps(msg))
        assert type(back) is type(msg)


def test_peer_closed_sees_the_close_without_reading_or_waiting() -> None:
    mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    user, loop = Channel(mine), Channel(theirs)
    assert not loop.peer_closed()  # open, nothing sent: no wait
    user.send(rq.Call(1, rq.Stop()))
    assert not loop.peer_closed()  # a message waits: not closed, and still there
    msg, _ = loop.recv()
    assert isinstance(msg, rq.Call) and msg.rid == 1
    user.close()
    assert loop.peer_closed()
    loop.close()


@pytest.fixture
def robot_socket():  # type: ignore[no-untyped-def]
    """The robot's end and the loop's end of a datagram pair standing for the state socket."""
    robot, loop = socket.socketpair(socket.AF_UNIX, socket.SOCK_DGRAM)
    yield robot, loop
    robot.close()
    loop.close()


def _running_move(srv: ControlServer) -> tuple[Any, Any]:
    old = tracker_for(REQUESTS[2].plan)  # type: ignore[attr-defined]
    srv.current = (old, 1)
    return old, SimpleNamespace(q=np.zeros(7))  # the tick's state, as far as a result reads it


def test_a_move_sent_between_ticks_takes_over_before_the_next_state(server, robot_socket) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    _, loop = robot_socket
    old, state = _running_move(srv)
    user.send(rq.Call(2, REQUESTS[2]))
    srv.block.header[HEADER.REQUESTS] += 1  # the user's process counts after its send
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert rid == 2 and isinstance(law, JointMove) and law is not old
    assert srv.current == (law, 2) and srv.replacement is None and srv.requests_taken == 1
    reply, _ = user.recv()  # the replaced move is answered at once
    assert reply.rid == 1 and reply.ok and "replaced by a new move" in reply.value.reason


def test_a_queued_state_comes_before_a_request(server, robot_socket) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    robot, loop = robot_socket
    old, state = _running_move(srv)
    user.send(rq.Call(2, REQUESTS[2]))
    srv.block.header[HEADER.REQUESTS] += 1
    robot.send(b"state")
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert (law, rid) == (old, 1) and srv.requests_taken == 0  # taken after this tick


def _written(message: Any) -> bytes:
    """The bytes Channel.send writes for ``message``, caught on a socket pair of its own."""
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    with a, b:
        Channel(a).send(message)
        a.shutdown(socket.SHUT_WR)
        chunks = []
        while chunk := b.recv(1 << 16):
            chunks.append(chunk)
    return b"".join(chunks)


def test_a_request_being_written_is_left_whole_for_a_later_tick(server, robot_socket) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    robot, loop = robot_socket
    old, state = _running_move(srv)
    data = _written(rq.Call(2, REQUESTS[2]))
    user.sock.sendall(data[:-8])  # not yet whole, nor counted
    threading.Timer(0.01, robot.send, (b"state",)).start()
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert (law, rid) == (old, 1) and srv.requests_taken == 0
    assert loop.recv(16) == b"state"  # it returned for the state, having waited on it alone
    user.sock.sendall(data[-8:])  # whole now, still not counted: taken at the next gap
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert rid == 2 and isinstance(law, JointMove) and srv.requests_taken == 1


def test_a_whole_request_is_taken_before_its_sender_counts_it(server, robot_socket) -> None:  # type: ignore[no-untyped-def]
    # the loop woken by the send often runs before the sender gets to count: it need not
    # wait for the count (it polled for it every COUNT_POLL, 100 us, before)
    srv, user = server
    robot, loop = robot_socket
    old, state = _running_move(srv)
    user.send(rq.Call(2, REQUESTS[2]))  # whole, not counted
    sent: list[float] = []

    def state_() -> None:
        sent.append(time.monotonic())
        robot.send(b"state")

    threading.Timer(0.6 * STATE_WAIT, state_).start()
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert rid == 2 and law is not old and srv.requests_taken == 1
    reply, _ = user.recv()
    assert reply.rid == 1 and reply.value.end_time < sent[0]  # handed over before the state
    srv.block.header[HEADER.REQUESTS] += 1  # counted late: nothing more to take
    assert loop.recv(16) == b"state"  # (the tick's state, read as readOnce would)
    assert srv._await_state(loop.fileno(), srv.chan.fileno(), law, 2, state) == (law, 2)
    assert srv.requests_taken == 1


def test_a_hand_over_waits_one_gap_when_a_state_is_queued(server, robot_socket) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    robot, loop = robot_socket
    old, state = _running_move(srv)
    new = tracker_for(REQUESTS[2].plan)  # type: ignore[attr-defined]
    srv.replacement = (new, 2)  # taken late in the last gap
    robot.send(b"state")
    assert srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state) == (old, 1)
    assert srv.replacement == (new, 2)  # the queued state's tick runs the old move first
    robot.send(b"state")  # behind again: it is put off once only
    assert srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state) == (new, 2)
    assert srv.replacement is None and not srv.deferred
    reply, _ = user.recv()
    assert reply.rid == 1 and "replaced by a new move" in reply.value.reason


def test_a_request_counted_after_the_channel_woke_the_loop_is_taken_before_the_state(
    server, robot_socket
) -> None:  # type: ignore[no-untyped-def]
    srv, user = server
    robot, loop = robot_socket
    old, state = _running_move(srv)
    user.send(rq.Call(2, REQUESTS[2]))  # readable now, counted a moment later

    def count() -> None:
        srv.block.header[HEADER.REQUESTS] += 1

    sent: list[float] = []

    def state_() -> None:
        sent.append(time.monotonic())
        robot.send(b"state")

    threading.Timer(0.005, count).start()
    # well within the loop's wait for a state (STATE_WAIT, 50 ms): at 50 ms, as it was, the
    # wait could end before the state came, on a loaded machine
    threading.Timer(0.6 * STATE_WAIT, state_).start()
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert rid == 2 and law is not old and srv.requests_taken == 1
    reply, _ = user.recv()
    assert reply.rid == 1 and reply.value.end_time < sent[0]  # handed over before the state


def test_a_request_never_counted_does_not_keep_the_loop_from_a_silent_robot(
    server, robot_socket, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    from panda_py.rt import child

    monkeypatch.setattr(child, "STATE_WAIT", 0.02)
    srv, user = server
    _, loop = robot_socket
    old, state = _running_move(srv)
    user.sock.sendall(_written(rq.Call(2, REQUESTS[2]))[:-8])  # its sender died half way
    t0 = time.monotonic()
    law, rid = srv._await_state(loop.fileno(), srv.chan.fileno(), old, 1, state)
    assert (law, rid) == (old, 1) and srv.requests_taken == 0
    assert time.monotonic() - t0 < 0.5  # back to readOnce, which times out on silence
