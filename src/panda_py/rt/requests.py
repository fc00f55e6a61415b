"""What the user's process and the control process say to each other: one typed seam.

Every request is a frozen dataclass with its :class:`Kind`, defined here once and used on
both sides: the user's process builds it (:meth:`ControlProcess.call`), the channel pickles
it, the control process dispatches on its kind. A field renamed on one side is a field
renamed on the other; an unknown kind is refused by name. Replies and events travel in
the same way (:class:`Reply`, :class:`LoopError`, :class:`LogLine`).

Requests are handled between ticks; what changes every tick (the state, a controller's
inputs and outputs) never travels here but through shared memory (:mod:`.shm`).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, ClassVar

from panda_py.controllers.plans import JointPlan, PosePlan

__all__ = [
    "Call",
    "Cancel",
    "Close",
    "Connect",
    "Connected",
    "DisableLog",
    "EnableLog",
    "Kind",
    "LogLine",
    "LoopError",
    "Move",
    "Recover",
    "Reply",
    "Request",
    "RobotCall",
    "StartController",
    "Stop",
]


class Kind(enum.Enum):
    """The kinds of request the control process serves."""

    CONNECT = "connect"
    START = "start_controller"
    MOVE = "move"
    CANCEL = "cancel"
    STOP = "stop"
    ROBOT = "robot"
    RECOVER = "recover"
    ENABLE_LOG = "enable_logging"
    DISABLE_LOG = "disable_logging"
    CLOSE = "close"


@dataclass(frozen=True)
class Connect:
    """Connect to the robot at ``hostname``, warm up, answer :class:`Connected`."""

    kind: ClassVar[Kind] = Kind.CONNECT
    hostname: str
    realtime_config: int  # libfranka's RealtimeConfig value
    timeout: float  # [s] for the robot to answer
    cpus: tuple[int, ...] | None = None  # the loop's CPUs (checked; None: any)


@dataclass(frozen=True)
class Connected:
    """The reply to :class:`Connect`: whom the control process is talking to."""

    server_version: int  # the robot's protocol version
    robot: str  # the robot's kind ("fer", "fr3"): its model
    limits: str  # whose joint limits apply (robots.params name)


@dataclass(frozen=True)
class StartController:
    """Run a :class:`~panda_py.controllers.TorqueController` (pickled by
    :mod:`.byvalue`); answers its starting inputs."""

    kind: ClassVar[Kind] = Kind.START
    payload: bytes


@dataclass(frozen=True)
class Move:
    """Track a planned move; answers a :class:`~panda_py.controllers.moves.MoveResult`
    when it ends. While a move runs, this one replaces it mid-motion (that one answers
    that it was replaced). ``until``: a condition (:mod:`panda_py.conditions`, pickled by
    value: it may hold a function of the user's script) that ends the move gently when it
    holds, or hands over to ``then``."""

    kind: ClassVar[Kind] = Kind.MOVE
    plan: JointPlan | PosePlan
    until: bytes | None = None
    then: JointPlan | PosePlan | None = None


@dataclass(frozen=True)
class Cancel:
    """Bring the move started by request ``move`` gently to rest (answers whether it was
    still running); it then answers its own request, cancelled."""

    kind: ClassVar[Kind] = Kind.CANCEL
    move: int


@dataclass(frozen=True)
class Stop:
    """Finish what runs; answers once it stopped."""

    kind: ClassVar[Kind] = Kind.STOP


@dataclass(frozen=True)
class RobotCall:
    """Call one of libfranka's ``Robot`` methods (``Panda.get_robot()``), checked in the
    user's process, between ticks."""

    kind: ClassVar[Kind] = Kind.ROBOT
    method: str
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Recover:
    """Automatic error recovery if the robot needs it; answers whether it did."""

    kind: ClassVar[Kind] = Kind.RECOVER


@dataclass(frozen=True)
class EnableLog:
    """Log every state into the ring of ``size`` records whose file travels with the
    request (one descriptor)."""

    kind: ClassVar[Kind] = Kind.ENABLE_LOG
    size: int


@dataclass(frozen=True)
class DisableLog:
    kind: ClassVar[Kind] = Kind.DISABLE_LOG


@dataclass(frozen=True)
class Close:
    """Finish what runs and exit."""

    kind: ClassVar[Kind] = Kind.CLOSE


Request = (
    Connect
    | StartController
    | Move
    | Cancel
    | Stop
    | RobotCall
    | Recover
    | EnableLog
    | DisableLog
    | Close
)


@dataclass(frozen=True)
class Call:
    """A request on its way to the control process, numbered for its reply."""

    rid: int
    request: Request


@dataclass(frozen=True)
class Reply:
    """The answer to the request numbered ``rid``: its value, or (``ok`` False) the
    exception to raise in the user's process."""

    rid: int
    ok: bool
    value: Any


@dataclass(frozen=True)
class LoopError:
    """Event: the error that ended a controller (raised by ``raise_error``)."""

    error: BaseException


@dataclass(frozen=True)
class LogLine:
    """Event: a line for the ``Panda``'s logger."""

    level: int
    message: str
