"""Whether the lockstep simulator's spin for the client's answer pays now.

In lockstep the simulator polls for the client's command a short while (``lockstep_spin``)
before it sleeps on it: its next tick then starts on warm caches, and a lone simulator and
client pair runs about 1.3x faster than when the simulator sleeps at once (3.1-3.7x against
2.4-3.0x real time here). On a machine whose cores are all taken the spin only takes a
core from someone else, often the client it waits for: a test suite that runs several
simulators at once on two cores took 409 s and 792 CPU-s with the spin, 374 s and 709
CPU-s without.

:class:`SpinGate` spins while no thread waits for a core: it reads the kernel's count of
runnable threads (``/proc/loadavg``, Linux) every ``period`` and spins while the mean of
the last ``window`` counts is at most the cores this process may run on. Where the count
cannot be read it spins as configured.
"""

from __future__ import annotations

import os
from collections import deque

LOADAVG = "/proc/loadavg"
PERIOD = 0.1  # [s] between two readings of the count
WINDOW = 5  # readings averaged


def _cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


class SpinGate:
    """``budget(now)``: how long to spin for the client's answer at ``now`` (monotonic
    seconds): ``spin`` while the machine has a core to spare, 0 otherwise."""

    def __init__(
        self,
        spin: float,
        *,
        path: str = LOADAVG,
        cores: int | None = None,
        period: float = PERIOD,
        window: int = WINDOW,
    ) -> None:
        self.spin = float(spin)
        self.cores = _cores() if cores is None else int(cores)
        self.period = float(period)
        self._counts: deque[int] = deque(maxlen=window)
        self._next = 0.0
        self._open = True
        self._fd: int | None = None
        if self.spin > 0.0:
            try:
                self._fd = os.open(path, os.O_RDONLY)
            except OSError:
                self._fd = None  # no count: spin as configured

    def _runnable(self) -> int | None:
        """The kernel's count of runnable threads (this one included), or None."""
        if self._fd is None:
            return None
        try:
            # "0.52 0.58 0.59 3/812 4242": runnable/total is the fourth field
            return int(os.pread(self._fd, 128, 0).split()[3].split(b"/")[0])
        except (OSError, IndexError, ValueError):
            self.close()
            return None

    def budget(self, now: float) -> float:
        if self._fd is not None and now >= self._next:
            self._next = now + self.period
            count = self._runnable()
            if count is None:
                self._open = True
            else:
                self._counts.append(count)
                self._open = sum(self._counts) <= self.cores * len(self._counts)
        return self.spin if self._open else 0.0

    def close(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)


__all__ = ["SpinGate"]
