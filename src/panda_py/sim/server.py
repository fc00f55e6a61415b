"""The simulated robot's server: the 1 kHz tick loop and the parts it runs.

One thread runs everything (``select`` with microsecond timeouts, absolute deadlines).
:class:`SimServer` owns the loop, its pacing (realtime on the wall clock, or lockstep
with the client's commands) and the tick; each concern is a part in its own module:

* :mod:`.sockets`: accepting clients, non-blocking TCP with bounded output queues and a
  per-tick request budget, idle and misbehaving connections;
* :mod:`.fci_session`: Connect (accepting a client: ``FciSession._handle_connect``), the
  TCP commands, the UDP states and commands;
* :mod:`.gripper_session`: the Franka Hand's protocol (TCP 1338), or
  :mod:`.vacuum_session`: the Cobot Pump's (TCP 1339), whichever is mounted;
* :mod:`.models`: URDF and model-library delivery off the loop;
* :mod:`.control`: the Python API's requests;
* the robot itself is :class:`~panda_py.sim.robot.RobotCore` (a Move starts in
  ``RobotCore.request_move``).
"""

from __future__ import annotations

import gc
import logging
import os
import selectors
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from panda_py.fci import (
    Command,
    RobotMode,
)
from panda_py.robots.end_effectors import EndEffector
from panda_py.robots.params import get_robot
from panda_py.sim.command import Command as RobotCommand
from panda_py.sim.config import LATE_THRESHOLD, SimConfig, Stats
from panda_py.sim.connections import Client, GripperConnection, RobotConnection
from panda_py.sim.control import ControlRpc
from panda_py.sim.desk.link import PUBLISH_EVERY, DeskLink
from panda_py.sim.fast_tick import compiled_tick
from panda_py.sim.fci_session import FciSession
from panda_py.sim.frames import FrameTaps
from panda_py.sim.gripper import GripperCore
from panda_py.sim.gripper_session import GRIPPER_STATE_PERIOD, GripperSession
from panda_py.sim.models import ModelDelivery
from panda_py.sim.physics import DT, Physics
from panda_py.sim.robot import RobotCore
from panda_py.sim.sockets import REQUEST_BUDGET, Sockets
from panda_py.sim.vacuum import VacuumCore
from panda_py.sim.vacuum_session import VacuumSession

log = logging.getLogger("panda_py.sim")

# Realtime: past RESYNC [s] behind, the loop gives up catching up and re-anchors (logged),
# keeping simulated and wall time together.
RESYNC = 0.1
# Lockstep: before a motion's first command arrives, each tick waits this long for it [s].
ENGAGE_WAIT = 0.02
# How often the loop looks for connections idle before Connect [s].
IDLE_CHECK_PERIOD = 0.1
# With nobody watching (no client, no viewer or recorder, no Desk drive), the loop runs the
# ticks of this long [s] back to back and then sleeps: the same ticks, woken 20 times a
# second instead of 1000 (the Desk's page shows the arm at 20 Hz). A woken process runs its
# first ticks several times slower than the next, so this halves an idle simulator's CPU.
UNWATCHED_BATCH = 0.05
# Lockstep: the most ticks of a torque motion one compiled call runs (sim/lockstep.py)
# before the loop looks round itself (it looks sooner for anything it must do).
LOCKSTEP_BATCH = 1000


