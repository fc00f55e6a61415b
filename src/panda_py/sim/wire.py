"""Per-connection datagram buffers of the simulated robot: the state it sends and the
command it receives, each one preallocated buffer with typed views onto its fields.

The robot core keeps its state as float64 views into one buffer laid out in the wire's
field order (:attr:`RobotCore.state_buffer`), so filling a state datagram is a handful of
block copies (one on v5..v9; one with a cast to float32 on v10; a few on the older
layouts, which lack some fields) plus the modes, errors and message id. A command datagram
is received into a scratch buffer and, once accepted, copied into the buffer the
:class:`Command` views read, so the robot sees a stable command until the next one.
"""

from __future__ import annotations

import socket
import struct

import numpy as np

from panda_py import fci
from panda_py.sim.command import Command, command_on
from panda_py.sim.robot import RobotCore

_U64 = fci.MESSAGE_ID


class StateWire:
    """One dialect's state datagram, filled from a :class:`RobotCore`'s state."""

    def __init__(self, d: fci.Dialect, core: RobotCore) -> None:
        dt = d.state_dtype
        self.buffer = bytearray(d.state_size)
        self._core = core
        self._copies: list[tuple[np.ndarray, np.ndarray]] = []
        run: list[int] | None = None  # [wire offset, wire end, state start, state end]
        runs: list[tuple[list[int], np.dtype]] = []
        for name in dt.names or ():
            if name not in core.state_offsets:
                run = None
                continue
            field, offset = dt.fields[name][:2]  # type: ignore[index]
            start, stop = core.state_offsets[name]
            size = (stop - start) * field.base.itemsize
            if int(np.prod(field.shape)) != stop - start:
                raise RuntimeError(f"state field {name}: wire shape {field.shape} mismatch")
            if (
                run is not None
                and runs[-1][1] == field.base
                and run[1] == offset
                and run[3] == start
            ):
                run[1] += size
                run[3] = stop
            else:
                run = [offset, offset + size, start, stop]
                runs.append((run, field.base))
        self._runs: list[tuple[int, int, int, int]] = []  # (offset, float size, start, count)
        for (offset, _, start, stop), base in runs:
            wire = np.ndarray((stop - start,), base, buffer=self.buffer, offset=offset)
            self._copies.append((wire, core.state_buffer[start:stop]))
            self._runs.append((offset, base.itemsize, start, stop - start))
        # The tail: motion generator and controller modes, errors, reflex reasons, robot
        # mode and command success rate, contiguous in every layout.
        n = d.errors_count
        first = dt.fields["motion_generator_mode"][1]  # type: ignore[index]
        rate = dt.fields["control_command_success_rate"][0]  # type: ignore[index]
        if dt.fields["control_command_success_rate"][1] != first + 3 + 2 * n:  # type: ignore[index]
            raise RuntimeError("unexpected state layout: the tail is not contiguous")
        self._tail = struct.Struct(f"<BB{n}s{n}sB{'f' if rate.itemsize == 4 else 'd'}")
        self._tail_offset = first
        self._n_errors = n
        self._rate = (first + 3 + 2 * n, rate.itemsize)

    def kernel_layout(self) -> tuple[list[tuple[int, int, int, int]], int, int]:
        """What a compiled fill writes (``sim._lockstep_jit``): the runs of the robot's
        state buffer (wire offset, float size 4 or 8, buffer start, count), the success
        rate's offset and size; the tail's modes and errors are :meth:`fill`'s."""
        return list(self._runs), *self._rate

    def fill(self, message_id: int, success_rate: float) -> bytearray:
        """Write the core's current state with ``message_id``; returns the datagram."""
        for wire, master in self._copies:
            wire[:] = master
        core, n = self._core, self._n_errors
        _U64.pack_into(self.buffer, 0, message_id)
        self._tail.pack_into(
            self.buffer,
            self._tail_offset,
            core.mg_mode,
            core.ctrl_mode,
            core.errors[:n].tobytes(),
            core.reflex_reason[:n].tobytes(),
            core.robot_mode,
            success_rate,
        )
        return self.buffer


class CommandWire:
    """One dialect's command datagrams: receive, validate size and id, accept."""

    def __init__(self, d: fci.Dialect) -> None:
        dt = d.command_dtype
        self.size = d.command_size
        self._scratch = bytearray(max(2048, 2 * self.size))
        self._scratch_view = memoryview(self._scratch)
        self._buffer = bytearray(self.size)
        self._view = memoryview(self._buffer)

        names = dt.names or ()
        for name in ("tau_J_d", "dq_c"):
            if dt.fields[name][0] != np.dtype(("<f8", (7,))):  # type: ignore[index]
                raise RuntimeError(f"command field {name}: expected 7 float64")
        self._kernel_offsets = (
            dt.fields["tau_J_d"][1],  # type: ignore[index]
            dt.fields["dq_c"][1],  # type: ignore[index]
            dt.fields["motion_generation_finished"][1],  # type: ignore[index]
            dt.fields["torque_command_finished"][1] if "torque_command_finished" in names else -1,  # type: ignore[index]
        )
        self._flag_offsets = tuple(
            dt.fields[n][1] if n in names else -1  # type: ignore[index]
            for n in ("valid_elbow", "motion_generation_finished", "torque_command_finished")
        )
        self.command = command_on(d, self._buffer)

    def kernel_layout(self) -> tuple[bytearray, bytearray, tuple[int, int, int, int]]:
        """What a compiled receive reads and writes (``sim._lockstep_jit``): the scratch
        buffer a datagram is received into, the buffer :meth:`accept` copies it to, and
        the offsets of tau_J_d, dq_c (float64 each), motion_generation_finished and
        torque_command_finished (-1: the layout has none)."""
        return self._scratch, self._buffer, self._kernel_offsets

    def receive(self, sock: socket.socket, source: tuple[str, int] | None) -> tuple[int, int]:
        """Read one datagram into the scratch buffer: (its size, its message id or -1);
        -1 too if it did not come from ``source`` (the client's address). Raises
        BlockingIOError when none is queued."""
        n, addr = sock.recvfrom_into(self._scratch)
        if n != self.size or addr != source:
            return n, -1
        return n, _U64.unpack_from(self._scratch)[0]

    def accept(self, message_id: int) -> Command:
        """Make the datagram last received the command the robot reads."""
        self._view[:] = self._scratch_view[: self.size]
        c, buf = self.command, self._buffer
        ov, om, ot = self._flag_offsets
        c.message_id = message_id
        c.valid_elbow = buf[ov] != 0
        c.motion_generation_finished = buf[om] != 0
        c.torque_command_finished = ot >= 0 and buf[ot] != 0
        return c
