"""The control loop's ticks compiled, their one skeleton: numba code that runs whole ticks
of a built-in law without returning to Python, as a C++ loop would: wait for the robot's
state datagram
(``poll`` on it and on the request channel), take the newest, check the robot still runs
the motion, decode the fields the law reads, read the user's signals from shared memory
(the seqlock), run the law, the joint walls, the torque-rate saturation, the torque limits
and the low-pass filter, encode and send the command, publish the state to shared memory,
append it to the log ring and publish the law's outputs. Each law's part of the tick is
its own (:func:`loop_kernel` makes its kernel on this skeleton): the controllers' and the
streamed targets' in :mod:`panda_py.rt._tick_laws`, the force laws' in
:mod:`panda_py.rt._tick_wrench`, the moves' in :mod:`panda_py.rt._tick_moves`.

A kernel returns to Python (:mod:`panda_py.rt.fastloop`) for whatever Python must do, with the
reason in ``io[STATUS]``:

* ``REQUEST``: a request came on the channel (or was counted) while waiting for a state;
* ``BUDGET``: it ran its budget of ticks (the loop's periodic checks are Python's);
* ``TIMEOUT``: no state within the wait (Python's receive waits on, and times out);
* ``PENDING``: a state arrived that Python must answer (the robot left the motion, the
  end effector or the load changed, the inputs changed what only Python computes); it
  is in ``buf``, unanswered;
* ``NONFINITE``: the law's torques (in ``tau``) were not finite; nothing was sent;
* ``SEND_FAILED``, ``RECEIVE_FAILED``: a system call failed (Python's own call of it
  reports the error, or succeeds on the retry).

The C library's ``poll``, ``recvmmsg`` and ``send`` are called as external symbols that the
dynamic linker resolves when the compiled code loads (no address is compiled in), so the
code is cached on disk as every other kernel (:mod:`panda_py.jit.cache`). The memory
fences of the shared memory's seqlock and latches are LLVM fences (``seq_cst``: a compiler
and a hardware barrier on every machine).

The state's fields arrive as the protocol lays them out (float64 or float32, at byte
offsets of the state datagram: ``lay``, built from the FCI dialect by
:func:`panda_py.libfranka.ActiveControl.torque_io`); each is decoded into float64 as
:class:`~panda_py.libfranka.state.TickState` decodes it.
"""

from __future__ import annotations

import sys
import types
from pathlib import Path
from typing import Any

import numpy as np

from panda_py.controllers import laws
from panda_py.jit import cache, libc

_FUSED, _KERNELS = laws.fused(), laws.compiled()
if _FUSED is None or _KERNELS is None:  # plain Python: Python ticks
    raise ImportError("the control laws run without numba")
_finalize_torques = _KERNELS.finalize_torques

__all__ = ["advance", "decode_field", "loop_kernel", "next_time"]

KEY = cache.source_key([Path(__file__), Path(libc.__file__)]) + _FUSED.KEY[:12]

# the skeleton's arguments: (taking, answering, view, law). ``view`` is what a law's tick
# reads and writes (loop_kernel), in this order: the io words, the state datagram, its layout
# (``lay``), an aligned decoding scratch, the law's time and last dt [s], the decoded q,
# dq, O_T_EE (read-only: the fused steps are compiled for read-only state arrays), the
# law's inputs (and the guard on them that _begin checks, with its key), its outputs (the
# time first), and the torques it computes
IO, BUF, LAY, TMP, LAW_T, Q, DQ, POSE, VALUES, GUARD, GUARD_KEY, OUT_VALUES, TAU = range(13)
# ``taking`` and ``answering``: the loop's own arrays, which no law reads, what taking a
# state needs (_begin) and what answering it needs (_finish); rt.fastloop.FastTicks builds
# them (once) and the view (each run). A kernel takes the arrays of the four one after the
# other (loop_kernel): its arguments up to TAKING are taking's, then up to ANSWERING
# answering's, then up to VIEWED the view's, the rest the law's
TAKING = 10
ANSWERING = TAKING + 14
VIEWED = ANSWERING + 13

