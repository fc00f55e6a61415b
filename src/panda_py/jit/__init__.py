"""One home for the compiled code: the optional numba modules, one switch, one cache.

Every compiled module of the package (the kinematics', the dynamics', the control laws',
the online generator's, the control loop's and the simulator's kernels) is optional:
:func:`optional` imports it on first use, or answers None where numba is missing or
``PANDA_PY_NO_JIT=1`` is set (the one switch, read here only); its callers then run their
plain-Python reference, which the kernels equal. The kernels cache their machine code on
disk under a key over their sources (:mod:`panda_py.jit.cache`, imported by the kernel
modules only: this package itself never imports numba).

Each kernel module declares what warms it (compiles or loads every kernel before a loop
starts) as a function of its own, named by its caller here (``warm=``).
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from types import ModuleType

__all__ = ["ENV", "LOADED", "enabled", "optional"]

ENV = "PANDA_PY_NO_JIT"
# the packages whose absence means "no compiled code here" rather than a bug
_COMPILERS = ("numba", "llvmlite")

#: what each optional module resolved to on first use: its name -> the module, or None
#: (run plain). A test may set an entry (``monkeypatch.setitem``) to run a path plain or
#: compiled.
LOADED: dict[str, ModuleType | None] = {}


def enabled() -> bool:
    """Whether compiled code may run: ``PANDA_PY_NO_JIT`` unset, empty or ``0``."""
    return os.environ.get(ENV, "") in ("", "0")


def optional(
    name: str, *, requires: Callable[[], object] | None = None, warm: str | None = None
) -> ModuleType | None:
    """The compiled module ``name``, imported on first use, or None: compiled code off
    (:func:`enabled`), numba missing, or ``requires()`` (another optional module it
    builds on) None. ``warm`` names a function of the module to call once it is imported
    (compiles or loads its kernels at once). An import error of anything but numba
    itself is a bug and propagates."""
    try:
        return LOADED[name]
    except KeyError:
        pass
    module: ModuleType | None = None
    if enabled() and (requires is None or requires() is not None):
        try:
            module = importlib.import_module(name)
        except ImportError as exc:
            if (exc.name or "").split(".")[0] not in _COMPILERS:
                raise
        else:
            if warm is not None:
                getattr(module, warm)()
    LOADED[name] = module
    return module
