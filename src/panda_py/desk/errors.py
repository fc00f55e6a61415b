"""The Desk client's exceptions: one root, structured fields, no message matching.

``DeskError`` derives from ``ConnectionError`` because panda-py's ``Desk`` raised
``ConnectionError`` for every failure; scripts that catch it keep working.
"""

from __future__ import annotations

import json


class DeskError(ConnectionError):
    """Anything that went wrong talking to a robot's Desk."""


class DeskHTTPError(DeskError):
    """The robot answered a request with an error status.

    ``method`` and ``path`` name the request, ``status`` is the HTTP status, ``message``
    the robot's answer (text), ``code`` the ``code`` field of a JSON answer if any
    (e.g. ``"Timeout"``, ``"BrakesClosed"``).
    """

    def __init__(self, method: str, path: str, status: int, message: str) -> None:
        self.method = method
        self.path = path
        self.status = status
        self.message = message
        self.code: str | None = None
        try:
            body = json.loads(message)
        except ValueError:
            body = None
        if isinstance(body, dict) and isinstance(body.get("code"), str):
            self.code = body["code"]
        super().__init__(f"{method} {path} answered {status}: {message.strip()[:500]}")


class DeskConnectionError(DeskError):
    """The robot could not be reached, or it did not answer within the timeout."""


class CertificateChangedError(DeskError):
    """The robot presented another TLS certificate than the one pinned on first use."""

    def __init__(self, host: str, pinned: str, presented: str) -> None:
        self.host = host
        self.pinned = pinned
        self.presented = presented
        super().__init__(
            f"the Desk at {host} presented a certificate with SHA-256 fingerprint {presented}, "
            f"but {pinned} was pinned on first use; refusing to send credentials. If the "
            "robot's certificate was replaced on purpose, re-pin it (Desk(..., repin=True) "
            "or --repin)."
        )


class TakeControlTimeoutError(DeskError, TimeoutError):
    """Control was not granted within the time allowed (no Pilot button press, or the
    holder did not release)."""


class NotInControlError(DeskError):
    """A control operation was asked for without holding the control token."""


__all__ = [
    "CertificateChangedError",
    "DeskConnectionError",
    "DeskError",
    "DeskHTTPError",
    "NotInControlError",
    "TakeControlTimeoutError",
]
