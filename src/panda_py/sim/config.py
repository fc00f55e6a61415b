"""How a simulated robot runs (:class:`SimConfig`) and what its loop counts
(:class:`Stats`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from panda_py import checks, fci
from panda_py.fci.vacuum import VACUUM_COMMAND_PORT
from panda_py.robots.end_effectors import EndEffector, get_end_effector
from panda_py.robots.params import START_POSE, get_robot

# Realtime: a tick that starts, or a state that goes out, this long after the tick was
# due is late [s].
LATE_THRESHOLD = 0.0005
# UDP datagrams read from one socket per loop pass (a flood must not starve the tick).
DATAGRAMS_PER_PASS = 64


@dataclass
class SimConfig:
    """How to run a simulated robot."""

    host: str = "127.0.0.1"
    robot: str = "fer"
    lockstep: bool = False
    lockstep_timeout: float = 2.0  # [s] wait for a command this long before counting it lost
    # Lockstep: poll for the client's answer this long before sleeping on it [s] (0: never).
    # A sleeping simulator wakes on cold caches: its next tick takes about twice as long.
    lockstep_spin: float = 300e-6
    # Lockstep: simulated time runs at most this many times as fast as the wall clock (1.0:
    # never ahead of it, as a robot whose client never misses a command; None: as fast as
    # the client answers).
    lockstep_max_speed: float | None = None
    # The CPUs the simulator's process runs on (os.sched_setaffinity; None: any). On the
    # client's core, a machine that stalls one core stalls both, and no command is lost.
    cpus: tuple[int, ...] | None = None
    # Accept only these protocol versions (None: every version the robot's systems speak).
    versions: tuple[int, ...] | None = None
    robot_port: int = fci.COMMAND_PORT
    gripper_port: int = fci.GRIPPER_COMMAND_PORT
    vacuum_port: int = VACUUM_COMMAND_PORT
    # What the flange carries: "hand" (the Franka Hand, served on gripper_port) or
    # "cobot_pump" (Franka's Cobot Pump, served on vacuum_port); an EndEffector after init.
    end_effector: EndEffector | str = EndEffector.HAND
    scene: bool = True
    extra: str | None = None  # MJCF file with extra bodies
    q_start: tuple[float, ...] = START_POSE
    desk_link: Any = None  # the simulated Desk's shared block (RawArray); None: no Desk
    # A TCP connection must send Connect within this time [s], else it is closed (it
    # would hold the robot from every other client).
    connect_timeout: float = 5.0
    # Rings of the processes that draw the robot (viewer, recorder): sim/frames.py.
    frame_feeds: tuple[Any, ...] = ()

    @property
    def accepted_versions(self) -> tuple[int, ...]:
        """The protocol versions this robot answers Connect with success."""
        return self.versions or get_robot(self.robot).protocol_versions

    def __post_init__(self) -> None:
        spoken = get_robot(self.robot).protocol_versions  # validates the name too
        self.end_effector = get_end_effector(self.end_effector)
        if self.versions is not None:
            bad = [v for v in self.versions if v not in spoken]
            if bad or not self.versions:
                raise ValueError(
                    f"versions: expected a non-empty subset of {spoken} (the protocol "
                    f"versions a {self.robot!r}'s robot systems speak), got {self.versions}"
                )
        if not self.lockstep_timeout > 0:
            raise ValueError(f"lockstep_timeout: expected > 0 s, got {self.lockstep_timeout}")
        if not 0 <= self.lockstep_spin <= 0.01:
            raise ValueError(f"lockstep_spin: expected 0..0.01 s, got {self.lockstep_spin}")
        speed = self.lockstep_max_speed
        if speed is not None:
            try:
                checks.number("lockstep_max_speed", speed, low=0.0, high=1e6, low_open=True,
                              high_open=True)  # fmt: skip
            except ValueError:
                raise ValueError(
                    "lockstep_max_speed: expected None or a speed factor in (0, 1e6), got "
                    f"{speed!r}"
                ) from None
        if speed is not None and not self.lockstep:
            raise ValueError(
                f"lockstep_max_speed: applies to lockstep only (realtime runs at the wall "
                f"clock's speed), got {speed!r} without lockstep"
            )
        self.cpus = checks.cpus("cpus", self.cpus)
        if not 0 < self.connect_timeout <= 3600:
            raise ValueError(f"connect_timeout: expected 0..3600 s, got {self.connect_timeout}")
        if len(self.q_start) != 7:
            raise ValueError(f"q_start: expected 7 joint positions, got {len(self.q_start)}")


@dataclass
class Stats:
    ticks: int = 0
    late_ticks: int = 0
    resyncs: int = 0
    commands_received: int = 0
    commands_lost: int = 0
    # Missing commands not counted against the client: the simulator (or the machine)
    # was late, with the state or with the tick that expected the answer.
    commands_excused: int = 0
    bad_datagrams: int = 0
    clients_dropped: int = 0  # disconnected for not reading, idling or a broken stream
    worst_late: float = 0.0  # [s] the latest a realtime tick started after its deadline
    started: float = field(default_factory=time.monotonic)
    cpu_started: float = field(default_factory=time.process_time)


__all__ = ["DATAGRAMS_PER_PASS", "LATE_THRESHOLD", "SimConfig", "Stats"]
