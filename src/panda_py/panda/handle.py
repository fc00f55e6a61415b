"""``MotionHandle``: a move that runs while the caller goes on.

``panda.move_to_pose(..., asynchronous=True)`` returns one at once; the move runs in the
control process, which answers when it ends. The handle waits for that answer, cancels
(a gentle stop: the arm decelerates within the robot's limits), and is awaitable::

    handle = panda.move_to_pose(pose, asynchronous=True)
    gripper.move(0.04, 0.1)           # the hand moves meanwhile
    ok = handle.wait()                # panda-py's success flag
    ok = await panda.move_to_start(asynchronous=True)   # in a coroutine
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import threading
from collections.abc import Callable, Generator
from typing import Any

from panda_py.controllers.plans import MoveResult
from panda_py.rt import requests as rq
from panda_py.rt.process import ControlProcess, ControlProcessError, Pending

__all__ = ["MotionHandle"]


class MotionHandle:
    """A move started with ``asynchronous=True`` (see the module's docstring)."""

    def __init__(
        self, proc: ControlProcess, pending: Pending, what: str,
        on_result: Callable[[MoveResult], None],
    ) -> None:  # fmt: skip
        self._proc = proc
        self._pending = pending
        self._what = what
        self._on_result: Callable[[MoveResult], None] | None = on_result
        self._lock = threading.Lock()
        # the result is logged, and a loop error queued for raise_error(), once: by the
        # reader thread when the answer arrives, or by wait() if it returns first
        pending.add_done_callback(lambda _: self._settle())

    def _settle(self) -> None:
        with self._lock:
            on_result, self._on_result = self._on_result, None
        pending = self._pending
        if on_result is not None and not pending.cancelled() and pending.exception() is None:
            on_result(pending.result())

    def __repr__(self) -> str:
        if not self.done():
            return f"<MotionHandle {self._what}: running>"
        result = self.result
        how = "failed" if result is None else ("succeeded" if result.success else "failed")
        return f"<MotionHandle {self._what}: {how}>"

    def done(self) -> bool:
        """Whether the move has ended (reached its goal, failed, was cancelled or
        replaced, or its ``until`` condition held)."""
        return self._pending.done()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until the move ends and return panda-py's success flag; False also when
        ``timeout`` [s] passed first (then ``done()`` is False). Raises if the control
        process is gone."""
        try:
            result: MoveResult = self._pending.result(timeout)
        except concurrent.futures.TimeoutError:
            return False  # the move still runs
        except ControlProcessError:
            if self._proc.dead:
                raise self._proc.gone() from None
            raise
        self._settle()
        return bool(result.success)

    def cancel(self) -> bool:
        """Bring the arm gently to rest (decelerating within the robot's limits, never an
        abrupt stop); the move then ends as cancelled. Returns at once, True if the move
        was still running. A move that is no longer running is left as it ended."""
        if self._pending.done():
            return False
        proc = self._proc
        if proc.closed or proc.dead:
            raise ControlProcessError("cancel: the Panda this move ran on is closed")
        return bool(proc.call(rq.Cancel(self._pending.rid)))

    @property
    def result(self) -> MoveResult | None:
        """How the move ended (success, the reason, the error; the condition that ended
        it and when), or None while it runs."""
        if not self._pending.done() or self._pending.exception() is not None:
            return None
        value: MoveResult = self._pending.result()
        return value

    def future(self) -> concurrent.futures.Future[MoveResult]:
        """The underlying future of the move's :class:`MoveResult`."""
        return self._pending

    def __await__(self) -> Generator[Any, None, bool]:
        """``await handle``: the success flag, without blocking the event loop."""
        result = yield from asyncio.wrap_future(self._pending).__await__()
        return bool(result.success)
