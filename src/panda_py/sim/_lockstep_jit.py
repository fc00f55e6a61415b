"""The simulator's lockstep ticks compiled: many ticks of a torque-controlled motion in one
numba call (:func:`lockstep_ticks`), each tick as the server's Python loop runs it (wait
for the command answering the last state on the robot's UDP socket, take it, the robot's
compiled tick :func:`panda_py.sim.compiled.torque_tick` with ``mj_step``, encode the
state, send it), with no Python between ticks.

It returns to Python (:class:`panda_py.sim.lockstep.LockstepTicks`) for whatever Python
must do, with the reason in ``io[STATUS]`` (:class:`Stop`), before it changes anything of
that tick: another descriptor the server watches is ready (a TCP request, a client, the
control connection), no command within the spin and the wait, a datagram that is not the
fresh answer to the last state (the Python reference sorts it out), a command the
compiled tick does not run (one that ends the motion, a robot-side generator's, one more
datagram queued, the Desk's switches or requests), the robot's checks failing (a reflex,
an error: :data:`~panda_py.sim.compiled.Tick.ROBOT`), a tick whose state's fill the
Python reference finishes, the batch's budget of ticks or of wall time.

The C library's ``poll``, ``recvfrom``, ``recv``, ``sendto`` and ``clock_gettime`` are
called as external symbols resolved when the compiled code loads (no address is compiled
in), so the kernel caches on disk as every other (:mod:`panda_py.jit.cache`).
"""

from __future__ import annotations

import enum
import hashlib
from pathlib import Path

import numpy as np

from panda_py.jit import cache, libc
from panda_py.sim import compiled

__all__ = ["Stop", "lockstep_ticks"]

# the compile cache's key: this file, the C library's calls and the robot's compiled tick
_SOURCES = cache.source_key([Path(__file__), Path(libc.__file__)]) + compiled.KEY
KEY = hashlib.sha256(_SOURCES.encode()).hexdigest()[:20]

_torque_tick = compiled.torque_tick
_ROBOT, _DONE = int(compiled.Tick.ROBOT), int(compiled.Tick.DONE)


class Stop(enum.IntEnum):
    """Why :func:`lockstep_ticks` returned (``io[TICKS]`` ticks done before)."""

    BUDGET = 0  # the ticks or the wall time the call had
    WAITING = 1  # no command (yet): the spin and the wait ended, or a call failed
    REQUEST = 2  # another descriptor is ready: nothing of the next tick taken
    DATAGRAM = 3  # a datagram not the fresh answer (``io[SIZE]``, ``io[MID]``): Python's
    COMMAND = 4  # the fresh command, taken (in the scratch): its tick is Python's
    AFTER = 5  # the last tick counted left its state's fill (``io[ROBOT_STATUS]``) and send


_BUDGET, _WAITING, _REQUEST, _DATAGRAM, _COMMAND, _AFTER = (int(s) for s in Stop)

# io: the kernel's integer words (in and out)
(UDP, NFDS, BUDGET, SPIN_NS, WAIT_NS, UNTIL_NS, DEADLINE_NS, LAST_ID, TICK, CMD_SIZE,
 TAU_AT, DQ_AT, MG_DONE_AT, TQ_DONE_AT, STATE_SIZE, RATE_AT, RATE_SIZE, WINDOW, DESK,
 STATUS, TICKS, SIZE, MID, ROBOT_STATUS, ERRNO, HAND_FD, HAND_PERIOD, FINGER_Q,
 FINGER_Q2) = range(29)  # fmt: skip
IO_SIZE = 32
# the hand's state datagram (fci.GRIPPER_STATE_DTYPE): its fields' offsets, and ``hand``'s
# values (float64): its max width [m], a held grasp's width range (NaN: none)
HAND_ID_AT, HAND_WIDTH_AT, HAND_GRASPED_AT = 0, 4, 20
HAND_MAX_WIDTH, HAND_GRASP_LO, HAND_GRASP_HI = 0, 1, 2
# the Desk's shared block (panda_py.sim.desk.link): its switches and move counters
_BRAKES_OPEN, _FCI_ACTIVE, _MOVE_REQUESTED, _MOVE_DONE = 0, 1, 5, 6

_POLLIN = 1
_MSG_PEEK, _MSG_DONTWAIT = 0x2, 0x40
_EAGAIN = 11  # (EWOULDBLOCK on Linux)
_CLOCK_MONOTONIC = 1
_SOCKADDR_IN = 16  # sizeof(struct sockaddr_in)