class SimServer(Sockets, FciSession, GripperSession, VacuumSession, ModelDelivery, ControlRpc):
    """A simulated Franka. ``serve_forever`` runs until :meth:`shutdown` (or a control
    message ``("stop",)`` on the optional control connection)."""

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        self.spec = get_robot(config.robot)
        extra = config.extra
        self.physics = Physics(
            self.spec, scene=config.scene, extra=extra, end_effector=config.end_effector
        )
        self.core = RobotCore(self.spec, self.physics, np.asarray(config.q_start, dtype=float))
        # What the flange carries, and the port its device serves (a robot with the pump
        # has no hand: 1338 is closed, as on hardware).
        hand = self.physics.end_effector is EndEffector.HAND
        self.gripper = GripperCore(self.physics) if hand else None
        self.pump = None if hand else VacuumCore(self.physics)
        # the common tick of a torque motion compiled (None: the Python reference only)
        self._fast = compiled_tick(self.core) if self.pump is None else None
        if self._fast is not None:
            self._fast.warm(self.gripper)
        # lockstep: a torque motion's ticks in compiled calls (None: one tick at a time)
        self._lockstep: Any = None
        if self._fast is not None and config.lockstep:
            from panda_py.sim.lockstep import LockstepTicks

            self._lockstep = LockstepTicks(self._fast, self.core.state_buffer.size)
            self._lockstep.warm(self.gripper)
        self.stats = Stats()
        # the simulated Desk's view of this robot (brakes, FCI), read without waiting
        self.desk = DeskLink(config.desk_link) if config.desk_link is not None else None
        self.desk_move = 0.0
        self.desk_ee = 0.0
        self.tick_count = 0
        self.drop_commands = 0
        # Snapshots for the viewer and the video recorder (their own processes draw them).
        self.frames = (
            FrameTaps(config.frame_feeds, lockstep=config.lockstep) if config.frame_feeds else None
        )
        self._running = True
        self._sel = selectors.SelectSelector()  # select(): microsecond timeouts, unlike epoll
        self._robot_listener = self._listen(config.robot_port)
        self._gripper_listener = self._listen(config.gripper_port if hand else config.vacuum_port)
        self._sel.register(self._robot_listener, selectors.EVENT_READ, ("accept-robot", None))
        self._sel.register(self._gripper_listener, selectors.EVENT_READ, ("accept-gripper", None))
        self.robot_conn: RobotConnection | None = None
        self.gripper_conn: GripperConnection | None = None
        self._refusing: list[Client] = []  # second clients awaiting "robot busy"
        self._control: Any = None
        self._gripper_pending: dict[int, int] = {}  # command_id -> Gripper/VacuumCommand
        self._budget = REQUEST_BUDGET  # [s] left for requests until the next tick
        self._tick_deadline = 0.0  # monotonic: when the current tick was due
        self._next_check = 0.0  # monotonic: next look for idle connections
        # Model delivery runs in its own thread; the loop answers once a build is done.
        self._models = ThreadPoolExecutor(max_workers=1, thread_name_prefix="panda-sim-models")
        self._urdf: Future[bytes | str] = self._models.submit(self._build_urdf)
        self._libraries: dict[tuple[int, int], Future[bytes | str]] = {}
        self._model_requests: list[tuple[RobotConnection, Command, int, Future[bytes | str]]] = []
        self._models.submit(self._build_host_library)

    def shutdown(self) -> None:
        self._running = False

    def close(self) -> None:
        for conn in (self.robot_conn, self.gripper_conn, *self._refusing):
            if conn is not None:
                self._close_conn(conn)
        self._models.shutdown(wait=False, cancel_futures=True)
        if self.frames is not None:
            self.frames.close()
        for s in (self._robot_listener, self._gripper_listener):
            self._sel.unregister(s)
            s.close()
        self._sel.close()

    def serve_forever(self) -> None:
        # Everything built so far (MuJoCo, numpy, the model) lives as long as the server:
        # out of the collector's sight, a full collection no longer walks it mid-tick.
        gc.collect()
        gc.freeze()
        next_tick = time.monotonic()
        lockstep_deadline = 0.0
        # lockstep_max_speed: a lockstep tick runs no earlier than paced_tick (0: never waits)
        speed = self.config.lockstep_max_speed
        pace = DT / speed if speed else 0.0
        paced_tick = 0.0
        try:
            while self._running:
                conn = self.robot_conn
                waiting = (
                    self.config.lockstep
                    and conn is not None
                    and self.core.robot_mode == RobotMode.MOVE
                    and self.core.async_gen is None  # its generator runs on the clock
                )
                now = time.monotonic()
                if (
                    waiting
                    and conn is not None
                    and conn.command is None
                    and conn.awaiting
                    and now >= paced_tick - self.config.lockstep_spin  # (paced: sleeps anyway)
                ):
                    ran = None if pace else self._compiled_lockstep(conn, lockstep_deadline)
                    if ran is None:
                        self._spin_for_command(conn)
                    elif ran[1]:  # ticks ran
                        lockstep_deadline = ran[0]
                        next_tick = time.monotonic() + DT
                    now = time.monotonic()
                    if not self._running:
                        continue
                if waiting:
                    if conn is not None and conn.command is not None:
                        timeout = max(0.0, paced_tick - now)
                    else:
                        timeout = max(0.0, max(lockstep_deadline, paced_tick) - now)
                else:
                    timeout = max(0.0, next_tick - now)
                if waiting:
                    # Lockstep time stands still while it waits for the client, who may be
                    # waiting for an answer: requests get a fresh budget every pass.
                    self._refill_budget()
                backlog = self._backlogged() if self._budget > 0.0 else []
                if backlog:
                    timeout = 0.0
                for key, mask in self._sel.select(timeout):
                    self._dispatch(key.data, mask)
                for client in backlog:
                    self._handle_backlog(client)
                if self._model_requests:
                    self._answer_models()
                now = time.monotonic()
                if waiting:
                    conn = self.robot_conn
                    have = conn is not None and conn.command is not None
                    if not have and now < lockstep_deadline:
                        continue
                    if now < paced_tick:
                        continue  # answered early: the wall clock has not caught up
                    if pace:  # on its schedule; a tick a period late or more re-anchors it
                        paced_tick = paced_tick + pace if now - paced_tick < pace else now + pace
                    self._tick(now, late=False)
                    next_tick = time.monotonic() + DT
                    lockstep_deadline = time.monotonic() + self._lockstep_wait()
                    continue
                if now < next_tick:
                    continue
                late = now - next_tick
                if late > LATE_THRESHOLD:
                    self.stats.late_ticks += 1
                    if late > self.stats.worst_late:
                        self.stats.worst_late = late
                if now - next_tick > RESYNC:
                    self.stats.resyncs += 1
                    log.warning(
                        "simulator fell %.0f ms behind; re-synchronising", 1e3 * (now - next_tick)
                    )
                    next_tick = now
                self._tick(next_tick, late=late > LATE_THRESHOLD)
                next_tick += DT
                ahead = now + UNWATCHED_BATCH
                while next_tick < ahead and self._running and self._unwatched():
                    self._tick(next_tick, late=False)
                    next_tick += DT
                lockstep_deadline = time.monotonic() + self._lockstep_wait()
        finally:
            self.close()

    def _unwatched(self) -> bool:
        """No client is connected (robot, gripper or pump, or one being refused), no
        request is pending, no viewer or recorder draws, and the arm is not moving to where
        the Desk asked: nobody sees when a tick runs, only that it ran."""
        return (
            self.robot_conn is None
            and self.gripper_conn is None
            and not self._refusing
            and not self._model_requests
            and self.frames is None
            and not self.core.driving
        )

    def _lockstep_wait(self) -> float:
        """How long lockstep waits for the next command [s]: the full timeout once the
        client's loop answers states, briefly before (libfranka skips the first state)."""
        conn = self.robot_conn
        if conn is not None and conn.awaiting:
            return self.config.lockstep_timeout
        return ENGAGE_WAIT

    def _tick(self, deadline: float, *, late: bool) -> None:
        """One 1 ms step due at ``deadline`` (monotonic); ``late``: it started late."""
        now = time.monotonic()
        self._tick_deadline = deadline
        self._refill_budget()
        if now >= self._next_check:
            self._next_check = now + IDLE_CHECK_PERIOD
            self._expire_idle(now)
        conn = self.robot_conn
        command = None
        excused = False
        if conn is not None:
            if not self.config.lockstep:  # its socket is not watched (FciSession._connect)
                self._read_robot_udp(conn)
            command, conn.command = conn.command, None
            if self.core.robot_mode == RobotMode.MOVE and conn.awaiting:
                if command is not None:
                    self.stats.commands_received += 1
                elif not self.config.lockstep and (late or conn.state_late):
                    # Fair realtime: the client cannot answer a state sent late, nor be
                    # blamed for a tick the simulator (or the machine) started late.
                    excused = True
                    self.stats.commands_excused += 1
                else:
                    self.stats.commands_lost += 1
        if self.desk is not None:
            self._follow_desk()
        conn = self.robot_conn  # the Desk may have closed it
        moving = self.core.robot_mode == RobotMode.MOVE
        if not (moving and command is not None and self._compiled_tick(command)):
            if self.gripper is not None:
                self.gripper.tick()
                self.core.finger_force = self.gripper.force
            if self.pump is not None:
                self.pump.tick()
            self.core.tick(command if moving else None, excused=excused)
        self._tick_tail(conn)

    def _tick_tail(self, conn: RobotConnection | None) -> None:
        """A tick's end, once the robot ticked: counted, shown, published, its state sent,
        the hand's answers and state sent."""
        self.tick_count += 1
        self.stats.ticks += 1
        if self.frames is not None:
            self.frames.tick(self.tick_count, self.physics.data.qpos)
        if self.desk is not None:
            self.desk.publish(self.tick_count, self.core.state, self.core.robot_mode)
        if conn is not None:
            if self.core.pending_final is not None:
                self._send_move_final(conn, self.core.pending_final)
            self._send_state(conn)
        elif self.core.pending_final is not None:
            self.core.pending_final = None
        if self.gripper is not None:
            self._flush_gripper()
        else:
            self._flush_vacuum()

    def _compiled_lockstep(
        self, conn: RobotConnection, deadline: float
    ) -> tuple[float, bool] | None:
        """Lockstep: the motion's next ticks in one compiled call where they may run
        compiled (:mod:`.lockstep`), ``deadline`` [s, monotonic] the awaited command's;
        None where the next tick is Python's (nothing done), else the command's lockstep
        deadline after the call and whether ticks ran. What the kernel left (a datagram, a
        command, a tick's end) is done here as the reference would."""
        loop, core = self._lockstep, self.core
        if (
            loop is None
            or self.frames is not None
            or self.drop_commands
            or self._model_requests
            or self._backlogged()
            or core.async_gen is not None
            or any(c is not None and c.out for c in (conn, self.gripper_conn))
        ):
            return None
        budget = LOCKSTEP_BATCH
        # the ticks that publish to the Desk's page are Python's
        if self.desk is not None:
            budget = min(budget, (-self.tick_count - 1) % PUBLISH_EVERY)
        until = self._next_check  # (the look for idle connections is Python's)
        if budget <= 0 or time.monotonic() >= until:
            return None
        args = self._fast.enter(self.gripper) if self._fast is not None else None
        if args is None:
            return None
        ran = loop.run(
            conn, args, self._sel, tick_count=self.tick_count, budget=budget,
            spin=self.config.lockstep_spin, wait=self._lockstep_wait(), deadline=deadline,
            until=until, desk=None if self.desk is None else self.desk.view, hand=self.gripper,
            hand_client=self.gripper_conn, hand_period=GRIPPER_STATE_PERIOD,
        )  # fmt: skip
        k = loop.stops
        if ran.ticks:
            assert self._fast is not None
            after = ran.stop == k.AFTER
            full = ran.ticks - after
            self._fast.leave(ran.ticks, ran.after, self.gripper)
            self.stats.commands_received += ran.ticks
            self.tick_count += full
            self.stats.ticks += full
            if full:
                conn.last_sent_id = self.tick_count + 1
            if after:  # the last tick's fill was the reference's: its end is too
                self._tick_deadline = time.monotonic()
                self._tick_tail(conn)
                return time.monotonic() + self._lockstep_wait(), True
        if ran.stop == k.DATAGRAM:
            self._take_datagram(conn, ran.size, ran.mid)
        elif ran.stop == k.COMMAND and conn.command_wire is not None:
            conn.command = conn.command_wire.accept(ran.mid)
        return (ran.deadline, True) if ran.ticks else (deadline, False)

    def _compiled_tick(self, command: RobotCommand) -> bool:
        """The hand's and the robot's tick with ``command`` compiled, where it may run
        (a torque motion's common tick: the command takes no generator's step and ends
        nothing); False: nothing done, the reference runs it."""
        fast = self._fast
        if (
            fast is None
            or command.motion_generation_finished
            or command.torque_command_finished
            or command.dq_c.any()  # (a protocol < 7 torque motion's generator: at rest)
        ):
            return False
        return fast.command(command.tau_J_d, self.gripper)

    def _dispatch(self, data: tuple[str, Any], mask: int = selectors.EVENT_READ) -> None:
        kind, conn = data
        if kind == "accept-robot":
            self._accept(robot=True)
        elif kind == "accept-gripper":
            self._accept(robot=False)
        elif kind in ("tcp", "busy"):
            if mask & selectors.EVENT_WRITE:
                self._flush(conn)
            if mask & selectors.EVENT_READ and not conn.closed:
                if kind == "tcp":
                    self._read_tcp(conn)
                else:
                    self._read_refusing(conn)
        elif kind == "robot-udp":
            self._read_robot_udp(conn)
        elif kind == "gripper-udp":
            self._drain(conn.udp)
        elif kind == "control":
            self._serve_control()


# SCHED_FIFO priority of a realtime simulator: above ordinary processes, below the
# kernel's own threads and below clients that ask for 99 (libfranka's control thread).
SIM_PRIORITY = 20


def raise_priority() -> bool:
    """Run this process under SCHED_FIFO when permitted (a robot keeps 1 kHz whatever
    else the machine does); otherwise stay as is. Returns whether it took effect."""
    import os

    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(SIM_PRIORITY))
    except (AttributeError, PermissionError, OSError):
        log.info("no realtime priority for the simulator (SCHED_FIFO not permitted)")
        return False
    return True


def pin(cpus: tuple[int, ...] | None) -> None:
    """Run this process (its threads from now on) on ``cpus`` (checked; None: as is)."""
    if cpus is not None:
        os.sched_setaffinity(0, cpus)


def run(config: SimConfig, control: Any = None, ready: Any = None) -> None:
    """Build a server from ``config`` and serve until stopped (process entry point)."""
    server = SimServer(config)
    if control is not None:
        server.attach_control(control)
    if ready is not None:
        ready.send(("ready", None))
    server.serve_forever()


__all__ = ["SimConfig", "SimServer", "Stats", "pin", "raise_priority", "run"]
