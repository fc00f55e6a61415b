"""The control loop's ticks compiled: numba code that runs whole ticks of a built-in law
without returning to Python, as a C++ loop would: wait for the robot's state datagram
(``poll`` on it and on the request channel), take the newest, check the robot still runs
the motion, decode the fields the law reads, read the user's signals from shared memory
(the seqlock), run the law, the joint walls, the torque-rate saturation, the torque limits
and the low-pass filter, encode and send the command, publish the state to shared memory,
append it to the log ring and publish the law's outputs.

It returns to Python (:mod:`panda_py.rt.fastloop`) for whatever Python must do, with the
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

from pathlib import Path

import numpy as np

from panda_py.controllers import laws
from panda_py.fci import PERIOD
from panda_py.jit import cache, libc
from panda_py.motion import online

_FUSED, _KERNELS = laws.fused(), laws.compiled()
_ONLINE = online.compiled_kernels()
if _FUSED is None or _KERNELS is None or _ONLINE is None:  # plain Python: Python ticks
    raise ImportError("the control laws run without numba")
_cartesian_impedance_step = _FUSED.cartesian_impedance_step
_joint_tracking_step = _FUSED.joint_tracking_step
_pose_target_step = _FUSED.pose_target_step
_finalize_torques = _KERNELS.finalize_torques
_sample = _ONLINE.sample

__all__ = [
    "applied_torque_ticks", "cartesian_impedance_ticks", "cartesian_target_ticks",
    "integrated_velocity_ticks", "joint_position_ticks", "joint_target_ticks",
]  # fmt: skip

KEY = cache.source_key([Path(__file__), Path(libc.__file__)]) + _FUSED.KEY[:12]

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
# a streamed target's scalars (controllers.streaming._Streamed.compiled): when the last
# target arrived [s], the timeout [s] (inf: none), 1 if stale; the generator's time in its
# trajectory [s], 1 once it finished, the trajectory's duration [s]; the ticks until the
# tracking's damping update and their period (CartesianTarget); the friction's speed and
# error rate, the offsets of the target among the inputs and of the reference among the
# outputs (JointTarget)
(T_TARGET, T_TIMEOUT, T_STALE, T_GEN_TIME, T_FINISHED, T_DURATION, T_DAMPING_DUE,
 T_DAMPING_TICKS, T_FRICTION_SPEED, T_ERROR_RATE, T_TARGET_AT, T_OUT_AT) = range(12)  # fmt: skip
TARGET_SCALARS = 12
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
def _advance(io, buf, law_t):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's clock to the state in ``buf``: its time and dt [s] in ``law_t`` (the
    robot's clock: message_id counts milliseconds, as libfranka's Duration)."""
    mid = np.int64(buf[:8].view(np.uint64)[0])
    dt = (mid - io[LAST_ID]) / 1000.0
    io[LAST_ID] = mid
    law_t[0] += dt
    law_t[1] = dt


@cache.keyed_jit(KEY, nogil=True)
def _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs, out_values, t,
            tau, q, dq, tau_J_d, walls, scale, flags, fin, tau_max, command):  # type: ignore[no-untyped-def,unused-ignore]  # fmt: skip
    """The law's torques ``tau`` finished (walls, rate, limits, filter: ``fin`` holds the
    rate bound and the filter's gain) into ``command``, sent, the state kept in
    ``answered``, published and logged, the outputs published (time ``t`` first): 0, or
    the status to return with."""
    if not _finalize_torques(tau, q, dq, tau_J_d, walls, scale, flags, fin[0],
                                     tau_max, fin[1], command):  # fmt: skip
        return NONFINITE
    if not _answer(io, lay, buf, cmd, command):
        io[ERRNO] = _errno()
        return SEND_FAILED
    n = io[LENGTH]
    _copy(answered, 0, buf, 0, n)
    io[ANSWERED] = n
    _publish(io, buf, header, states, ring, spans)
    if io[OUT_N] > 0:
        out_values[0] = t
        _outputs(header, outputs, out_values, io[OUT_N])
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d, signals, new,
           values, guard, guard_key):  # type: ignore[no-untyped-def,unused-ignore]  # fmt: skip
    """A tick's beginning: wait for the next state, take and decode it, and read the
    law's inputs ``values`` from ``signals`` (through ``new``) if the user changed them,
    unless the inputs at ``guard``'s spans (offset, length) differ from ``guard_key`` (what
    the law computes from them is Python's to compute: PENDING, the inputs left unread).
    0, or the status to return with."""
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
def _next_time(io, buf, law_t):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's time at the state in ``buf`` (not yet advanced: :func:`_advance`)."""
    mid = np.int64(buf[:8].view(np.uint64)[0])
    return law_t[0] + (mid - io[LAST_ID]) / 1000.0


