"""The processes that draw the simulated robot (the viewer, the video recorder): started
before the simulator, fed by a :class:`~panda_py.sim.frames.FrameFeed`, ended after it.

A drawing process runs at a lower priority than the simulator (``nice``), ignores
Ctrl-C (the terminal sends it to the whole process group; the simulator's end tells it
to finish, so a video is always closed properly) and ends by itself when the process that
started it is gone.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
from typing import Any

from panda_py.sim.children import start_child
from panda_py.sim.frames import FrameFeed, close_feed

log = logging.getLogger("panda_py.sim")

# How much lower a drawing process's priority is than the simulator's (nice increment).
NICE = 10


class DrawingError(RuntimeError):
    """A drawing process could not start (no display, no OpenGL, no video encoder)."""


def child_setup() -> None:
    """First thing in a drawing process: below the simulator, deaf to Ctrl-C."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        os.nice(NICE)
    except OSError:
        pass


def parent_alive() -> bool:
    parent = multiprocessing.parent_process()
    return parent is None or parent.is_alive()


class DrawingProcess:
    """A drawing process's handle: ``start`` waits for it to say it is ready (or why not),
    ``stop`` waits for it to finish (a recorder encodes the frames still queued)."""

    name = "drawing"

    def __init__(self, feed: FrameFeed, target: Any, args: tuple[Any, ...]) -> None:
        self.feed = feed
        self._target, self._args = target, args
        self._proc: Any = None
        self._conn: Any = None
        self.result: Any = None  # what the process reported when it finished

    def start(self, timeout: float) -> DrawingProcess:
        ctx = multiprocessing.get_context("spawn")
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=self._target, args=(self.feed, child, *self._args), daemon=True)
        start_child(proc)
        child.close()
        self._proc, self._conn = proc, parent
        if not parent.poll(timeout):
            self._abort()
            raise DrawingError(f"{self.name}: did not start within {timeout:g} s")
        try:
            kind, detail = parent.recv()
        except EOFError:
            self._abort()
            raise DrawingError(f"{self.name}: its process died on start") from None
        if kind != "ready":
            self._abort()
            raise DrawingError(detail)
        return self

    def stop(self, timeout: float = 60.0) -> Any:
        """Tell it the simulator ended, wait up to ``timeout`` [s] for it to finish and
        return what it reported (None if it had to be killed)."""
        proc, conn = self._proc, self._conn
        if proc is None:
            return self.result
        self._proc = self._conn = None
        close_feed(self.feed)
        try:
            if conn.poll(timeout):
                self.result = conn.recv()
        except (EOFError, OSError):
            pass
        proc.join(5)
        if proc.is_alive():
            proc.kill()
            proc.join(5)
        conn.close()
        return self.result

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.is_alive()

    def _abort(self) -> None:
        proc, self._proc = self._proc, None
        if proc is not None:
            proc.kill()
            proc.join(5)
        if self._conn is not None:
            self._conn.close()
            self._conn = None


__all__ = [
    "NICE",
    "DrawingError",
    "DrawingProcess",
    "child_setup",
    "parent_alive",
]
