"""Scratch arrays on the stack for the per-tick kernels: ``stack_array(n)`` inside a
numba kernel is a C-contiguous float64 array of ``n`` (a literal) elements in the calling
function's frame, where ``np.empty(n)`` costs a heap allocation and its release through
numba's runtime (a ``malloc``, a ``free`` and two atomic reference counts: together a few
microseconds a tick in the Cartesian laws' dozens of temporaries, more on the loop's cold
caches), and hides from the optimiser that the array is local.

Its contents start undefined, as ``np.empty``'s. It lives until the kernel that made it
returns: it must never be returned, stored or captured (a view of it neither); the
kernels use it for temporaries only. Imported by the kernel modules only (it imports
numba); the cache keys of every kernel that uses it cover this file.
"""

from __future__ import annotations

from typing import Any

import numba
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["stack_array"]

_F8P = types.CPointer(types.float64)


def _alloca_typer(typingctx: Any, n: Any) -> Any:
    """A pointer to ``n`` (a literal) float64 on the caller's stack (its entry block: once
    per call, not per loop iteration)."""
    if not isinstance(n, types.IntegerLiteral) or n.literal_value <= 0:
        return None
    size = n.literal_value

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return cgutils.alloca_once(builder, ir.DoubleType(), size=size)

    return _F8P(n), codegen


_alloca: Any = intrinsic(_alloca_typer)


@numba.njit(inline="always")
def stack_array(n: Any) -> Any:  # pragma: no cover - compiled only
    """A float64 array of ``n`` (a literal) on the stack of the kernel that calls it."""
    return numba.carray(_alloca(n), n)