@cache.keyed_jit(KEY, nogil=True)
def _ema(filtered, target, alpha):  # type: ignore[no-untyped-def,unused-ignore]
    """``controllers.laws.ema``: in place, ``filtered <- alpha target + (1 - alpha)
    filtered`` (at once for alpha >= 1)."""
    if alpha >= 1.0:
        _copy(filtered, 0, target, 0, filtered.size)
    else:
        for i in range(filtered.size):
            filtered[i] += alpha * (target[i] - filtered[i])


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


# Every loop kernel takes the loop's arrays first, in this order (rt.fastloop.FastTicks),
# then the law's (its ``compiled()``); each runs ticks from waiting for the next state until
# a reason to return (io[STATUS]; the ticks run in io[TICKS]). ``q_in``, ``dq_in``,
# ``pose_in``: read-only views of the decoded q, dq, O_T_EE (the fused steps are compiled
# for read-only state arrays); ``values``/``values_in`` likewise the law's inputs.


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def cartesian_impedance_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, values_in, at, filtered, Kd_t, chain, origin, ca, sa, mass, h,
    inertia, J,
):  # fmt: skip
    """``CartesianImpedance`` (``controllers._fused.cartesian_impedance_step``); the
    impedance and the damping ratio are guarded (the damping target ``Kd_t`` is Python's
    to compute)."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0:
            _advance(io, buf, law_t)
            _cartesian_impedance_step(values_in, at, filtered, Kd_t, pose_in, q_in, dq_in,
                                      chain, origin, ca, sa, mass, h, inertia, J,
                                      tau)  # fmt: skip
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def joint_position_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, at, q_d, dq_d, K, D,
):  # fmt: skip
    """``JointPosition``: its inputs (at ``at``: position, velocity, stiffness, damping,
    filter_coeff) filtered into ``q_d``, ``dq_d``, ``K``, ``D``; ``tau = K (q_d - q) +
    D (dq_d - dq)``."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0:
            _advance(io, buf, law_t)
            a = values[at[4]]
            _ema(q_d, values[at[0] : at[0] + 7], a)
            _ema(dq_d, values[at[1] : at[1] + 7], a)
            _ema(K, values[at[2] : at[2] + 7], a)
            _ema(D, values[at[3] : at[3] + 7], a)
            for i in range(7):
                tau[i] = K[i] * (q_d[i] - q[i]) + D[i] * (dq_d[i] - dq[i])
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def integrated_velocity_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, at, q_d, lower, upper,
):  # fmt: skip
    """``IntegratedVelocity``: ``q_d += dt dq_d`` within [``lower``, ``upper``] (published
    at ``at[3]`` of the outputs), ``tau = K (q_d - q) - D dq`` (the inputs at ``at``:
    velocity, stiffness, damping)."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0:
            _advance(io, buf, law_t)
            dt = law_t[1]
            v, k, d, o = at[0], at[1], at[2], at[3]
            for i in range(7):
                x = q_d[i] + dt * values[v + i]
                q_d[i] = min(max(x, lower[i]), upper[i])  # (np.clip's order)
                out_values[o + i] = q_d[i]
                tau[i] = values[k + i] * (q_d[i] - q[i]) - values[d + i] * dq[i]
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def applied_torque_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, at, applied, D,
):  # fmt: skip
    """``AppliedTorque``: its inputs (at ``at``: torque, damping, filter_coeff) filtered
    into ``applied`` and ``D``; ``tau = applied - D dq``."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0:
            _advance(io, buf, law_t)
            a = values[at[2]]
            _ema(applied, values[at[0] : at[0] + 7], a)
            _ema(D, values[at[1] : at[1] + 7], a)
            for i in range(7):
                tau[i] = applied[i] - D[i] * dq[i]
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return


