"""Serve a policy over openpi's websocket protocol, so that openpi's own client
(``openpi_client.websocket_client_policy.WebsocketClientPolicy``, the ``openpi-client``
package) and every robot script built on it can call it.

The protocol, as openpi's server speaks it (Physical-Intelligence/openpi,
``src/openpi/serving/websocket_policy_server.py`` and the client's
``packages/openpi-client/src/openpi_client/{websocket_client_policy,msgpack_numpy}.py``):

* on connecting, the client receives the server's metadata (a dict), one binary message;
* then each binary message it sends is an observation and gets one binary message back:
  the policy's output (a dict, e.g. ``{"actions": (10, 8) array}``) with
  ``"server_timing"`` added (``infer_ms``, and ``prev_total_ms``: the previous request's
  time from the server waiting for it to its response sent);
* messages are msgpack, numpy arrays and scalars in openpi's extension (a map with
  ``b"__ndarray__"``: ``b"data"`` the raw bytes, ``b"dtype"`` its ``dtype.str``,
  ``b"shape"``; ``b"__npgeneric__"``: ``b"data"``, ``b"dtype"``), never pickle;
* a failing request (the policy raised, the message did not decode) gets the traceback as
  a text message, then the connection closes with code 1011 (internal error); the client
  raises ``RuntimeError("Error in inference server: ...")``. The server serves on: other
  connections, and new ones;
* ``GET /healthz`` answers ``200 OK``.

Requests of several clients are served each on its own connection and thread; the policy
runs one request at a time (openpi's server calls it on its one event loop).
"""

from __future__ import annotations

import http
import logging
import threading
import time
import traceback
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from panda_py.learning.recording import INSTALL_HINT

__all__ = ["DEFAULT_PORT", "PolicyServer"]

DEFAULT_PORT = 8000  # openpi's (scripts/serve_policy.py; examples/droid/main.py's remote_port)
_CLOSE_REASON = "Internal server error. Traceback included in previous frame."  # openpi's

logger = logging.getLogger(__name__)


def _msgpack() -> Any:
    try:
        import msgpack
    except ImportError as exc:
        raise ImportError(f"the policy server needs msgpack: {INSTALL_HINT}") from exc
    return msgpack


def _pack_array(obj: Any) -> Any:
    """openpi's numpy extension (msgpack_numpy.pack_array)."""
    if isinstance(obj, (np.ndarray, np.generic)) and obj.dtype.kind in ("V", "O", "c"):
        raise ValueError(f"Unsupported dtype: {obj.dtype}")
    if isinstance(obj, np.ndarray):
        return {
            b"__ndarray__": True,
            b"data": obj.tobytes(),
            b"dtype": obj.dtype.str,
            b"shape": obj.shape,
        }
    if isinstance(obj, np.generic):
        return {b"__npgeneric__": True, b"data": obj.item(), b"dtype": obj.dtype.str}
    return obj


def _unpack_array(obj: dict[Any, Any]) -> Any:
    """openpi's numpy extension, decoded (msgpack_numpy.unpack_array)."""
    if b"__ndarray__" in obj:
        return np.ndarray(buffer=obj[b"data"], dtype=np.dtype(obj[b"dtype"]), shape=obj[b"shape"])
    if b"__npgeneric__" in obj:
        return np.dtype(obj[b"dtype"]).type(obj[b"data"])
    return obj


def pack(obj: Any) -> bytes:
    """``obj`` as openpi's msgpack bytes (numpy arrays and scalars in its extension)."""
    return bytes(_msgpack().packb(obj, default=_pack_array))


def unpack(data: bytes) -> Any:
    """openpi's msgpack bytes decoded (arrays are read-only views of ``data``)."""
    return _msgpack().unpackb(data, object_hook=_unpack_array)


def _health_check(connection: Any, request: Any) -> Any:
    if request.path == "/healthz":  # openpi's
        return connection.protocol.reject(http.HTTPStatus.OK, "OK\n")
    return None


