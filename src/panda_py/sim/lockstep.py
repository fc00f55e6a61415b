"""Lockstep ticks at compiled speed: the server's loop hands a torque-controlled motion's
ticks to one numba call (:func:`panda_py.sim._lockstep_jit.lockstep_ticks`) that waits for
each command, runs the robot's compiled tick and sends the state, and takes the motion
back in the state its Python reference would have left it in (the robot's counters, the
statistics, the connection's last state) wherever the kernel stops: a request, a datagram
or a command it leaves to the reference, a tick whose fill or send is Python's, its budget.

:class:`LockstepTicks` is bound to one server's robot and its :class:`CompiledTick`;
:meth:`~LockstepTicks.run` prepares one call (the descriptors the server watches, the
connection's buffers and address, the budget) and returns what the server's loop needs.
Built only where the robot's tick runs compiled (numba, ``PANDA_PY_NO_JIT`` unset).
"""

from __future__ import annotations

import math
import selectors
import socket
import struct
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.sim.connections import GripperConnection, RobotConnection
from panda_py.sim.desk.link import SIZE as DESK_SIZE
from panda_py.sim.fast_tick import CompiledTick
from panda_py.sim.gripper import GripperCore
from panda_py.sim.wire import CommandWire, StateWire

__all__ = ["LockstepTicks", "Ran"]

_POLLIN, _POLLOUT = 0x1, 0x4


class Ran:
    """What one call did: ``ticks`` it completed (the last one's fill and send left to
    Python where ``after``), ``deadline`` the command's lockstep deadline [s, monotonic]
    after its last tick, and what Python takes over: ``stop`` (a
    :class:`~panda_py.sim._lockstep_jit.Stop`), ``size`` and ``mid`` of a datagram it
    received and left."""

    __slots__ = ("after", "deadline", "mid", "size", "stop", "ticks")

    def __init__(self, stop: int, ticks: int, after: int, deadline: float, size: int,
                 mid: int) -> None:  # fmt: skip
        self.stop, self.ticks, self.after = stop, ticks, after
        self.deadline, self.size, self.mid = deadline, size, mid


def _sockaddr(address: tuple[str, int]) -> np.ndarray:
    """``address`` (an IPv4 address, a port) as a ``struct sockaddr_in``."""
    host, port = address
    return np.frombuffer(
        struct.pack("<H", socket.AF_INET) + struct.pack(">H", port) + socket.inet_aton(host)
        + bytes(8), dtype=np.uint8,
    ).copy()  # fmt: skip


class _Wires:
    """One connection's buffers and addresses as the kernel takes them."""

    def __init__(self, k: Any, conn: RobotConnection) -> None:
        state, command = conn.state_wire, conn.command_wire
        assert state is not None and command is not None and conn.udp_target is not None
        self.state_wire: StateWire = state
        self.command_wire: CommandWire = command
        scratch, buffer, offsets = command.kernel_layout()
        self.scratch = np.frombuffer(scratch, dtype=np.uint8)
        self.command = np.frombuffer(buffer, dtype=np.uint8)
        self.offsets = offsets  # tau_J_d, dq_c, the two finished flags (-1: none)
        runs, self.rate_at, self.rate_size = state.kernel_layout()
        self.runs = np.array(runs, dtype=np.int64).reshape(-1, 4)
        self.state = np.frombuffer(state.buffer, dtype=np.uint8)
        self.target = _sockaddr(conn.udp_target)
        self.longest = int(self.runs[:, 3].max()) if len(self.runs) else 1


