"""The Desk client's exceptions: one root, structured fields, no message matching.

``DeskError`` derives from ``ConnectionError`` because panda-py's ``Desk`` raised
``ConnectionError`` for every failure; scripts that catch it keep working. Every failure
talking to a Desk is one: what the robot answered, that it answered too late or too
much or in a shape the client cannot read, or that it could not be reached.

Every exception here pickles with its fields (an error raised in a worker process
reaches its parent whole): ``BaseException`` pickles ``args``, the formatted message,
which the structured constructors do not take, so each says how to rebuild itself.
Text taken from an answer goes in as one line with credentials hidden
(:mod:`panda_py.desk.excerpt`).
"""

from __future__ import annotations

import enum
import json
from typing import Any

from panda_py.desk.excerpt import excerpt, redact


class DeskError(ConnectionError):
    """Anything that went wrong talking to a robot's Desk."""


class DeskHTTPError(DeskError):
    """The robot answered a request with an error status.

    ``method`` and ``path`` name the request, ``status`` is the HTTP status, ``message``
    the robot's answer (text), ``code`` the ``code`` field of a JSON answer if any
    (e.g. ``"Timeout"``, ``"ActionUnavailable"``), ``reason`` its ``reason`` field if any
    (e.g. ``"BrakesClosed"``).
    """

    def __init__(self, method: str, path: str, status: int, message: str) -> None:
        self.method = method
        self.path = path
        self.status = status
        self.message = message = redact(message)
        self.code: str | None = None
        self.reason: str | None = None
        try:
            body = json.loads(message)
        except (ValueError, RecursionError):  # (not JSON, or nested past the stack)
            body = None
        if isinstance(body, dict):
            if isinstance(body.get("code"), str):
                self.code = body["code"]
            if isinstance(body.get("reason"), str):
                self.reason = body["reason"]
        super().__init__(f"{method} {path} answered {status}: {excerpt(message, limit=500)}")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.method, self.path, self.status, self.message))


class DeskAnswerError(DeskError):
    """The robot answered something the client cannot use: more than it reads at most,
    no JSON where JSON was due, JSON of another shape, a session or token that cannot
    be sent back in a header.

    ``method`` and ``path`` name the request, ``status`` is the answer's HTTP status,
    ``problem`` says what is wrong with it, ``excerpt`` shows its beginning (one line,
    credentials hidden; empty if nothing of it is worth showing).
    """

    def __init__(
        self, method: str, path: str, status: int, problem: str, excerpt: str = ""
    ) -> None:
        self.method = method
        self.path = path
        self.status = status
        self.problem = problem = redact(problem)
        self.excerpt = excerpt = redact(excerpt)
        super().__init__(
            f"{method} {path} answered {status} with {problem}"
            + (f": {excerpt}" if excerpt else "")
        )

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.method, self.path, self.status, self.problem, self.excerpt))


class DeskConnectionError(DeskError):
    """The robot could not be reached, the connection failed, or the answer was not
    HTTP: ``detail`` says what happened; ``host`` names the robot and ``what`` the
    request or stream (``"GET /api/system"``, ``"Pilot events"``) where known."""

    def __init__(self, detail: str, *, host: str = "", what: str = "") -> None:
        self.detail = detail = redact(detail)
        self.host = host
        self.what = what
        where = " on ".join(part for part in (what, host) if part)
        super().__init__(f"{where}: {detail}" if where else detail)

    def _fields(self) -> dict[str, Any]:
        return {"host": self.host, "what": self.what}

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (type(self), (self.detail,), self._fields()))


class DeskTimeoutError(DeskConnectionError, TimeoutError):
    """The robot did not answer ``what`` in full within ``timeout`` [s] (a deadline for
    the whole request: connecting, the TLS handshake, sending, the whole answer).
    ``received`` is how many bytes of the answer came by then, ``start`` their
    beginning (one line, credentials hidden)."""

    def __init__(
        self, timeout: float, *, host: str = "", what: str = "", received: int = 0, start: str = ""
    ) -> None:
        self.timeout = timeout
        self.received = received
        self.start = start = redact(start)
        came = f"{received} bytes came by then: {start}" if received else "nothing came"
        super().__init__(f"no complete answer within {timeout:g} s ({came})", host=host, what=what)

    def __reduce__(self) -> tuple[Any, ...]:
        fields = {**self._fields(), "received": self.received, "start": self.start}
        return (_rebuild, (type(self), (self.timeout,), fields))


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

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.host, self.pinned, self.presented))


class TakeControlTimeoutError(DeskError, TimeoutError):
    """Control was not granted within the time allowed (no Pilot button press, or the
    holder did not release)."""


class NotInControlError(DeskError):
    """A control operation was asked for without holding the control token."""


class DeskUnsupportedError(DeskError):
    """The robot's Desk has no such duty: ``feature`` (e.g. ``"self_test"``) is not served
    by the ``api`` it speaks (``"legacy"`` or ``"v1"``) on this robot."""

    def __init__(self, feature: str, api: str, hint: str = "") -> None:
        self.feature = feature
        self.api = api
        self.hint = hint
        super().__init__(
            f"{feature}: the robot's Desk ({api} API) has no such function"
            + (f"; {hint}" if hint else "")
        )

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.feature, self.api, self.hint))