# io: the kernel's integer words (in and out)
UDP, CHAN, LAST_ID, MG, CTRL, MOVE, TAKEN, BUDGET, LOGGING, SLOTS, RECORD = range(11)
WAIT_MS, LENGTH, STATUS, TICKS, IN_SEQ, ANSWERED, STATE_MAX, OUT_N, ERRNO = range(11, 20)
# (io[ANSWERED]: the length of the last state answered, kept in ``answered``)
IO_SIZE = 24
# io[STATUS]
REQUEST, BUDGET_DONE, TIMEOUT, PENDING, NONFINITE, SEND_FAILED, RECEIVE_FAILED = range(1, 8)
# lay: byte offsets (and element sizes) in the state datagram and the command
# (tau_J: decoded by the kernels of the laws that read it, rt._tick_wrench)
(L_MG, L_CTRL, L_MODE, L_Q, L_Q_SIZE, L_DQ, L_DQ_SIZE, L_POSE, L_POSE_SIZE, L_TAU_D,
 L_TAU_D_SIZE, L_TAU_J, L_TAU_J_SIZE, L_CMD_TAU, L_KEY_SPANS) = range(15)  # fmt: skip
LAY_SIZE = L_KEY_SPANS + 2 * 8  # up to eight spans (offset, length) of the model's key
# the shared block's header words (panda_py.rt.shm.HEADER)
H_STATE_SEQ, H_STATE_LEN, H_TICKS, H_OUT_SEQ, H_LOG_COUNT, H_REQUESTS = 0, 1, 2, 6, 7, 8
H_IN_SEQ = 5
POLLIN = 1
MSG_DONTWAIT = 0x40
# datagrams a receive takes at most (recvmmsg), and the sizes of Linux's struct mmsghdr and
# struct iovec on 64-bit machines [bytes]: the scratch buffer holds RECV_BATCH states and
# their headers (SCRATCH_PER_STATE bytes for each state's STATE_MAX)
RECV_BATCH = 4
MMSG_BYTES, IOVEC_BYTES = 64, 16
SCRATCH_PER_STATE = MMSG_BYTES + IOVEC_BYTES

# the C library's calls and the fence, as intrinsics (panda_py.jit.libc)
_send, _recvmmsg, _poll = libc.send, libc.recvmmsg, libc.poll
_errno, _fence, _copy = libc.errno, libc.fence, libc.copy


