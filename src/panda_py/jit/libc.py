"""The C library's calls the compiled loops make, as numba intrinsics: ``poll``, ``recv``,
``recvfrom``, ``recvmmsg``, ``send``, ``sendto``, ``clock_gettime``, this thread's
``errno``, a memory fence, and a copy between arrays at about ``memcpy``'s cost.

Each is called as an external symbol that the dynamic linker resolves when the compiled
code loads (no address is compiled in), so the kernels that call them cache on disk as
every other (:mod:`panda_py.jit.cache`; their keys cover this file). Pointers are passed
as integer addresses (``array.ctypes.data``); every result is widened to 64 bits. Used by
the control loop's ticks (:mod:`panda_py.rt._tick`) and the simulator's lockstep ticks
(:mod:`panda_py.sim._lockstep_jit`). Linux (``__errno_location``, ``struct mmsghdr``).
Imported by the kernel modules only (it imports numba).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from panda_py.jit import cache

__all__ = [
    "LOOP_KERNEL", "clock_gettime", "copy", "errno", "fence", "poll", "recv", "recvfrom",
    "recvmmsg", "send", "sendto",
]  # fmt: skip

KEY = cache.source_key([Path(__file__)])

#: The compile options of the loops that run whole ticks (the control loop's and the
#: simulator's lockstep ticks): numba's reference counting off. Every numba function counts
#: a reference to each array it is given, on entry and again on exit, with an atomic
#: instruction each (which the compiler's pruning cannot remove around a call): a control
#: loop's tick passes some 200 arrays down through its helpers, and those 400 atomics were
#: a tenth of the control process's CPU (perf). An array that enters a kernel compiled
#: without the counting carries none, and the helpers compiled within skip theirs. Such a
#: kernel allocates nothing (``jit.stack`` for temporaries, :func:`copy` for copies:
#: numba's slice copies need the runtime) and works on its caller's arrays, which the
#: caller holds throughout the call. (Here, not in ``jit.cache``: both loops' cache keys
#: cover this file, so a change of the options compiles them afresh.)
LOOP_KERNEL: dict[str, Any] = {"nogil": True, "_nrt": False}

_I32, _I64 = ir.IntType(32), ir.IntType(64)
_PTR = ir.IntType(8).as_pointer()
_IO = [_I32, _PTR, _I64, _I32]  # (fd, buffer, length, flags)
_IO_ADDR = [_I32, _PTR, _I64, _I32, _PTR]  # ... and the peer's address


def _call(builder, name, restype, argtypes, args):  # type: ignore[no-untyped-def,unused-ignore]
    """Call the C library's ``name``: integers standing for pointers turned into
    pointers, wider integers truncated, the result widened to 64 bits."""
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(restype, argtypes), name)
    values = []
    for value, want in zip(args, argtypes, strict=True):
        if isinstance(want, ir.PointerType):
            value = builder.inttoptr(value, want)
        elif value.type != want:
            value = builder.trunc(value, want)
        values.append(value)
    result = builder.call(fn, values)
    return result if result.type == _I64 else builder.sext(result, _I64)


def _ints(n: int) -> Any:
    """The signature of a call of ``n`` integer arguments returning one."""
    return types.int64(*(types.int64,) * n)


def _poll_typer(typingctx, fds, nfds, timeout):  # type: ignore[no-untyped-def,unused-ignore]
    """``poll(fds, nfds, timeout_ms)``; ``fds`` the address of a ``struct pollfd`` array."""
    return _ints(3), lambda c, b, s, a: _call(b, "poll", _I32, [_PTR, _I64, _I32], a)


def _recv_typer(typingctx, fd, buf, n, flags):  # type: ignore[no-untyped-def,unused-ignore]
    """``recv(fd, buf, n, flags)``; ``buf`` an address."""
    return _ints(4), lambda c, b, s, a: _call(b, "recv", _I64, _IO, a)


def _send_typer(typingctx, fd, buf, n, flags):  # type: ignore[no-untyped-def,unused-ignore]
    """``send(fd, buf, n, flags)``; ``buf`` an address."""
    return _ints(4), lambda c, b, s, a: _call(b, "send", _I64, _IO, a)


def _recvfrom_typer(typingctx, fd, buf, n, flags, addr, addrlen):  # type: ignore[no-untyped-def,unused-ignore]
    """``recvfrom(fd, buf, n, flags, addr, addrlen)``; the pointers as addresses."""
    return _ints(6), lambda c, b, s, a: _call(b, "recvfrom", _I64, [*_IO_ADDR, _PTR], a)


def _sendto_typer(typingctx, fd, buf, n, flags, addr, addrlen):  # type: ignore[no-untyped-def,unused-ignore]
    """``sendto(fd, buf, n, flags, addr, addrlen)``; the pointers as addresses."""
    return _ints(6), lambda c, b, s, a: _call(b, "sendto", _I64, [*_IO_ADDR, _I32], a)


def _recvmmsg_typer(typingctx, fd, msgs, vlen, flags):  # type: ignore[no-untyped-def,unused-ignore]
    """``recvmmsg(fd, msgs, vlen, flags, NULL)``; ``msgs`` the address of a ``struct
    mmsghdr`` array (Linux)."""

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def,unused-ignore]
        return _call(builder, "recvmmsg", _I32, [_I32, _PTR, _I32, _I32, _PTR],
                     [*args, ir.Constant(_I64, 0)])  # fmt: skip

    return _ints(4), codegen


def _clock_typer(typingctx, clock, ts):  # type: ignore[no-untyped-def,unused-ignore]
    """``clock_gettime(clock, ts)``; ``ts`` the address of a ``struct timespec``."""
    return _ints(2), lambda c, b, s, a: _call(b, "clock_gettime", _I32, [_I32, _PTR], a)


def _errno_typer(typingctx):  # type: ignore[no-untyped-def,unused-ignore]
    """This thread's ``errno``."""

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def,unused-ignore]
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(_I32.as_pointer(), []), "__errno_location"
        )
        return builder.sext(builder.load(builder.call(fn, [])), _I64)

    return types.int64(), codegen


