"""The JIT backend: the kinematics' scalar Python (:mod:`._fk`, :mod:`._ik`) compiled by
numba, plus the thin kernels that own the arrays.

Imported by :mod:`._backend` on the first kinematics call that can use it (never at
``import panda_py``), unless ``PANDA_PY_NO_JIT=1`` or numba is missing. Importing it
registers the solvers' functions with numba (``register_jitable``: the same function
objects Python runs plain) and the branch-free :mod:`._nbmath` in place of
:mod:`._scalar`'s libm calls; nothing is compiled until a kernel is first called or
:func:`compile_all` runs.

The compile cache (:mod:`panda_py.jit.cache`: where the user can write, never in
site-packages) is keyed over the source of every module in this package (what the kernels
compile: the solvers, the math, the constants they bake in), numba's version and the
Python build: an edit to a helper or a constant elsewhere selects a new directory and the
kernels compile afresh, where numba's own cache would key on the kernel's file alone and
load stale machine code.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numba.extending import overload, register_jitable

from panda_py import progress
from panda_py.jit import cache
from panda_py.kinematics import _fk, _follow, _ik, _nbmath, _scalar

_OPTS: dict[str, Any] = {"nogil": True, "error_model": "numpy"}
# The arithmetic helpers may fuse a * b + c into one multiply-add (fastmath "contract":
# one rounding instead of two, no reassociation, nothing assumed about NaN or infinity).
# Every kernel calls the same compiled loop, so batched and single calls stay equal bit
# for bit.
_ARITH: dict[str, Any] = {**_OPTS, "forceinline": True, "fastmath": {"contract"}}


# (numba requires the typing functions' parameters to equal the implementations', names
# and annotations alike)
@overload(_scalar.atan2, jit_options=_ARITH)  # type: ignore[arg-type]
def _atan2(y: float, x: float) -> Any:
    return _nbmath.atan2


@overload(_scalar.sincos, jit_options=_ARITH)  # type: ignore[arg-type]
def _sincos(x: float) -> Any:
    return _nbmath.sincos


_fn: Any
for _fn in (
    _scalar.flip, _fk.unpack_chain, _fk.link, _fk.tail, _fk.ee_pose, _fk._column,
    _fk.jacobian_columns, _ik.unpack_ik_params,
    _ik.rigid_error, _ik.case_row, _ik.pose_part, _ik.arm_part, _ik.branch, _ik.solve,
    _ik.search_q7,
):  # fmt: skip
    register_jitable(**_ARITH)(_fn)
for _fn in (
    _fk.fk_range, _fk.frames_range, _fk.jacobian_range, _ik.ik_range, _ik.rigid_range,
    _follow._rrt, _follow._step, _follow.follow_path,
):  # fmt: skip
    register_jitable(**_OPTS)(_fn)


# ----------------------------------------------------------------- the keyed disk cache

SOURCE_KEY = cache.source_key(Path(__file__).parent.glob("*.py"))


def cache_dir() -> Path:
    """Where the compiled kernels are kept (see the module docstring)."""
    return cache.cache_dir(SOURCE_KEY)


def _jit(**kw: Any) -> Any:
    """numba.njit, caching in :func:`cache_dir` where it can."""
    return cache.keyed_jit(SOURCE_KEY, **kw)


# ----------------------------------------------------------------------------- kernels

_PAR_CHUNK = 64  # rows per parallel work item: enough to make each item's call negligible


@_jit(**_OPTS)
def fk_one(q: Any, C: Any, out: Any) -> bool:
    """O_T_EE of q (7,) into out (4, 4); False (out untouched) if q is not finite or not
    of shape (7,)."""
    if q.shape[0] != 7:
        return False
    if not math.isfinite(q[0] + q[1] + q[2] + q[3] + q[4] + q[5] + q[6]):
        return False
    v = _fk.ee_pose(_fk.unpack_chain(C), (q[0], q[1], q[2], q[3], q[4], q[5], q[6]))
    for i in range(3):
        for j in range(4):
            out[i, j] = v[4 * i + j]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0
    return True


@_jit(**_OPTS)
def fk_batch(Q: Any, C: Any, out: Any) -> None:
    """O_T_EE for each row of Q (N, 7) into out (N, 4, 4)."""
    _fk.fk_range(Q, C, out, 0, Q.shape[0])


@_jit(parallel=True, **_OPTS)
def fk_batch_par(Q: Any, C: Any, out: Any) -> None:
    """:func:`fk_batch` on all cores (the same arithmetic per row)."""
    n = Q.shape[0]
    for c in numba.prange((n + _PAR_CHUNK - 1) // _PAR_CHUNK):
        k0 = np.int64(c) * _PAR_CHUNK  # prange's index is unsigned; keep the rest signed
        _fk.fk_range(Q, C, out, k0, min(k0 + _PAR_CHUNK, n))


@_jit(**_OPTS)
def frames_batch(Q: Any, C: Any, out: Any) -> None:
    """J1..J7, flange, EE for each row of Q into out (N, 9, 4, 4)."""
    _fk.frames_range(Q, C, out, 0, Q.shape[0])


@_jit(**_OPTS)
def jacobian_batch(Q: Any, C: Any, body: bool, out: Any) -> None:
    """The EE Jacobian for each row of Q into out (N, 6, 7) (see ``_fk.jacobian_range``)."""
    _fk.jacobian_range(Q, C, body, out, 0, Q.shape[0])


@_jit(**_OPTS)
def jacobian_one(q: Any, C: Any, body: bool, out: Any) -> bool:
    """:func:`jacobian_batch` for one C-contiguous q (7,) into out (1, 6, 7); False if q
    is not finite."""
    if not math.isfinite(q[0] + q[1] + q[2] + q[3] + q[4] + q[5] + q[6]):
        return False
    _fk.jacobian_range(q.reshape((1, 7)), C, body, out, 0, 1)
    return True


def _ik_single(A: Any, T: Any, qi: Any, q7: float, radius: float, full: bool, Q: Any) -> bool:
    if T.shape[0] != 4 or T.shape[1] != 4 or qi.shape[0] != 7:
        return False
    st = np.empty(4 if full else 1, dtype=np.int8)
    q7a = np.empty(2)  # [0]: q7 given, [1]: q7 solved for
    q7a[0] = q7
    # (copies only where T or qi is not C-contiguous: decided at compile time)
    QI = np.ascontiguousarray(qi).reshape((1, 7))
    T3 = np.ascontiguousarray(T).reshape((1, 4, 4))
    _ik.ik_range(A, T3, QI, q7a[:1], radius, full, Q, st, q7a[1:], 0, 1)
    return st[0] != _ik.INVALID


register_jitable(**_OPTS)(_ik_single)


@_jit(**_OPTS)
def ik_one(A: Any, T: Any, qi: Any, q7: float, radius: float, out: Any) -> bool:
    """One pose T (4, 4), q_init qi (7,), q7 (``radius`` > 0 [rad]: the q7 nearest it
    within radius with a solution in q_init's case, ``_ik.search_q7``): the solution in
    q_init's case into out (7,) (NaN if none). False if the input is not finite and rigid
    or has the wrong shape."""
    return _ik_single(A, T, qi, q7, radius, False, out.reshape((1, 7)))


@_jit(**_OPTS)
def ik_full_one(A: Any, T: Any, qi: Any, q7: float, radius: float, out: Any) -> bool:
    """As :func:`ik_one`, all four branches (at the q7 found) into out (4, 7)."""
    return _ik_single(A, T, qi, q7, radius, True, out)


@_jit(**_OPTS)
def ik_batch(
    A: Any, T: Any, QI: Any, q7: Any, radius: float, full: bool, qout: Any, stout: Any,
    q7out: Any,
) -> None:  # fmt: skip
    """``_ik.ik_range`` over all poses of T (N, 4, 4)."""
    _ik.ik_range(A, T, QI, q7, radius, full, qout, stout, q7out, 0, T.shape[0])


@_jit(parallel=True, **_OPTS)
def ik_batch_par(
    A: Any, T: Any, QI: Any, q7: Any, radius: float, full: bool, qout: Any, stout: Any,
    q7out: Any,
) -> None:  # fmt: skip
    """:func:`ik_batch` on all cores (the same arithmetic per pose)."""
    n = T.shape[0]
    for c in numba.prange((n + _PAR_CHUNK - 1) // _PAR_CHUNK):
        k0 = np.int64(c) * _PAR_CHUNK
        k1 = min(k0 + _PAR_CHUNK, n)
        _ik.ik_range(A, T, QI, q7, radius, full, qout, stout, q7out, k0, k1)


@_jit(**_OPTS)
def follow_batch(P: Any, C: Any, q0: Any, damping: float, iterations: int, out: Any) -> None:
    """``_follow.follow_path`` (compiled)."""
    _follow.follow_path(P, C, q0, damping, iterations, out)


@_jit(**_OPTS)
def rigid_batch(T: Any, err: Any) -> None:
    """``_ik.rigid_error`` of each pose of T (N, 4, 4) into err (N,)."""
    _ik.rigid_range(T, err, 0, T.shape[0])


# --------------------------------------------------------------------------- signatures

_f8, _b1, _i1 = numba.float64, numba.boolean, numba.int8
_V, _M, _M3 = _f8[::1], _f8[:, ::1], _f8[:, :, ::1]  # C-contiguous
_VA, _MA = _f8[:], _f8[:, :]  # any layout
# The single-call kernels take float64 only, C-contiguous (the dispatcher's exact match)
# or of any layout (copied in the kernel), and refuse anything else with a TypeError
# instead of compiling for it, so their callers check only the dtype.
_SINGLE: dict[str, list[Any]] = {
    "fk_one": [_b1(_V, _V, _M), _b1(_VA, _V, _M)],
    "ik_one": [_b1(_V, _M, _V, _f8, _f8, _V), _b1(_V, _MA, _VA, _f8, _f8, _V)],
    "ik_full_one": [_b1(_V, _M, _V, _f8, _f8, _M), _b1(_V, _MA, _VA, _f8, _f8, _M)],
}
# The batch kernels' callers pass exactly these types (other ones compile on first use).
_BATCH: dict[str, list[Any]] = {
    "fk_batch": [(_M, _V, _M3)],
    "fk_batch_par": [(_M, _V, _M3)],
    "frames_batch": [(_M, _V, _f8[:, :, :, ::1])],
    "jacobian_batch": [(_M, _V, _b1, _M3)],
    "jacobian_one": [(_V, _V, _b1, _M3)],
    "ik_batch": [(_V, _M3, _M, _V, _f8, _b1, _M, _i1[::1], _V)],
    "ik_batch_par": [(_V, _M3, _M, _V, _f8, _b1, _M, _i1[::1], _V)],
    "rigid_batch": [(_M3, _V)],
    "follow_batch": [(_M3, _V, _V, _f8, numba.int64, _M)],
}
_READY: set[str] = set()


def _compile(names: list[str], what: str) -> None:
    """Compile (or load from the cache) the kernels ``names`` for their signatures, with
    a progress bar where that takes long (the first time after installing)."""
    todo = [(name, sig) for name in names if name not in _READY
            for sig in _SINGLE.get(name) or _BATCH[name]]  # fmt: skip
    if not todo:
        return
    what = f"panda_py: compiling {what}, once after installing"
    with progress.work(what, total=len(todo)) as work:
        for name, sig in todo:
            globals()[name].compile(sig)
            work.advance()
    for name in names:
        if name in _SINGLE:
            globals()[name].disable_compile()
        _READY.add(name)


def single(name: str) -> Any:
    """The single-call kernel ``name`` (fk_one, ik_one, ik_full_one), compiled (or
    loaded from the cache) on first use for its signatures only."""
    if name not in _READY:
        _compile([name], name.removesuffix("_one"))
    return globals()[name]


def compile_all() -> None:
    """Compile (or load from the cache) every kernel for the types its callers pass;
    cheap once done. Nothing runs (no thread pool starts)."""
    _compile([*_SINGLE, *_BATCH], "the kinematics")
