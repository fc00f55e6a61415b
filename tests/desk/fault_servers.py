"""Small misbehaving Desks for the fault tests: a TLS server on loopback whose every
connection is served by a handler in a thread of its own.

Each handler ends by itself within a bound (or when the server stops), so a client that
waits for it fails its test by a wrong figure, not by hanging; ``stop`` closes every
connection and joins every thread.
"""

from __future__ import annotations

import base64
import hashlib
import socket
import ssl
import threading
import time
from collections.abc import Callable
from pathlib import Path

from panda_py.sim.desk.cert import ensure_certificate

Handler = Callable[[ssl.SSLSocket, "FaultServer", bytes], None]
"""How a fault server answers one request: ``handler(conn, server, request)``, the request
(head and body) already read."""
HEAD_TIMEOUT = 10.0  # [s] the server waits this long for the client's request head
LONGEST = 12.0  # [s] no handler keeps a connection longer (a client that waits for it fails)
WS_GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455 section 1.3


class FaultServer:
    """A TLS server on 127.0.0.1 answering one request per connection (clients of the
    Desk send ``Connection: close``): by ``handlers[path]`` (a handler, or a whole
    response to send), 404 for other paths; or by ``handlers`` itself for every path."""

    def __init__(self, handlers: Handler | dict[str, Handler | bytes], cert_dir: Path) -> None:
        self.handlers = handlers
        self.context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        self.context.load_cert_chain(ensure_certificate(cert_dir))
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.05)
        self.port = self.listener.getsockname()[1]
        self.stopped = threading.Event()
        self.requests: list[bytes] = []  # every request received (head and body), in order
        self.sent = 0  # [bytes] of body the handlers wrote
        self._lock = threading.Lock()
        self._conns: list[socket.socket] = []
        self._threads: list[threading.Thread] = []

    @property
    def hostname(self) -> str:
        return f"127.0.0.1:{self.port}"

    def __enter__(self) -> FaultServer:
        self._spawn(self._accept)
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _spawn(self, target: Callable[..., None], *args: object) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True, name="fault-server")
        with self._lock:
            self._threads.append(thread)
        thread.start()

    def _accept(self) -> None:
        while not self.stopped.is_set():
            try:
                raw, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with self._lock:
                self._conns.append(raw)
            self._spawn(self._serve, raw)

    def _serve(self, raw: socket.socket) -> None:
        conn: socket.socket = raw
        try:
            raw.settimeout(HEAD_TIMEOUT)
            conn = self.context.wrap_socket(raw, server_side=True)
            with self._lock:
                self._conns.append(conn)
            request = self.read_request(conn)
            path = request.split(b" ", 2)[1].decode().split("?")[0]
            handler = self.handlers
            if isinstance(handler, dict):
                handler = handler.get(path, answer(404, b"File not found", "text/plain"))
            if isinstance(handler, bytes):
                conn.sendall(handler)
            else:
                handler(conn, self, request)
        except OSError:
            pass  # the client went, or the server stopped
        finally:
            conn.close()

    def read_request(self, conn: socket.socket) -> bytes:
        """The next request head (up to the blank line) and its body, as received."""
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = conn.recv(4096)
            if not chunk:
                raise ConnectionError("the client closed before its request head")
            data += chunk
        head, _, body = data.partition(b"\r\n\r\n")
        for line in head.split(b"\r\n"):
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":", 1)[1])
                while len(body) < length:
                    chunk = conn.recv(4096)
                    if not chunk:
                        break
                    body += chunk
        request = head + b"\r\n\r\n" + body
        with self._lock:
            self.requests.append(request)
        return request

    def stop(self) -> None:
        self.stopped.set()
        self.listener.close()
        with self._lock:
            conns, threads = list(self._conns), list(self._threads)
        for c in conns:
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            c.close()
        for t in threads:
            t.join(5)
        assert not any(t.is_alive() for t in threads), "a fault server thread outlived stop()"


def answer(status: int, body: bytes, content_type: str = "application/json") -> bytes:
    reason = {200: "OK", 400: "Bad Request", 401: "Unauthorized", 404: "Not Found"}
    return (
        f"HTTP/1.1 {status} {reason.get(status, 'Status')}\r\nContent-Type: {content_type}\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    ).encode() + body


def drip(response: bytes, every: float = 0.5) -> Handler:
    """Send ``response`` a byte every ``every`` [s] (for at most ``LONGEST`` s, then close)."""

    def run(conn: ssl.SSLSocket, server: FaultServer, request: bytes) -> None:
        end = time.monotonic() + LONGEST
        for i in range(len(response)):
            if server.stopped.wait(every) or time.monotonic() > end:
                return
            conn.sendall(response[i : i + 1])

    return run


def echo(status: int = 400) -> Handler:
    """Answer ``status`` with the request (head and body) as the body, as some servers'
    error pages do."""

    def run(conn: ssl.SSLSocket, server: FaultServer, request: bytes) -> None:
        conn.sendall(answer(status, b"bad request:\r\n" + request, "text/plain"))

    return run


def huge(size: int, *, declared: bool) -> Handler:
    """Answer 200 with ``size`` bytes of blanks, their length declared or not (then the
    end of the body is the end of the connection), written as fast as the client reads."""

    def run(conn: ssl.SSLSocket, server: FaultServer, request: bytes) -> None:
        length = f"Content-Length: {size}\r\n" if declared else ""
        conn.sendall(
            f"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\n{length}"
            "Connection: close\r\n\r\n".encode()
        )
        block = b" " * 65536
        conn.settimeout(LONGEST)
        while server.sent < size and not server.stopped.is_set():
            conn.sendall(block)
            server.sent += len(block)

    return run


def _accept_key(request: bytes) -> str:
    for line in request.split(b"\r\n"):
        if line.lower().startswith(b"sec-websocket-key:"):
            key = line.split(b":", 1)[1].strip().decode()
            return base64.b64encode(hashlib.sha1((key + WS_GUID).encode()).digest()).decode()
    raise ValueError("no Sec-WebSocket-Key in the upgrade request")


def silent_websocket(*, upgrade: bool) -> Handler:
    """Answer the websocket upgrade request (``upgrade``) or not; then say and read
    nothing more (for at most ``LONGEST`` s)."""

    def run(conn: ssl.SSLSocket, server: FaultServer, request: bytes) -> None:
        if upgrade:
            conn.sendall(
                b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n"
                b"Connection: Upgrade\r\nSec-WebSocket-Accept: "
                + _accept_key(request).encode()
                + b"\r\n\r\n"
            )
        server.stopped.wait(LONGEST)

    return run


def no_threads_left(before: set[threading.Thread], grace: float = 2.0) -> list[str]:
    """The names of threads started since ``before`` still alive after ``grace`` [s]."""
    deadline = time.monotonic() + grace
    while True:
        left = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not left or time.monotonic() > deadline:
            return [t.name for t in left]
        time.sleep(0.02)
