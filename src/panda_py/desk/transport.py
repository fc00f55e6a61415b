"""The seam between the Desk client and the network.

A :class:`Transport` turns one request into one :class:`Response`. :class:`HTTPSTransport`
speaks HTTPS to a robot and pins its certificate; :class:`MockTransport` hands requests to
a function, so the client's logic is tested without sockets (as httpx's MockTransport).

Pinning: robots serve self-signed certificates, so there is no CA to verify against.
The SHA-256 fingerprint of the certificate seen on first use is stored; every later TLS
handshake must present the same certificate, checked *before* any byte of a request (and
so any credential) is sent.

Bounds: a request's timeout is one deadline for all of it (connecting, the TLS handshake,
sending, the whole answer), not a timeout per read (``deadline.py``); an answer larger
than :data:`MAX_ANSWER` is refused, not read into memory. Every failure is a
:class:`~panda_py.desk.errors.DeskError` naming the request and what came back.
"""

from __future__ import annotations

import hashlib
import http.client
import logging
import socket
import ssl
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

from panda_py.desk.deadline import DeadlineSocket, remaining
from panda_py.desk.errors import (
    CertificateChangedError,
    DeskAnswerError,
    DeskConnectionError,
    DeskError,
    DeskTimeoutError,
)
from panda_py.desk.excerpt import excerpt, one_line, redact, request_secrets
from panda_py.desk.store import TokenStore

log = logging.getLogger("panda_py.desk")

DEFAULT_TIMEOUT = 10.0  # [s] for every request unless the caller says otherwise
MAX_ANSWER = 8 * 2**20
"""The largest answer a Desk client reads [bytes]. It reads JSON status and configuration
documents and login tokens: the simulated Desk's largest, the legacy system status, is
891 bytes; a robot's carry more fields, but are documents of that kind. 8 MiB leaves
three or four orders of magnitude, and is still nothing to hold in memory. Larger answers (a
200 MB one was read whole) are refused unread, or once this much has come."""


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
    # the request this answers (set by the Desk client, for its errors; None from a transport)
    request: Request | None = field(default=None, repr=False, compare=False)

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
            raise DeskConnectionError("presented no certificate", host=self.hostname)
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
        return self._connect(time.monotonic() + timeout, timeout, "")

    def _connect(self, deadline: float, timeout: float, what: str) -> ssl.SSLSocket:
        """A TLS connection with the pinned certificate, made by ``deadline`` (for ``what``,
        a request, named in the errors)."""
        host = self.hostname
        try:
            raw = socket.create_connection((self.host, self.port), timeout=remaining(deadline))
        except TimeoutError as exc:
            raise DeskTimeoutError(timeout, host=host, what=what) from exc
        except OSError as exc:
            raise DeskConnectionError(
                f"cannot reach the Desk: {exc}", host=host, what=what
            ) from exc
        sock: ssl.SSLSocket | None = None
        try:
            raw.settimeout(remaining(deadline))  # (the handshake: one deadline for all of it)
            sock = self._context.wrap_socket(raw, server_hostname=self.host)
            self._check_pin(sock)
        except BaseException as exc:
            # once wrapped, the TLS socket holds the connection (raw is detached): closing
            # only raw left a refused Desk's connection open for as long as the error lived
            (raw if sock is None else sock).close()
            if isinstance(exc, DeskError):
                raise
            if isinstance(exc, TimeoutError):
                raise DeskTimeoutError(timeout, host=host, what=what) from exc
            if isinstance(exc, OSError):  # ssl.SSLError among them
                raise DeskConnectionError(
                    f"TLS with the Desk: {exc}", host=host, what=what
                ) from exc
            raise
        return sock

    def request(self, request: Request, *, timeout: float) -> Response:
        """Send ``request`` and read the answer, all of it within ``timeout`` [s]."""
        deadline = time.monotonic() + timeout
        what = f"{request.method} {request.path.split('?')[0]}"
        transport = self
        stream: DeadlineSocket | None = None

        class _Pinned(http.client.HTTPSConnection):
            def connect(self) -> None:
                nonlocal stream
                stream = DeadlineSocket(transport._connect(deadline, timeout, what), deadline)
                self.sock = stream

        conn = _Pinned(self.host, self.port, timeout=timeout)
        res: http.client.HTTPResponse | None = None
        try:
            headers = {"Connection": "close", **request.headers}
            conn.request(request.method, request.path, body=request.body, headers=headers)
            res = conn.getresponse()
            body = _read_body(res, request)
            return Response(res.status, {k.lower(): v for k, v in res.getheaders()}, body)
        except DeskError:
            raise
        except TimeoutError as exc:
            secrets = request_secrets(request.headers, request.body)
            came = (stream.received, excerpt(stream.start, secrets)) if stream else (0, "")
            raise DeskTimeoutError(
                timeout, host=self.hostname, what=what, received=came[0], start=came[1]
            ) from exc
        except (OSError, http.client.HTTPException, ValueError) as exc:
            # ValueError: http.client's answer to a malformed chunk size
            text = redact(
                f"{type(exc).__name__}: {exc}", request_secrets(request.headers, request.body)
            )
            raise DeskConnectionError(one_line(text), host=self.hostname, what=what) from exc
        finally:
            if res is not None:
                res.close()  # (the connection closed already, but for the answer's reader)
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


def _read_body(res: http.client.HTTPResponse, request: Request) -> bytes:
    """The body of ``res``, at most :data:`MAX_ANSWER` bytes (:class:`DeskAnswerError` for
    a larger one, refused unread where its length is declared)."""
    mib = f"{MAX_ANSWER / 2**20:g} MiB"
    declared = res.length  # None: chunked, or until the connection closes
    if declared is not None and declared > MAX_ANSWER:
        raise DeskAnswerError(
            request.method, request.path, res.status,
            f"a body of {declared} bytes (Content-Length), more than the {mib} a Desk client reads",
        )  # fmt: skip
    body = res.read(MAX_ANSWER + 1)
    if len(body) > MAX_ANSWER:
        raise DeskAnswerError(
            request.method, request.path, res.status,
            f"a body of more than the {mib} a Desk client reads",
            excerpt(body, request_secrets(request.headers, request.body)),
        )  # fmt: skip
    if res.length:  # (a read of a given size does not check the declared length)
        raise http.client.IncompleteRead(body, res.length)
    return body


def header_lookup(headers: Mapping[str, str], name: str) -> str | None:
    lname = name.lower()
    for key, value in headers.items():
        if key.lower() == lname:
            return value
    return None


__all__ = [
    "DEFAULT_TIMEOUT",
    "MAX_ANSWER",
    "HTTPSTransport",
    "MockTransport",
    "Request",
    "Response",
    "Transport",
    "fingerprint_of",
    "split_host",
]
