"""One TLS connection shared by two threads, every OpenSSL call made under one lock.

websockets' synchronous client reads its socket in a thread of its own while the caller's
thread writes (the upgrade request, then frames). On a plain socket that is fine; on a TLS
socket a read and a write run OpenSSL on the same connection at once, which OpenSSL does
not allow: a TLS 1.3 server sends its session tickets just after the handshake, so the
reader is inside OpenSSL exactly when the upgrade request goes out. Under load that broke
one Pilot-event handshake in sixteen (a stall to the timeout with a socket timeout set,
"connection closed while reading HTTP status line" in blocking mode). Here the TLS socket
is non-blocking; each call into it holds the lock only for that non-blocking step, and
waits for readiness outside it, so reader and writer take turns and neither waits on the
other's socket state.

A wait ends when the socket is closed, too: websockets reads with no timeout, and a
``select`` is not woken by another thread closing its socket. A Desk that sent its TLS
session tickets and then nothing left the reader waiting for the rest of a record, and
the caller's close (after the upgrade's timeout) joining it, until the Desk hung up.
Waits therefore look at the closed flag every :data:`CLOSE_POLL`.
"""

from __future__ import annotations

import select
import socket
import ssl
import threading
import time
from typing import Any

CLOSE_POLL = 0.05  # [s] a waiting read or write notices a close within this


class SerializedTLSSocket:
    """The socket methods websockets' sync client uses, over an :class:`ssl.SSLSocket`."""

    def __init__(self, sock: ssl.SSLSocket) -> None:
        sock.setblocking(False)
        self._sock = sock
        self._lock = threading.Lock()
        self._timeout: float | None = None
        self._closed = False
        self.family = sock.family

    def settimeout(self, timeout: float | None) -> None:
        self._timeout = timeout

    def _wait(self, write: bool, deadline: float | None) -> None:
        while True:
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                raise TimeoutError("timed out")
            fd = self._sock.fileno()
            if self._closed or fd < 0:
                raise OSError("the socket is closed")
            wait = CLOSE_POLL if remaining is None else min(remaining, CLOSE_POLL)
            r, w, _ = select.select([] if write else [fd], [fd] if write else [], [], wait)
            if r or w:
                return

    def _deadline(self) -> float | None:
        return None if self._timeout is None else time.monotonic() + self._timeout

    def recv(self, size: int) -> bytes:
        deadline = self._deadline()
        while True:
            with self._lock:
                try:
                    return self._sock.recv(size)
                except ssl.SSLWantReadError:
                    write = False
                except ssl.SSLWantWriteError:
                    write = True
            self._wait(write, deadline)

    def sendall(self, data: bytes | bytearray | memoryview) -> None:
        view = memoryview(data)
        deadline = self._deadline()
        while view:
            with self._lock:
                try:
                    view = view[self._sock.send(view) :]
                    continue
                except ssl.SSLWantWriteError:
                    write = True
                except ssl.SSLWantReadError:
                    write = False
            self._wait(write, deadline)

    def shutdown(self, how: int) -> None:
        self._sock.shutdown(how)  # the TCP connection's, not OpenSSL's: no lock needed

    def close(self) -> None:
        self._closed = True  # (a wait in the other thread sees it within CLOSE_POLL)
        with self._lock:  # not in the middle of the other thread's OpenSSL call
            self._sock.close()

    def fileno(self) -> int:
        return self._sock.fileno()

    def setsockopt(self, *args: Any) -> None:
        self._sock.setsockopt(*args)

    def getsockname(self) -> Any:
        return self._sock.getsockname()

    def getpeername(self) -> Any:
        return self._sock.getpeername()


def shared_tls(sock: socket.socket) -> socket.socket:
    """``sock`` made safe for websockets' reader and writer threads when it is a TLS
    socket (typed as the socket websockets expects)."""
    if not isinstance(sock, ssl.SSLSocket):
        return sock
    return SerializedTLSSocket(sock)  # type: ignore[return-value]


__all__ = ["CLOSE_POLL", "SerializedTLSSocket", "shared_tls"]
