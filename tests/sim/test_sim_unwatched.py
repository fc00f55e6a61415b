"""A simulator nobody watches (no client, viewer, recorder or Desk drive) runs its ticks in
batches of ``UNWATCHED_BATCH`` and sleeps between them; once a client connects, each tick
runs on its own again. The loop runs in this process, its ``select`` counted."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from panda_py.sim import free_loopback_host
from panda_py.sim.config import SimConfig
from panda_py.sim.server import UNWATCHED_BATCH, SimServer

pytestmark = pytest.mark.timeout(60)


class Counted:
    """The server's selector, its passes counted."""

    def __init__(self, selector: Any) -> None:
        self.selector, self.passes = selector, 0

    def select(self, timeout: float | None = None) -> Any:
        self.passes += 1
        return self.selector.select(timeout)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.selector, name)


@pytest.fixture(params=[False, True], ids=["realtime", "lockstep"])
def server(request: pytest.FixtureRequest) -> Iterator[SimServer]:
    srv = SimServer(SimConfig(host=free_loopback_host(), lockstep=request.param))
    srv._sel = Counted(srv._sel)  # type: ignore[assignment]
    loop = threading.Thread(target=srv.serve_forever, daemon=True)
    loop.start()
    yield srv
    srv.shutdown()
    loop.join(5)
    assert not loop.is_alive()


def _over(srv: SimServer, seconds: float) -> tuple[int, int, float, bool]:
    """Ticks, loop passes and wall time over ``seconds``, and whether the machine stalled
    the loop past its catching up (a resync: the clock's ticks were skipped)."""
    sel: Any = srv._sel
    resyncs = srv.stats.resyncs
    ticks, passes, t0 = srv.tick_count, sel.passes, time.monotonic()
    time.sleep(seconds)
    stalled = srv.stats.resyncs != resyncs
    return srv.tick_count - ticks, sel.passes - passes, time.monotonic() - t0, stalled


def test_unwatched_ticks_run_in_batches_and_keep_the_wall_clock(server: SimServer) -> None:
    time.sleep(0.2)  # started
    ticks, passes, wall, stalled = _over(server, 1.0)
    # the same ticks as one a millisecond, within a batch either way
    if not stalled:
        assert abs(ticks - 1000 * wall) <= 1000 * UNWATCHED_BATCH + 5, (ticks, wall)
    # woken about once a batch, not once a tick
    assert passes <= 3 * wall / UNWATCHED_BATCH, (ticks, passes)


def test_a_connected_client_gets_every_tick_on_its_own(server: SimServer) -> None:
    time.sleep(0.2)
    host, port = server.config.host, server.config.robot_port
    with socket.create_connection((host, port), timeout=5):
        deadline = time.monotonic() + 5
        while server.robot_conn is None:  # accepted
            assert time.monotonic() < deadline
            time.sleep(0.01)
        ticks, passes, wall, stalled = _over(server, 0.5)
        if not stalled:
            assert abs(ticks - 1000 * wall) <= 100, (ticks, wall)
        assert passes >= ticks, (ticks, passes)  # a pass (at least) for every tick
    deadline = time.monotonic() + 5
    while server.robot_conn is not None:  # gone: batches again
        assert time.monotonic() < deadline
        time.sleep(0.01)
    _, passes, wall, _ = _over(server, 0.5)
    assert passes <= 3 * wall / UNWATCHED_BATCH