# the C library's calls, as intrinsics (panda_py.jit.libc)
_poll, _recvfrom, _recv, _sendto = libc.poll, libc.recvfrom, libc.recv, libc.sendto
_clock_gettime, _errno, _copy = libc.clock_gettime, libc.errno, libc.copy


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _now(ts):  # type: ignore[no-untyped-def,unused-ignore]
    """CLOCK_MONOTONIC [ns] (Python's ``time.monotonic``), through ``ts`` (int64 (2,))."""
    _clock_gettime(_CLOCK_MONOTONIC, ts.ctypes.data)
    return ts[0] * 1_000_000_000 + ts[1]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _wait(io, pfd, ts):  # type: ignore[no-untyped-def,unused-ignore]
    """Wait for the robot's UDP socket (``pfd``'s first descriptor) to be readable:
    polling every descriptor until ``io[SPIN_NS]`` has passed, then sleeping in ``poll``
    until the command's deadline or the call's; 0 once it is readable, else the stop."""
    nfds = io[NFDS]
    now = _now(ts)
    spin_end = now + io[SPIN_NS]
    while True:
        if now < spin_end:
            timeout = 0
        else:
            timeout = (min(io[DEADLINE_NS], io[UNTIL_NS]) - now) // 1_000_000
            if timeout <= 0:
                return _WAITING  # (Python's select waits out the rest, to the microsecond)
        for i in range(nfds):
            pfd[2 * i + 1] &= 0xFFFF  # the revents cleared, the events kept
        ready = _poll(pfd.ctypes.data, nfds, timeout)
        if ready < 0:
            io[ERRNO] = _errno()
            return _WAITING  # (EINTR: Python runs its signal handlers)
        if ready > 0:
            for i in range(1, nfds):
                if (pfd[2 * i + 1] >> 16) != 0:
                    return _REQUEST
            if (pfd[1] >> 16) != 0:
                return 0  # (an error on the socket too: the receive meets it)
        now = _now(ts)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _encode(io, sb, runs, state, tmp, rate):  # type: ignore[no-untyped-def,unused-ignore]
    """The state datagram as ``StateWire.fill`` writes it, but for its tail's modes and
    errors (written by Python before the call; no compiled tick changes them): the runs
    of the state buffer ``sb`` (rows of ``runs``: wire offset, float size, buffer start,
    count), the message id ``io[LAST_ID]``, the success ``rate``."""
    raw = tmp.view(np.uint8)
    single = tmp.view(np.float32)
    for r in range(runs.shape[0]):
        at, size, start, count = runs[r, 0], runs[r, 1], runs[r, 2], runs[r, 3]
        if size == 8:
            for i in range(count):
                tmp[i] = sb[start + i]
        else:
            for i in range(count):
                single[i] = np.float32(sb[start + i])
        _copy(state, at, raw, 0, size * count)
    tmp.view(np.uint64)[0] = np.uint64(io[LAST_ID])
    _copy(state, 0, raw, 0, 8)
    at = io[RATE_AT]
    if io[RATE_SIZE] == 4:
        single[0] = np.float32(rate)
        _copy(state, at, raw, 0, 4)
    else:
        tmp[0] = rate
        _copy(state, at, raw, 0, 8)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _send_hand_state(io, tick, qpos, hand, hand_target, hand_state, tmp):  # type: ignore[no-untyped-def,unused-ignore]
    """The hand's state datagram of ``tick`` (GripperSession._send_gripper_state): its
    template ``hand_state`` (max width and temperature written) with the message id, the
    width the hand measures and whether it holds its grasp."""
    fq = io[FINGER_Q]
    opening = qpos[fq] + qpos[io[FINGER_Q2]] if fq >= 0 else 0.0
    width = min(max(opening, 0.0), hand[HAND_MAX_WIDTH])
    raw = tmp.view(np.uint8)
    tmp.view(np.uint32)[0] = np.uint32(tick & 0xFFFFFFFF)
    _copy(hand_state, HAND_ID_AT, raw, 0, 4)
    tmp[0] = width
    _copy(hand_state, HAND_WIDTH_AT, raw, 0, 8)
    grasped = hand[HAND_GRASP_LO] <= width <= hand[HAND_GRASP_HI]  # (False for NaN)
    hand_state[HAND_GRASPED_AT] = 1 if grasped else 0
    _sendto(io[HAND_FD], hand_state.ctypes.data, hand_state.size, 0, hand_target.ctypes.data,
            _SOCKADDR_IN)  # fmt: skip


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL, error_model="numpy")
def lockstep_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    io, pfd, ts, target, source, addrlen, scratch, command, state, sb, runs, tmp, tau,
    desk, qpos, hand, hand_target, hand_state, robot,
):  # fmt: skip
    """Lockstep ticks of a torque-controlled motion until Python must act (the module's
    docstring; the reason in ``io[STATUS]``, the ticks done in ``io[TICKS]``).

    ``io`` (int64, :data:`IO_SIZE`): the words above; ``pfd``: ``struct pollfd`` as int32
    pairs, the robot's UDP socket first, then every other descriptor the server watches;
    ``ts`` (int64 (2,)): a ``struct timespec``; ``target``: the client's ``struct
    sockaddr_in``, ``source`` (uint8 (16,)) and ``addrlen`` (int32 (1,)): the sender's;
    ``scratch``, ``command``, ``state``: the connection's command scratch and command
    buffer (``CommandWire``) and state datagram (``StateWire``), uint8; ``sb``: the
    robot's state buffer; ``runs``: ``_encode``'s; ``tmp``: float64 scratch, as long as
    the longest run; ``tau`` (7,): the command's torques; ``desk``: the Desk's block
    (read only if ``io[DESK]``); ``qpos``: MuJoCo's positions, ``hand``, ``hand_target``
    and ``hand_state``: the hand's values, its client's ``struct sockaddr_in`` and its
    state datagram (sent every ``io[HAND_PERIOD]`` ticks where ``io[HAND_FD]`` is a
    socket, not -1: ``_send_hand_state``); ``robot``: :func:`~panda_py.sim.compiled.torque_tick`'s
    arguments after the torques (``CompiledTick.enter``)."""
    ints = robot[0]
    ticks = 0
    io[TICKS] = 0
    io[ROBOT_STATUS] = _DONE
    udp = io[UDP]
    while True:
        if ticks >= io[BUDGET]:
            io[STATUS] = _BUDGET
            return
        if ticks > 0 and _now(ts) >= io[UNTIL_NS]:
            io[STATUS] = _BUDGET
            return
        # -- the command answering the state last sent (FciSession._read_robot_udp)
        stop = _wait(io, pfd, ts)
        if stop != 0:
            io[STATUS] = stop
            return
        addrlen[0] = _SOCKADDR_IN
        n = _recvfrom(udp, scratch.ctypes.data, scratch.size, _MSG_DONTWAIT,
                      source.ctypes.data, addrlen.ctypes.data)  # fmt: skip
        if n < 0:
            if _errno() == _EAGAIN:
                continue  # (woken for nothing)
            io[STATUS] = _WAITING  # an error (an ICMP's): the reference swallows it too
            return
        mid = -1
        if n == io[CMD_SIZE] and addrlen[0] == _SOCKADDR_IN:
            same = True
            for i in range(8):  # family, port, address (the zeros after it unused)
                if source[i] != target[i]:
                    same = False
            if same:
                raw = tmp.view(np.uint8)
                _copy(raw, 0, scratch, 0, 8)
                mid = np.int64(tmp.view(np.uint64)[0])
        io[SIZE] = n
        io[MID] = mid
        if mid != io[LAST_ID]:
            io[STATUS] = _DATAGRAM
            return
        # -- a command the compiled tick runs (SimServer._compiled_tick), nothing queued
        # behind it (the reference would read that too), the Desk's switches on and no
        # request of it (SimServer._follow_desk does nothing then)
        tq = io[TQ_DONE_AT]
        if scratch[io[MG_DONE_AT]] != 0 or (tq >= 0 and scratch[tq] != 0):
            io[STATUS] = _COMMAND
            return
        raw = tmp.view(np.uint8)
        at = io[DQ_AT]
        _copy(raw, 0, scratch, at, 56)
        for i in range(7):
            if tmp[i] != 0.0:
                io[STATUS] = _COMMAND
                return
        if _recv(udp, tmp.ctypes.data, 1, _MSG_PEEK | _MSG_DONTWAIT) >= 0:
            io[STATUS] = _COMMAND
            return
        if io[DESK] != 0 and (
            desk[_FCI_ACTIVE] == 0.0
            or desk[_BRAKES_OPEN] == 0.0
            or desk[_MOVE_REQUESTED] != desk[_MOVE_DONE]
        ):
            io[STATUS] = _COMMAND
            return
        at = io[TAU_AT]
        _copy(raw, 0, scratch, at, 56)
        for i in range(7):
            tau[i] = tmp[i]
        # -- the tick (CompiledTick.command), then the state (FciSession._send_state)
        status = _torque_tick(tau, *robot)
        if status == _ROBOT:
            io[STATUS] = _COMMAND  # nothing changed: the reference ticks with it
            return
        size = io[CMD_SIZE]
        _copy(command, 0, scratch, 0, size)  # (CommandWire.accept)
        ticks += 1
        io[TICKS] = ticks
        if status != _DONE:
            io[ROBOT_STATUS] = status
            io[STATUS] = _AFTER
            return
        io[LAST_ID] = io[TICK] + ticks + 1
        rate = np.float64(ints[compiled.I_SUCCESS_COUNT]) / np.float64(io[WINDOW])
        _encode(io, sb, runs, state, tmp, rate)
        _sendto(udp, state.ctypes.data, io[STATE_SIZE], 0, target.ctypes.data, _SOCKADDR_IN)
        tick = io[TICK] + ticks
        if io[HAND_FD] >= 0 and tick % io[HAND_PERIOD] == 0:
            _send_hand_state(io, tick, qpos, hand, hand_target, hand_state, tmp)
        io[DEADLINE_NS] = _now(ts) + io[WAIT_NS]
