"""The control process: one per ``Panda``; owns the FCI connection and runs the 1 kHz loop.

Started by :mod:`panda_py.rt.process` (forked warm, never importing the user's script:
:func:`main`). It connects, warms every code path the loop runs, answers "ready", then
serves:

* idle: it reads every state the robot sends (1 kHz), publishes it to shared memory and
  appends it to the log, and answers requests from the channel between states;
* running a controller or a move: ``state -> law -> joint walls, torque-rate saturation,
  torque limits -> command``, then publish and log, then a non-blocking look at the
  channel. The loop reads its inputs from shared memory without waiting and never takes
  a lock the user's process can hold; the cyclic garbage collector is off.

If the user's process goes away (its end of the channel closes, or this process is
re-parented), a running motion is finished at once and the process exits. Errors become
replies or asynchronous events on the channel; the user's process raises them.
"""

from __future__ import annotations

import gc
import logging
import os
import pickle
import select
import sys
import time
import traceback
from typing import Any, cast

from panda_py.controllers import TorqueController, laws
from panda_py.controllers.finalize import Finalize
from panda_py.controllers.law import ControlLaw
from panda_py.controllers.model import ControlModel
from panda_py.controllers.moves import tracker_for
from panda_py.controllers.plans import MoveResult
from panda_py.controllers.warmup import warm_up
from panda_py.libfranka import (
    ControlException,
    FrankaException,
    InvalidOperationException,
    RealtimeException,
    Robot,
    RobotMode,
    RobotState,
)
from panda_py.libfranka.limits import MAX_CUTOFF_FREQUENCY
from panda_py.libfranka.realtime import set_current_thread_to_highest_priority
from panda_py.libfranka.state import TickState
from panda_py.libfranka.types import RealtimeConfig
from panda_py.robots.params import RobotSpec, get_robot, robot_for_protocol
from panda_py.rt import fastloop
from panda_py.rt import requests as rq
from panda_py.rt.channel import Channel, ChannelClosed
from panda_py.rt.fastloop import FastTicks
from panda_py.rt.shm import HEADER, LOG_FIELDS, LogRing, SharedBlock
from panda_py.warmstart import InheritedFd

__all__ = ["ControlServer", "limits_spec_for_version", "main"]

PARENT_CHECK_TICKS = 100  # look for a re-parenting every this many ticks
IDLE_WAIT = 0.05  # [s] longest idle wait for a state or a request
STATE_WAIT = 0.05  # [s] longest wait between ticks before readOnce takes over the wait
COUNT_POLL = 100e-6  # [s] how often a request being written is looked for between ticks
STATE_WAIT_MS = round(1e3 * STATE_WAIT)  # [ms] the compiled ticks' longest wait for a state
# Laws that offer compiled ticks (ControlLaw.compiled) run them between the moments the
# loop must act in Python (rt.fastloop); PANDA_PY_FAST_TICKS=0 runs every tick in Python
FAST_TICKS = os.environ.get("PANDA_PY_FAST_TICKS", "1") != "0"
# libfranka's rate limiter stays off: the loop's own saturation (laws.DTAU_MAX_PER_TICK,
# 1 Nm a tick around tau_J_d) is libfranka's torque-rate bound (1000 Nm/s), applied before
# the low-pass filter (controllers.finalize, which the loop applies itself, so libfranka
# is asked for none), which only shrinks the step further (to FILTER_GAIN of it: 386 Nm/s,
# as panda-py's controllers get, which a Cartesian plan keeps within:
# panda.plan_torques); the limiter could never bind, so running it (as panda-py does)
# would only cost time. tests/rt/test_loop_limits.py holds this.
LIMIT_RATE = False
# what Panda.get_robot() may run on the robot (between ticks)
ROBOT_METHODS = frozenset({
    "set_collision_behavior", "set_joint_impedance", "set_cartesian_impedance",
    "set_guiding_mode", "set_k", "set_ee", "set_load", "set_filters",
    "automatic_error_recovery", "stop", "read_once", "server_version", "get_robot_model",
})  # fmt: skip


