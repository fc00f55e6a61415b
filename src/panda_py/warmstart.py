"""Child processes that start warm: forked from a server process that has already imported
the package's heavy modules and loaded its compiled kernels, instead of a new interpreter
doing all of that again for each child.

A ``Panda``'s control process and a simulator each took about a second of CPU to start,
most of it numba's own start (its import, its type registries, SciPy's BLAS) and loading
the kernels from the disk cache; forked from the warm server they start in a few tens of
milliseconds. The server is ``multiprocessing``'s forkserver: it is started by the first
child that asks for it, imports the modules registered with :func:`register` (each
module's import does its warming) and ends with this process; the children it forks are
``multiprocessing`` processes (pid, exit code, ``join``, ``terminate``, ``kill``).

What a fork cannot take from this process is taken care of:

* the environment: a child gets this process's, as it is when it starts
  (:func:`run_with_environ`); where a setting read once at import (MuJoCo's GL backend,
  numba's and this package's JIT switches and cache places) differs from what the server
  started with, the child is spawned as a new interpreter instead;
* the user's script is never imported by the server or a child (``__main__`` is hidden
  while a child starts, see :func:`start`), so a script without
  ``if __name__ == "__main__":``, one piped on stdin and ``python -c`` all work;
* where ``fork`` does not exist (Windows), every child is spawned.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
import threading
import types
from collections.abc import Callable, Iterator
from typing import Any

__all__ = ["InheritedFd", "context", "register", "run_with_environ", "start"]

# read once, at import, by what the warm server imports
_IMPORT_TIME_ENV = ("MUJOCO_GL", "PYOPENGL_PLATFORM", "PANDA_PY_NO_JIT", "PANDA_PY_CACHE",
                    "XDG_CACHE_HOME", "HOME", "PYTHONPATH")  # fmt: skip
_LOCK = threading.Lock()
_modules: list[str] = []  # what the server imports (registered before it starts)
_server_env: dict[str, str] | None = None  # the import-time settings it started with


def register(module: str) -> None:
    """Have the warm server import ``module`` (a module whose import warms what its
    children need; it must not raise). Effective for a server not started yet."""
    if not isinstance(module, str) or not all(p.isidentifier() for p in module.split(".")):
        raise ValueError(f"module: expected a dotted module name, got {module!r}")
    with _LOCK:
        if module not in _modules:
            _modules.append(module)


def _import_time_env() -> dict[str, str]:
    env = os.environ
    names = (*_IMPORT_TIME_ENV, *(k for k in env if k.startswith("NUMBA_")))
    return {k: env[k] for k in names if k in env}


def context() -> Any:
    """The ``multiprocessing`` context to start a child in: the warm server's
    (forkserver), or spawn where there is no fork or this process's import-time settings
    are no longer those the server started with."""
    global _server_env
    import multiprocessing  # (here: importing this module stays cheap for ``panda_py``'s)

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    env = _import_time_env()
    with _LOCK:
        if _server_env is None:
            from multiprocessing import forkserver

            # the caller's own preloads stay (there is no public getter); a server
            # already running keeps what it has
            preload = list(getattr(forkserver._forkserver, "_preload_modules", ["__main__"]))
            forkserver.set_forkserver_preload(preload + [m for m in _modules if m not in preload])
            _server_env = env
        server_env = _server_env
    if env != server_env:
        return multiprocessing.get_context("spawn")
    return multiprocessing.get_context("forkserver")


def run_with_environ(env: dict[str, str], target: Callable[..., Any] | str, *args: Any) -> Any:
    """A child's entry: take ``env`` (the starting process's environment when it started
    the child; a forked child would otherwise have its server's) and run
    ``target(*args)``; ``target`` may be named ``"module:function"`` (the starting
    process then need not import its module)."""
    if os.environ != env:
        os.environ.clear()
        os.environ.update(env)
    if isinstance(target, str):
        module, _, name = target.partition(":")
        if not module or not name:
            raise ValueError(f"target: expected 'module:function', got {target!r}")
        run: Callable[..., Any] = getattr(importlib.import_module(module), name)
    else:
        run = target
    return run(*args)


class InheritedFd:
    """A file descriptor of this process handed to a ``multiprocessing`` child among its
    arguments: the child finds a duplicate of it in ``fd`` (close it when done)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def __reduce__(self) -> tuple[Any, ...]:
        from multiprocessing import reduction

        return (_inherited, (reduction.DupFd(self.fd),))


def _inherited(dup: Any) -> InheritedFd:
    return InheritedFd(dup.detach())


_MAIN_SWAP = threading.Lock()


@contextlib.contextmanager
def _main_module_hidden() -> Iterator[None]:
    """``multiprocessing`` makes a child (and the forkserver) import the parent's main
    script (so that what it unpickles from there exists): a script without ``if __name__
    == "__main__":`` then starts its children again in each child, and a script piped on
    stdin cannot be imported at all. These children need nothing from it (their targets
    and arguments live in ``panda_py``), so while one starts, ``__main__`` is an empty
    module."""
    with _MAIN_SWAP:
        main = sys.modules.get("__main__")
        sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            yield
        finally:
            if main is not None:
                sys.modules["__main__"] = main


def start(proc: Any) -> None:
    """``proc.start()`` for a ``multiprocessing`` process whose target and arguments come
    from ``panda_py``, whatever the caller's main module is."""
    with _main_module_hidden():
        proc.start()
