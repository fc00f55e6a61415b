"""Warm the caches for the next control tick while its state is still on its way.

Between two ticks the control thread sleeps about 0.85 ms; meanwhile other work (the
robot simulator, other processes, the hypervisor) evicts its code and data from the CPU
caches, and the next tick then runs several times slower than warm (measured on a 2-core
VM: a tick path of 4 us warm took 15-35 us right after the sleep). The hybrid state wait
(:mod:`._network`) wakes about 150 us before the next state is due and polls; at that
moment the loop runs its own part of a tick once, on the last state: the header read, a
``RobotState`` and one field of it, the construction of the callback's command type and
its conversion into a scratch datagram. No user code runs, nothing is sent, and nothing
the loop keeps is touched (its own command objects and a scratch :class:`Commander`), so
when the state arrives the tick's code and data are in cache. Errors are ignored: a
rehearsal has no result to report, and the real tick reports its own.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from panda_py.libfranka._commander import Commander
from panda_py.libfranka._connection import RobotConnection
from panda_py.libfranka.commands import (
    CartesianPose,
    CartesianVelocities,
    JointPositions,
    JointVelocities,
    Torques,
)
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import Duration

__all__ = ["rehearsal"]

_IDENTITY = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
_CONVERT: dict[type, str] = {
    Torques: "torques",
    JointPositions: "joint_positions",
    JointVelocities: "joint_velocities",
    CartesianPose: "cartesian_pose",
    CartesianVelocities: "cartesian_velocities",
}


def _make(kind: type) -> Any:
    if kind is CartesianPose:
        return CartesianPose(_IDENTITY)
    return kind([0.0] * (6 if kind is CartesianVelocities else 7))


def rehearsal(
    conn: RobotConnection, scratch: Commander, kinds: tuple[type, ...]
) -> Callable[[], None]:
    """A function that rehearses a tick of a loop whose callbacks return ``kinds`` on the
    connection's last state, with ``scratch`` (a Commander of the loop's settings that the
    loop does not use)."""
    dialect = conn.dialect
    header = conn._header
    scratch.initialized = True  # the filters' path of every tick after the first
    steps = [(kind, getattr(scratch, _CONVERT[kind])) for kind in kinds]
    pack_id = conn.layout.c_message_id.struct_.pack_into
    buffer = scratch.buffer
    pending = conn.net.pending

    def rehearse() -> None:
        data = conn.last_data
        try:
            header(data)
            state = RobotState(dialect, data)
            state.q  # noqa: B018 (a field read, the array path callbacks take)
            Duration(1)
            pack_id(buffer, 0, 0)
            for kind, convert in steps:
                if pending():  # the state is here: leave the rest cold, serve it now
                    return
                convert(_make(kind), data)
        except Exception:  # a rehearsal has nothing to report (see the module docstring)
            pass

    return rehearse