class BringUpStep(enum.Enum):
    """The steps of :meth:`~panda_py.desk.Desk.bring_up`, in their order."""

    CONTROL = "control"
    RECOVERY = "recovery"
    SELF_TEST = "self_test"
    OPERATING_MODE = "operating_mode"
    BRAKES = "brakes"
    FCI = "fci"


class BringUpError(DeskError):
    """A robot could not be made ready for control: what blocked it and where.

    ``host`` names the robot, ``step`` the :class:`BringUpStep` that failed, ``detail``
    says what happened in words; ``status``, ``code`` and ``reason`` are the robot's HTTP
    status and the ``code``/``reason`` fields of its answer, where it answered one
    (None otherwise).
    """

    step = BringUpStep.CONTROL

    def __init__(
        self,
        host: str,
        detail: str,
        *,
        status: int | None = None,
        code: str | None = None,
        reason: str | None = None,
    ) -> None:
        self.host = host
        self.detail = detail
        self.status = status
        self.code = code
        self.reason = reason
        answer = ", ".join(
            f"{k} {v}" for k, v in (("status", status), ("code", code), ("reason", reason)) if v
        )
        super().__init__(
            f"bring-up of {host} stopped at {self.step.value}: {detail}"
            + (f" ({answer})" if answer else "")
        )

    @classmethod
    def from_http(cls, host: str, detail: str, exc: DeskHTTPError, **fields: Any) -> Any:
        """This error for a refusal ``exc`` of the robot."""
        return cls(host, detail, status=exc.status, code=exc.code, reason=exc.reason, **fields)

    def _fields(self) -> dict[str, Any]:
        return {"status": self.status, "code": self.code, "reason": self.reason}

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (type(self), (self.host, self.detail), self._fields()))


def _rebuild(cls: type[DeskError], args: tuple[Any, ...], fields: dict[str, Any]) -> Any:
    return cls(*args, **fields)


class ControlNotGrantedError(BringUpError, NotInControlError):
    """Control of the robot was not granted: ``holder`` is in control (``""`` if
    unknown), and nobody confirmed a forced take on the Pilot in time."""

    step = BringUpStep.CONTROL

    def __init__(self, host: str, detail: str, *, holder: str = "", **answer: Any) -> None:
        self.holder = holder
        super().__init__(host, detail, **answer)

    def _fields(self) -> dict[str, Any]:
        return {**super()._fields(), "holder": self.holder}


class RecoveryRefusedError(BringUpError):
    """The robot refused to confirm a pending recoverable safety error (of ``kind``,
    e.g. ``"SafetyError"``), or it is still pending after the confirmation."""

    step = BringUpStep.RECOVERY

    def __init__(self, host: str, detail: str, *, kind: str = "", **answer: Any) -> None:
        self.kind = kind
        super().__init__(host, detail, **answer)

    def _fields(self) -> dict[str, Any]:
        return {**super()._fields(), "kind": self.kind}


class SelfTestFailedError(BringUpError):
    """The safety self-test did not pass: it was refused, it did not end within the wait,
    or the robot still demands it afterwards. ``due_in`` [s] is how long until it is due
    as the robot reported it last (0: due now; None: not known)."""

    step = BringUpStep.SELF_TEST

    def __init__(
        self, host: str, detail: str, *, due_in: float | None = None, **answer: Any
    ) -> None:
        self.due_in = due_in
        super().__init__(host, detail, **answer)

    def _fields(self) -> dict[str, Any]:
        return {**super()._fields(), "due_in": self.due_in}


class OperatingModeError(BringUpError):
    """The robot would not switch to the Execution mode the FCI needs."""

    step = BringUpStep.OPERATING_MODE


class BrakesError(BringUpError):
    """The brakes would not open: the robot refused, or some are still ``"Locked"``
    afterwards (``brakes``: each joint's state as the robot reports it, if it does)."""

    step = BringUpStep.BRAKES

    def __init__(
        self, host: str, detail: str, *, brakes: tuple[str, ...] = (), **answer: Any
    ) -> None:
        self.brakes = tuple(brakes)
        super().__init__(host, detail, **answer)

    def _fields(self) -> dict[str, Any]:
        return {**super()._fields(), "brakes": self.brakes}


class FCIRefusedError(BringUpError):
    """The robot refused to activate the FCI, or it is still inactive afterwards."""

    step = BringUpStep.FCI


__all__ = [
    "BrakesError",
    "BringUpError",
    "BringUpStep",
    "CertificateChangedError",
    "ControlNotGrantedError",
    "DeskAnswerError",
    "DeskConnectionError",
    "DeskError",
    "DeskHTTPError",
    "DeskTimeoutError",
    "DeskUnsupportedError",
    "FCIRefusedError",
    "NotInControlError",
    "OperatingModeError",
    "RecoveryRefusedError",
    "SelfTestFailedError",
    "TakeControlTimeoutError",
]
