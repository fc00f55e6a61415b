"""The simulated Desk under connections that never send a request nor read an answer
(issue 46): it let go of each only after a TLS goodbye such a peer never completes
(uvicorn's 30 s SSL shutdown timeout), and 80 of them answered every real client 503 for
about 40 s a wave."""

from __future__ import annotations

import socket
import ssl
import time
from pathlib import Path

import pytest
from desk_support import HEADER_TIMEOUT

from panda_py.desk import Desk
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(120)
IDLE = 80  # more than the Desk's connection limit (64)
PROMPT = 2.0  # [s] a real request answers within this, however many idle connections


def _context() -> ssl.SSLContext:
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE
    return ctx


def _handshake_by_hand(host: str, port: int) -> socket.socket:
    """A TCP connection with TLS set up over memory buffers: the TLS layer then reads
    nothing more, and the TCP connection shows when the Desk lets go of it."""
    raw = socket.create_connection((host, port), timeout=10)
    incoming, outgoing = ssl.MemoryBIO(), ssl.MemoryBIO()
    tls = _context().wrap_bio(incoming, outgoing)
    while True:
        try:
            tls.do_handshake()
            break
        except ssl.SSLWantReadError:
            raw.sendall(outgoing.read())
            data = raw.recv(65536)
            assert data, "the Desk closed during the TLS handshake"
            incoming.write(data)
    raw.sendall(outgoing.read())
    tls.write(b"GET /api/system HTTP/1.1\r\nHost: robot\r\n")  # a head never completed
    raw.sendall(outgoing.read())
    return raw


def test_a_silent_connection_is_let_go_at_the_header_timeout(fr3: Simulator) -> None:
    assert fr3.desk is not None
    raw = _handshake_by_hand(fr3.host, fr3.desk.port)
    t0 = time.monotonic()
    end = t0 + 2 * HEADER_TIMEOUT + PROMPT
    try:
        while True:
            raw.settimeout(max(0.01, end - time.monotonic()))
            try:
                if not raw.recv(65536):  # (the TLS goodbye, unanswered, then the end)
                    break
            except ConnectionResetError:
                break
            except TimeoutError:
                pytest.fail(f"the Desk still holds the connection after {end - t0:.1f} s")
    finally:
        raw.close()


def _served_while_held(fr3: Simulator, tmp_path: Path, request: bytes | None) -> None:
    """IDLE connections held open, each after sending ``request`` (None: nothing), none
    read: while they are held, and while the Desk lets go of them, a real client's every
    request is answered within PROMPT (a 503 raises)."""
    assert fr3.desk is not None
    held = []
    try:
        for _ in range(IDLE):
            raw = socket.create_connection((fr3.host, fr3.desk.port), timeout=10)
            tls = _context().wrap_socket(raw)
            if request is not None:
                tls.sendall(request)
            held.append(tls)  # and then nothing read
        desk = Desk(
            fr3.desk.hostname, "franka", "franka123", timeout=10.0,
            token_dir=str(tmp_path / "store"), connect=False,
        )  # fmt: skip
        end = time.monotonic() + 2 * HEADER_TIMEOUT + PROMPT
        while time.monotonic() < end:
            t0 = time.monotonic()
            desk.login()  # GET /api/system
            assert time.monotonic() - t0 < PROMPT
    finally:
        for sock in held:
            sock.close()


def test_idle_connections_do_not_lock_out_a_real_client(fr3: Simulator, tmp_path: Path) -> None:
    _served_while_held(fr3, tmp_path, None)


def test_connections_that_never_read_their_answer_do_not_lock_out_a_real_client(
    fr3: Simulator, tmp_path: Path
) -> None:
    """Peers that send a whole request (``Connection: close``) and then never read: each
    answer ends in a TLS goodbye they never complete, and until the Desk cuts it short
    (one to two header timeouts) the connection counts against the limit. Making room
    took idle connections only, and a real client was answered 503."""
    _served_while_held(fr3, tmp_path, b"GET /api/system HTTP/1.1\r\nHost: robot\r\n"
                                      b"Connection: close\r\n\r\n")  # fmt: skip
