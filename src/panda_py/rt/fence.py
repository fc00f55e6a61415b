"""The memory fence the two processes' seqlocks and latches need (:mod:`.shm`).

A seqlock works only if its writer's stores become visible in program order (the
sequence number before the data it guards, the data before the number that ends the
write) and its reader's loads happen in program order (the number, the data, the number
again). x86-64 keeps both orders by itself (stores are not reordered with stores, loads
not with loads), and a Python function call is a barrier to the C compiler, so there the
fence is a no-op. Arm (aarch64), POWER and RISC-V reorder both: there the fence is a real
``fence seq_cst`` (``dmb ish`` on aarch64), one call of a numba-compiled function (about
70 ns), placed by :mod:`.shm` between the number and the data on both sides.
"""

from __future__ import annotations

import platform
from collections.abc import Callable
from typing import Any

__all__ = ["ORDERED_MACHINES", "compiled_fence", "fence_for", "memory_fence", "no_fence"]

# Machines whose memory model keeps stores in order and loads in order (TSO).
ORDERED_MACHINES = frozenset({"x86_64", "amd64", "i386", "i686"})


def no_fence() -> None:
    """Nothing to do: the machine keeps the orders a seqlock needs."""


def compiled_fence() -> Callable[[], None]:
    """A function that issues a full hardware memory fence (LLVM's ``fence seq_cst``),
    compiled with numba. Raises RuntimeError if numba is not installed."""
    try:
        import numba
        from numba.core import types
        from numba.extending import intrinsic
    except ImportError as exc:
        raise RuntimeError(
            "panda_py's shared memory needs a memory fence on this machine "
            f"({platform.machine()}, which reorders memory accesses) and numba to issue "
            "it: pip install numba"
        ) from exc

    @intrinsic
    def _fence(typingctx: Any) -> Any:
        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            builder.fence("seq_cst")
            return context.get_dummy_value()

        return types.void(), codegen

    @numba.njit(nogil=True)
    def fence() -> None:
        _fence()  # type: ignore[call-arg]

    fence()  # compile now, not inside the first tick
    return fence


def fence_for(machine: str) -> Callable[[], None]:
    """The fence for a machine named as ``platform.machine()`` names it."""
    return no_fence if machine.lower() in ORDERED_MACHINES else compiled_fence()


_fence_impl: Callable[[], None] | None = None


def memory_fence() -> Callable[[], None]:
    """This machine's fence (chosen, and compiled where needed, on first use)."""
    global _fence_impl
    if _fence_impl is None:
        _fence_impl = fence_for(platform.machine())
    return _fence_impl
