"""The Desk client's exceptions: one root, structured fields, no message matching.

``DeskError`` derives from ``ConnectionError`` because panda-py's ``Desk`` raised
``ConnectionError`` for every failure; scripts that catch it keep working.

Every exception here pickles with its fields (an error raised in a worker process
reaches its parent whole): ``BaseException`` pickles ``args``, the formatted message,
which the structured constructors do not take, so each says how to rebuild itself.
"""

from __future__ import annotations

import enum
import json
from typing import Any


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
        self.message = message
        self.code: str | None = None
        self.reason: str | None = None
        try:
            body = json.loads(message)
        except ValueError:
            body = None
        if isinstance(body, dict):
            if isinstance(body.get("code"), str):
                self.code = body["code"]
            if isinstance(body.get("reason"), str):
                self.reason = body["reason"]
        super().__init__(f"{method} {path} answered {status}: {message.strip()[:500]}")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.method, self.path, self.status, self.message))


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


def _rebuild(cls: type[BringUpError], args: tuple[Any, ...], fields: dict[str, Any]) -> Any:
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
    "DeskConnectionError",
    "DeskError",
    "DeskHTTPError",
    "DeskUnsupportedError",
    "FCIRefusedError",
    "NotInControlError",
    "OperatingModeError",
    "RecoveryRefusedError",
    "SelfTestFailedError",
    "TakeControlTimeoutError",
]
