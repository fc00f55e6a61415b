"""libfranka's exception tree, under one base (:class:`FrankaException`).

The names and the meaning of each class mirror libfranka's ``franka/exception.h`` (and
pylibfranka, whose exceptions are ``RuntimeError`` subclasses); structured fields
(``status``, ``command``, ``log``, versions) are added for programmatic handling, so
callers never need to match on message text.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from panda_py.libfranka.state import RobotState

__all__ = [
    "CommandException",
    "ControlException",
    "FrankaException",
    "IncompatibleVersionException",
    "InvalidOperationException",
    "ModelException",
    "NetworkException",
    "ProtocolException",
    "RealtimeException",
]


class FrankaException(RuntimeError):
    """Base of every error raised by :mod:`panda_py.libfranka` (libfranka's ``Exception``).

    Every subclass pickles with its structured fields (errors cross from the control
    process to the user's process)."""

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (type(self), self.args, self.__dict__))


def _rebuild(
    cls: type[FrankaException], args: tuple[Any, ...], fields: dict[str, Any]
) -> FrankaException:
    exc = cls.__new__(cls)
    exc.args = args
    exc.__dict__.update(fields)
    return exc


class CommandException(FrankaException):
    """The robot rejected or aborted a command (a non-success status in a TCP response).

    ``command`` is the command's display name (e.g. ``"Set Joint Impedance"``), ``status``
    the decoded status enum member (or None for client-side failures).
    """

    def __init__(self, message: str, *, command: str | None = None, status: Any = None) -> None:
        super().__init__(message)
        self.command = command
        self.status = status


class ControlException(FrankaException):
    """A motion or control loop was aborted by the robot (reflex, user stop, bad input).

    ``log`` holds the last robot states received before the error (oldest first, at most
    the Robot's ``log_size``); ``reflex_reason`` the names of the error flags that caused
    a reflex (empty for other aborts); ``status`` the Move status; ``success_rate`` the
    robot's last ``control_command_success_rate``.
    """

    def __init__(
        self,
        message: str,
        *,
        log: Sequence[RobotState] = (),
        reflex_reason: Sequence[str] = (),
        status: Any = None,
        success_rate: float | None = None,
    ) -> None:
        super().__init__(message)
        self.log: list[RobotState] = list(log)
        self.reflex_reason: tuple[str, ...] = tuple(reflex_reason)
        self.status = status
        self.success_rate = success_rate


class NetworkException(FrankaException):
    """A socket failed: connection refused, timeout, or the robot closed the connection."""


class ProtocolException(FrankaException):
    """The robot sent bytes this client cannot make sense of (size, status, version)."""


class IncompatibleVersionException(FrankaException):
    """The robot speaks a protocol version this library cannot (``server_version``), or
    refused the one this client offered (``library_version``)."""

    def __init__(self, message: str, *, server_version: int, library_version: int) -> None:
        super().__init__(message)
        self.server_version = server_version
        self.library_version = library_version

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        # keyword-only fields: rebuilt through a partial so the exception pickles (it
        # crosses the control process's boundary)
        rebuild = functools.partial(
            type(self), server_version=self.server_version, library_version=self.library_version
        )
        return rebuild, (str(self),)


#: panda-py's name (``panda_py.IncompatibleVersionError``) for the same error
IncompatibleVersionError = IncompatibleVersionException


class RealtimeException(FrankaException):
    """Realtime scheduling was required (``RealtimeConfig.kEnforce``) but is not available."""


class ModelException(FrankaException):
    """The robot model could not be built or evaluated."""


class InvalidOperationException(FrankaException):
    """The call is not allowed now, e.g. a second motion while one is running."""
