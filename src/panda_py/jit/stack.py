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

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import populate_array

__all__ = ["stack_array"]

_F8_1D = types.Array(types.float64, 1, "C")


def _stack_array_typer(typingctx: Any, n: Any) -> Any:
    """An array of ``n`` (a literal) float64 on the caller's stack (in its entry block:
    once per call, not per loop iteration), built in place as ``numba.carray`` builds
    one, without a meminfo: it compiles in kernels without numba's reference counting too
    (``jit.libc.LOOP_KERNEL``), where ``carray``'s own function may not return an array."""
    if not isinstance(n, types.IntegerLiteral) or n.literal_value <= 0:
        return None
    size = n.literal_value

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        data = cgutils.alloca_once(builder, ir.DoubleType(), size=size)
        ary = context.make_array(_F8_1D)(context, builder)
        itemsize = context.get_constant(types.intp, 8)
        shape = [context.get_constant(types.intp, size)]
        strides = [itemsize]
        populate_array(ary, data=data, shape=shape, strides=strides, itemsize=itemsize,
                       meminfo=None)  # fmt: skip
        return ary._getvalue()

    return _F8_1D(n), codegen


stack_array: Any = intrinsic(_stack_array_typer)
stack_array.__doc__ = "A float64 array of ``n`` (a literal) on the stack of the kernel calling it."