@cache.keyed_jit(KEY, nogil=True)
def _decode(buf, offset, size, count, tmp, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``count`` floats of ``size`` bytes each at ``offset`` of ``buf`` into ``out``
    (float64), through the aligned scratch ``tmp``."""
    raw = tmp.view(np.uint8)
    _copy(raw, 0, buf, offset, size * count)
    if size == 8:
        _copy(out, 0, tmp, 0, count)
    else:
        small = tmp.view(np.float32)
        for i in range(count):
            out[i] = np.float64(small[i])


@cache.keyed_jit(KEY, nogil=True)
def _receive_newest(io, buf, scratch):  # type: ignore[no-untyped-def,unused-ignore]
    """Every datagram queued on the robot's socket, the newest one (by message_id) newer
    than ``io[LAST_ID]`` kept in ``buf`` (its length in ``io[LENGTH]``); its id, or 0 if
    none was newer, or -1 if a receive failed.

    Up to RECV_BATCH datagrams a ``recvmmsg`` call (into ``scratch``: RECV_BATCH slots of
    ``io[STATE_MAX]`` bytes, then their ``struct mmsghdr`` and ``struct iovec``, filled
    here): one system call takes the state and finds the queue empty where ``recv`` took
    two (the second answering EAGAIN; a system call costs 1-2 us on the VMs here)."""
    best = 0
    limit = io[STATE_MAX]
    base = scratch.ctypes.data
    at = RECV_BATCH * limit  # the headers (8 words each), then the iovecs (2 words each)
    words = scratch[at : at + RECV_BATCH * (MMSG_BYTES + IOVEC_BYTES)].view(np.uint64)
    for k in range(RECV_BATCH):
        for w in range(8):
            words[8 * k + w] = 0
        iov = 8 * RECV_BATCH + 2 * k
        words[8 * k + 2] = base + at + 8 * iov  # msg_iov
        words[8 * k + 3] = 1  # msg_iovlen
        words[iov] = base + k * limit  # iov_base
        words[iov + 1] = limit  # iov_len
    first = True
    while True:
        got = _recvmmsg(io[UDP], base + at, RECV_BATCH, MSG_DONTWAIT)
        if got < 0:  # none queued (EAGAIN), or an error, which Python's receive reports
            return -1 if first else best  # (called once poll said one is there)
        first = False
        for k in range(got):
            n = np.int64(words[8 * k + 7] & 0xFFFFFFFF)  # msg_len
            if n < 8:
                continue
            slot = scratch[k * limit : k * limit + n]
            mid = np.int64(slot[:8].view(np.uint64)[0])
            if mid > io[LAST_ID] and mid > best:
                best = mid
                _copy(buf, 0, slot, 0, n)
                io[LENGTH] = n
        if got < RECV_BATCH:  # the queue is empty
            return best


@cache.keyed_jit(KEY, nogil=True)
def _wait(io, pfd, header):  # type: ignore[no-untyped-def,unused-ignore]
    """Wait for the robot's next state or a request: 0 when a state is readable (a state
    goes first, as in the loop's Python wait: a request is taken in the gap after it),
    else the status to return with."""
    pfd[1] = POLLIN
    pfd[3] = POLLIN
    ready = _poll(pfd.ctypes.data, 2, io[WAIT_MS])
    if ready < 0:
        io[ERRNO] = _errno()
        return RECEIVE_FAILED  # (EINTR: Python runs its signal handlers, then goes on)
    if (pfd[1] >> 16) != 0:
        return 0  # (an error on the socket too: the receive reports it)
    if (pfd[3] >> 16) != 0 or header[H_REQUESTS] > io[TAKEN]:
        return REQUEST
    return TIMEOUT


@cache.keyed_jit(KEY, nogil=True)
def _unchanged(lay, buf, key):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether the state's bytes at the key's spans equal ``key`` (the end effector and
    the load the model's arrays were made for). The bytes' differences OR-ed without an
    early exit: a loop the compiler vectorises (the spans are some 360 bytes, compared
    every tick, and almost always equal)."""
    k = 0
    diff = np.uint8(0)
    for s in range(8):
        offset, length = lay[L_KEY_SPANS + 2 * s], lay[L_KEY_SPANS + 2 * s + 1]
        for i in range(length):
            diff |= buf[offset + i] ^ key[k + i]
        k += length
    return diff == 0


@cache.keyed_jit(KEY, nogil=True)
def _answer(io, lay, buf, cmd, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """The command for the state in ``buf`` (its message_id, the torques ``tau``) sent."""
    _copy(cmd, 0, buf, 0, 8)
    _copy(cmd, lay[L_CMD_TAU], tau.view(np.uint8), 0, 56)
    n = _send(io[UDP], cmd.ctypes.data, cmd.size, 0)
    return n == cmd.size


@cache.keyed_jit(KEY, nogil=True)
def _publish(io, buf, header, states, ring, spans):  # type: ignore[no-untyped-def,unused-ignore]
    """The state in ``buf`` into the shared block's latch (two copies) and, if logging,
    one record of the log ring (``rt.shm.SharedBlock.publish_state``, ``LogRing.append``)."""
    n = io[LENGTH]
    half = io[STATE_MAX]
    header[H_STATE_SEQ] += 1
    _fence()
    _copy(states, 0, buf, 0, n)
    header[H_STATE_LEN] = n
    _fence()
    header[H_STATE_SEQ] += 1
    _fence()
    _copy(states, half, buf, 0, n)
    _fence()
    header[H_TICKS] += 1
    if io[LOGGING] != 0:
        count = header[H_LOG_COUNT]
        base = (count % io[SLOTS]) * io[RECORD]
        for s in range(spans.shape[0]):
            src, dst, length = spans[s, 0], spans[s, 1], spans[s, 2]
            _copy(ring, base + dst, buf, src, length)
        _fence()
        header[H_LOG_COUNT] = count + 1


@cache.keyed_jit(KEY, nogil=True)
def _outputs(header, outputs, values, n):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's outputs into the shared block's latch (``SharedBlock.write_outputs``)."""
    header[H_OUT_SEQ] += 1
    _fence()
    _copy(outputs[0], 0, values, 0, n)
    _fence()
    header[H_OUT_SEQ] += 1
    _fence()
    _copy(outputs[1], 0, values, 0, n)


@cache.keyed_jit(KEY, nogil=True)
def _signals(io, header, signals, scratch, n):  # type: ignore[no-untyped-def,unused-ignore]
    """The user's inputs, if they changed since ``io[IN_SEQ]`` and are consistent, into
    ``scratch`` (``SharedBlock.read_signals``); their sequence number, or -1 if the copy
    was skipped or torn (the law keeps its inputs)."""
    seq = header[H_IN_SEQ]
    if seq == io[IN_SEQ] or seq & 1:
        return -1
    _fence()
    _copy(scratch, 0, signals, 0, n)
    _fence()
    if header[H_IN_SEQ] != seq:
        return -1
    return seq


@cache.keyed_jit(KEY, nogil=True)
def _take_state(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d):  # type: ignore[no-untyped-def,unused-ignore]
    """The next state taken and decoded: 0, or the status to return with (the state in
    ``buf`` is then left unanswered where it is PENDING)."""
    while True:
        mid = _receive_newest(io, buf, scratch)
        if mid < 0:
            return RECEIVE_FAILED
        if mid > 0:
            break
        status = _wait(io, pfd, header)  # nothing newer (a stray datagram): wait again
        if status != 0:
            return status
    if (
        buf[lay[L_MODE]] != io[MOVE]
        or buf[lay[L_MG]] != io[MG]
        or buf[lay[L_CTRL]] != io[CTRL]
        or not _unchanged(lay, buf, key)
    ):
        return PENDING
    _decode(buf, lay[L_Q], lay[L_Q_SIZE], 7, tmp, q)
    _decode(buf, lay[L_DQ], lay[L_DQ_SIZE], 7, tmp, dq)
    _decode(buf, lay[L_POSE], lay[L_POSE_SIZE], 16, tmp, pose)
    _decode(buf, lay[L_TAU_D], lay[L_TAU_D_SIZE], 7, tmp, tau_J_d)
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _begin(taking, view):  # type: ignore[no-untyped-def,unused-ignore]
    """A tick's beginning: wait for the next state, take and decode it, and read the
    law's inputs ``view[VALUES]`` from the shared block's signals (through ``new``) if the
    user changed them, unless the inputs at ``guard``'s spans (offset, length) differ from
    ``guard_key`` (what the law computes from them is Python's to compute: PENDING, the
    inputs left unread). 0, or the status to return with."""
    pfd, scratch, key, header, signals, new, q, dq, pose, tau_J_d = taking
    io, buf, lay, tmp, values = view[IO], view[BUF], view[LAY], view[TMP], view[VALUES]
    guard, guard_key = view[GUARD], view[GUARD_KEY]
    status = _wait(io, pfd, header)
    if status == 0:
        status = _take_state(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose,
                             tau_J_d)  # fmt: skip
    n = values.size
    if status != 0 or n == 0:
        return status
    seq = _signals(io, header, signals, new, n)
    if seq < 0:
        return 0
    k = 0
    for g in range(guard.shape[0]):
        for i in range(guard[g, 1]):
            if new[guard[g, 0] + i] != guard_key[k]:
                return PENDING
            k += 1
    _copy(values, 0, new, 0, n)
    io[IN_SEQ] = seq
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _finish(answering, view):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's torques ``view[TAU]`` finished (walls, rate, limits, filter: ``fin``
    holds the rate bound and the filter's gain) into ``command``, sent, the state kept in
    ``answered``, published and logged, the outputs published (the law's time first): 0,
    or the status to return with."""
    (answered, cmd, header, states, ring, spans, outputs, fin, walls, scale, flags, tau_max,
     tau_J_d, command) = answering  # fmt: skip
    io, buf, lay, tau, out_values = view[IO], view[BUF], view[LAY], view[TAU], view[OUT_VALUES]
    q, dq = view[Q], view[DQ]
    if not _finalize_torques(tau, q, dq, tau_J_d, walls, scale, flags, fin[0], tau_max,
                             fin[1], command):  # fmt: skip
        return NONFINITE
    if not _answer(io, lay, buf, cmd, command):
        io[ERRNO] = _errno()
        return SEND_FAILED
    n = io[LENGTH]
    _copy(answered, 0, buf, 0, n)
    io[ANSWERED] = n
    _publish(io, buf, header, states, ring, spans)
    if io[OUT_N] > 0:
        out_values[0] = view[LAW_T][0]
        _outputs(header, outputs, out_values, io[OUT_N])
    return 0


@cache.keyed_jit(KEY, nogil=True)
def advance(view):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's clock to the state in ``view[BUF]``: its time and dt [s] in
    ``view[LAW_T]`` (the robot's clock: message_id counts milliseconds, as libfranka's
    Duration)."""
    io, law_t = view[IO], view[LAW_T]
    mid = np.int64(view[BUF][:8].view(np.uint64)[0])
    dt = (mid - io[LAST_ID]) / 1000.0
    io[LAST_ID] = mid
    law_t[0] += dt
    law_t[1] = dt


@cache.keyed_jit(KEY, nogil=True)
def decode_field(view, at, count, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``count`` floats of the state field at ``lay[at]`` (its offset, then its element
    size: an ``L_*`` pair) of the state in ``view[BUF]`` into ``out`` (float64), for a law
    that reads a field the skeleton does not decode."""
    lay = view[LAY]
    _decode(view[BUF], lay[at], lay[at + 1], count, view[TMP], out)


@cache.keyed_jit(KEY, nogil=True)
def next_time(view):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's time at the state in ``view[BUF]`` (not yet advanced: :func:`advance`)."""
    mid = np.int64(view[BUF][:8].view(np.uint64)[0])
    return view[LAW_T][0] + (mid - view[IO][LAST_ID]) / 1000.0


@cache.keyed_jit(KEY, nogil=True)
def _ends(io, status):  # type: ignore[no-untyped-def,unused-ignore]
    """A loop kernel's tick done with ``status`` (0: it ran and was answered): counted
    against the budget; True where the kernel returns, the reason in ``io[STATUS]``."""
    if status == 0:
        io[TICKS] += 1
        if io[TICKS] >= io[BUDGET]:
            status = BUDGET_DONE
    if status != 0:
        io[STATUS] = status
        return True
    return False


#: the law's tick that a kernel's skeleton calls: each kernel's own global (loop_kernel)
_law_tick: Any


def _skeleton(taking, answering, view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """Ticks from waiting for the next state until a reason to return (``io[STATUS]``;
    the ticks run in ``io[TICKS]``): each tick begun (:func:`_begin`), the law's
    ``_law_tick`` run on it (a global of each kernel made by :func:`loop_kernel`), its
    torques finished and sent (:func:`_finish`)."""
    io = view[IO]
    io[TICKS] = 0
    while True:
        status = _begin(taking, view)
        if status == 0:
            status = _law_tick(view, law)  # noqa: F821  (declared above, set per kernel)
        if status == 0:
            status = _finish(answering, view)
        if _ends(io, status):
            return


def loop_kernel(law_tick: Any, name: str, arity: int) -> Any:
    """The loop kernel ``name`` of a law whose tick is ``law_tick``, on ``arity`` arrays of
    its own: :func:`_skeleton` with ``law_tick`` as its ``_law_tick``, compiled without
    reference counting (``jit.libc.LOOP_KERNEL``) and cached under the key of
    ``law_tick``'s module (its ``KEY``, which covers this one's).

    ``law_tick(view, law)`` runs one tick of the law on a state taken and decoded, and
    returns 0 with its torques in ``view[TAU]`` (its clock advanced: :func:`advance`), or
    PENDING with nothing changed where the state is Python's to answer. ``view`` is what a
    law reads and writes (``IO`` ... ``TAU``: the io words, the state datagram and its
    layout, a decoding scratch, the law's time and dt, the decoded q, dq, O_T_EE as
    read-only arrays, the law's inputs, their guard, its outputs, the torques), ``law`` the
    law's own arrays (``CompiledTicks.arrays`` past the inputs and their guard).

    The kernel takes every array as an argument of its own, the loop's, the view's and
    the law's one after the other, and packs them into the skeleton's four tuples (numba
    calls a function of 60 arrays a microsecond sooner than one of the same arrays in
    tuples). The skeleton is made a kernel's own from its code with the law's tick as a
    global, not as a closure: numba caches no closure on disk."""
    module = sys.modules[law_tick.__module__]
    jit = cache.keyed_jit(module.KEY, **libc.LOOP_KERNEL)
    body = types.FunctionType(_skeleton.__code__, {**globals(), "_law_tick": law_tick})
    body.__qualname__, body.__module__ = f"{name}_skeleton", module.__name__
    names = [f"a{i}" for i in range(VIEWED + arity)]
    groups = (names[:TAKING], names[TAKING:ANSWERING], names[ANSWERING:VIEWED], names[VIEWED:])
    packed = ", ".join("(" + "".join(f"{n}, " for n in group) + ")" for group in groups)
    scope = {"_skeleton": jit(body)}
    # (generated, as dataclasses and namedtuple generate theirs: the argument list)
    exec(f"def {name}({', '.join(names)}):\n    _skeleton({packed})\n", scope)
    kernel = scope[name]
    kernel.__qualname__, kernel.__module__, kernel.__doc__ = name, module.__name__, law_tick.__doc__
    return jit(kernel)
