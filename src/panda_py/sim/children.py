"""Starting and ending the processes the simulator starts (its 1 kHz loop, its Desk)."""

from __future__ import annotations

import contextlib
import sys
import threading
import types
from collections.abc import Iterator
from typing import Any

__all__ = ["start_child", "stop_child"]

_MAIN_SWAP = threading.Lock()


@contextlib.contextmanager
def _main_module_hidden() -> Iterator[None]:
    """``multiprocessing``'s spawn makes a child re-run the parent's main script (so that
    what it unpickles from there exists): a script without ``if __name__ ==
    "__main__":`` then starts the simulator again in its child, and a script piped on
    stdin cannot be re-run at all. The simulator's children need nothing from it (their
    targets and arguments live in ``panda_py``), so while one starts, ``__main__`` is an
    empty module: they start from any script, the REPL or a notebook, as ``Panda``'s
    control process does."""
    with _MAIN_SWAP:
        main = sys.modules.get("__main__")
        sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            yield
        finally:
            if main is not None:
                sys.modules["__main__"] = main


def start_child(proc: Any) -> None:
    """``proc.start()`` for a ``multiprocessing`` (spawn) process whose target and
    arguments come from ``panda_py``, whatever the caller's main module is."""
    with _main_module_hidden():
        proc.start()


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
