"""Shared by the tests that start ``panda-sim`` as a command: wait until it serves."""

from __future__ import annotations

import subprocess
import time

from panda_py.sim.probe import RawClient


def connect_when_serving(proc: subprocess.Popen, host: str, version: int, timeout: float = 30.0):  # type: ignore[no-untyped-def,type-arg]
    """A raw FCI client of ``version`` connected to the ``panda-sim`` at ``host`` once it
    accepts; raises what the last attempt raised if ``proc`` exits or ``timeout`` [s]
    passes first."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return RawClient(host, version)
        except OSError:
            if time.monotonic() > deadline or proc.poll() is not None:
                raise
            time.sleep(0.1)
