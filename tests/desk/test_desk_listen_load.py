"""Desk.listen() under load: every Pilot-event handshake completes and the first event
arrives, none waits out its timeout (one of 16 runs of panda-py's pilot_buttons.py did,
on a loaded machine; counted here, not timed)."""

from __future__ import annotations

import multiprocessing
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from desk_support import desk_sim

from panda_py.desk import Desk
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(180)
HANDSHAKES = 30
STALL = 5.0  # [s] half the Desk's default timeout: a handshake this slow has stalled


def _burn(stop: multiprocessing.synchronize.Event) -> None:
    deadline = time.monotonic() + 120  # stops by itself, whatever happens to the test
    while not stop.is_set() and time.monotonic() < deadline:
        pass


@pytest.fixture
def busy_machine() -> Iterator[None]:
    ctx = multiprocessing.get_context("spawn")
    stop = ctx.Event()
    burners = [ctx.Process(target=_burn, args=(stop,), daemon=True) for _ in range(2)]
    for b in burners:
        b.start()
    try:
        yield
    finally:
        stop.set()
        for b in burners:
            b.join(10)
            if b.is_alive():
                b.kill()


def test_listen_handshakes_never_stall_under_load(tmp_path: Path, busy_machine: None) -> None:
    sim: Simulator
    with desk_sim("fr3", tmp_path / "cert", locked=False) as sim:
        assert sim.desk is not None
        stalled = []
        for i in range(HANDSHAKES):
            d = Desk(sim.desk.hostname, "franka", "franka123", token_dir=str(tmp_path / f"t{i}"))
            first = threading.Event()
            t0 = time.monotonic()
            d.listen(lambda event, first=first: first.set())
            opened = time.monotonic() - t0
            got = first.wait(2 * STALL)  # the full key map comes first
            d.stop_listen()
            if opened > STALL or not got:
                stalled.append((i, round(opened, 2), got))
        assert stalled == [], f"handshakes that stalled (index, seconds, first event): {stalled}"
