"""The control loop's compiled ticks, seen from Python: :class:`FastTicks` runs a law's
ticks in its loop kernel (:mod:`panda_py.rt._tick`) between the moments the control
process must act in Python, and hands the motion back to it in the state libfranka's
bookkeeping and the law expect.

A law offers compiled ticks through :meth:`ControlLaw.compiled
<panda_py.controllers.law.ControlLaw.compiled>`; the loop never asks which law it runs.
Where numba is missing, ``PANDA_PY_NO_JIT=1`` is set or a law offers none, the control
process runs every tick in Python as before, with the same results.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py import jit, progress
from panda_py.controllers.finalize import Finalize
from panda_py.controllers.law import CompiledTicks, ControlLaw, readonly
from panda_py.libfranka import ActiveControl, TorqueIO
from panda_py.libfranka.errors import ControlException, NetworkException
from panda_py.libfranka.state import RobotState
from panda_py.robots.params import RobotSpec
from panda_py.rt.shm import STATE_MAX, LogRing, SharedBlock

__all__ = ["KERNEL_MODULES", "FastTicks", "Outcome", "kernel", "kernels", "warm_up"]


#: the modules of the loop kernels a law's ``CompiledTicks.kernel`` names, each kernel a
#: law's tick on the skeleton of :mod:`panda_py.rt._tick`: the controllers' and the
#: streamed targets', the force laws', the moves'
KERNEL_MODULES = ("panda_py.rt._tick_laws", "panda_py.rt._tick_wrench",
                  "panda_py.rt._tick_moves")  # fmt: skip


def kernels() -> Any:
    """The loop kernels' skeleton (:mod:`panda_py.rt._tick`: its constants, its helpers),
    or None where the laws run without numba (or ``PANDA_PY_NO_JIT=1``): imported, and
    compiled or loaded, on first use."""
    from panda_py.controllers import laws

    return jit.optional("panda_py.rt._tick", requires=laws.fused)


def kernel(name: str) -> Any:
    """The loop kernel ``name`` of :data:`KERNEL_MODULES` (where :func:`kernels` runs)."""
    for module in KERNEL_MODULES:
        found = getattr(jit.optional(module, requires=kernels), name, None)
        if found is not None:
            return found
    raise ValueError(f"{name}: expected the name of a loop kernel of {KERNEL_MODULES}")


@dataclass
class Outcome:
    """Why the compiled ticks handed back and what Python does next."""

    ticks: int  #: ticks run and answered
    #: "wait": wait for the next state (a request, the budget);
    #: "tick": the next tick is Python's (no state within the wait, a receive failed);
    #: "pending": Python answers the state ``pending`` (unanswered)
    then: str
    state: RobotState | None = None  #: the last state answered, if any ticks ran
    pending: bytes | None = None


def _float_field(layout: Any, name: str) -> tuple[int, int]:
    field = layout.fields[name]
    if field.dtype.kind != "f" or field.dtype.itemsize not in (4, 8):
        raise ValueError(f"{name}: a compiled loop reads float fields, got {field.dtype}")
    return field.offset, field.dtype.itemsize


class FastTicks:
    """Compiled ticks of the laws of one torque motion on ``active``: the loop's arrays
    made once (the robot's socket and command, the shared block, the finishing), the
    law's at each :meth:`run`."""

    def __init__(
        self, torque_io: TorqueIO, block: SharedBlock, finalize: Finalize,
        active: ActiveControl | None,
    ) -> None:  # fmt: skip
        tick = kernels()
        assert tick is not None
        self.tick = tick
        self.active = active  # (None: the warm-up's, which runs no tick)
        self.torque_io = torque_io
        layout = self.torque_io.layout
        self.layout = layout
        lay = np.zeros(tick.LAY_SIZE, dtype=np.int64)
        for at, name in ((tick.L_MG, "motion_generator_mode"), (tick.L_CTRL, "controller_mode"),
                         (tick.L_MODE, "robot_mode")):  # fmt: skip
            field = layout.fields[name]
            if field.dtype.itemsize != 1:
                raise ValueError(f"{name}: a compiled loop reads one byte, got {field.dtype}")
            lay[at] = field.offset
        for at, name in ((tick.L_Q, "q"), (tick.L_DQ, "dq"), (tick.L_POSE, "O_T_EE"),
                         (tick.L_TAU_D, "tau_J_d"), (tick.L_TAU_J, "tau_J")):  # fmt: skip
            lay[at], lay[at + 1] = _float_field(layout, name)
        lay[tick.L_CMD_TAU] = layout.c_tau.offset
        self.lay = lay
        self._key_fields: tuple[str, ...] | None = None
        io = self.io = np.zeros(tick.IO_SIZE, dtype=np.int64)
        io[tick.UDP] = self.torque_io.udp
        mg, ctrl, move = self.torque_io.modes
        io[tick.MG], io[tick.CTRL], io[tick.MOVE] = mg, ctrl, move
        io[tick.STATE_MAX] = STATE_MAX
        self.pfd = np.zeros(4, dtype=np.int32)  # two struct pollfd: (fd, events | revents)
        self.pfd[0] = self.torque_io.udp
        self.buf = np.zeros(STATE_MAX, dtype=np.uint8)
        # (RECV_BATCH states a receive, with their recvmmsg headers)
        self.scratch = np.zeros(tick.RECV_BATCH * (STATE_MAX + tick.SCRATCH_PER_STATE), np.uint8)
        self.answered = np.zeros(STATE_MAX, dtype=np.uint8)
        self.key = np.zeros(STATE_MAX, dtype=np.uint8)
        header, states, signals, outputs = block.arrays()
        self.shared = (header, states, outputs, signals)
        self.new = np.zeros(signals.size)
        walls, scale, flags = finalize.walls.kernel_state()
        self.finish = (np.array([finalize.dtau_max, finalize.gain]), walls, scale, flags,
                       finalize.tau_max)  # fmt: skip
        self.decoded = (np.zeros(16), np.zeros(7), np.zeros(7), np.zeros(16), np.zeros(7))
        q, dq, pose = self.decoded[1:4]
        self.views = tuple(readonly(a) for a in (q, dq, pose))
        self.tau = np.zeros(7)
        self.command = finalize.out
        self._ring: tuple[np.ndarray, np.ndarray] = (
            np.zeros(1, np.uint8),
            np.zeros((0, 3), np.int64),
        )
        self._ring_of: LogRing | None = None
        self._kernels: dict[str, Any] = {}
        self._key_spans: tuple[tuple[int, int], ...] = ()
        # the loop's part of the kernel's arguments, and the log ring it was made for
        self._loop: tuple[LogRing | None, Any] = (None, None)

    def _set_key(self, fields: tuple[str, ...], data: bytes) -> None:
        """The spans of ``fields`` in the state, and their bytes in ``data`` (the state the
        law's arrays were made for)."""
        if fields != self._key_fields:
            tick, lay = self.tick, self.lay
            spans = self.layout.spans(fields)
            if len(spans) > 8:
                raise ValueError(f"key_fields: at most 8 runs of fields, got {fields}")
            lay[tick.L_KEY_SPANS :] = 0
            for i, (start, stop) in enumerate(spans):
                lay[tick.L_KEY_SPANS + 2 * i] = start
                lay[tick.L_KEY_SPANS + 2 * i + 1] = stop - start
            self._key_spans, self._key_fields = spans, fields
        key = b"".join([data[a:b] for a, b in self._key_spans])
        self.key[: len(key)] = np.frombuffer(key, np.uint8)

    def _arguments(self, compiled: CompiledTicks, out: np.ndarray) -> tuple[Any, ...]:
        """The loop kernel's arguments (:func:`panda_py.rt._tick.loop_kernel`) for
        ``compiled``, whose outputs are ``out``, one after the other: the loop's arrays
        (taking a state, answering it: made again only for another log ring), the view of
        what the law reads and writes, the law's own arrays."""
        ring_of, loop = self._loop
        if loop is None or ring_of is not self._ring_of:
            header, states, outputs, signals = self.shared
            q, dq, pose, tau_J_d = self.decoded[1:]
            taking = (self.pfd, self.scratch, self.key, header, signals, self.new, q, dq, pose,
                      tau_J_d)  # fmt: skip
            answering = (self.answered, self.torque_io.command, header, states, *self._ring,
                         outputs, *self.finish, tau_J_d, self.command)  # fmt: skip
            loop = (*taking, *answering)
            assert len(taking) == self.tick.TAKING and len(loop) == self.tick.ANSWERING
            self._loop = (self._ring_of, loop)
        a = compiled.arrays  # (the law's inputs, their guard and its key first)
        return (*loop, self.io, self.buf, self.lay, self.decoded[0], compiled.time, *self.views,
                a[0], a[1], a[2], out, self.tau, *a[3:])  # fmt: skip

    def run(
        self, law: ControlLaw, compiled: CompiledTicks, data: bytes, *, chan: int,
        requests_taken: int, log: LogRing | None, budget: int, wait_ms: int,
    ) -> Outcome:  # fmt: skip
        """Run ``law``'s ticks (its compiled form ``compiled``, made on the state ``data``,
        the last one answered) until something needs Python: the channel ``chan`` has a
        request (``requests_taken`` taken so far), ``budget`` ticks ran, no state came
        within ``wait_ms``, or a state needs the law's Python step. Appends to ``log``
        while logging. Raises as the Python tick would: ControlException for non-finite
        torques, NetworkException for a failed send."""
        tick, io = self.tick, self.io
        loop_kernel = self._kernels.get(compiled.kernel)
        if loop_kernel is None:
            loop_kernel = self._kernels[compiled.kernel] = kernel(compiled.kernel)
        out, in_seq = law.compiled_io()
        n = len(data)
        self.buf[:n] = np.frombuffer(data, np.uint8)
        self.answered[:n] = self.buf[:n]
        io[tick.LENGTH] = io[tick.ANSWERED] = n
        io[tick.LAST_ID] = int.from_bytes(data[:8], "little")
        io[tick.CHAN], io[tick.TAKEN], io[tick.BUDGET] = chan, requests_taken, budget
        io[tick.WAIT_MS], io[tick.IN_SEQ], io[tick.OUT_N] = wait_ms, in_seq, len(out)
        io[tick.STATUS] = io[tick.TICKS] = 0
        self.pfd[2] = chan
        if log is not None:
            if log is not self._ring_of:
                self._ring, self._ring_of = log.arrays(), log
            io[tick.LOGGING], io[tick.SLOTS], io[tick.RECORD] = 1, log.slots, log.record.itemsize
        else:
            io[tick.LOGGING] = 0
        self._set_key(compiled.key_fields, data)
        loop_kernel(*self._arguments(compiled, out))
        ran = int(io[tick.TICKS])
        law.compiled_ran(compiled.time, int(io[tick.IN_SEQ]))
        state = None
        if ran and self.active is not None:
            state = self.active.caught_up(self.answered[: io[tick.ANSWERED]].tobytes())
        status = int(io[tick.STATUS])
        if status in (tick.REQUEST, tick.BUDGET_DONE):
            return Outcome(ran, "wait", state)
        if status == tick.PENDING:
            return Outcome(ran, "pending", state, self.buf[: io[tick.LENGTH]].tobytes())
        if status == tick.NONFINITE:
            raise ControlException(
                f"the controller commanded non-finite torques: {self.tau.tolist()}"
            )
        if status == tick.SEND_FAILED:
            raise NetworkException(f"libfranka: UDP send: {os.strerror(int(io[tick.ERRNO]))}")
        return Outcome(ran, "tick", state)  # TIMEOUT, RECEIVE_FAILED: Python's receive goes on


def warm_up(state: RobotState, model: Any, limits: RobotSpec, finalize: Finalize) -> None:
    """Compile (or load) every loop kernel now, not in a tick: each run once on ``state``
    (a :class:`~panda_py.libfranka.state.TickState`) with no socket to wait on, after one
    Python tick of its law, as the loop runs it (the same argument types)."""
    if kernels() is None:
        return
    from panda_py.controllers.moves import tracker_for
    from panda_py.controllers.warmup import BUILTIN, example_plans

    io = TorqueIO.unconnected(state.version)
    block, fd = SharedBlock.create()
    os.close(fd)
    try:
        fast = FastTicks(io, block, finalize, None)
        laws: list[ControlLaw] = []
        for cls in BUILTIN:
            ctrl = cls()
            ctrl.start(state, model)
            ctrl.open_slot(block)
            laws.append(ctrl)
        laws += [tracker_for(plan) for plan in example_plans(state, limits)]
        label = "panda_py: compiling the control loop's ticks, once after installing"
        with progress.work(label, len(laws)) as w:
            for law in laws:
                law.tick(0.0)
                law.step(state, model)
                compiled = law.compiled(state, model)
                if compiled is not None:
                    fast.run(law, compiled, state.raw, chan=-1, requests_taken=0, log=None,
                             budget=1, wait_ms=0)  # fmt: skip
                w.advance()
        finalize.reset()
        del fast
    finally:
        block.close()
