"""Bad input to the simulated Desk: the documented status code, nothing changed on the
robot, and the server keeps serving."""

from __future__ import annotations

import base64
import http.client
import json
import logging
import socket
import ssl
import time
from typing import Any

import pytest
from desk_support import HEADER_TIMEOUT, desk_sim

from panda_py.desk import Desk, encode_password
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(120)
USER, PASSWORD = "franka", "franka123"
BASIC = {"Authorization": "Basic " + base64.b64encode(f"{USER}:{PASSWORD}".encode()).decode()}


def _context() -> ssl.SSLContext:
    ctx = ssl.create_default_context()
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE
    return ctx


def call(
    sim: Simulator, method: str, path: str, body: bytes | None = None, **headers: str
) -> tuple[int, str]:
    assert sim.desk is not None
    conn = http.client.HTTPSConnection(sim.host, sim.desk.port, context=_context(), timeout=10)
    try:
        conn.request(
            method, path, body=body, headers={k.replace("_", "-"): v for k, v in headers.items()}
        )
        res = conn.getresponse()
        return res.status, res.read().decode()
    finally:
        conn.close()


def declare_body(sim: Simulator, path: str, length: int) -> int:
    """POST ``path`` declaring a body of ``length`` bytes and sending none: the answer's
    status. (Sending an oversized body races the server, which answers it unread and
    closes: the client may still be writing and see the connection torn down instead.)"""
    assert sim.desk is not None
    conn = http.client.HTTPSConnection(sim.host, sim.desk.port, context=_context(), timeout=10)
    try:
        conn.putrequest("POST", path)
        conn.putheader("Content-Length", str(length))
        conn.endheaders()
        return conn.getresponse().status
    finally:
        conn.close()


def stream_body(
    sim: Simulator, path: str, chunks: list[bytes], end: bool = True
) -> tuple[int, str]:
    """POST ``path`` with a chunked body (no Content-Length: the server counts as it
    reads), ``end``: with the last chunk's terminator; the answer's status and text."""
    assert sim.desk is not None
    conn = http.client.HTTPSConnection(sim.host, sim.desk.port, context=_context(), timeout=10)
    try:
        conn.putrequest("POST", path)
        conn.putheader("Content-Type", "application/json")
        conn.putheader("Transfer-Encoding", "chunked")
        conn.endheaders()
        data = b"".join(b"%x\r\n%s\r\n" % (len(c), c) for c in chunks)
        conn.send(data + b"0\r\n\r\n" if end else data[:-2])
        res = conn.getresponse()
        return res.status, res.read().decode()
    finally:
        conn.close()


def login(sim: Simulator) -> str:
    body = json.dumps({"login": USER, "password": encode_password(USER, PASSWORD)}).encode()
    status, text = call(sim, "POST", "/admin/api/login", body, Content_Type="application/json")
    assert status == 200
    return text


def brakes(sim: Simulator) -> Any:
    assert sim.desk is not None
    return sim.desk.status()["safety"]["brakeState"][0]


def test_wrong_password_and_no_auth(fer: Simulator) -> None:
    fer.desk.power_cycle()  # type: ignore[union-attr]
    body = json.dumps({"login": USER, "password": encode_password(USER, "nope")}).encode()
    assert call(fer, "POST", "/admin/api/login", body)[0] == 401
    assert call(fer, "POST", "/admin/api/login", b'{"login": 1}')[0] == 401
    assert call(fer, "GET", "/admin/api/control-token")[0] == 401
    assert call(fer, "POST", "/desk/api/robot/open-brakes")[0] == 401
    assert call(fer, "GET", "/admin/api/control-token", authorization="forged")[0] == 401
    assert brakes(fer) == "Locked"
    login(fer)  # still serving


def test_foreign_token_and_second_user(fer: Simulator) -> None:
    fer.desk.power_cycle()  # type: ignore[union-attr]
    cookie = f"authorization={login(fer)}"
    status, text = call(
        fer, "POST", "/admin/api/control-token/request", b'{"requestedBy": "alice"}',
        Cookie=cookie, Content_Type="application/json",
    )  # fmt: skip
    assert status == 200
    token = json.loads(text)["token"]
    for bad in ("not-a-token", token + "x"):
        status, _ = call(
            fer, "POST", "/desk/api/robot/open-brakes", Cookie=cookie, X_Control_Token=bad
        )
        assert status == 423
    assert brakes(fer) == "Locked"
    # a second user's request is queued, not granted: alice keeps control
    status, text = call(
        fer, "POST", "/admin/api/control-token/request", b'{"requestedBy": "bob"}',
        Cookie=cookie, Content_Type="application/json",
    )  # fmt: skip
    bob = json.loads(text)["token"]
    assert (
        call(fer, "POST", "/desk/api/robot/open-brakes", Cookie=cookie, X_Control_Token=bob)[0]
        == 423
    )
    assert (
        call(fer, "POST", "/desk/api/robot/open-brakes", Cookie=cookie, X_Control_Token=token)[0]
        == 200
    )
    assert brakes(fer) == "Unlocked"
    # an expired token (after a power cycle) is refused
    fer.desk.power_cycle()  # type: ignore[union-attr]
    cookie = f"authorization={login(fer)}"
    assert (
        call(fer, "POST", "/desk/api/robot/open-brakes", Cookie=cookie, X_Control_Token=token)[0]
        == 423
    )


