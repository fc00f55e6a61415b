"""``PandaContext``: a loop at a fixed frequency beside a running controller
(panda-py's ``Panda.create_context``).

    with panda.create_context(frequency=1e3, max_runtime=10) as ctx:
        while ctx.ok():
            ctrl.set_control(...)

``ok()`` raises a pending error of the control loop, waits for the next tick of an
absolute schedule (``t_k = t_0 + k / frequency``, never re-anchored to "now": a late
iteration does not shift the ones after it), and says whether to go on.
"""

from __future__ import annotations

import math
import time
from typing import Any, Protocol

__all__ = ["PandaContext"]


class _Raises(Protocol):
    """What the loop needs of its ``Panda`` (any object with this method): the control
    process's error, raised."""

    def raise_error(self) -> None: ...


SPIN = 200e-6  # [s] sleep until this close to the deadline, then spin


class PandaContext:
    """A fixed-frequency loop tied to a :class:`~panda_py.Panda`."""

    def __init__(
        self, panda: _Raises, frequency: float, max_runtime: float = 0.0, max_iter: int = 0
    ) -> None:
        if isinstance(frequency, bool) or not isinstance(frequency, (int, float)):
            raise ValueError(f"frequency: expected a number > 0 [Hz], got {frequency!r}")
        if not (math.isfinite(frequency) and frequency > 0.0):
            raise ValueError(f"frequency: expected a number > 0 [Hz], got {frequency!r}")
        if isinstance(max_runtime, bool) or not isinstance(max_runtime, (int, float)):
            raise ValueError(f"max_runtime: expected a number >= 0 [s], got {max_runtime!r}")
        if not max_runtime >= 0.0:
            raise ValueError(f"max_runtime: expected a number >= 0 [s], got {max_runtime!r}")
        if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 0:
            raise ValueError(f"max_iter: expected an int >= 0, got {max_iter!r}")
        self._panda = panda
        self._dt = 1.0 / float(frequency)
        self._max_runtime = float(max_runtime)
        self._max_iter = max_iter
        self._start: float | None = None
        self._next = 0.0
        self._last = 0.0
        self._ticks = 0

    def __enter__(self) -> PandaContext:
        self._start = time.perf_counter()
        self._next = self._start
        self._last = self._start
        self._ticks = 0
        return self

    def __exit__(self, *exc: Any) -> None:
        return None

    @property
    def num_ticks(self) -> int:
        """Calls of :meth:`ok` so far."""
        return self._ticks

    @property
    def time(self) -> float:
        """Time from entering the context to the last :meth:`ok` [s]."""
        if self._start is None:
            return 0.0
        return self._last - self._start

    def ok(self) -> bool:
        """Raise a pending control error, wait for the next tick, and return False once
        ``max_iter`` ticks or ``max_runtime`` seconds have passed."""
        self._panda.raise_error()
        if self._start is None:
            self.__enter__()
        self._next += self._dt
        now = time.perf_counter()
        if now < self._next:
            remaining = self._next - now
            if remaining > SPIN:
                time.sleep(remaining - SPIN)
            while time.perf_counter() < self._next:
                pass
        elif now - self._next > self._dt:
            # fallen behind by whole periods: skip them, keeping the schedule's phase
            self._next += math.floor((now - self._next) / self._dt) * self._dt
        self._last = time.perf_counter()
        self._ticks += 1
        if self._max_iter > 0 and self._ticks - 1 >= self._max_iter:
            return False
        return not (self._max_runtime > 0.0 and self.time >= self._max_runtime)