@cache.keyed_jit(KEY, nogil=True)
def _stale_due(io, buf, law_t, s):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether the state in ``buf`` is the one at which a streamed target's timeout passes
    (``_Streamed._pending``: that tick is Python's)."""
    return s[T_STALE] == 0.0 and _next_time(io, buf, law_t) - s[T_TARGET] > s[T_TIMEOUT]


@cache.keyed_jit(KEY, nogil=True)
def _gen_advance(s):  # type: ignore[no-untyped-def,unused-ignore]
    """``OnlineGenerator._advance`` (its input unchanged since ruckig's step, its
    trajectory packed): the time to sample at, or -1 where it finished (it stands)."""
    if s[T_FINISHED] != 0.0:
        return -1.0
    s[T_GEN_TIME] += PERIOD
    s[T_FINISHED] = 1.0 if s[T_GEN_TIME] > s[T_DURATION] else 0.0
    return s[T_GEN_TIME]


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def joint_target_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, s, traj, position, velocity, acceleration, K, D, origin, ca, sa,
    mass, h, inertia, armature, coulomb,
):  # fmt: skip
    """``JointTarget`` between its news (``controllers.streaming``): its generator's
    compiled step (the trajectory ``traj`` ruckig calculated, sampled into ``position``,
    ``velocity``, ``acceleration``), ``_fused.joint_tracking_step`` toward it and its
    outputs. A new target (the count of targets, guarded: the inputs left unread) or the
    timeout passing (``s``: the scalars, ``T_*``) is Python's: PENDING."""
    io[TICKS] = 0
    t_at, o = int(s[T_TARGET_AT]), int(s[T_OUT_AT])
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0 and _stale_due(io, buf, law_t, s):
            status = PENDING
        if status == 0:
            _advance(io, buf, law_t)
            t = _gen_advance(s)
            if t >= 0.0:
                _sample(traj, s[T_DURATION], t, position, velocity, acceleration)
            _joint_tracking_step(q_in, dq_in, origin, ca, sa, mass, h, inertia, armature,
                                 coulomb, K, D, position, velocity, acceleration,
                                 s[T_FRICTION_SPEED], s[T_ERROR_RATE], tau)  # fmt: skip
            lag = 0.0
            for i in range(7):  # (JointTarget._publish)
                out_values[o + i] = position[i]
                out_values[o + 7 + i] = velocity[i]
                out_values[o + 14 + i] = acceleration[i]
                lag = max(lag, abs(values[t_at + i] - position[i]))
            out_values[o + 21] = lag
            out_values[o + 22] = s[T_STALE]
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL)
def cartesian_target_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, lay, pfd, buf, scratch, answered, key, cmd, header, states, ring, spans, outputs,
    signals, new, fin, walls, scale, flags, tau_max, law_t, out_values, tmp, q, dq, pose,
    tau_J_d, q_in, dq_in, pose_in, tau, command,
    values, guard, guard_key, s, step, traj, p, v, a, Ft, Fr, R0, q0, position, orientation,
    twist, accel, law, target, chain, origin, ca, sa, mass, h, inertia, armature, coulomb,
):  # fmt: skip
    """``CartesianTarget`` between its news, as :func:`joint_target_ticks`: one
    ``_fused.pose_target_step`` a tick (its generator's compiled step, the tracking on the
    tracking law's buffer ``law``, the outputs), ``step`` its per-tick scalars (sample,
    duration, time, stale, the outputs' offset: ``CartesianTarget._fused_step``), the
    buffer's scalars set as ``tracking.PoseImpedance.compiled_inputs`` sets them."""
    io[TICKS] = 0
    while True:
        status = _begin(io, lay, pfd, header, buf, scratch, key, tmp, q, dq, pose, tau_J_d,
                        signals, new, values, guard, guard_key)  # fmt: skip
        if status == 0 and _stale_due(io, buf, law_t, s):
            status = PENDING
        if status == 0:
            _advance(io, buf, law_t)
            t = _gen_advance(s)
            if t < 0.0:
                step[0] = 0.0  # the reference stands
            else:
                step[0], step[1], step[2] = 1.0, s[T_DURATION], t
            step[3] = s[T_STALE]
            s[T_DAMPING_DUE] -= 1.0  # (PoseImpedance.compiled_inputs)
            law[0] = law_t[1]
            law[7] = 1.0  # a previous Jacobian: this law has ticked before
            if s[T_DAMPING_DUE] < 0.0:
                law[6] = 1.0
                s[T_DAMPING_DUE] = s[T_DAMPING_TICKS] - 1.0
            else:
                law[6] = 0.0
            _pose_target_step(step, traj, p, v, a, Ft, Fr, R0, q0, position, orientation, twist,
                              accel, pose_in, q_in, dq_in, chain, origin, ca, sa, mass, h,
                              inertia, armature, coulomb, law, target, out_values,
                              tau)  # fmt: skip
            status = _finish(io, lay, buf, answered, cmd, header, states, ring, spans, outputs,
                             out_values, law_t[0], tau, q_in, dq_in, tau_J_d, walls, scale,
                             flags, fin, tau_max, command)  # fmt: skip
        if _ends(io, status):
            return
