"""Faults of a Desk that nobody had run before (issue 46), against small local servers:
an answer dripped a byte at a time, a huge answer, answers of the wrong shape or binary,
an error page that echoes the request. Each ends in a ``DeskError`` within the Desk's
timeout, naming what came back and no credential."""

from __future__ import annotations

import base64
import json
import math
import pickle
import time
import tracemalloc
from pathlib import Path

import pytest
from fault_servers import FaultServer, answer, drip, echo, huge

from panda_py.desk import Desk, DeskConnectionError, DeskError, DeskHTTPError, encode_password

pytestmark = pytest.mark.timeout(60)
USER, PASSWORD = "franka", "pa55-w0rd-x"
BASIC = base64.b64encode(f"{USER}:{PASSWORD}".encode()).decode()
SLACK = 1.5  # [s] beyond a timeout, for a loaded machine (the faults took 10-30 s and more)
V1 = {"/api/system": answer(200, b'{"version": "5.8.0"}')}
LEGACY_LOGIN = {"/api/system": answer(404, b"File not found", "text/plain")}


@pytest.fixture(scope="module")
def cert_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fault-cert")


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


def _shape(path: str, body: bytes, content_type: str = "application/json") -> dict[str, bytes]:
    return {path: answer(200, body, content_type)}


WRONG_SHAPES = {
    # (dialect, the call, the answers the Desk gives, what must be named)
    "v1 system status a list": (
        "v1", lambda d: d.system_status(), _shape("/api/system", b"[1, 2]"), "[1, 2]",
    ),
    "v1 active token a list": (
        "v1", lambda d: d.has_control(), {**V1, **_shape("/api/system/control-token", b"[3]")},
        "[3]",
    ),
    "v1 take without tokenId": (
        "v1", lambda d: d.take_control(),
        {**V1, **_shape("/api/system/control-token", b"{}"),
         **_shape("/api/system/control-token:take", b'{"token": "abc"}')},
        "tokenId",
    ),
    "v1 fci status a string": (
        "v1", lambda d: d.fci_status(), {**V1, **_shape("/api/fci", b'"Active"')}, "Active",
    ),
    "v1 operating mode an object": (
        "v1", lambda d: d.operating_mode(),
        {**V1, **_shape("/api/system/operating-mode", b'{"status": {"x": 1}}')}, "status",
    ),
    "v1 joints an object": (
        "v1", lambda d: d.brake_states(), {**V1, **_shape("/api/arm/joints", b'{"joints": []}')},
        "joints",
    ),
    "v1 self-test status a list": (
        "v1", lambda d: d.self_test_due_in(), {**V1, **_shape("/api/safety/self-tests", b"[1]")},
        "[1]",
    ),
    "v1 JSON nested past the stack": (
        "v1", lambda d: d.system_status(), _shape("/api/system", b"[" * 100_000), "nested",
    ),
    "v1 not JSON": (
        "v1", lambda d: d.system_status(), _shape("/api/system", b"<html>oops</html>"), "<html>",
    ),
    "legacy binary session": (
        "legacy", lambda d: d.has_control(),
        {**LEGACY_LOGIN, **_shape("/admin/api/login", b"\xff\xfe\x00\x01ses", "text/plain")},
        "session of 7 bytes, not ASCII",  # (not shown: it would be the credential)
    ),
    "legacy active token a string": (
        "legacy", lambda d: d.has_control(),
        {**LEGACY_LOGIN, **_shape("/admin/api/login", b"SESSION", "text/plain"),
         **_shape("/admin/api/control-token", b'{"activeToken": "x"}')},
        "activeToken",
    ),
    "legacy take without token": (
        "legacy", lambda d: d.take_control(),
        {**LEGACY_LOGIN, **_shape("/admin/api/login", b"SESSION", "text/plain"),
         **_shape("/admin/api/control-token", b'{"activeToken": null}'),
         **_shape("/admin/api/control-token/request", b'{"id": 3}')},
        "token",
    ),
    "legacy system status brakes a string": (
        "legacy", lambda d: d.pending_recoveries(),
        {**LEGACY_LOGIN, **_shape("/admin/api/login", b"SESSION", "text/plain"),
         **_shape("/admin/api/system-status", b'{"safety": {"recoverableErrors": [1]}}')},
        "recoverableErrors",
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", WRONG_SHAPES.values(), ids=WRONG_SHAPES.keys())
def test_an_answer_of_the_wrong_shape_is_a_desk_error_naming_it(
    cert_dir: Path, tokens: str, case: tuple
) -> None:
    api, call, table, named = case
    with FaultServer(table, cert_dir) as s:
        desk = _desk(s, tokens, api=api)
        with pytest.raises(DeskError) as info:
            desk.login()
            call(desk)
    exc = info.value
    assert named in str(exc), str(exc)
    assert len(str(exc).splitlines()) == 1
    assert getattr(exc, "status", None) == 200 and getattr(exc, "path", "").startswith("/")
    assert str(pickle.loads(pickle.dumps(exc))) == str(exc)


SECRETS = {
    "v1 basic auth": ("v1", V1 | {"/api/system": echo(400)}, [BASIC, PASSWORD]),
    "legacy password": (
        "legacy", {**LEGACY_LOGIN, "/admin/api/login": echo(401)},
        [*encode_password(USER, PASSWORD).split(), PASSWORD],  # (base64 in lines)
    ),
    "legacy session": (
        "legacy",
        {**LEGACY_LOGIN, **_shape("/admin/api/login", b"SESSION-SECRET-42", "text/plain"),
         "/admin/api/control-token": echo(401)},
        ["SESSION-SECRET-42"],
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", SECRETS.values(), ids=SECRETS.keys())
def test_an_echoed_request_shows_no_credential(cert_dir: Path, tokens: str, case: tuple) -> None:
    api, table, secrets = case
    with FaultServer(table, cert_dir) as s:
        desk = _desk(s, tokens, api=api)
        with pytest.raises(DeskHTTPError) as info:
            desk.login()
            desk.has_control()
        sent = b"".join(s.requests).decode()
    assert all(secret in sent for secret in secrets[:1])  # what the robot echoed held it
    exc = info.value
    shown = [str(exc), repr(exc), exc.message, *map(str, exc.args)]
    shown.append(pickle.dumps(exc).decode("latin-1"))
    for secret in secrets:
        for text in shown:
            assert secret not in text
    assert "bad request" in exc.message  # the rest of what came back is kept


def test_an_error_page_nested_past_the_stack_is_still_a_desk_http_error(
    cert_dir: Path, tokens: str
) -> None:
    """The code/reason fields are read from a JSON error body: one nested 100 000 deep
    raised RecursionError."""
    with FaultServer({"/api/system": answer(500, b"[" * 100_000)}, cert_dir) as s:
        with pytest.raises(DeskHTTPError) as info:
            _desk(s, tokens, api="v1").login()
    assert info.value.status == 500 and info.value.code is None


@pytest.mark.parametrize("timeout", [math.inf, math.nan, 0.0, -1.0, 1e300, "5", None])
def test_a_timeout_that_is_no_finite_positive_number_is_refused(timeout: object) -> None:
    with pytest.raises(ValueError, match="timeout") as info:
        Desk("robot", USER, PASSWORD, timeout=timeout, connect=False)  # type: ignore[arg-type]
    assert repr(timeout) in str(info.value) or str(timeout) in str(info.value)


def test_json_of_a_wrong_shape_names_the_request_and_status(cert_dir: Path, tokens: str) -> None:
    """The fields of the error say which request got which answer."""
    with FaultServer({**V1, **_shape("/api/fci", json.dumps([1]).encode())}, cert_dir) as s:
        desk = _desk(s, tokens, api="v1")
        desk.login()
        with pytest.raises(DeskError) as info:
            desk.fci_status()
    exc = info.value
    assert (getattr(exc, "method", None), getattr(exc, "path", None)) == ("GET", "/api/fci")