def limits_spec_for_version(server_version: int) -> str:
    """Whose joint limits apply, from the robot's protocol version (as panda-py):
    <= 5 FER; 6-9 FR3 before robot system 5.9; >= 10 FR3 with 5.9's wider limits."""
    return robot_for_protocol(server_version).name


def _transferable(exc: BaseException, where: str) -> BaseException:
    """``exc`` if it pickles, else a ControlException carrying its description."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        text = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        return ControlException(f"{where}: {text}")


class _Deferred:
    """A request whose reply is sent later (when a motion ends)."""


DEFERRED = _Deferred()


class ControlServer:
    """The control process's state and its two loops."""

    def __init__(self, channel: Channel, block: SharedBlock, parent: int) -> None:
        self.chan = channel
        self.block = block
        self.parent = parent
        self.robot: Robot | None = None
        self.model: ControlModel | None = None
        self.finalize: Finalize | None = None  # (set at connect: the limits are the robot's)
        self.limits: RobotSpec | None = None  # whose joint limits apply (set at connect)
        self.log: LogRing | None = None
        self.logging = False
        self.closing = False
        self.pending: tuple[ControlLaw, int | None] | None = None  # (law, move's request id)
        # while the loop runs: its law and the id of the move request it answers
        self.current: tuple[ControlLaw, int | None] | None = None
        self.replacement: tuple[ControlLaw, int] | None = None  # a move replacing the current
        self.deferred = False  # its hand-over was put off one tick (a state was queued)
        self.stopping = False
        self.stop_waiters: list[int] = []
        self._current_rid = 0
        self.requests_taken = 0  # requests received so far (HEADER.REQUESTS counts those sent)
        self._handlers: dict[rq.Kind, Any] = {
            rq.Kind.START: self._start,
            rq.Kind.MOVE: self._move,
            rq.Kind.CANCEL: self._cancel,
            rq.Kind.STOP: self._stop,
            rq.Kind.ROBOT: self._robot_call,
            rq.Kind.RECOVER: self._recover,
            rq.Kind.ENABLE_LOG: self._enable_log,
            rq.Kind.DISABLE_LOG: self._disable_log,
            rq.Kind.CLOSE: self._close,
        }

    # --- channel ---------------------------------------------------------------------

    def reply(self, rid: int, ok: bool, value: Any) -> None:
        try:
            self.chan.send(rq.Reply(rid, ok, value))
        except ChannelClosed:
            self.closing = True

    def event(self, event: rq.LoopError | rq.LogLine) -> None:
        self.block.header[HEADER.EVENTS] += 1  # counted first: the reader may be quick
        try:
            self.chan.send(event)
        except ChannelClosed:
            self.closing = True

    def _parent_gone(self) -> bool:
        return os.getppid() != self.parent

    # --- start -------------------------------------------------------------------------

    def connect(self, request: rq.Connect) -> rq.Connected:
        config = RealtimeConfig(request.realtime_config)
        if request.cpus is not None:  # (this thread: the loop's)
            os.sched_setaffinity(0, request.cpus)
        robot = Robot(request.hostname, config, timeout=request.timeout)
        # sleep until each state arrives: polling for it cost this process about a
        # quarter of its CPU and lowered no latency (benchmarks/bench_panda.py)
        robot.spin_wait = False
        self.robot = robot
        version = robot.server_version()
        limits = self.limits = get_robot(limits_spec_for_version(version))
        self.model = ControlModel(robot.robot_spec)
        laws.warmup()  # the compiled laws: compiled or loaded now, not in a tick
        self.finalize = Finalize(limits)
        if set_current_thread_to_highest_priority() is None and config == RealtimeConfig.kEnforce:
            raise RealtimeException(
                "libfranka: realtime scheduling (SCHED_FIFO) is required "
                "(RealtimeConfig.kEnforce) but not permitted for the control process"
            )
        data = robot.receive_raw_state()
        self.block.publish_state(data)
        # the states the loop's laws get: read-only arrays, compiled for as such
        state = robot.decode_state(data, TickState)
        warm_up(state, self.model, limits, self.finalize)
        fastloop.warm_up(state, self.model, limits, self.finalize)
        return rq.Connected(version, robot.robot_spec.name, limits.name)

    # --- the idle loop -------------------------------------------------------------------

    def serve(self) -> None:
        assert self.robot is not None
        robot = self.robot
        udp = robot.fileno()
        chan = self.chan.sock.fileno()
        last_gc = time.monotonic()
        while not self.closing:
            if self.pending is not None:
                pending, self.pending = self.pending, None
                self._run(*pending)
                continue
            readable = select.select([udp, chan], [], [], IDLE_WAIT)[0]
            if udp in readable:
                self._publish(robot.receive_raw_state())
            if chan in readable:
                self._receive(running=False)
            if self._parent_gone():
                self.closing = True
            now = time.monotonic()
            if now - last_gc > 10.0:  # the collector is off; tidy up between motions
                gc.collect()
                last_gc = now

    def _publish(self, data: bytes) -> None:
        block = self.block
        block.publish_state(data)
        if self.logging and self.log is not None:
            self.log.append(data, block.header)

    def _receive(self, running: bool) -> None:
        try:
            msg, fds = self.chan.recv()
        except ChannelClosed:
            self.closing = True
            self.stopping = True
            return
        self.requests_taken += 1
        if not isinstance(msg, rq.Call):
            for fd in fds:
                os.close(fd)
            return  # not ours to answer: nothing numbered it
        rid, request = msg.rid, msg.request
        self._current_rid = rid
        kind = getattr(request, "kind", None)
        handler = self._handlers.get(kind) if isinstance(kind, rq.Kind) else None
        try:
            if handler is None:
                raise ValueError(
                    f"request: expected one of {[k.value for k in rq.Kind]}, got {request!r}"
                )
            value = handler(request, fds, running)
        except Exception as exc:
            for fd in fds:
                os.close(fd)
            self.reply(rid, False, _transferable(exc, kind.value if kind else "request"))
            return
        if value is DEFERRED:
            return
        self.reply(rid, True, value)

    # --- requests ----------------------------------------------------------------------

    def _not_running(self, running: bool, what: str) -> None:
        if running:
            raise InvalidOperationException(
                f"{what}: not while a controller or a move runs (stop it first)"
            )

    def _fresh_state(self) -> RobotState:
        assert self.robot is not None
        data = self.robot.receive_raw_state()
        self._publish(data)
        return self.robot.decode_state(data)

    def _start(self, request: rq.StartController, fds: list[int], running: bool) -> Any:
        self._not_running(running, "start_controller")
        ctrl = pickle.loads(request.payload)
        if not isinstance(ctrl, TorqueController):
            raise ValueError(f"controller: expected a TorqueController, got {type(ctrl)!r}")
        ctrl.t = ctrl.dt = 0.0
        # (set once connected; a test's server may run laws that need no model)
        ctrl.start(self._fresh_state(), cast("ControlModel", self.model))
        values = ctrl.open_slot(self.block)
        self._schedule(ctrl, None)
        return values

    def _schedule(self, law: ControlLaw, move_rid: int | None) -> None:
        """Run ``law`` once this request is answered: it shows as running from now on, so
        whoever sees the answer and asks ``is_moving()`` sees it running (or, once it
        ended, finds its error posted first)."""
        self.pending = (law, move_rid)
        self.block.header[HEADER.RUNNING] = 1

    def _move(self, request: rq.Move, fds: list[int], running: bool) -> Any:
        law = tracker_for(request.plan)
        if request.until is not None:
            law.until = pickle.loads(request.until)
            if not callable(getattr(law.until, "holds", None)):
                raise ValueError(f"until: expected a condition, got {type(law.until).__name__}")
            law.then = request.then
        if running:
            current = self.current
            if current is None or not current[0].replaceable:
                raise InvalidOperationException("move: not while a controller runs (stop it first)")
            if self.replacement is not None:  # two in one tick: the newer wins
                self._answer_replaced(self.replacement[0], self.replacement[1], None,
                                      time.monotonic())  # fmt: skip
            self.replacement = (law, self._current_rid)
        else:
            self._schedule(law, self._current_rid)
        return DEFERRED

    def _cancel(self, request: rq.Cancel, fds: list[int], running: bool) -> Any:
        current = self.current
        if not running or current is None or current[1] != request.move:
            return False
        law = current[0]
        law.cancel(f"cancelled after {law.t:.3f} s")
        return True

    def _stop(self, request: rq.Stop, fds: list[int], running: bool) -> Any:
        if not running:
            return None
        self.stopping = True
        self.stop_waiters.append(self._current_rid)
        return DEFERRED

    def _robot_call(self, request: rq.RobotCall, fds: list[int], running: bool) -> Any:
        method = request.method
        if method not in ROBOT_METHODS:
            raise ValueError(f"method: expected one of {sorted(ROBOT_METHODS)}, got {method!r}")
        if method == "read_once":
            self._not_running(running, "read_once")
            return self._fresh_state()
        if method != "server_version":
            self._not_running(running, method)
        return getattr(self.robot, method)(*request.args, **request.kwargs)

    def _recover(self, request: rq.Recover, fds: list[int], running: bool) -> Any:
        self._not_running(running, "recover")
        assert self.robot is not None
        state = self._fresh_state()
        if state.current_errors or state.robot_mode in (RobotMode.kReflex, RobotMode.kOther):
            self.event(rq.LogLine(logging.WARNING, "Irregular state detected. Attempting "
                                  "automatic error recovery."))  # fmt: skip
            self.robot.automatic_error_recovery()
            return True
        return False

    def _enable_log(self, request: rq.EnableLog, fds: list[int], running: bool) -> Any:
        if len(fds) != 1:
            raise ValueError(f"enable_logging: expected one file descriptor, got {len(fds)}")
        assert self.robot is not None
        record, spans = LogRing.layout(self.robot.state_dtype, LOG_FIELDS)
        ring = LogRing(fds[0], request.size, record, spans)
        os.close(fds[0])
        old, self.log = self.log, ring
        self.block.header[HEADER.LOG_COUNT] = 0
        self.logging = True
        if old is not None:
            old.close()
        return None

    def _disable_log(self, request: rq.DisableLog, fds: list[int], running: bool) -> Any:
        self.logging = False
        return None

    def _close(self, request: rq.Close, fds: list[int], running: bool) -> Any:
        self.closing = True
        self.stopping = True
        return None

    # --- the control loop ----------------------------------------------------------------

    def _await_state(
        self, udp: int, requests: int, law: ControlLaw, move_rid: int | None, state: RobotState
    ) -> tuple[ControlLaw, int | None]:
        """Wait for the robot's next state, taking the requests that arrive meanwhile;
        returns the law and move that run on. A move that replaces the running one is
        unpacked and takes over here, from this tick's state and reference, as soon as it
        arrives (it was noticed only once the next state had come: up to a period later).
        A state already queued goes first: a hand-over it would delay waits for the next
        gap, once, on that tick's state (unpacking and handing over each take up to about
        half a millisecond on cold caches, together more than a gap, and a late command
        is a lost one). A request is whole once all its bytes are buffered, or once the
        user's process has counted it (it counts after its send: the woken loop often runs
        before the sender gets to count); until then the buffer and the count are looked
        at every COUNT_POLL while waiting on the robot's socket alone."""
        header, chan = self.block.header, self.chan
        both, alone = [udp, requests], [udp]
        deadline = time.monotonic() + STATE_WAIT
        polling = False  # the channel is readable, its request not counted yet
        while True:
            if self.replacement is not None:
                if self.deferred or not select.select(alone, [], [], 0.0)[0]:
                    self.deferred = False
                    law, move_rid = self._replace(law, move_rid, state)
                else:  # once: a loop that stays behind must not put it off for ever
                    self.deferred = True
            left = deadline - time.monotonic()
            if left <= 0.0:
                return law, move_rid  # silence: readOnce waits (and times out)
            if polling:
                readable = select.select(alone, [], [], min(left, COUNT_POLL))[0]
            else:
                readable = select.select(both, [], [], left)[0]
            if udp in readable:
                return law, move_rid  # the state
            if header[HEADER.REQUESTS] > self.requests_taken or (
                (readable or polling) and chan.whole()
            ):
                self._receive(running=True)
                polling = False
            elif readable:  # being written (or the user's side closed: PARENT_CHECK_TICKS)
                polling = True

    def _run(self, law: ControlLaw, move_rid: int | None) -> None:
        assert self.robot is not None and self.model is not None and self.finalize is not None
        robot, model, block, chan = self.robot, self.model, self.block, self.chan
        finalize = self.finalize
        header = block.header
        self.stopping = self.deferred = False
        finalize.reset()
        error: BaseException | None = None
        state: RobotState | None = None
        header[HEADER.RUNNING] = 1
        self.current = (law, move_rid)
        ticks = 0
        next_check = PARENT_CHECK_TICKS
        active = None
        fast: FastTicks | None = None
        # compiled ticks where asked for and where the loop kernels run (not without numba
        # or with PANDA_PY_NO_JIT=1, where a built-in law still offers its compiled form)
        fast_ticks = FAST_TICKS and fastloop.kernels() is not None
        pending: bytes | None = None  # a state the compiled ticks left for Python to answer
        udp, requests = robot.fileno(), chan.fileno()
        try:
            active = robot.start_torque_control(
                limit_rate=LIMIT_RATE, cutoff_frequency=MAX_CUTOFF_FREQUENCY, state_type=TickState
            )
            while True:
                if pending is None:
                    state, dt = active.readOnce()
                else:
                    state, dt = active.read_received(pending)
                    pending = None
                if ticks == 0:
                    law.begin(state, model)
                law.tick(dt.to_sec())
                tau = finalize(law.step(state, model), state)
                finished = self.stopping or law.finished(state)
                if finished and not self.stopping:
                    after = law.next_law(state, model)
                    if after is not None:  # (a guarded move's then) it goes on
                        law = after
                        self.current = (law, move_rid)
                        finished = False
                active.write_torques(tau, finished)
                self._publish(state.raw)
                law.published()
                if finished:
                    break
                while True:  # until the next tick is Python's
                    law, move_rid = self._await_state(udp, requests, law, move_rid, state)
                    ticks += 1
                    if ticks >= next_check:
                        next_check = ticks + PARENT_CHECK_TICKS
                        if self._parent_gone() or chan.peer_closed():  # the user's side is gone
                            self.closing = self.stopping = True
                    compiled = None
                    if self.replacement is None and not self.stopping and fast_ticks:
                        compiled = law.compiled(state, model)
                    if compiled is None:
                        break
                    if fast is None:
                        fast = FastTicks(active.torque_io(), block, finalize, active)
                    outcome = fast.run(
                        law, compiled, state.raw, chan=requests, requests_taken=self.requests_taken,
                        log=self.log if self.logging else None, budget=next_check - ticks,
                        wait_ms=STATE_WAIT_MS,
                    )  # fmt: skip
                    ticks += outcome.ticks
                    header[HEADER.COMPILED] += outcome.ticks
                    if outcome.then != "wait":
                        pending = outcome.pending
                        break
                    if outcome.state is not None:  # the last state the compiled ticks answered
                        state = outcome.state
        except BaseException as exc:  # the robot refused to start, or the loop ended
            if active is not None:
                active.cancel()
            error = _transferable(exc, law.name)
        self.current = None
        try:
            law.stop(state, model)
        except Exception as exc:
            error = error or _transferable(exc, f"{law.name}.stop")
        if self.replacement is not None:  # arrived as the loop ended
            new, rid = self.replacement
            self.replacement = None
            if error is None:  # it starts from where the arm rests (see _run)
                self.pending = (new, rid)
            else:  # what ended the loop ends it too (the user recovers, then moves)
                result = MoveResult(False, f"not started: {error}", error=error)
                self.reply(rid, True, result)
        if error is not None and move_rid is None:
            self.event(rq.LoopError(error))
        # the error is posted before the loop shows as stopped: whoever sees is_moving()
        # turn False finds it in raise_error() (a replacement that starts next runs on)
        if self.pending is None:
            header[HEADER.RUNNING] = 0
        if move_rid is not None:
            self._finish_move(law, move_rid, error)
        for rid in self.stop_waiters:
            self.reply(rid, True, None)
        self.stop_waiters.clear()

    def _replace(
        self, law: ControlLaw, move_rid: int | None, state: RobotState
    ) -> tuple[ControlLaw, int | None]:
        """Hand over from the running move to the one that replaces it, mid-motion."""
        assert self.replacement is not None
        new, rid = self.replacement
        self.replacement = None
        new.replace(law, state, cast("ControlModel", self.model))
        handed_over = time.monotonic()  # the new move's reference is the one in effect
        if move_rid is not None:
            self._answer_replaced(law, move_rid, state, handed_over)
        self.current = (new, rid)
        return new, rid

    def _answer_replaced(
        self, law: ControlLaw, rid: int, state: RobotState | None, end_time: float
    ) -> None:
        """Answer a move that another replaced at ``end_time`` (judged on this tick's
        state)."""
        if state is not None:
            result = law.result(state)
        else:
            result = MoveResult(False, "", elapsed=law.t)
        result.success, result.cancelled = False, True
        result.reason = f"replaced by a new move after {law.t:.3f} s"
        result.end_time = end_time
        self.reply(rid, True, result)

    def _finish_move(self, law: ControlLaw, rid: int, error: BaseException | None) -> None:
        end_time = time.monotonic()
        try:
            state = self._fresh_state()
            result: MoveResult = law.result(state)
        except Exception as exc:
            result = MoveResult(False, f"no state after the move: {exc}", elapsed=law.t)
            state = None
        if error is not None:
            result.success = False
            result.error = error
            result.reason = f"aborted after {law.t:.3f} s: {error}"
        elif self.stopping and law.t < law.duration:
            result.success = False
            result.reason = f"stopped after {law.t:.3f} s of {law.duration:.3f} s"
        result.end_time = end_time
        self.reply(rid, True, result)


