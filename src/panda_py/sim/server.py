"""The simulated robot's network side: FCI on TCP 1337, the gripper on TCP 1338, UDP
states and commands, and the 1 kHz tick loop.

One thread runs everything (``select`` with microsecond timeouts, absolute deadlines):
accepting clients, cutting TCP streams into messages, draining UDP commands, stepping the
robot and sending states. The wire dialect of each robot connection is chosen from the
version in its Connect request.
"""

from __future__ import annotations

import gc
import logging
import selectors
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import (
    Command,
    CommandBaseStatus,
    ConnectStatus,
    GetterSetterStatus,
    GripperCommand,
    GripperStatus,
    LoadModelLibraryStatus,
    MoveStatus,
    ProtocolError,
    RobotMode,
)
from panda_py.robots.params import START_POSE, get_robot
from panda_py.sim.desk.link import DeskLink, accept_fci_connect, may_start_move
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import DT, Physics
from panda_py.sim.robot import Command as RobotCommand
from panda_py.sim.robot import RobotCore
from panda_py.sim.wire import CommandWire, StateWire

log = logging.getLogger("panda_py.sim")

GRIPPER_STATE_PERIOD = 10  # [ticks] gripper state datagrams at 100 Hz
# Realtime: a tick that starts this late counts as late [s]; past RESYNC the loop gives up
# catching up and re-anchors (logged), keeping simulated and wall time together.
LATE_THRESHOLD = 0.0005
RESYNC = 0.1
# Lockstep: before a motion's first command arrives, each tick waits this long for it [s].
ENGAGE_WAIT = 0.02


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
    versions: tuple[int, ...] | None = None  # accept only these protocol versions
    robot_port: int = fci.COMMAND_PORT
    gripper_port: int = fci.GRIPPER_COMMAND_PORT
    scene: bool = True
    extra: str | None = None  # MJCF file with extra bodies
    q_start: tuple[float, ...] = START_POSE
    desk_link: Any = None  # the simulated Desk's shared block (RawArray); None: no Desk

    def __post_init__(self) -> None:
        get_robot(self.robot)  # validates the name
        if self.versions is not None:
            bad = [v for v in self.versions if v not in fci.SUPPORTED_VERSIONS]
            if bad or not self.versions:
                raise ValueError(
                    f"versions: expected a non-empty subset of {fci.SUPPORTED_VERSIONS}, "
                    f"got {self.versions}"
                )
        if not self.lockstep_timeout > 0:
            raise ValueError(f"lockstep_timeout: expected > 0 s, got {self.lockstep_timeout}")
        if not 0 <= self.lockstep_spin <= 0.01:
            raise ValueError(f"lockstep_spin: expected 0..0.01 s, got {self.lockstep_spin}")
        if len(self.q_start) != 7:
            raise ValueError(f"q_start: expected 7 joint positions, got {len(self.q_start)}")


@dataclass
class Stats:
    ticks: int = 0
    late_ticks: int = 0
    resyncs: int = 0
    commands_received: int = 0
    commands_lost: int = 0
    bad_datagrams: int = 0
    started: float = field(default_factory=time.monotonic)
    cpu_started: float = field(default_factory=time.process_time)


class _RobotConnection:
    def __init__(self, sock: socket.socket, addr: tuple[str, int]) -> None:
        self.sock = sock
        self.addr = addr
        self.reader = fci.RobotMessageReader()
        self.dialect: fci.Dialect | None = None
        self.udp: socket.socket | None = None
        self.udp_target: tuple[str, int] | None = None
        self.state_wire: StateWire | None = None
        self.command_wire: CommandWire | None = None
        self.move_id: int | None = None
        self.last_sent_id = -1
        self.command: RobotCommand | None = None  # newest fresh command since last tick
        self.awaiting = False  # lockstep: a command for the last state is expected


class _GripperConnection:
    def __init__(self, sock: socket.socket, addr: tuple[str, int]) -> None:
        self.sock = sock
        self.addr = addr
        self.reader = fci.GripperMessageReader()
        self.connected = False
        self.udp: socket.socket | None = None
        self.udp_target: tuple[str, int] | None = None


