"""Gripper commands with ``asynchronous=True``: futures of what the blocking calls return,
against the simulated Franka Hand and, for broken connections, a scripted one."""

from __future__ import annotations

import asyncio
import concurrent.futures
import gc
import socket
import threading
import time

import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.fci import GripperStatus
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fer", lockstep=True) as s:
        yield s


@pytest.fixture
def gripper(sim):
    with lf.Gripper(sim.host) as g:
        assert g.move(0.08, 0.1) is True  # every test starts open
        yield g


def test_async_move_returns_at_once_and_resolves_to_the_blocking_result(gripper):
    future = gripper.move(0.02, 0.1, asynchronous=True)  # 60 mm at 0.1 m/s: >= 0.6 s
    assert isinstance(future, concurrent.futures.Future)
    assert not future.done()
    assert gripper.read_once().width > 0.021  # states keep coming while the fingers move
    assert future.result() is True
    gripper.read_once()  # a state sent before the move ended may still be queued
    assert gripper.read_once().width == pytest.approx(0.02, abs=2e-3)
    assert not future.cancel() and future.result() is True  # it ran: cancel() is a no-op


def test_async_grasp_and_homing(gripper):
    grasp = gripper.grasp(0.01, 0.1, 20.0, asynchronous=True)
    assert not grasp.done()
    assert grasp.result() is False  # nothing between the fingers, as the blocking call
    assert not gripper.read_once().is_grasped
    homing = gripper.homing(asynchronous=True)
    assert not homing.done()
    assert homing.result() is True
    gripper.read_once()
    state = gripper.read_once()
    assert state.max_width == pytest.approx(0.08, abs=1e-3)
    assert state.width == pytest.approx(0.08, abs=2e-3)


def test_stop_aborts_an_async_move(gripper):
    future = gripper.move(0.0, 0.05, asynchronous=True)  # 1.6 s
    while gripper.read_once().width > 0.07:  # under way (read_once bounds each wait)
        pass
    assert gripper.stop() is True
    with pytest.raises(lf.CommandException, match="Move command aborted") as info:
        future.result()
    assert info.value.status == GripperStatus.ABORTED and info.value.command == "Move"
    gripper.read_once()
    stopped = gripper.read_once().width
    assert 0.005 < stopped < 0.07  # it stopped on the way
    assert gripper.read_once().width == pytest.approx(stopped, abs=1e-3)  # and stays


def test_a_new_command_replaces_a_running_one_which_ends_aborted(gripper):
    first = gripper.move(0.0, 0.05, asynchronous=True)
    second = gripper.move(0.05, 0.1, asynchronous=True)
    with pytest.raises(lf.CommandException, match="aborted"):
        first.result()
    assert second.result() is True
    gripper.read_once()
    assert gripper.read_once().width == pytest.approx(0.05, abs=2e-3)


def test_await_from_asyncio_keeps_the_loop_running(gripper):
    async def main() -> tuple[bool, int]:
        ticks = 0
        task = asyncio.ensure_future(gripper.move(0.03, 0.1, asynchronous=True))
        while not task.done():  # the loop runs other work while the hand moves
            ticks += 1
            await asyncio.sleep(0.01)
        ok = await gripper.grasp(0.0, 0.1, 10.0, epsilon_outer=0.08, asynchronous=True)
        return (await task) and ok, ticks

    ok, ticks = asyncio.run(main())
    assert ok is True and ticks > 1


def test_bad_input_raises_in_the_caller_and_nothing_is_sent(gripper):
    before = gripper.read_once().width
    with pytest.raises(ValueError, match="width"):
        gripper.move(0.09, 0.1, asynchronous=True)
    with pytest.raises(ValueError, match="speed"):
        gripper.move(0.04, float("nan"), asynchronous=True)
    with pytest.raises(ValueError, match="force"):
        gripper.grasp(0.02, 0.1, 1000.0, asynchronous=True)
    with pytest.raises(ValueError, match="asynchronous"):
        gripper.move(0.04, 0.1, asynchronous="yes")  # type: ignore[call-overload]
    with pytest.raises(TypeError):
        gripper.move(0.04, 0.1, True)  # type: ignore[call-overload]  # keyword-only
    # a move sent would have started: the fingers stay where they were
    gripper.read_once()
    assert gripper.read_once().width == pytest.approx(before, abs=1e-3)
    assert gripper.move(0.07, 0.1) is True  # the connection is in order


