"""Starting and ending the processes the simulator starts (its 1 kHz loop, its Desk).

The 1 kHz loop's process starts warm (:mod:`panda_py.warmstart`): forked from a server
that has imported the simulator and MuJoCo and loaded the compiled kinematics
(:mod:`panda_py.sim.warm`), not a new interpreter doing that again for each simulator.
"""

from __future__ import annotations

from typing import Any

from panda_py import warmstart

__all__ = ["start_child", "stop_child"]

warmstart.register("panda_py.sim.warm")


def start_child(proc: Any) -> None:
    """``proc.start()`` for a ``multiprocessing`` process whose target and arguments come
    from ``panda_py``, whatever the caller's main module is (``warmstart.start``)."""
    warmstart.start(proc)


def stop_child(proc: Any, conn: Any, *, kill: bool) -> None:
    """Ask a ``multiprocessing`` child to stop over ``conn``, wait 5 s, then end it
    (``kill``: SIGKILL, else SIGTERM) and close the connection."""
    try:
        conn.send(("stop",))
    except (OSError, EOFError):
        pass
    proc.join(5)
    if proc.is_alive():
        proc.kill() if kill else proc.terminate()
        proc.join(5)
    conn.close()
