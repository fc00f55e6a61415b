"""``listen()`` and ``stop_listen()`` against a Desk that goes silent on the Pilot-event
websocket: each ends within the Desk's timeout and leaves no thread behind (issue 46:
``listen`` waited until the server closed, ``stop_listen`` 10 s whatever the timeout)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from fault_servers import FaultServer, answer, no_threads_left, silent_websocket

from panda_py.desk import Desk, DeskConnectionError
from panda_py.desk.api import PILOT_EVENTS_PATH

pytestmark = pytest.mark.timeout(60)
TIMEOUT = 2.0  # [s] the Desk's
SLACK = 1.5  # [s] beyond it, for a loaded machine
V1 = {"/api/system": answer(200, b'{"version": "5.8.0"}')}


def _server_threads() -> set[threading.Thread]:
    return {t for t in threading.enumerate() if t.name == "fault-server"}


def _desk(server: FaultServer, tmp_path: Path) -> Desk:
    desk = Desk(
        server.hostname, "franka", "franka123", timeout=TIMEOUT,
        token_dir=str(tmp_path / "store"), connect=False,
    )  # fmt: skip
    desk.login()
    return desk


def test_listen_ends_at_the_timeout_when_the_upgrade_is_never_answered(tmp_path: Path) -> None:
    before = set(threading.enumerate())
    handlers = {**V1, PILOT_EVENTS_PATH: silent_websocket(upgrade=False)}
    with FaultServer(handlers, tmp_path / "cert") as server:
        desk = _desk(server, tmp_path)
        t0 = time.monotonic()
        with pytest.raises(DeskConnectionError, match="Pilot events"):
            desk.listen(lambda event: None)
        elapsed = time.monotonic() - t0
        left = no_threads_left(before | _server_threads())
    assert elapsed < TIMEOUT + SLACK
    assert left == []


def test_stop_listen_ends_at_the_timeout_when_the_desk_goes_silent(tmp_path: Path) -> None:
    before = set(threading.enumerate())
    handlers = {**V1, PILOT_EVENTS_PATH: silent_websocket(upgrade=True)}
    with FaultServer(handlers, tmp_path / "cert") as server:
        desk = _desk(server, tmp_path)
        t0 = time.monotonic()
        desk.listen(lambda event: None)
        opened = time.monotonic() - t0
        t0 = time.monotonic()
        desk.stop_listen()
        stopped = time.monotonic() - t0
        left = no_threads_left(before | _server_threads())
    assert opened < TIMEOUT + SLACK
    assert stopped < TIMEOUT + SLACK
    assert left == []