def _readers() -> int:
    return sum(t.name == "panda_py gripper responses" for t in threading.enumerate())


def test_close_fails_a_pending_future(sim):
    before = _readers()
    with lf.Gripper(sim.host) as g:
        assert _readers() == before + 1
        future = g.move(0.0, 0.05, asynchronous=True)
        g.close()
        assert _readers() == before  # the reader thread has ended
        with pytest.raises(lf.NetworkException, match="Move command: the client was closed"):
            future.result(timeout=5)
        with pytest.raises(lf.NetworkException, match="closed"):
            g.move(0.04, 0.1, asynchronous=True)
    with lf.Gripper(sim.host) as again:  # the hand serves the next client
        assert again.move(0.08, 0.1) is True


def test_a_blocking_call_in_a_done_callback_is_refused(gripper):
    errors: list[BaseException] = []

    def callback(_: concurrent.futures.Future[bool]) -> None:
        try:
            gripper.stop()
        except RuntimeError as exc:
            errors.append(exc)

    future = gripper.move(0.06, 0.1, asynchronous=True)
    future.add_done_callback(callback)
    assert future.result() is True
    waited = threading.Event()
    future.add_done_callback(lambda _: waited.set())  # runs after the first callback ran
    assert waited.wait(5)
    assert len(errors) == 1 and "done-callback" in str(errors[0])
    assert gripper.stop() is True  # from any other thread it works


def test_commands_from_several_threads_each_get_their_answer(gripper):
    """The reader hands each response to its command, however many threads wait."""
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        reads = [pool.submit(gripper.read_once) for _ in range(3)]
        move = pool.submit(gripper.move, 0.04, 0.1)
        assert move.result() is True
        assert all(r.result().max_width > 0.0 for r in reads)


# -- a scripted hand: silence and a dropped connection ---------------------------------


class _ScriptedHand:
    """Answers Connect; then to each command: nothing ("silent") or closes ("hang up")."""

    def __init__(self, behaviour: str) -> None:
        self.behaviour = behaviour
        self.host = free_loopback_host()
        self.listener = socket.create_server((self.host, fci.GRIPPER_COMMAND_PORT))
        self.got_command = threading.Event()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.listener.accept()
        reader = fci.GripperMessageReader()
        with conn:
            while not self.done.is_set():
                data = conn.recv(4096)
                if not data:
                    return
                for msg in reader.feed(data):
                    if msg.command == 0:
                        conn.sendall(fci.encode_gripper_connect_response(
                            msg.command_id, fci.GripperConnectStatus.SUCCESS))  # fmt: skip
                        continue
                    self.got_command.set()
                    if self.behaviour == "hang up":
                        return
            self.done.wait(10)

    def close(self) -> None:
        self.done.set()
        self.listener.close()


@pytest.fixture
def scripted():
    hands: list[_ScriptedHand] = []

    def make(behaviour: str) -> _ScriptedHand:
        hands.append(_ScriptedHand(behaviour))
        return hands[-1]

    yield make
    for h in hands:
        h.close()


def test_an_unanswered_command_times_out_as_the_blocking_call(scripted):
    hand = scripted("silent")
    with lf.Gripper(hand.host, timeout=0.5) as g:
        start = time.monotonic()
        future = g.move(0.04, 0.2, asynchronous=True)
        with pytest.raises(lf.NetworkException, match="Timeout"):
            future.result(timeout=10)
        assert time.monotonic() - start >= 0.5
        with pytest.raises(lf.NetworkException, match="Timeout"):
            g.homing()


def test_a_dropped_connection_fails_the_pending_future(scripted):
    hand = scripted("hang up")
    with lf.Gripper(hand.host) as g:
        future = g.grasp(0.02, 0.1, 20.0, asynchronous=True)
        with pytest.raises(lf.NetworkException, match="server closed connection"):
            future.result(timeout=10)
        with pytest.raises(lf.NetworkException, match="server closed connection"):
            g.stop()  # the connection is gone: later commands fail at once


def test_a_client_dropped_unclosed_is_closed_when_collected(sim):
    """Its reader thread holds the connection, not the client: the hand is free again."""
    before = _readers()
    lf.Gripper(sim.host).move(0.06, 0.1, asynchronous=True).result()
    gc.collect()
    assert _readers() == before
    with lf.Gripper(sim.host) as again:  # not "robot busy"
        assert again.move(0.08, 0.1) is True