def main(chan_fd: InheritedFd, shm_fd: InheritedFd) -> None:
    """The control process's entry (:mod:`panda_py.rt.process` starts it): its end of the
    channel and the shared-memory file; exits 1 if it could not connect."""
    code = _serve(chan_fd.fd, shm_fd.fd)
    if code:
        sys.exit(code)


def _serve(chan_fd: int, shm_fd: int) -> int:
    chan = Channel.from_fd(chan_fd)
    block = SharedBlock(shm_fd)
    os.close(shm_fd)
    # re-parented once its parent (the warm server, or the user's process) is gone
    server = ControlServer(chan, block, os.getppid())
    try:
        msg, _ = chan.recv()
    except (ChannelClosed, ValueError):
        return 1
    if not (isinstance(msg, rq.Call) and isinstance(msg.request, rq.Connect)):
        return 1
    server.requests_taken = 1
    rid = msg.rid
    try:
        info = server.connect(msg.request)
    except BaseException as exc:
        if not isinstance(exc, FrankaException):  # a bug, not the robot: show where
            traceback.print_exc()
        server.reply(rid, False, _transferable(exc, "connect"))
        return 1
    server.reply(rid, True, info)
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        server.serve()
    finally:
        if server.robot is not None:
            server.robot.close()
        chan.close()
    return 0