class SimServer:
    """A simulated Franka. ``serve_forever`` runs until :meth:`shutdown` (or a control
    message ``("stop",)`` on the optional control connection)."""

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        self.spec = get_robot(config.robot)
        extra = config.extra
        self.physics = Physics(self.spec, scene=config.scene, extra=extra)
        self.core = RobotCore(self.spec, self.physics, np.asarray(config.q_start, dtype=float))
        self.gripper = GripperCore(self.physics)
        self.desk = DeskLink(config.desk_link) if config.desk_link is not None else None
        self.stats = Stats()
        self.tick_count = 0
        self.drop_commands = 0
        self._running = True
        self._sel = selectors.SelectSelector()  # select(): microsecond timeouts, unlike epoll
        self._robot_listener = self._listen(config.robot_port)
        self._gripper_listener = self._listen(config.gripper_port)
        self._sel.register(self._robot_listener, selectors.EVENT_READ, ("accept-robot", None))
        self._sel.register(self._gripper_listener, selectors.EVENT_READ, ("accept-gripper", None))
        self.robot_conn: _RobotConnection | None = None
        self.gripper_conn: _GripperConnection | None = None
        self._control: Any = None
        self._urdf: bytes | None = None
        self._libraries: dict[tuple[int, int], bytes | str] = {}
        self._gripper_pending: dict[int, int] = {}  # command_id -> GripperCommand
        self._model_thread = threading.Thread(target=self._prepare_models, daemon=True)
        self._model_thread.start()

    # -- setup ---------------------------------------------------------------------------

    def _listen(self, port: int) -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind((self.config.host, port))
        s.listen(4)
        s.setblocking(False)
        return s

    def _prepare_models(self) -> None:
        """Build the URDF and this host's native model library off the tick thread (the
        compiler may take a second on first use); requests wait for it."""
        from panda_py.robots.clib import host_platform
        from panda_py.robots.urdf import robot_urdf

        self._urdf = robot_urdf(self.spec).encode()
        host = host_platform()
        if host is not None:
            self._model_library(int(host[0]), int(host[1]))

    def _model_library(self, architecture: int, system: int) -> bytes | str:
        """The library bytes for a client platform, or why there are none."""
        from panda_py.robots.clib import ModelLibraryUnavailable, model_library

        key = (architecture, system)
        if key not in self._libraries:
            try:
                self._libraries[key] = model_library(
                    self.spec, architecture=architecture, system=system
                )
            except (ModelLibraryUnavailable, ValueError) as exc:
                self._libraries[key] = str(exc)
        return self._libraries[key]

    def attach_control(self, conn: Any) -> None:
        """A ``multiprocessing`` connection to serve control requests on between ticks."""
        self._control = conn
        self._sel.register(conn.fileno(), selectors.EVENT_READ, ("control", None))

    def shutdown(self) -> None:
        self._running = False

    def close(self) -> None:
        for conn in (self.robot_conn, self.gripper_conn):
            if conn is not None:
                self._close_conn(conn)
        for s in (self._robot_listener, self._gripper_listener):
            self._sel.unregister(s)
            s.close()
        self._sel.close()

    # -- the loop ------------------------------------------------------------------------

    def serve_forever(self) -> None:
        # Everything built so far (MuJoCo, numpy, the model) lives as long as the server:
        # out of the collector's sight, a full collection no longer walks it mid-tick.
        gc.collect()
        gc.freeze()
        next_tick = time.monotonic()
        lockstep_deadline = 0.0
        try:
            while self._running:
                conn = self.robot_conn
                waiting = (
                    self.config.lockstep
                    and conn is not None
                    and self.core.robot_mode == RobotMode.MOVE
                )
                now = time.monotonic()
                if waiting and conn is not None and conn.command is None and conn.awaiting:
                    self._spin_for_command(conn)
                    now = time.monotonic()
                if waiting:
                    if conn is not None and conn.command is not None:
                        timeout = 0.0
                    else:
                        timeout = max(0.0, lockstep_deadline - now)
                else:
                    timeout = max(0.0, next_tick - now)
                for key, _ in self._sel.select(timeout):
                    self._dispatch(key.data)
                now = time.monotonic()
                if waiting:
                    conn = self.robot_conn
                    have = conn is not None and conn.command is not None
                    if not have and now < lockstep_deadline:
                        continue
                    self._tick()
                    next_tick = time.monotonic() + DT
                    lockstep_deadline = time.monotonic() + self._lockstep_wait()
                    continue
                if now < next_tick:
                    continue
                if now - next_tick > LATE_THRESHOLD:
                    self.stats.late_ticks += 1
                if now - next_tick > RESYNC:
                    self.stats.resyncs += 1
                    log.warning(
                        "simulator fell %.0f ms behind; re-synchronising", 1e3 * (now - next_tick)
                    )
                    next_tick = now
                self._tick()
                next_tick += DT
                lockstep_deadline = time.monotonic() + self._lockstep_wait()
        finally:
            self.close()

    def _spin_for_command(self, conn: _RobotConnection) -> None:
        """Lockstep: poll the command socket for up to ``lockstep_spin`` (the client's
        answer usually comes within it), keeping this core's caches warm."""
        end = time.monotonic() + self.config.lockstep_spin
        read = self._read_robot_udp
        while conn.command is None and conn.udp is not None and time.monotonic() < end:
            read(conn)

    def _lockstep_wait(self) -> float:
        """How long lockstep waits for the next command [s]: the full timeout once the
        client's loop answers states, briefly before (libfranka skips the first state)."""
        conn = self.robot_conn
        if conn is not None and conn.awaiting:
            return self.config.lockstep_timeout
        return ENGAGE_WAIT

    def _tick(self) -> None:
        conn = self.robot_conn
        command = None
        if conn is not None:
            command, conn.command = conn.command, None
            if self.core.robot_mode == RobotMode.MOVE and conn.awaiting:
                if command is None:
                    self.stats.commands_lost += 1
                else:
                    self.stats.commands_received += 1
        self.gripper.tick()
        self.core.finger_force = self.gripper.force
        self.core.tick(command if self.core.robot_mode == RobotMode.MOVE else None)
        self.tick_count += 1
        self.stats.ticks += 1
        if self.desk is not None:
            self.desk.publish(self.tick_count, self.core.state, self.core.robot_mode)
        if conn is not None:
            if self.core.pending_final is not None:
                self._send_move_final(conn, self.core.pending_final)
            self._send_state(conn)
        elif self.core.pending_final is not None:
            self.core.pending_final = None
        self._flush_gripper()

    # -- dispatch ------------------------------------------------------------------------

    def _dispatch(self, data: tuple[str, Any]) -> None:
        kind, conn = data
        if kind == "accept-robot":
            self._accept(robot=True)
        elif kind == "accept-gripper":
            self._accept(robot=False)
        elif kind == "tcp":
            self._read_tcp(conn)
        elif kind == "robot-udp":
            self._read_robot_udp(conn)
        elif kind == "gripper-udp":
            self._drain(conn.udp)
        elif kind == "control":
            self._serve_control()

    def _accept(self, robot: bool) -> None:
        """Accept an FCI (``robot``) or gripper client; one of each at a time."""
        listener = self._robot_listener if robot else self._gripper_listener
        what = "FCI" if robot else "gripper"
        try:
            sock, addr = listener.accept()
        except OSError:
            return
        if robot and not accept_fci_connect(self.desk):
            log.warning("refusing the FCI client from %s:%d: the FCI is not active", *addr)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\1\0\0\0\0\0\0\0")
            sock.close()  # a reset, as from a robot whose FCI port is closed
            return
        current = self.robot_conn if robot else self.gripper_conn
        if current is not None and not self._alive(current):
            self._close_conn(current)
            current = None
        if current is not None:
            log.warning(
                "refusing a second %s client from %s:%d while %s:%d is connected",
                what, *addr, *current.addr,
            )  # fmt: skip
            sock.close()
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn: _RobotConnection | _GripperConnection
        if robot:
            conn = self.robot_conn = _RobotConnection(sock, addr)
        else:
            conn = self.gripper_conn = _GripperConnection(sock, addr)
        self._sel.register(sock, selectors.EVENT_READ, ("tcp", conn))
        log.info("%s client connected from %s:%d", what, *addr)

    def _close_conn(self, conn: _RobotConnection | _GripperConnection) -> None:
        for s in (conn.sock, conn.udp):
            if s is None:
                continue
            try:
                self._sel.unregister(s)
            except (KeyError, ValueError):
                pass
            s.close()
        conn.udp = None
        if conn is self.robot_conn:
            self.robot_conn = None
            self.drop_commands = 0  # injected losses belong to the session that saw them
            self.core.client_lost()
            log.info("FCI client %s:%d disconnected", *conn.addr)
        elif conn is self.gripper_conn:
            self.gripper_conn = None
            self.gripper.client_lost()
            log.info("gripper client %s:%d disconnected", *conn.addr)

    @staticmethod
    def _alive(conn: _RobotConnection | _GripperConnection) -> bool:
        """Whether a connection is still open (its peer may have closed it unseen yet)."""
        try:
            return conn.sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) != b""
        except (BlockingIOError, InterruptedError):
            return True
        except OSError:
            return False

    def _recv(self, conn: _RobotConnection | _GripperConnection) -> bytes | None:
        try:
            data = conn.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            log.info("connection from %s:%d failed: %s", *conn.addr, exc)
            self._close_conn(conn)
            return None
        if not data:
            self._close_conn(conn)
            return None
        return data

    def _send_tcp(self, conn: _RobotConnection | _GripperConnection, data: bytes) -> None:
        try:
            conn.sock.setblocking(True)
            conn.sock.settimeout(1.0)
            conn.sock.sendall(data)
        except OSError as exc:
            log.info("sending to %s:%d failed: %s", *conn.addr, exc)
            self._close_conn(conn)
        else:
            conn.sock.setblocking(False)

    # -- robot TCP ---------------------------------------------------------------------

    def _read_tcp(self, conn: _RobotConnection | _GripperConnection) -> None:
        """Cut what arrived into messages and handle them; a stream that cannot be cut
        (bad size) is closed, the server keeps serving."""
        data = self._recv(conn)
        if not data:
            return
        try:
            messages = conn.reader.feed(data)
        except ProtocolError as exc:
            log.warning("closing connection from %s:%d: %s", *conn.addr, exc)
            self._close_conn(conn)
            return
        for msg in messages:
            if conn is self.robot_conn and isinstance(conn, _RobotConnection):
                self._handle_robot_message(conn, msg)
            elif conn is self.gripper_conn and isinstance(conn, _GripperConnection):
                self._handle_gripper_message(conn, msg)
            else:
                return  # closed while handling an earlier message

    def _handle_robot_message(self, conn: _RobotConnection, msg: fci.Message) -> None:
        if conn.dialect is None:
            self._handle_connect(conn, msg)
            return
        d = conn.dialect
        command = d.command_for_id(msg.command)
        if command is None or command is Command.CONNECT:
            log.warning(
                "unknown command id %d (protocol v%d) from %s:%d",
                msg.command,
                d.version,
                *conn.addr,
            )
            # Answer with the generic "command not possible" so a waiting client fails fast.
            self._send_tcp(conn, fci.HEADER.pack(msg.command, msg.command_id, 13) + b"\x01")
            return
        try:
            fields = d.decode_request(command, msg.payload)
        except ProtocolError as exc:
            log.warning("malformed %s request: %s", command.value, exc)
            self._reply_invalid(conn, command, msg.command_id)
            return
        handler = getattr(self, f"_cmd_{command.name.lower()}")
        handler(conn, command, msg.command_id, fields)

    def _reply(
        self, conn: _RobotConnection, command: Command, cid: int, status: Any, **extra: Any
    ) -> None:
        assert conn.dialect is not None
        self._send_tcp(conn, conn.dialect.encode_response(command, cid, status, **extra))

    def _reply_invalid(self, conn: _RobotConnection, command: Command, cid: int) -> None:
        assert conn.dialect is not None
        status_type = conn.dialect.status_type(command)
        for name in ("INVALID_ARGUMENT_REJECTED", "COMMAND_NOT_POSSIBLE_REJECTED", "ERROR"):
            if hasattr(status_type, name):
                self._reply(conn, command, cid, getattr(status_type, name))
                return

    def _handle_connect(self, conn: _RobotConnection, msg: fci.Message) -> None:
        try:
            _, version, udp_port = fci.decode_connect_request(msg.raw)
        except ProtocolError as exc:
            log.warning("closing connection from %s:%d: expected Connect: %s", *conn.addr, exc)
            self._close_conn(conn)
            return
        accepted = self.config.versions or fci.SUPPORTED_VERSIONS
        if version not in accepted:
            answer = self.config.versions[-1] if self.config.versions else fci.NEWEST_VERSION
            log.warning("client speaks protocol v%d; this robot speaks %s", version, list(accepted))
            self._send_tcp(
                conn,
                fci.encode_connect_response(
                    msg.command_id, ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION, answer
                ),
            )
            return
        d = fci.dialect(version)
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind((self.config.host, 0))
        udp.setblocking(False)
        conn.udp = udp
        conn.udp_target = (conn.addr[0], udp_port)
        conn.dialect = d
        conn.state_wire = StateWire(d, self.core)
        conn.command_wire = CommandWire(d)
        self._sel.register(udp, selectors.EVENT_READ, ("robot-udp", conn))
        self._send_tcp(
            conn, fci.encode_connect_response(msg.command_id, ConnectStatus.SUCCESS, version)
        )
        log.info(
            "FCI client speaks protocol v%d; streaming states to %s:%d", version, *conn.udp_target
        )
        self._send_state(conn)  # clients block for a first state right after Connect

    def _cmd_move(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        assert conn.dialect is not None
        if not may_start_move(self.desk):  # the brakes are closed
            self._reply(conn, command, cid, MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED)
            return
        deviations = np.concatenate((f["maximum_path_deviation"], f["maximum_goal_pose_deviation"]))
        status = self.core.request_move(
            f["controller_mode"],
            f["motion_generator_mode"],
            deviations,
            has_none=conn.dialect.has_motion_generator_none,
            use_async=bool(f.get("use_async_motion_generator", False)),
        )
        self._reply(conn, command, cid, status)
        if status == MoveStatus.MOTION_STARTED:
            conn.move_id = cid
            conn.awaiting = False
            conn.command = None

    def _send_move_final(self, conn: _RobotConnection, status: MoveStatus) -> None:
        self.core.pending_final = None
        if conn.move_id is not None:
            self._reply(conn, Command.MOVE, conn.move_id, status)
        conn.move_id = None
        conn.awaiting = False

    def _cmd_stop_move(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        status = self.core.request_stop_move()
        if self.core.pending_final is not None and self.robot_conn is conn:
            self._send_move_final(conn, self.core.pending_final)
        self._reply(conn, command, cid, status)

    def _cmd_automatic_error_recovery(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.request_recovery())

    def _cmd_set_collision_behavior(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_collision_behavior(f))

    def _cmd_set_joint_impedance(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_joint_impedance(f["K_theta"]))

    def _cmd_set_cartesian_impedance(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_cartesian_impedance(f["K_x"]))

    def _cmd_set_guiding_mode(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(
            conn, command, cid, self.core.set_guiding_mode(f["guiding_mode"], f["nullspace"])
        )

    def _cmd_set_ee_to_k(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_ee_to_k(f["EE_T_K"]))

    def _cmd_set_ne_to_ee(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_ne_to_ee(f["NE_T_EE"]))

    def _cmd_set_f_to_ee(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(conn, command, cid, self.core.set_f_to_ee(f["F_T_EE"]))

    def _cmd_set_load(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(
            conn, command, cid, self.core.set_load(f["m_load"], f["F_x_Cload"], f["I_load"])
        )

    def _cmd_set_filters(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._reply(
            conn, command, cid, self.core.set_filters(np.array(list(f.values()), dtype=float))
        )

    def _cmd_get_cartesian_limit(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        # No virtual walls are configured on the simulated robot.
        self._reply(conn, command, cid, GetterSetterStatus.SUCCESS, object_world_size=np.zeros(3),
                    object_frame=np.eye(4).reshape(16), object_activation=False)  # fmt: skip

    def _wait_models(self) -> None:
        self._model_thread.join(timeout=60.0)

    def _cmd_get_robot_model(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._wait_models()
        if self._urdf is None:
            log.error("no URDF to serve (its generator failed)")
            self._reply(conn, command, cid, CommandBaseStatus.COMMAND_NOT_POSSIBLE_REJECTED)
            return
        self._reply(conn, command, cid, CommandBaseStatus.SUCCESS, urdf=self._urdf)

    def _cmd_load_model_library(
        self, conn: _RobotConnection, command: Command, cid: int, f: dict[str, Any]
    ) -> None:
        self._wait_models()
        lib = self._model_library(int(f["architecture"]), int(f["system"]))
        if isinstance(lib, str):
            log.error("answering LoadModelLibrary with kError: %s", lib)
            self._reply(conn, command, cid, LoadModelLibraryStatus.ERROR)
            return
        self._reply(conn, command, cid, LoadModelLibraryStatus.SUCCESS, library=lib)

    # -- robot UDP ---------------------------------------------------------------------

    def _read_robot_udp(self, conn: _RobotConnection) -> None:
        wire, udp = conn.command_wire, conn.udp
        if udp is None or wire is None:
            return
        while True:
            try:
                size, mid = wire.receive(udp)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return  # e.g. ICMP port unreachable from a vanished client
            if size != wire.size:
                self.stats.bad_datagrams += 1
                if self.stats.bad_datagrams <= 3 or self.stats.bad_datagrams % 1000 == 0:
                    log.warning(
                        "dropping a %d-byte command datagram (protocol v%d expects %d)",
                        size,
                        conn.dialect.version if conn.dialect else 0,
                        wire.size,
                    )
                continue
            if self.drop_commands > 0:
                self.drop_commands -= 1
                continue
            if mid < conn.last_sent_id:
                continue  # late: answers a state older than the newest one sent
            conn.command = wire.accept(mid)

    def _send_state(self, conn: _RobotConnection) -> None:
        wire = conn.state_wire
        if wire is None or conn.udp is None or conn.udp_target is None:
            return
        core = self.core
        moving = core.robot_mode == RobotMode.MOVE
        mid = self.tick_count + 1  # ms since power-up; never 0, strictly increasing
        data = wire.fill(mid, core.success_rate if moving else 0.0)
        try:
            conn.udp.sendto(data, conn.udp_target)
        except OSError:
            pass  # the client's socket is gone; the TCP side will tell
        conn.last_sent_id = mid
        # libfranka answers states only once its control loop runs: it skips the state that
        # first shows the motion's modes. Await commands (lockstep) once one has arrived.
        conn.awaiting = moving and not core.first_command

    # -- gripper -------------------------------------------------------------------------

    def _gripper_reply(
        self, conn: _GripperConnection, command: int, cid: int, status: GripperStatus
    ) -> None:
        payload = fci.GRIPPER_RESPONSE.encode(status=int(status))
        self._send_tcp(conn, fci.encode_gripper_message(GripperCommand(command), cid, payload))

    def _handle_gripper_message(self, conn: _GripperConnection, msg: fci.Message) -> None:
        if not conn.connected:
            try:
                _, version, udp_port = fci.decode_gripper_connect_request(msg.raw)
            except ProtocolError as exc:
                log.warning("closing gripper connection: expected Connect: %s", exc)
                self._close_conn(conn)
                return
            if version != fci.GRIPPER_VERSION:
                log.warning(
                    "gripper client speaks v%d; the hand speaks v%d", version, fci.GRIPPER_VERSION
                )
                self._send_tcp(
                    conn,
                    fci.encode_gripper_connect_response(
                        msg.command_id,
                        fci.GripperConnectStatus.INCOMPATIBLE_LIBRARY_VERSION,
                    ),
                )
                return
            udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            udp.bind((self.config.host, 0))
            udp.setblocking(False)
            conn.udp, conn.udp_target, conn.connected = udp, (conn.addr[0], udp_port), True
            self._sel.register(udp, selectors.EVENT_READ, ("gripper-udp", conn))
            self._send_tcp(
                conn,
                fci.encode_gripper_connect_response(
                    msg.command_id, fci.GripperConnectStatus.SUCCESS
                ),
            )
            self._send_gripper_state(conn)
            return
        try:
            command = GripperCommand(msg.command)
            codec = fci.GRIPPER_REQUESTS[command]
            f = codec.decode(msg.payload)
        except (ValueError, KeyError, ProtocolError) as exc:
            log.warning("bad gripper request %d: %s", msg.command, exc)
            self._send_tcp(
                conn,
                fci.gripper.GRIPPER_HEADER.pack(msg.command, msg.command_id, 12)
                + int(GripperStatus.FAIL).to_bytes(2, "little"),
            )
            return
        g = self.gripper
        self._gripper_pending[msg.command_id] = int(command)
        status: GripperStatus | None
        if command is GripperCommand.HOMING:
            g.homing(msg.command_id)
            status = None
        elif command is GripperCommand.MOVE:
            status = g.move(msg.command_id, f["width"], f["speed"])
        elif command is GripperCommand.GRASP:
            status = g.grasp_object(
                msg.command_id,
                f["width"],
                f["epsilon_inner"],
                f["epsilon_outer"],
                f["speed"],
                f["force"],
            )
        elif command is GripperCommand.STOP:
            status = g.stop()
        else:
            status = GripperStatus.FAIL
        self._flush_gripper()
        if status is not None:
            self._gripper_pending.pop(msg.command_id, None)
            self._gripper_reply(conn, int(command), msg.command_id, status)

    def _flush_gripper(self) -> None:
        conn = self.gripper_conn
        done, self.gripper.completed = self.gripper.completed, []
        if conn is None:
            return
        for cid, status in done:
            command = self._gripper_pending.pop(cid, int(GripperCommand.MOVE))
            self._gripper_reply(conn, command, cid, status)
        if self.tick_count % GRIPPER_STATE_PERIOD == 0:
            self._send_gripper_state(conn)

    def _send_gripper_state(self, conn: _GripperConnection) -> None:
        if conn.udp is None or conn.udp_target is None:
            return
        rec = np.zeros((), fci.GRIPPER_STATE_DTYPE)
        rec["message_id"] = self.tick_count & 0xFFFFFFFF
        rec["width"] = self.gripper.width
        rec["max_width"] = self.gripper.max_width
        rec["is_grasped"] = self.gripper.is_grasped
        rec["temperature"] = self.gripper.temperature
        try:
            conn.udp.sendto(rec.tobytes(), conn.udp_target)
        except OSError:
            pass

    @staticmethod
    def _drain(sock: socket.socket | None) -> None:
        if sock is None:
            return
        while True:
            try:
                sock.recv(2048)
            except OSError:
                return

    # -- control -----------------------------------------------------------------------

    def _serve_control(self) -> None:
        conn = self._control
        try:
            request = conn.recv()
        except (EOFError, OSError):
            self._sel.unregister(conn.fileno())
            self._control = None
            self._running = False
            return
        try:
            reply: Any = ("ok", self.control(*request))
        except Exception as exc:  # reported to the caller; the server keeps serving
            reply = ("error", f"{type(exc).__name__}: {exc}")
        try:
            conn.send(reply)
        except (OSError, EOFError):
            self._running = False

    def control(self, op: str, *args: Any) -> Any:
        """Requests of the Python API (between ticks)."""
        core = self.core
        if op == "stop":
            self._running = False
            return None
        if op == "state":
            out: dict[str, Any] = {k: v.copy() for k, v in core.state.items()}
            mg, ctrl, mode = core.state_modes()
            out.update(
                motion_generator_mode=mg, controller_mode=ctrl, robot_mode=mode,
                errors=core.errors.copy(), reflex_reason=core.reflex_reason.copy(),
                time=self.tick_count * DT, gripper_width=self.gripper.width,
                gripper_is_grasped=self.gripper.is_grasped,
                cube_position=self._body_position("cube"),
            )  # fmt: skip
            return out
        if op == "inject_reflex":
            core.inject_reflex(list(args[0]))
            return None
        if op == "drop_commands":
            n = int(args[0])
            if n < 0:
                raise ValueError(f"drop_commands: expected n >= 0, got {n}")
            self.drop_commands = n
            return None
        if op == "user_stop":
            core.set_user_stop(bool(args[0]))
            return None
        if op == "guiding":
            core.set_guiding(bool(args[0]))
            return None
        if op == "set_joint_positions":
            if core.robot_mode == RobotMode.MOVE:
                raise ValueError("set_joint_positions: not while a motion runs")
            q = np.asarray(args[0], dtype=float)
            if q.shape != (7,) or not np.all(np.isfinite(q)):
                raise ValueError(f"q: expected 7 finite joint positions, got {q.tolist()}")
            core.reset(q)
            return None
        if op == "stats":
            st = self.stats
            wall = time.monotonic() - st.started
            return {
                "ticks": st.ticks, "late_ticks": st.late_ticks, "resyncs": st.resyncs,
                "commands_received": st.commands_received, "commands_lost": st.commands_lost,
                "bad_datagrams": st.bad_datagrams, "wall_time": wall,
                "cpu_time": time.process_time() - st.cpu_started,
                "sim_time": st.ticks * DT,
            }  # fmt: skip
        if op == "reset_stats":
            self.stats = Stats()
            return None
        raise ValueError(f"unknown control request {op!r}")

    def _body_position(self, name: str) -> list[float] | None:
        import mujoco

        bid = mujoco.mj_name2id(self.physics.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            return None
        return [float(x) for x in self.physics.data.xpos[bid]]


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


def run(config: SimConfig, control: Any = None, ready: Any = None) -> None:
    """Build a server from ``config`` and serve until stopped (process entry point)."""
    server = SimServer(config)
    if control is not None:
        server.attach_control(control)
    if ready is not None:
        ready.send(("ready", None))
    server.serve_forever()


__all__ = ["SimConfig", "SimServer", "Stats", "run"]
