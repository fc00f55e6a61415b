"""Faults of a Desk that nobody had run before (issue 46), against small local servers:
an answer dripped a byte at a time, a huge answer. Each ends in a ``DeskError`` within the
Desk's timeout, naming what came back."""

from __future__ import annotations

import pickle
import time
import tracemalloc
from pathlib import Path

import pytest
from fault_servers import FaultServer, answer, drip, huge

from panda_py.desk import Desk, DeskConnectionError, DeskError

pytestmark = pytest.mark.timeout(60)
USER, PASSWORD = "franka", "pa55-w0rd-x"
SLACK = 1.5  # [s] beyond a timeout, for a loaded machine (the faults took 10-30 s and more)


@pytest.fixture(scope="module")
def cert_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fault-cert")


@pytest.fixture
def tokens(tmp_path: Path) -> str:
    return str(tmp_path / "store")


def _desk(server: FaultServer, tokens: str, timeout: float = 5.0, api: str | None = None) -> Desk:
    return Desk(
        server.hostname, USER, PASSWORD, timeout=timeout, token_dir=tokens, api=api, connect=False
    )


def test_a_dripping_answer_ends_at_the_deadline(cert_dir: Path, tokens: str) -> None:
    """A byte every 0.5 s: each read is quick, the answer never complete. The socket's
    timeout applied per read, so the request lasted as long as the server dripped."""
    with FaultServer(drip(answer(200, b'{"version": "5.8.0"}' + b" " * 100)), cert_dir) as s:
        desk = _desk(s, tokens, timeout=2.0)
        t0 = time.monotonic()
        with pytest.raises(DeskConnectionError) as info:
            desk.login()
        elapsed = time.monotonic() - t0
    assert elapsed < 2.0 + SLACK
    exc = info.value
    assert isinstance(exc, TimeoutError)
    assert "GET /api/system" in str(exc) and "2 s" in str(exc)
    assert exc.received >= 3 and "came by then: HTT" in str(exc)  # (what came: a byte each 0.5 s)
    assert pickle.loads(pickle.dumps(exc)).args == exc.args


@pytest.mark.parametrize("declared", [True, False], ids=["content-length", "until-close"])
def test_a_huge_answer_is_refused_not_read_into_memory(
    cert_dir: Path, tokens: str, declared: bool
) -> None:
    size = 200 * 2**20
    with FaultServer(huge(size, declared=declared), cert_dir) as s:
        desk = _desk(s, tokens, timeout=20.0)
        tracemalloc.start()
        try:
            with pytest.raises(DeskError) as info:
                desk.login()
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    assert peak < 32 * 2**20, f"{peak / 2**20:.0f} MiB held reading the answer"
    text = str(info.value)
    assert "GET /api/system" in text and "MiB" in text
    if declared:
        assert str(size) in text  # the length the robot declared
    assert getattr(info.value, "status", None) == 200
