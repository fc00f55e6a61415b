"""numba kernels cached on disk under a key over every source file they compile.

numba's own cache (``cache=True``) stamps a kernel with its own file alone, so an edit to
a helper it calls from another file, or to a constant it bakes in, silently loads stale
machine code. A kernel made with :func:`keyed_jit` is cached in
``$PANDA_PY_CACHE/numba/<key>`` (default ``$XDG_CACHE_HOME/panda_py`` or
``~/.cache/panda_py``), ``key`` a SHA-256 over the source files it compiles (as its module
lists them), numba's version and the Python build: any edit selects a new directory and
the kernels compile afresh (old directories are left for the user to delete). The cache
lives where the user can write, never in site-packages; where no directory is writable
the kernels compile in memory, each process anew.

Used by every compiled module: the kinematics (over its package's files), the control laws
compiled with the model terms they need (:mod:`panda_py.controllers._fused`, over the
files it inlines), and the laws, the dynamics, the online generator's helpers and the
simulator's tick (each over its own file). The key names the sources, not where they
lie: a fresh checkout or a reinstall of the same sources loads what an earlier one
compiled.
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, ClassVar

import numba

__all__ = ["cache_dir", "keyed_jit", "source_key"]


def source_key(paths: Iterable[Path]) -> str:
    """A key over the files ``paths`` (their names and bytes), numba's version and the
    Python build."""
    h = hashlib.sha256(f"{numba.__version__}\n{sys.version}\n{sys.platform}\n".encode())
    for path in sorted(Path(p) for p in paths):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:20]


def cache_dir(key: str) -> Path:
    """Where the kernels of ``key`` are kept (see the module docstring)."""
    root = os.environ.get("PANDA_PY_CACHE")
    if root:
        base = Path(root)
    else:
        xdg = os.environ.get("XDG_CACHE_HOME")
        base = (Path(xdg) if xdg else Path.home() / ".cache") / "panda_py"
    return base / "numba" / key


_CACHE_CLASSES: dict[str, Any] = {}


def _cache_class(key: str) -> Any:
    """numba's per-function cache, located in :func:`cache_dir` and stamped with ``key``
    (numba stamps with the kernel's own file); None if this numba's caching internals
    differ (then no disk cache)."""
    if key in _CACHE_CLASSES:
        return _CACHE_CLASSES[key]
    try:
        from numba.core import caching
    except ImportError:
        return None
    base_locator = getattr(caching, "_CacheLocator", None)
    base_impl = getattr(caching, "CompileResultCacheImpl", None)
    base_cache = getattr(caching, "FunctionCache", None)
    if base_locator is None or base_impl is None or base_cache is None:
        _CACHE_CLASSES[key] = None
        return None

    class Locator(base_locator):  # type: ignore[misc, valid-type]
        def __init__(self, py_func: Any, py_file: str) -> None:
            self._lineno = py_func.__code__.co_firstlineno
            self._path = str(cache_dir(key))

        def get_cache_path(self) -> str:
            return self._path

        def get_source_stamp(self) -> str:
            return key

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            self = cls(py_func, py_file)
            try:
                self.ensure_cache_path()  # creates it, and tests that it is writable
            except OSError:
                return None
            return self

    class Impl(base_impl):  # type: ignore[misc, valid-type]
        _locator_classes: ClassVar[list[Any]] = [Locator]

    class Cache(base_cache):  # type: ignore[misc, valid-type]
        _impl_class = Impl

    _CACHE_CLASSES[key] = Cache
    return Cache


def keyed_jit(key: str, **kw: Any) -> Callable[[Any], Any]:
    """``numba.njit(**kw)``, caching in :func:`cache_dir` of ``key`` where it can."""

    def deco(fn: Any) -> Any:
        dispatcher = numba.njit(**kw)(fn)
        cache = _cache_class(key)
        if cache is not None:
            try:
                dispatcher._cache = cache(fn)
            except (RuntimeError, OSError):  # no writable place: compile in memory
                pass
        return dispatcher

    return deco