def _fence_typer(typingctx):  # type: ignore[no-untyped-def,unused-ignore]
    """A sequentially consistent fence: a compiler and a hardware barrier."""

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def,unused-ignore]
        builder.fence("seq_cst")
        return context.get_dummy_value()

    return types.void(), codegen


poll: Any = intrinsic(_poll_typer)
recv: Any = intrinsic(_recv_typer)
send: Any = intrinsic(_send_typer)
recvfrom: Any = intrinsic(_recvfrom_typer)
sendto: Any = intrinsic(_sendto_typer)
recvmmsg: Any = intrinsic(_recvmmsg_typer)
clock_gettime: Any = intrinsic(_clock_typer)
errno: Any = intrinsic(_errno_typer)
fence: Any = intrinsic(_fence_typer)


@cache.keyed_jit(KEY, nogil=True)
def copy(dst, dst_at, src, src_at, n):  # type: ignore[no-untyped-def,unused-ignore]
    """``dst[dst_at : dst_at + n] = src[src_at : src_at + n]`` (1-d arrays of one type) as
    a plain loop, which the compiler turns into a vector copy: numba's slice assignment
    costs some 15 ns a call and 0.23 ns a byte (a state of protocol 5, 2373 bytes: 550 ns a
    copy against 30 here, and a control loop's tick copies it four times). Bounds checked,
    as the slices were."""
    if n < 0 or dst_at < 0 or src_at < 0 or dst_at + n > dst.size or src_at + n > src.size:
        raise IndexError("a compiled copy out of its arrays' bounds")
    for i in range(n):
        dst[dst_at + i] = src[src_at + i]