class PolicyServer:
    """Serves ``policy(observation: dict) -> dict | array`` over openpi's websocket
    protocol on ``host``:``port`` (0: a free port; :attr:`port` is the one bound). An
    array (e.g. an (H, 8) chunk) is sent as ``{"actions": array}``. ``metadata`` (a
    msgpack-able dict) goes to each client as it connects (openpi's policies send their
    config's, e.g. the action horizon). The default host serves this machine only; a
    robot's laptop calling a GPU server needs ``host="0.0.0.0"``.

    :meth:`start` serves from a background thread (or ``with PolicyServer(...) as
    server:``); :meth:`serve_forever` serves from the calling thread until :meth:`close`
    (from another thread) or Ctrl+C. An openpi policy object passes its ``infer``."""

    def __init__(
        self,
        policy: Callable[[dict[str, Any]], Any],
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        *,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        if not callable(policy):
            raise ValueError(
                f"policy: expected a callable observation -> dict or array (an openpi "
                f"policy's .infer), got {policy!r}"
            )
        if not (isinstance(host, str) and host):
            raise ValueError(f"host: expected an address or name to listen on, got {host!r}")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ValueError(f"port: expected a TCP port in 0..65535 (0: a free one), got {port!r}")
        if metadata is not None and not isinstance(metadata, Mapping):
            raise ValueError(f"metadata: expected a dict, got {metadata!r}")
        meta = dict(metadata or {})
        try:
            self._metadata = pack(meta)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"metadata: expected msgpack-able values, got {meta!r}") from exc
        self.policy, self.host, self.port = policy, host, port
        self._server: Any = None  # websockets.sync.server's, once bound
        self._thread: threading.Thread | None = None
        self._closed = False
        self._infer_lock = threading.Lock()  # one request at a time through the policy
        self._lock = threading.Lock()  # the connections and handler threads below
        self._connections: set[Any] = set()
        self._handlers: set[threading.Thread] = set()

    @property
    def url(self) -> str:
        """The address to give openpi's client, ``ws://host:port``."""
        host = f"[{self.host}]" if ":" in self.host else self.host  # IPv6
        return f"ws://{host}:{self.port}"

    def _bind(self) -> Any:
        if self._closed or self._server is not None:
            raise RuntimeError("PolicyServer: already serving or closed (one start per server)")
        _msgpack()  # a missing msgpack says so now, not on the first request
        from websockets.sync.server import serve

        self._server = serve(
            self._handle,
            self.host,
            self.port,
            compression=None,  # openpi's (its client asks for none either)
            max_size=None,  # images: no message size limit, as openpi
            process_request=_health_check,
        )
        self.port = int(self._server.socket.getsockname()[1])
        logger.info("serving a policy on %s", self.url)
        return self._server

    def start(self) -> PolicyServer:
        """Bind and serve from a background thread; returns once clients can connect."""
        server = self._bind()
        self._thread = threading.Thread(
            target=server.serve_forever, name=f"PolicyServer:{self.port}", daemon=True
        )
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        """Bind and serve from this thread until :meth:`close` or Ctrl+C."""
        server = self._bind()
        try:
            server.serve_forever()
        finally:
            self.close()

    def close(self) -> None:
        """Stop listening, close the open connections (code 1001, going away) and wait
        for their requests to finish. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        if self._server is None:
            return
        self._server.shutdown()
        with self._lock:
            connections, handlers = list(self._connections), list(self._handlers)
        from websockets.frames import CloseCode

        for connection in connections:  # websockets < 17 leaves them open
            connection.close(CloseCode.GOING_AWAY)
        for handler in handlers:
            if handler is not threading.current_thread():
                handler.join(timeout=10.0)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=10.0)

    def __enter__(self) -> PolicyServer:
        return self if self._server is not None else self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _infer(self, observation: Any) -> dict[str, Any]:
        with self._infer_lock:
            result = self.policy(observation)
        if isinstance(result, Mapping):
            return dict(result)
        actions = np.asarray(result)
        if actions.dtype.kind not in "biuf":
            raise TypeError(
                f"policy: expected a dict or an array of numbers, returned {result!r:.200}"
            )
        return {"actions": actions}

    def _handle(self, connection: Any) -> None:
        """One client: the metadata, then a response to each request."""
        from websockets.exceptions import ConnectionClosed
        from websockets.frames import CloseCode

        with self._lock:
            if self._closed:
                connection.close()
                return
            self._connections.add(connection)
            self._handlers.add(threading.current_thread())
        peer = connection.remote_address
        logger.info("connection from %s opened", peer)
        try:
            connection.send(self._metadata)
            prev_total = None
            while True:
                start = time.monotonic()  # openpi's: from waiting for the request
                message = connection.recv()
                try:
                    observation = unpack(message)
                    infer = time.monotonic()
                    response = self._infer(observation)
                    infer = time.monotonic() - infer
                    response["server_timing"] = {"infer_ms": infer * 1000}
                    if prev_total is not None:  # (this one's ends with its send)
                        response["server_timing"]["prev_total_ms"] = prev_total * 1000
                    data = pack(response)
                except Exception:
                    logger.exception("request from %s failed", peer)
                    connection.send(traceback.format_exc())
                    connection.close(CloseCode.INTERNAL_ERROR, _CLOSE_REASON)
                    return
                connection.send(data)
                prev_total = time.monotonic() - start
        except ConnectionClosed:
            logger.info("connection from %s closed", peer)
        finally:
            with self._lock:
                self._connections.discard(connection)
                self._handlers.discard(threading.current_thread())
