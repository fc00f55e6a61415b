"""One deadline for a whole request to a Desk.

A socket's timeout bounds each call, not the request: a Desk that sends a byte every
0.5 s answers every ``recv`` in time, and a request with a 2 s timeout went on for as long
as it dripped (30 s and more). :class:`DeadlineSocket` gives each send and receive only
what is left of one deadline, and keeps the beginning of what came, for the error that
names it. It offers what ``http.client`` uses of a socket: ``sendall``, ``makefile("rb")``
and ``close`` (which, as a socket's, closes the connection once its reader is closed too:
``http.client`` closes the socket of a ``Connection: close`` answer before reading it).
"""

from __future__ import annotations

import io
import socket
import time
from typing import Any

KEPT = 512  # [bytes] of the answer's beginning kept for an error


def remaining(deadline: float) -> float:
    """Seconds until ``deadline`` (``time.monotonic()``); ``TimeoutError`` once it passed."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise TimeoutError("the deadline passed")
    return left


class DeadlineSocket:
    """A connected socket (TLS or not) whose every send and receive ends by ``deadline``
    (``time.monotonic()``), raising ``TimeoutError`` past it. ``received`` counts the bytes
    received, ``start`` holds their first :data:`KEPT`."""

    def __init__(self, sock: socket.socket, deadline: float) -> None:
        self.sock = sock
        self.deadline = deadline
        self.received = 0
        self.start = b""
        self._readers = 0
        self._closed = False

    def sendall(self, data: Any) -> None:
        view = memoryview(data).cast("B")
        while view:
            self.sock.settimeout(remaining(self.deadline))
            view = view[self.sock.send(view) :]

    def recv_into(self, buffer: Any, nbytes: int = 0) -> int:
        self.sock.settimeout(remaining(self.deadline))
        n = self.sock.recv_into(buffer, nbytes or memoryview(buffer).nbytes)
        if len(self.start) < KEPT:
            self.start += bytes(memoryview(buffer)[: min(n, KEPT - len(self.start))])
        self.received += n
        return n

    def makefile(self, mode: str = "rb", *args: Any, **kwargs: Any) -> io.BufferedReader:
        if mode != "rb":
            raise ValueError(f"mode: expected 'rb' (answers are only read), got {mode!r}")
        self._readers += 1
        return io.BufferedReader(_Reader(self))

    def _reader_closed(self) -> None:
        self._readers -= 1
        if self._closed and not self._readers:
            self.sock.close()

    def close(self) -> None:
        self._closed = True
        if not self._readers:
            self.sock.close()


class _Reader(io.RawIOBase):
    def __init__(self, sock: DeadlineSocket) -> None:
        self._sock = sock

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        return self._sock.recv_into(buffer)

    def close(self) -> None:
        if not self.closed:
            self._sock._reader_closed()
        super().close()


__all__ = ["KEPT", "DeadlineSocket", "remaining"]
