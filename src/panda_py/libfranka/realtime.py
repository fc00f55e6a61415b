"""Realtime scheduling of the thread that runs a control loop (``SCHED_FIFO``)."""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

from panda_py.libfranka.errors import RealtimeException
from panda_py.libfranka.types import RealtimeConfig

__all__ = [
    "check_realtime",
    "fifo_permitted",
    "has_realtime_kernel",
    "realtime_scope",
    "set_current_thread_to_highest_priority",
]

_warned = False


def has_realtime_kernel() -> bool:
    """True if the running kernel is a PREEMPT_RT kernel (``/sys/kernel/realtime``)."""
    try:
        with open("/sys/kernel/realtime") as f:
            return f.read().strip() == "1"
    except OSError:
        return False


def _fifo_available() -> bool:
    return sys.platform.startswith("linux") and hasattr(os, "sched_setscheduler")


def set_current_thread_to_highest_priority() -> tuple[int, int] | None:
    """Put the calling thread under ``SCHED_FIFO`` at the highest priority.

    Returns the previous ``(policy, priority)`` to restore, or None if not permitted or not
    supported here (no exception).
    """
    if not _fifo_available():
        return None
    try:
        previous = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
        top = os.sched_get_priority_max(os.SCHED_FIFO)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(top))
    except (OSError, AttributeError):
        return None
    return previous


def _restore(previous: tuple[int, int]) -> None:
    try:
        os.sched_setscheduler(0, previous[0], os.sched_param(previous[1]))
    except OSError:
        pass


def fifo_permitted() -> bool:
    """True if this thread may switch to ``SCHED_FIFO`` (tried, then switched back)."""
    previous = set_current_thread_to_highest_priority()
    if previous is None:
        return False
    _restore(previous)
    return True


def check_realtime(config: RealtimeConfig) -> None:
    """With ``kEnforce``, raise :class:`RealtimeException` unless this thread may switch to
    ``SCHED_FIFO`` (checked by switching and switching back)."""
    if config != RealtimeConfig.kEnforce:
        return
    if not fifo_permitted():
        raise RealtimeException(
            "libfranka: Running kernel does not have realtime capabilities "
            "(SCHED_FIFO not permitted). Use RealtimeConfig.kIgnore, or grant the "
            "permission (e.g. ulimit -r / CAP_SYS_NICE)."
        )


@contextmanager
def realtime_scope(config: RealtimeConfig) -> Iterator[bool]:
    """Run the block with ``SCHED_FIFO`` when permitted (yields whether it is). With
    ``kEnforce`` and no permission, raise :class:`RealtimeException`; with ``kIgnore``
    warn once per process and run at normal priority. The previous policy is restored."""
    global _warned
    previous = set_current_thread_to_highest_priority()
    if previous is None:
        if config == RealtimeConfig.kEnforce:
            raise RealtimeException(
                "libfranka: Running kernel does not have realtime capabilities "
                "(SCHED_FIFO not permitted)."
            )
        if not _warned:
            _warned = True
            warnings.warn(
                "panda_py.libfranka: realtime scheduling (SCHED_FIFO) is not permitted; the "
                "control loop runs at normal priority (RealtimeConfig.kIgnore).",
                RuntimeWarning,
                stacklevel=3,
            )
        yield False
        return
    try:
        yield True
    finally:
        _restore(previous)
