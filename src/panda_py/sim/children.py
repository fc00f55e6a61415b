"""Ending the processes the simulator starts (its 1 kHz loop, its Desk)."""

from __future__ import annotations

from typing import Any

__all__ = ["stop_child"]


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