class LockstepTicks:
    """The compiled lockstep ticks of one server's robot (its :class:`CompiledTick`)."""

    def __init__(self, fast: CompiledTick, state_floats: int) -> None:
        from panda_py.sim import _lockstep_jit

        self._k = _lockstep_jit
        self.stops = _lockstep_jit.Stop
        self._fast = fast
        self.io = np.zeros(_lockstep_jit.IO_SIZE, dtype=np.int64)
        self._ts = np.zeros(2, dtype=np.int64)
        self._source = np.zeros(16, dtype=np.uint8)
        self._addrlen = np.zeros(1, dtype=np.int32)
        self._tau = np.zeros(7)
        self._tmp = np.zeros(max(state_floats, 16))
        self._no_desk = np.zeros(DESK_SIZE)
        self._pfd = np.zeros(2, dtype=np.int32)
        ph = fast.physics
        self._qpos = ph.data.qpos
        self._fingers = (ph.finger_q, ph.finger_q2)
        self._hand = np.zeros(3)
        self._hand_target = np.zeros(16, dtype=np.uint8)
        self._hand_to: tuple[str, int] | None = None
        self._hand_state = np.zeros(fci.GRIPPER_STATE_DTYPE.itemsize, dtype=np.uint8)
        offsets = [fci.GRIPPER_STATE_DTYPE.fields[n][1]  # type: ignore[index]
                   for n in ("message_id", "width", "is_grasped")]  # fmt: skip
        if offsets != [_lockstep_jit.HAND_ID_AT, _lockstep_jit.HAND_WIDTH_AT,
                       _lockstep_jit.HAND_GRASPED_AT]:  # fmt: skip
            raise ImportError("the hand's state is not laid out as the kernel writes it")
        self._wires: _Wires | None = None
        self._entry: Any = None
        self.ticks_run = 0  # ticks the kernel ran, in all (diagnostics, tests)

    def _call(self, *args: Any) -> None:
        """The kernel, by its compiled entry point once it has one (the dispatcher's type
        checks of the robot's arguments cost more than several ticks)."""
        entry = self._entry
        if entry is None:
            kernel = self._k.lockstep_ticks
            kernel(*args)
            if len(kernel.signatures) == 1:
                self._entry = kernel.overloads[kernel.signatures[0]].entry_point
            return
        entry(*args)

    def warm(self, hand: GripperCore | None) -> None:
        """Compile (or load) the kernel now, not at a motion's first tick: one call with
        no tick in its budget (it returns at once)."""
        io, k = self.io, self._k
        io[:] = 0
        io[k.BUDGET] = 0
        buf = np.zeros(16, dtype=np.uint8)
        args = self._fast.warm_arguments(hand)
        self._call(io, self._pfd, self._ts, buf, self._source, self._addrlen, buf.copy(),
                   buf.copy(), buf.copy(), self._tmp, np.zeros((0, 4), dtype=np.int64),
                   self._tmp, self._tau, self._no_desk, self._qpos, self._hand,
                   self._hand_target, self._hand_state, args)  # fmt: skip
        if io[k.STATUS] != k.Stop.BUDGET or io[k.TICKS] != 0:
            raise RuntimeError(f"the lockstep kernel's warm-up ran a tick ({io[k.STATUS]})")

    def run(
        self, conn: RobotConnection, args: tuple[Any, ...], sel: selectors.BaseSelector, *,
        tick_count: int, budget: int, spin: float, wait: float, deadline: float,
        until: float, desk: np.ndarray | None, hand: GripperCore | None,
        hand_client: GripperConnection | None, hand_period: int,
    ) -> Ran:  # fmt: skip
        """Run up to ``budget`` lockstep ticks on ``conn`` (its last state sent, its
        command awaited until ``deadline``, each next one ``wait`` [s] after its state)
        with the robot's compiled tick on ``args`` (``CompiledTick.enter``), spinning
        ``spin`` [s] for each command before sleeping on it, until the wall clock's
        ``until`` [s, monotonic]; every descriptor ``sel`` watches but the robot's UDP
        socket ends the call when ready. The hand's state goes to ``hand_client`` (None:
        no client) every ``hand_period`` ticks."""
        k, io = self._k, self.io
        w = self._wires
        if w is None or w.state_wire is not conn.state_wire:
            w = self._wires = _Wires(k, conn)
            if w.longest > self._tmp.size:
                self._tmp = np.zeros(w.longest)
        assert conn.udp is not None
        udp = conn.udp.fileno()
        watched = [(udp, _POLLIN)]
        for key in sel.get_map().values():
            if key.fd != udp:
                events = (_POLLIN if key.events & selectors.EVENT_READ else 0) | (
                    _POLLOUT if key.events & selectors.EVENT_WRITE else 0
                )
                watched.append((key.fd, events))
        if self._pfd.size != 2 * len(watched):
            self._pfd = np.zeros(2 * len(watched), dtype=np.int32)
        self._pfd[:] = np.array(watched, dtype=np.int32).reshape(-1)
        # the tail's modes and errors as the reference writes them (the kernel writes the
        # rest; no compiled tick changes these)
        w.state_wire.fill(conn.last_sent_id, 0.0)
        tau_at, dq_at, mg_done_at, tq_done_at = w.offsets
        io[:] = 0
        io[k.UDP], io[k.NFDS], io[k.BUDGET] = udp, len(watched), budget
        io[k.SPIN_NS], io[k.WAIT_NS] = int(spin * 1e9), int(wait * 1e9)
        io[k.UNTIL_NS], io[k.DEADLINE_NS] = int(until * 1e9), int(deadline * 1e9)
        io[k.LAST_ID], io[k.TICK] = conn.last_sent_id, tick_count
        io[k.CMD_SIZE] = w.command_wire.size
        io[k.TAU_AT], io[k.DQ_AT], io[k.MG_DONE_AT], io[k.TQ_DONE_AT] = (
            tau_at, dq_at, mg_done_at, tq_done_at,
        )  # fmt: skip
        io[k.STATE_SIZE], io[k.RATE_AT], io[k.RATE_SIZE] = w.state.size, w.rate_at, w.rate_size
        io[k.WINDOW] = self._fast.success_window
        io[k.DESK] = desk is not None
        io[k.HAND_FD] = -1
        if hand is not None and hand_client is not None:
            udp_hand, to = hand_client.udp, hand_client.udp_target
            if udp_hand is not None and to is not None:
                self._hand_values(hand, to)
                io[k.HAND_FD], io[k.HAND_PERIOD] = udp_hand.fileno(), hand_period
                io[k.FINGER_Q], io[k.FINGER_Q2] = self._fingers
        self._call(io, self._pfd, self._ts, w.target, self._source, self._addrlen, w.scratch,
                   w.command, w.state, self._fast.state_buffer, w.runs, self._tmp, self._tau,
                   self._no_desk if desk is None else desk, self._qpos, self._hand,
                   self._hand_target, self._hand_state, args)  # fmt: skip
        ticks = int(io[k.TICKS])
        self.ticks_run += ticks
        stop = int(io[k.STATUS])
        return Ran(stop, ticks, int(io[k.ROBOT_STATUS]) if stop == k.Stop.AFTER else 0,
                   io[k.DEADLINE_NS] / 1e9, int(io[k.SIZE]), int(io[k.MID]))  # fmt: skip

    def _hand_values(self, hand: GripperCore, to: tuple[str, int]) -> None:
        """The hand's state datagram's template and values as
        ``GripperSession._send_gripper_state`` writes them, and its client's address."""
        if to != self._hand_to:
            self._hand_target[:] = _sockaddr(to)
            self._hand_to = to
        rec = np.zeros((), fci.GRIPPER_STATE_DTYPE)
        rec["max_width"] = hand.max_width
        rec["temperature"] = hand.temperature
        self._hand_state[:] = np.frombuffer(rec.tobytes(), dtype=np.uint8)
        g = hand.grasp
        self._hand[:] = (hand.max_width, math.nan, math.nan) if g is None else (
            hand.max_width, g.width - g.eps_in, g.width + g.eps_out)  # fmt: skip
