"""The simulated Desk's HTTP connections: uvicorn's HTTP/1.1 protocol with the bounds it
lacks, so that peers which never send a request, or never read, cannot lock clients out.

uvicorn waits for a request head for ever, and it ends a connection through a TLS goodbye
(its close_notify, then up to asyncio's 30 s SSL shutdown timeout for the peer's) that a
peer which never reads never completes. All that while the connection counts against
``limit_concurrency``, past which every request is answered 503: 80 idle connections shut
real clients out for about 40 s a wave. Here:

- a connection that sends no complete request head within the header timeout (to twice
  it), or idles past uvicorn's keep-alive timeout, is aborted: its TCP connection is
  dropped at once, with no goodbye to wait for (it was sent nothing it could miss);
- a goodbye still unanswered one to two header timeouts after it began is cut short (its
  socket shut down where asyncio's TLS transport, closed twice by uvicorn, no longer
  reaches its connection);
- a new connection that finds the limit reached makes room: a connection in its TLS
  goodbye (its answer sent; the peer never read it) is aborted first, then the one idle
  longest (no request under way), so a client with a request is served at once however
  many such connections are held.
"""

from __future__ import annotations

import logging
import socket
from typing import Any

log = logging.getLogger("panda_py.sim.desk")


def desk_protocol(header_timeout: float) -> Any:
    """uvicorn's HTTP/1.1 protocol class with the bounds of the module docstring;
    ``header_timeout`` [s] is the time a connection has to send a request head."""
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class DeskProtocol(H11Protocol):
        def connection_made(self, transport: Any) -> None:
            # asyncio's TLS transport, closed twice, lets go of its connection (and of its
            # extra info) while the TLS goodbye goes on: its socket, kept here, is the way
            # left to drop it
            self._sock = transport.get_extra_info("socket")
            super().connection_made(transport)
            self._heads = 0
            self._heads_at_check = 0
            self._quiet_since = self.loop.time()
            self._closing_seen = False
            self._lost = False
            self._make_room()
            self._check_later()

        def connection_lost(self, exc: Exception | None) -> None:
            self._lost = True
            super().connection_lost(exc)

        def data_received(self, data: bytes) -> None:
            self._quiet_since = self.loop.time()
            idle = self.conn.their_state is h11.IDLE
            super().data_received(data)
            if idle and self.conn.their_state is not h11.IDLE:
                self._heads += 1  # a complete request head arrived

        def _idle(self) -> bool:
            """No request under way: none sent yet, or between two."""
            cycle = self.cycle
            return self.conn.their_state is h11.IDLE and (cycle is None or cycle.response_complete)

        def _abort(self, why: str) -> None:
            log.info("aborting a connection that %s", why)
            # it counts against the limit no more from now (connection_lost comes later)
            self.connections.discard(self)
            self.transport.abort()
            # and the socket itself: a TLS transport closed twice, abort() reaches nothing
            if self._sock is not None:
                try:
                    self._sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass  # gone already

        def _make_room(self) -> None:
            limit = self.limit_concurrency
            if limit is None:
                return
            excess = len(self.connections) - (limit - 1)  # this one's request must fit
            if excess <= 0:
                return
            # those in their TLS goodbye first (answered: they serve nobody), then the
            # idle ones; the quiet longest first within each
            spare = [
                p
                for p in self.connections
                if p is not self
                and isinstance(p, DeskProtocol)
                and (p.transport.is_closing() or p._idle())
            ]
            spare.sort(key=lambda p: (not p.transport.is_closing(), p._quiet_since))
            for p in spare[:excess]:
                why = "was closing" if p.transport.is_closing() else "was idle longest"
                p._abort(f"{why}, to make room for a new one")

        def timeout_keep_alive_handler(self) -> None:
            if not self.transport.is_closing():
                self._abort(f"idled past the keep-alive timeout ({self.timeout_keep_alive} s)")

        def _check_later(self) -> None:
            self.loop.call_later(header_timeout, self._check)

        def _check(self) -> None:
            try:
                upgraded = self.transport.get_protocol() is not self
            except AttributeError:  # a TLS transport closed twice (see connection_made)
                upgraded = False
            if self._lost or upgraded:
                return  # gone, or upgraded to a websocket
            if self.transport.is_closing():
                if self._closing_seen:
                    self._abort("did not answer the TLS goodbye")
                    return
                self._closing_seen = True
            elif self.conn.their_state is h11.IDLE and self._heads == self._heads_at_check:
                self._abort(f"sent no request head in {header_timeout:g} s")
                return
            self._heads_at_check = self._heads
            self._check_later()

    return DeskProtocol


__all__ = ["desk_protocol"]
