"""Progress bars (tqdm) for long one-time work: the first compile of the numba kernels
after installing, and the first build of the simulator's model library.

The same call compiles or loads a cache, and only compiling is slow: loading one kernel
takes milliseconds (the first of a process up to half a second: numba starts its code
generator), compiling one takes seconds. So a bar appears once one step of the work (one
kernel, one build) has run for :data:`DELAY` seconds, and only where someone
watches: stderr is a terminal, or ``PANDA_PY_PROGRESS=1`` asks for it (``0``: never). A
thread draws the bar while a step runs and ends with the work, so nothing of this is left
running when a real-time loop starts after it.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
import time
import warnings
from collections.abc import Iterator
from typing import IO, Any

__all__ = ["DELAY", "ENV", "Work", "enabled", "work"]

ENV = "PANDA_PY_PROGRESS"
# [s] a step done sooner shows no bar. Measured here: a kernel loads from the cache in
# 2-15 ms (the first of a process 0.36-0.50 s), compiles in 1-5 s (the kinematics' first
# single-call kernel about 2 s, the mass matrix 4.5 s).
DELAY = 1.5
REFRESH = 0.25  # [s] between redraws while a step runs
SIZE = (100, 24)  # (columns, lines) where no terminal tells its size
_FORMAT = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}]"
_SETTINGS = {"1": True, "0": False, "": None}


def enabled(stream: IO[str] | None = None) -> bool:
    """Whether bars are shown on ``stream`` (default: stderr): as ``PANDA_PY_PROGRESS``
    says (``1`` always, ``0`` never), else when the stream is a terminal."""
    value = os.environ.get(ENV, "").strip()
    setting = _SETTINGS.get(value)
    if setting is None and value:
        warnings.warn(
            f"{ENV}={value!r}: expected 1 (show progress), 0 (never) or unset (on a "
            "terminal); showing it on a terminal only",
            stacklevel=2,
        )
    if setting is not None:
        return setting
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream is not None and stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


class Work:
    """The handle of :func:`work`: ``advance()`` after each finished step (the steps
    left count as done when the work's block ends without an error)."""

    def __init__(self, description: str, total: int, delay: float, file: IO[str]) -> None:
        self._args = (description, total, file)
        self._delay = delay
        self._lock = threading.Lock()
        self._bar: Any = None
        self._n = 0
        self._start = self._step_start = time.monotonic()
        if delay <= 0.0:
            self._show()
        self._done = threading.Event()
        self._ticker = threading.Thread(target=self._tick, name="panda_py progress", daemon=True)
        self._ticker.start()

    def advance(self, n: int = 1) -> None:
        with self._lock:
            self._n += n
            self._step_start = time.monotonic()
            if self._bar is not None:
                self._bar.update(n)

    def complete(self) -> None:
        """All steps done (the work's block ended without an error)."""
        self.advance(max(self._args[1] - self._n, 0))

    def _show(self) -> None:
        """Draw the bar (under the lock, or before the ticker starts)."""
        description, total, file = self._args
        columns, lines = _size(file)
        # (a delay > 0 only keeps tqdm from drawing before start_t is set below)
        bar = _bar_class()(total=total, desc=description, file=file, mininterval=0.0,
                           miniters=0, smoothing=0.0, bar_format=_FORMAT, ncols=columns,
                           nrows=lines, delay=1e-9)  # fmt: skip
        # the time since the work began, not since the bar appeared, so that the rate and
        # the time left average over every step (tqdm's own reset() sets start_t too)
        bar.start_t -= time.monotonic() - self._start
        bar.update(self._n)  # redrawn with the steps already done
        self._bar = bar

    def _tick(self) -> None:
        while not self._done.wait(REFRESH):
            if self._bar is None and time.monotonic() - self._step_start < self._delay:
                continue
            _bar_class()  # imported outside the lock, which the working thread takes
            with self._lock:
                if self._bar is None:
                    self._show()
                else:
                    self._bar.refresh()  # the elapsed time moves while a step runs

    def close(self) -> None:
        self._done.set()
        self._ticker.join()
        with self._lock:
            if self._bar is not None:
                self._bar.close()


def _size(file: IO[str]) -> tuple[int, int]:
    """The terminal's (columns, lines), or :data:`SIZE` where it tells none: a pipe, a
    file, or a pseudo-terminal of size 0 (``script``, a fresh ``docker run -t``), where
    tqdm would draw an empty line."""
    try:
        columns, lines = os.get_terminal_size(file.fileno())
    except (AttributeError, ValueError, OSError):  # no file descriptor, not a terminal
        columns = lines = 0
    return (columns, lines) if columns > 0 and lines > 0 else SIZE


@functools.cache
def _bar_class() -> Any:
    """tqdm, imported on first use, without its monitor thread (ours redraws the bar,
    and ends with the work)."""
    from tqdm import tqdm

    class Bar(tqdm):
        monitor_interval = 0

    return Bar


class _Silent:
    """:class:`Work`'s stand-in where nobody watches: nothing imported, no thread."""

    def advance(self, n: int = 1) -> None:
        pass


@contextlib.contextmanager
def work(
    description: str,
    total: int = 1,
    *,
    delay: float | None = None,
    file: IO[str] | None = None,
) -> Iterator[Any]:
    """A progress bar over ``total`` steps of one-time work, on ``file`` (default:
    stderr), drawn once a step has run ``delay`` [s] (default :data:`DELAY`) and only if
    :func:`enabled`; yields a handle whose ``advance()`` the caller calls after each
    step::

        with progress.work("panda_py: compiling the kinematics", total=len(sigs)) as w:
            for sig in sigs:
                kernel.compile(sig)
                w.advance()
    """
    if isinstance(total, bool) or not isinstance(total, int) or total < 1:
        raise ValueError(f"total: expected a whole number of steps >= 1, got {total!r}")
    delay = DELAY if delay is None else delay
    if not delay >= 0.0:
        raise ValueError(f"delay: expected seconds >= 0, got {delay!r}")
    stream = sys.stderr if file is None else file
    if stream is None or not enabled(stream):
        yield _Silent()
        return
    handle = Work(description, total, delay, stream)
    try:
        yield handle
        handle.complete()
    finally:
        handle.close()