def test_malformed_oversized_unknown(fer: Simulator, fr3: Simulator) -> None:
    assert (
        call(fer, "POST", "/admin/api/login", b"{not json", Content_Type="application/json")[0]
        == 400
    )
    cookie = f"authorization={login(fer)}"
    status, _ = call(
        fer, "POST", "/admin/api/control-token/request", b"[1,", Cookie=cookie,
        Content_Type="application/json",
    )  # fmt: skip
    assert status == 400
    assert declare_body(fer, "/admin/api/login", 65 * 1024) == 413
    assert call(fer, "GET", "/no/such/path") == (404, "File not found")
    assert call(fr3, "GET", "/no/such/path") == (404, 'No handler accepted "/no/such/path"')
    # each arm serves only its own brake endpoints, and the FER no Desk API v1
    assert call(fer, "POST", "/desk/api/joints/unlock", Cookie=cookie)[0] == 404
    assert call(fer, "GET", "/api/system", **BASIC)[0] == 404
    assert call(fr3, "POST", "/desk/api/robot/open-brakes", **BASIC)[0] == 404
    assert call(fr3, "GET", "/api/system")[0] == 401
    assert call(fr3, "GET", "/api/system", **BASIC)[0] == 200
    assert call(fr3, "DELETE", "/api/system", **BASIC)[0] == 405


def test_a_streamed_body_is_read_and_bounded_as_it_arrives(fer: Simulator) -> None:
    """A chunked body (no length declared) is read whole below the limit, and answered 413
    once what arrived passes it. The oversized one is sent whole but for the chunk's
    closing line: the server must read every byte before it can answer, so the answer
    never races the client's writing."""
    body = json.dumps({"login": USER, "password": encode_password(USER, PASSWORD)}).encode()
    status, token = stream_body(fer, "/admin/api/login", [body[:10], body[10:]])
    assert status == 200 and token
    status, text = stream_body(fer, "/admin/api/login", [b" " * (64 * 1024 + 1)], end=False)
    assert status == 413 and "PayloadTooLarge" in text
    assert stream_body(fer, "/admin/api/login", [body])[0] == 200  # still serving


def test_a_slow_client_gets_408_and_does_not_block_others(fr3: Simulator) -> None:
    assert fr3.desk is not None
    raw = socket.create_connection((fr3.host, fr3.desk.port), timeout=30)
    slow = _context().wrap_socket(raw)
    slow.sendall(
        b"POST /api/system/control-token:take HTTP/1.1\r\nHost: robot\r\n"
        + f"Authorization: {BASIC['Authorization']}\r\n".encode()
        + b'Content-Type: application/json\r\nContent-Length: 100\r\n\r\n{"own'
    )
    t0 = time.monotonic()
    assert call(fr3, "GET", "/api/system", **BASIC)[0] == 200  # served meanwhile
    assert time.monotonic() - t0 < 2.0
    answer = slow.recv(4096)
    slow.close()
    assert answer.startswith(b"HTTP/1.1 408")


def test_a_client_sending_no_request_head_is_closed(fr3: Simulator) -> None:
    assert fr3.desk is not None
    raw = socket.create_connection((fr3.host, fr3.desk.port), timeout=30)
    slow = _context().wrap_socket(raw)
    slow.sendall(b"GET /api/system HTTP/1.1\r\nHost: robot\r\n")  # and nothing more
    t0 = time.monotonic()
    assert call(fr3, "GET", "/api/system", **BASIC)[0] == 200  # served meanwhile
    assert slow.recv(4096) == b""  # closed by the robot
    assert time.monotonic() - t0 < 2 * HEADER_TIMEOUT + 1.0
    slow.close()


def test_a_connection_a_client_holds_does_not_keep_a_stopped_desk_alive(tmp_path: Any) -> None:
    """A client that never closes its connection (nor answers the TLS close): the Desk
    still ends with the simulator's stop (it waited 10 s, then was left running)."""
    with desk_sim("fer", tmp_path / "cert") as sim:
        assert sim.desk is not None
        process = sim.desk._process
        raw = socket.create_connection((sim.host, sim.desk.port), timeout=30)
        held = _context().wrap_socket(raw)
    try:
        assert process.exitcode is not None, "the Desk's process outlived the stop"
    finally:
        held.close()


def test_the_client_never_shows_the_password_or_token(
    fr3: Simulator,
    tmp_path: Any,
    caplog: pytest.LogCaptureFixture,
    capsys: pytest.CaptureFixture[str],
) -> None:
    fr3.desk.power_cycle()  # type: ignore[union-attr]
    caplog.set_level(logging.DEBUG)
    for api in ("v1", "legacy"):
        d = Desk(fr3.desk.hostname, USER, PASSWORD, token_dir=str(tmp_path / api), api=api)  # type: ignore[union-attr]
        d.unlock()
        secret = d.token.token
        try:
            d.take_control(force=False)
            d.activate_fci()  # fails: nothing here may echo a secret
        except Exception as exc:
            assert secret not in str(exc) and PASSWORD not in str(exc)
        text = repr(d) + repr(d.token) + caplog.text + "".join(capsys.readouterr())
        assert secret not in text and PASSWORD not in text
        d.lock()
        d.release_control()
