"""The seam between the Desk client and the network.

A :class:`Transport` turns one request into one :class:`Response`. :class:`HTTPSTransport`
speaks HTTPS to a robot and pins its certificate; :class:`MockTransport` hands requests to
a function, so the client's logic is tested without sockets (as httpx's MockTransport).

Pinning: robots serve self-signed certificates, so there is no CA to verify against.
The SHA-256 fingerprint of the certificate seen on first use is stored; every later TLS
handshake must present the same certificate, checked *before* any byte of a request (and
so any credential) is sent.
"""

from __future__ import annotations

import hashlib
import http.client
import logging
import socket
import ssl
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

from panda_py.desk.errors import CertificateChangedError, DeskConnectionError
from panda_py.desk.store import TokenStore

log = logging.getLogger("panda_py.desk")

DEFAULT_TIMEOUT = 10.0  # [s] for every request unless the caller says otherwise


@dataclass
class Request:
    """One HTTP request to the Desk: ``method``, ``path`` (with the query), ``headers`` and
    ``body`` (bytes, or None for none)."""

    method: str
    path: str
    headers: dict[str, str] = field(default_factory=dict)
    body: bytes | None = None


@dataclass
class Response:
    """One HTTP response from the Desk: ``status``, ``headers`` (lower-case names) and ``body``
    (bytes)."""

    status: int
    headers: dict[str, str] = field(default_factory=dict)  # lower-case names
    body: bytes = b""

    @property
    def text(self) -> str:
        """The body decoded as UTF-8 (undecodable bytes replaced)."""
        return self.body.decode("utf-8", "replace")


class Transport(Protocol):
    def request(self, request: Request, *, timeout: float) -> Response: ...

    def secure_socket(self, *, timeout: float) -> socket.socket:
        """A connected TLS socket to the robot whose certificate has been checked (for
        the websocket)."""
        ...

    def close(self) -> None: ...


def split_host(hostname: str, default_port: int = 443) -> tuple[str, int]:
    """``host``, ``host:port``, ``[v6]`` or ``[v6]:port`` -> (host, port)."""
    text = hostname.strip()
    if text.startswith("["):
        host, _, rest = text[1:].partition("]")
        port = rest[1:] if rest.startswith(":") else ""
    elif text.count(":") == 1:
        host, _, port = text.partition(":")
    else:
        host, port = text, ""
    if not host:
        raise ValueError(f"hostname: expected 'host' or 'host:port', got {hostname!r}")
    if port:
        if not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"hostname: expected a port 1..65535 after ':', got {hostname!r}")
        return host, int(port)
    return host, default_port


def fingerprint_of(der: bytes) -> str:
    """SHA-256 of a DER certificate as colon-separated upper-case hex (as browsers show)."""
    digest = hashlib.sha256(der).hexdigest().upper()
    return ":".join(digest[i : i + 2] for i in range(0, len(digest), 2))


class HTTPSTransport:
    """HTTPS to one robot, one TLS connection per request, the certificate pinned in
    ``store`` under ``hostname`` (``repin``: replace a stored pin with what the robot
    presents now)."""

    def __init__(self, hostname: str, store: TokenStore, *, repin: bool = False) -> None:
        self.hostname = hostname
        self.host, self.port = split_host(hostname)
        self.store = store
        self._repin = repin
        # No CA can vouch for a robot's self-signed certificate; the pin below does.
        self._context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
        self._context.check_hostname = False
        self._context.verify_mode = ssl.CERT_NONE
        self._context.minimum_version = ssl.TLSVersion.TLSv1_2

    def _check_pin(self, sock: ssl.SSLSocket) -> None:
        der = sock.getpeercert(binary_form=True)
        if der is None:
            raise DeskConnectionError(f"the Desk at {self.hostname} presented no certificate")
        presented = fingerprint_of(der)
        pinned = self.store.fingerprint(self.hostname)
        if pinned == presented:
            return
        if pinned is None or self._repin:
            self.store.pin(self.hostname, presented)
            log.info("pinned the Desk certificate of %s: SHA-256 %s", self.hostname, presented)
            self._repin = False
            return
        raise CertificateChangedError(self.hostname, pinned, presented)

    def secure_socket(self, *, timeout: float) -> socket.socket:
        try:
            raw = socket.create_connection((self.host, self.port), timeout=timeout)
        except OSError as exc:
            raise DeskConnectionError(f"cannot reach the Desk at {self.hostname}: {exc}") from exc
        sock: ssl.SSLSocket | None = None
        try:
            sock = self._context.wrap_socket(raw, server_hostname=self.host)
            self._check_pin(sock)
        except BaseException as exc:
            # once wrapped, the TLS socket holds the connection (raw is detached): closing
            # only raw left a refused Desk's connection open for as long as the error lived
            (raw if sock is None else sock).close()
            if isinstance(exc, ssl.SSLError):
                raise DeskConnectionError(f"TLS with the Desk at {self.hostname}: {exc}") from exc
            raise
        return sock

    def request(self, request: Request, *, timeout: float) -> Response:
        transport = self

        class _Pinned(http.client.HTTPSConnection):
            def connect(self) -> None:
                self.sock = transport.secure_socket(timeout=timeout)

        conn = _Pinned(self.host, self.port, timeout=timeout)
        try:
            headers = {"Connection": "close", **request.headers}
            conn.request(request.method, request.path, body=request.body, headers=headers)
            res = conn.getresponse()
            body = res.read()
            return Response(res.status, {k.lower(): v for k, v in res.getheaders()}, body)
        except (OSError, http.client.HTTPException) as exc:
            if isinstance(exc, CertificateChangedError | DeskConnectionError):
                raise
            raise DeskConnectionError(
                f"{request.method} {request.path.split('?')[0]} on {self.hostname}: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        finally:
            conn.close()

    def close(self) -> None:
        pass


class MockTransport:
    """Hands each request to ``handler`` (tests): no sockets, no TLS."""

    def __init__(self, handler: Callable[[Request], Response]) -> None:
        self.handler = handler
        self.requests: list[Request] = []

    def request(self, request: Request, *, timeout: float) -> Response:
        """Record ``request`` (in ``requests``) and return what ``handler`` answers; ``timeout``
        [s] is ignored."""
        self.requests.append(request)
        return self.handler(request)

    def secure_socket(self, *, timeout: float) -> socket.socket:
        """Raise :class:`~panda_py.desk.DeskConnectionError`: a mock has no websocket."""
        raise DeskConnectionError("the mock transport has no websocket")

    def close(self) -> None:
        """Nothing to close."""
        pass


def header_lookup(headers: Mapping[str, str], name: str) -> str | None:
    lname = name.lower()
    for key, value in headers.items():
        if key.lower() == lname:
            return value
    return None


__all__ = [
    "DEFAULT_TIMEOUT",
    "HTTPSTransport",
    "MockTransport",
    "Request",
    "Response",
    "Transport",
    "fingerprint_of",
    "split_host",
]
