"""The Pilot's buttons as events: :meth:`PilotEvents.listen` reads the Desk's
``navigation/events`` websocket (WSS over the pinned TLS connection) in a thread of its
own and hands each event to a callback, until :meth:`PilotEvents.stop_listen`.

Both are bounded by the Desk's timeout: opening (connection, TLS, upgrade) is one
deadline, and the closing handshake is cut off when a Desk does not answer it within the
timeout (websockets' default waited 10 s whatever the Desk's timeout).

A mixin of :class:`~panda_py.desk.client.Desk` (it uses the session's login, transport
and timeout).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from panda_py.desk.api import PILOT_EVENTS_PATH, DeskAPI
from panda_py.desk.deadline import remaining
from panda_py.desk.errors import DeskConnectionError, DeskError, DeskTimeoutError
from panda_py.desk.excerpt import redact, request_secrets
from panda_py.desk.tls_stream import shared_tls

if TYPE_CHECKING:
    from panda_py.desk.api import V1API, LegacyAPI
    from panda_py.desk.transport import Transport

log = logging.getLogger("panda_py.desk")

RECV_POLL = 0.2  # [s] the listener looks whether it is to stop this often
JOIN_GRACE = 0.5  # [s] beyond the closing handshake, for the listener to see it


class PilotEvents:
    """Pilot button events of a :class:`~panda_py.desk.client.Desk`."""

    _listening = False
    _listen_thread: threading.Thread | None = None
    _listen_ws: Any = None  # the Pilot event stream the listener reads

    if TYPE_CHECKING:
        _hostname: str
        _api: DeskAPI | None
        _v1: V1API
        _legacy: LegacyAPI
        _transport: Transport
        timeout: float

        def _need_login(self) -> DeskAPI: ...

    def listen(self, cb: Callable[[dict[str, bool]], None]) -> None:
        """Call ``cb`` with each Pilot button event (``{"circle": True}`` on press,
        False on release; the first event is the full key map) from a thread, until
        :meth:`stop_listen`. Returns once the stream is open, within the Desk's timeout
        (:class:`~panda_py.desk.errors.DeskConnectionError` if it cannot be opened)."""
        if self._listen_thread is not None:
            raise DeskError("already listening: call stop_listen() first")
        self._need_login()
        ws = self._open_events()
        self._listening = True
        self._listen_ws = ws
        self._listen_thread = threading.Thread(
            target=self._listen, args=(ws, cb), name="panda-py-desk-listen", daemon=True
        )
        self._listen_thread.start()

    def _open_events(self) -> Any:
        from websockets.exceptions import WebSocketException
        from websockets.sync.client import connect

        what = "Pilot events"
        deadline = time.monotonic() + self.timeout
        sock = self._transport.secure_socket(timeout=self.timeout)  # (a DeskError if not)
        headers = self._v1.ws_headers() if self._api == DeskAPI.V1 else self._legacy.ws_headers()
        try:
            # ws:// over a socket that is already TLS, its certificate checked against the pin.
            return connect(
                f"ws://{self._hostname}{PILOT_EVENTS_PATH}",
                sock=shared_tls(sock),  # websockets reads and writes from two threads
                additional_headers=headers,
                open_timeout=remaining(deadline),
                close_timeout=self.timeout,
                proxy=None,
            )
        except TimeoutError as exc:
            sock.close()
            raise DeskTimeoutError(self.timeout, host=self._hostname, what=what) from exc
        except (WebSocketException, OSError, ValueError) as exc:
            sock.close()
            detail = redact(f"{exc}", request_secrets(headers))
            raise DeskConnectionError(detail, host=self._hostname, what=what) from exc

    def _listen(self, ws: Any, cb: Callable[[dict[str, bool]], None]) -> None:
        from websockets.exceptions import ConnectionClosed

        with ws:
            while self._listening:
                try:
                    message = ws.recv(timeout=RECV_POLL)
                except TimeoutError:
                    continue
                except ConnectionClosed:
                    if self._listening:  # (stop_listen closes it too)
                        log.warning("the Desk at %s closed the Pilot event stream", self._hostname)
                    return
                try:
                    event = json.loads(message)
                except (ValueError, RecursionError):
                    continue  # not an event
                if isinstance(event, dict):
                    cb(event)

    def stop_listen(self) -> None:
        """Stop the listener thread started by :meth:`listen`, within the Desk's timeout
        (a Desk that does not answer the closing handshake is cut off then). Called from
        the callback, it stops the listener once the callback returns."""
        deadline = time.monotonic() + self.timeout
        self._listening = False
        thread, self._listen_thread = self._listen_thread, None
        ws, self._listen_ws = self._listen_ws, None
        if ws is not None:
            # the closing handshake ends the listener's receive at once (it would see the
            # flag only at its next 0.2 s timeout)
            try:
                ws.close()  # (waits for the Desk's answer up to the timeout: close_timeout)
            except OSError:
                pass  # the connection is gone: the listener's receive ends all the same
        if thread is not None and thread is not threading.current_thread():
            thread.join(max(0.0, deadline - time.monotonic()) + JOIN_GRACE)
            if thread.is_alive():
                log.warning(
                    "the Pilot event listener of %s is still in its callback; it stops "
                    "when that returns",
                    self._hostname,
                )


__all__ = ["PilotEvents"]
