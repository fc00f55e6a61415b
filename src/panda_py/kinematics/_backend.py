"""Which code runs the kinematics, and the batch entry points on it.

One source (:mod:`._fk`, :mod:`._ik`), two ways to run it: compiled by numba
(:mod:`._numba`, the default wherever numba is installed: a regular dependency on the
platforms it ships wheels for) or as plain Python (no numba, or ``PANDA_PY_NO_JIT=1``).
The choice is made on the first call that needs it, so ``import panda_py.kinematics``
loads no numba; :func:`warmup` makes it, and compiles everything, ahead of time.
"""

from __future__ import annotations

import os
import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import jit as jit_
from panda_py.kinematics import _fk, _follow, _ik

# the compiled kernels (numba), an optional module (panda_py.jit: a test may set its
# entry in jit.LOADED to run a path plain or compiled)
NAME = "panda_py.kinematics._numba"


def load_jit() -> Any:
    """The JIT backend module, or None: imported on first use (importing numba and
    loading the cached kernels takes a few hundred ms; compiling them the first time,
    after installing or upgrading, tens of seconds, see :func:`warmup`)."""
    return jit_.optional(NAME)


def jit() -> Any:
    """The JIT backend module in use, or None (plain Python)."""
    try:
        return jit_.LOADED[NAME]
    except KeyError:
        return load_jit()


def warmup() -> bool:
    """Compile (or load from the disk cache) every kinematics kernel now, so that no call
    compiles later: for a process that must not stall inside its loop (the ``Panda``
    control process, the simulator) before the loop starts. Cheap once done; nothing to
    do on the plain backend. True if the JIT is in use."""
    kernels = jit()
    if kernels is None:
        return False
    kernels.compile_all()
    return True


# Batches of at least this many rows run the JIT kernels on all cores; never on a
# single-core machine. Measured on a 2-core box shared with other busy processes, a
# parallel launch cost a fixed ~7 ms (a thread waiting for its turn on the busy core):
# 10,000 rows took 0.8 us per row in parallel against 0.12 serially, 100,000 rows the
# same either way. So only batches whose serial run takes several ms go parallel.
PARALLEL_MIN_ROWS = 65536 if (os.cpu_count() or 1) > 1 else 2**62
# A pose with a q7 search (``_ik.search_q7``) counts as this many rows [-] toward
# PARALLEL_MIN_ROWS: the ~10 us a whole-range search takes on average against ~0.15 us for
# one solution.
SEARCH_ROW_COST = 64
# One parallel launch at a time (numba's fallback threading layer aborts on concurrent
# launches; a second caller takes the serial kernel instead of waiting), and none in a
# forked child (GNU OpenMP, numba's default layer on Linux, is not fork-safe).
_PAR_LOCK = threading.Lock()
_PAR_PID = os.getpid()


def _run(serial: Any, parallel: Any, n: int, *args: Any) -> None:
    """A JIT batch kernel over n rows (or their cost in rows): the parallel variant where
    it pays and is safe."""
    if n >= PARALLEL_MIN_ROWS and os.getpid() == _PAR_PID and _PAR_LOCK.acquire(blocking=False):
        try:
            parallel(*args)
        finally:
            _PAR_LOCK.release()
    else:
        serial(*args)


# Plain Python gets the packed parameters as lists (indexing a list gives Python floats,
# whose arithmetic is several times faster than NumPy scalars'), and runs the loops on
# NumPy scalars, which warn where floats (and the JIT's
# error_model="numpy") quietly give NaN or infinity.
def _plain_errstate() -> Any:
    return np.errstate(invalid="ignore", over="ignore", divide="ignore")


# The batch entry points: C-contiguous float64 arrays in (the kernels' exact types), out
# filled in place.


def fk(Q: NDArray[np.float64], C: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """O_T_EE (N, 4, 4) of Q (N, 7); C the packed chain (``_fk.pack_chain``)."""
    j = jit()
    if j is None:
        _fk.fk_range(Q, C.tolist(), out, 0, Q.shape[0])
    else:
        _run(j.fk_batch, j.fk_batch_par, Q.shape[0], Q, C, out)


def frames(Q: NDArray[np.float64], C: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """J1..J7, flange, EE (N, 9, 4, 4) of Q (N, 7)."""
    j = jit()
    if j is None:
        _fk.frames_range(Q, C.tolist(), out, 0, Q.shape[0])
    else:
        j.frames_batch(Q, C, out)


def jacobian(
    Q: NDArray[np.float64], C: NDArray[np.float64], body: bool, out: NDArray[np.float64]
) -> None:
    """EE Jacobians (N, 6, 7) of Q (N, 7), in the base or (``body``) the EE frame."""
    j = jit()
    if j is None:
        _fk.jacobian_range(Q, C.tolist(), body, out, 0, Q.shape[0])
    else:
        j.jacobian_batch(Q, C, body, out)


def ik(
    A: NDArray[np.float64],
    T: NDArray[np.float64],
    QI: NDArray[np.float64],
    q7: NDArray[np.float64],
    radius: float,
    full: bool,
    qout: NDArray[np.float64],
    stout: NDArray[np.int8],
    q7out: NDArray[np.float64],
) -> None:
    """``_ik.ik_range`` over all poses of T (N, 4, 4); QI (N or 1, 7), q7 (N or 1,),
    radius [rad] of the q7 search (0: none), qout (4N or N, 7), stout (4N or N,), q7out
    (N,)."""
    j = jit()
    n = T.shape[0]
    if j is None:
        with _plain_errstate():
            _ik.ik_range(A.tolist(), T, QI, q7, radius, full, qout, stout, q7out, 0, n)
    else:
        # A search costs tens of solutions per pose: it pays to go parallel from fewer rows.
        work = n * SEARCH_ROW_COST if radius > 0.0 else n
        _run(j.ik_batch, j.ik_batch_par, work, A, T, QI, q7, radius, full, qout, stout, q7out)


def follow(
    P: NDArray[np.float64],
    C: NDArray[np.float64],
    q0: NDArray[np.float64],
    damping: float,
    iterations: int,
    out: NDArray[np.float64],
) -> None:
    """``_follow.follow_path``: from q0 (7,) along the poses of P (N, 4, 4) into out (N, 7)."""
    j = jit()
    if j is None:
        with _plain_errstate():
            _follow.follow_path(P, C.tolist(), q0, damping, iterations, out)
    else:
        j.follow_batch(P, C, q0, float(damping), int(iterations), out)


def rigid_errors(T: NDArray[np.float64]) -> NDArray[np.float64]:
    """``_ik.rigid_error`` of each pose of T (N, 4, 4) (C-contiguous float64)."""
    err = np.empty(T.shape[0])
    j = jit()
    if j is None:
        with _plain_errstate():
            _ik.rigid_range(T, err, 0, T.shape[0])
    else:
        j.rigid_batch(T, err)
    return err
