"""Wire-level probes: deliberately small FCI robot and gripper clients.

They speak the protocol with nothing but :mod:`panda_py.fci` codecs, one request at a time,
so the simulator's tests, its demo and anyone debugging a robot connection can look at
exactly what goes over the wire. For programs, use :mod:`panda_py.libfranka`.
"""

from __future__ import annotations

import socket
import time
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import Command, MoveControllerMode, MoveMotionGeneratorMode

# A receive queue this long may have overflowed; the kernel then dropped the newest
# datagrams, so what is queued is stale and the next arrival is waited for instead.
_OVERFLOW_SUSPECT = 32


def _fresh_datagram(sock: socket.socket, size: int) -> tuple[bytes, Any]:
    """The newest queued datagram, or the next one if none (or too many) were queued."""
    newest = None
    count = 0
    sock.setblocking(False)
    try:
        while True:
            newest = sock.recvfrom(size)
            count += 1
    except BlockingIOError:
        pass
    finally:
        sock.setblocking(True)
        sock.settimeout(5.0)
    if newest is None or count >= _OVERFLOW_SUSPECT:
        return sock.recvfrom(size)
    return newest


def _receive(
    tcp: socket.socket, reader: fci.MessageReader, pending: list[fci.Message], command_id: int
) -> fci.Message:
    """The response with ``command_id``, keeping others that arrive meanwhile."""
    while True:
        for i, m in enumerate(pending):
            if m.command_id == command_id:
                return pending.pop(i)
        data = tcp.recv(65536)
        if not data:
            raise ConnectionError("server closed connection")
        pending += reader.feed(data)


class RawClient:
    """Connects to ``host``:1337 speaking protocol ``version``; ``status`` and
    ``server_version`` hold the Connect answer."""

    def __init__(self, host: str, version: int = 10, *, timeout: float = 5.0) -> None:
        self.host = host
        self.tcp = socket.create_connection((host, fci.COMMAND_PORT), timeout=timeout)
        self.tcp.settimeout(timeout)
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp.bind(("0.0.0.0", 0))
        self.udp.settimeout(timeout)
        self.reader = fci.RobotMessageReader()
        self.pending: list[fci.Message] = []
        self.counter = 0
        self.robot_addr: tuple[str, int] | None = None
        self.tcp.sendall(fci.encode_connect_request(version, self.udp.getsockname()[1]))
        msg = self.receive(0)
        _, self.status, self.server_version = fci.decode_connect_response(msg.raw)
        self.dialect = fci.dialect(version) if self.status == fci.ConnectStatus.SUCCESS else None
        self.counter = 1

    def close(self) -> None:
        self.tcp.close()
        self.udp.close()

    # -- TCP --------------------------------------------------------------------------

    def receive(self, command_id: int) -> fci.Message:
        return _receive(self.tcp, self.reader, self.pending, command_id)

    def send(self, command: Command, **fields: Any) -> int:
        assert self.dialect is not None
        cid = self.counter
        self.counter += 1
        self.tcp.sendall(self.dialect.encode_request(command, cid, **fields))
        return cid

    def response(self, command: Command, cid: int) -> tuple[Any, dict[str, Any]]:
        assert self.dialect is not None
        return self.dialect.decode_response(command, self.receive(cid).payload)

    def request(self, command: Command, **fields: Any) -> tuple[Any, dict[str, Any]]:
        return self.response(command, self.send(command, **fields))

    def move(
        self, controller: MoveControllerMode, generator: MoveMotionGeneratorMode
    ) -> tuple[int, Any]:
        dev = np.array(fci.DEFAULT_DEVIATION)
        cid = self.send(
            Command.MOVE,
            controller_mode=int(controller),
            motion_generator_mode=int(generator),
            maximum_path_deviation=dev,
            maximum_goal_pose_deviation=dev,
        )
        status, _ = self.response(Command.MOVE, cid)
        return cid, status

    # -- UDP --------------------------------------------------------------------------

    def state(self) -> np.void:
        """The newest state (see :func:`_fresh_datagram`)."""
        assert self.dialect is not None
        data, self.robot_addr = _fresh_datagram(self.udp, 4096)
        return self.dialect.decode_state(data).copy()

    def wait_state(self, predicate: Any, timeout: float = 5.0) -> np.void:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            s = self.state()
            if predicate(s):
                return s
        raise TimeoutError("no state matched")

    def command(self, state: np.void, **fields: Any) -> None:
        """Answer ``state`` with a RobotCommand carrying ``fields``."""
        assert self.dialect is not None and self.robot_addr is not None
        rec = self.dialect.new_command()
        rec["message_id"] = state["message_id"]
        for k, v in fields.items():
            rec[k] = v
        self.udp.sendto(self.dialect.encode_command(rec), self.robot_addr)


class GripperProbe:
    """Connects to ``host``:1338 (gripper protocol v3); each command blocks until done."""

    def __init__(self, host: str, *, timeout: float = 30.0) -> None:
        from panda_py.fci import gripper as g

        self._g = g
        self.tcp = socket.create_connection((host, g.GRIPPER_COMMAND_PORT), timeout=timeout)
        self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.udp.bind(("0.0.0.0", 0))
        self.udp.settimeout(5.0)
        self.reader = g.GripperMessageReader()
        self.pending: list[fci.Message] = []
        self.tcp.sendall(g.encode_gripper_connect_request(self.udp.getsockname()[1]))
        _, self.status, self.server_version = g.decode_gripper_connect_response(
            self._receive(0).raw
        )
        self.counter = 1

    def close(self) -> None:
        self.tcp.close()
        self.udp.close()

    def _receive(self, command_id: int) -> fci.Message:
        return _receive(self.tcp, self.reader, self.pending, command_id)

    def request(self, command: Any, **fields: Any) -> Any:
        """Send a command (a ``GripperCommand``) and return its ``GripperStatus``."""
        g = self._g
        codec = g.GRIPPER_REQUESTS.get(command)
        payload = codec.encode(**fields) if codec is not None else b""
        cid = self.counter
        self.counter += 1
        self.tcp.sendall(g.encode_gripper_message(command, cid, payload))
        return g.decode_gripper_status(self._receive(cid).payload)

    def state(self) -> np.void:
        """A fresh gripper state (see :meth:`RawClient.state`)."""
        data, _ = _fresh_datagram(self.udp, 64)
        return self._g.decode_gripper_state(data).copy()


def follow_joint_positions(client: RawClient, q_of_t: Any, duration: float) -> tuple[Any, np.void]:
    """Stream joint positions ``q_of_t(t)`` [rad] for ``duration`` [s] as one joint-position
    motion, the way libfranka drives a callback; returns the final Move status and the
    last state."""
    cid, status = client.move(
        MoveControllerMode.JOINT_IMPEDANCE, MoveMotionGeneratorMode.JOINT_POSITION
    )
    if status != fci.MoveStatus.MOTION_STARTED:
        return status, client.state()
    gen = fci.MotionGeneratorMode.JOINT_POSITION
    client.wait_state(lambda s: s["motion_generator_mode"] == gen)
    ticks = max(1, round(duration * 1000))
    k = 0
    s = client.state()
    while s["robot_mode"] == fci.RobotMode.MOVE and k < ticks:
        k += 1
        client.command(
            s,
            q_c=np.asarray(q_of_t(k / 1000.0), dtype=float),
            motion_generation_finished=k == ticks,
        )
        s = client.state()
    final, _ = client.response(Command.MOVE, cid)
    return final, s


# -- hostile clients (the simulator's robustness tests and benchmarks) --------------------


def slow_reader(
    host: str, requests: int = 2000, *, version: int = 10, port: int = fci.COMMAND_PORT
) -> socket.socket:
    """Connect, then send ``requests`` requests and never read an answer: GetRobotModel
    on the FCI port (each answered with the URDF, about 5 kB), Stop on the gripper port.
    Returns the socket (the caller closes it); the robot should disconnect it once its
    answers pile up, and never wait for it."""
    from panda_py.fci import gripper as g

    tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    tcp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # fills at once
    tcp.settimeout(5.0)
    tcp.connect((host, port))
    if port == fci.COMMAND_PORT:
        tcp.sendall(fci.encode_connect_request(version, 9))
        d = fci.dialect(version)
        batch = b"".join(d.encode_request(Command.GET_ROBOT_MODEL, i + 1) for i in range(100))
    else:
        tcp.sendall(g.encode_gripper_connect_request(9))
        stop = g.GripperCommand.STOP
        batch = b"".join(g.encode_gripper_message(stop, i + 1, b"") for i in range(100))
    try:
        for _ in range(max(1, requests // 100)):
            tcp.sendall(batch)
    except OSError:
        pass  # disconnected, as it should be
    return tcp


def gripper_flood(host: str, requests: int = 20000) -> int:
    """Connect to the gripper and pipeline ``requests`` Stop commands as fast as the
    socket takes them, reading answers only to keep the stream going; returns how many
    answers arrived (the hand answers all of them)."""
    from panda_py.fci import gripper as g

    tcp = socket.create_connection((host, g.GRIPPER_COMMAND_PORT), timeout=10.0)
    with tcp:
        tcp.sendall(g.encode_gripper_connect_request(9))
        reader = g.GripperMessageReader()
        got = -1  # the Connect answer
        batch = b"".join(
            g.encode_gripper_message(g.GripperCommand.STOP, i + 1, b"") for i in range(500)
        )
        for _ in range(max(1, requests // 500)):
            tcp.sendall(batch)
            tcp.setblocking(False)
            try:
                while data := tcp.recv(65536):
                    got += len(reader.feed(data))
                return got  # the robot hung up (e.g. "robot busy")
            except BlockingIOError:
                pass
            finally:
                tcp.setblocking(True)
        deadline = time.monotonic() + 10.0
        while got < requests and time.monotonic() < deadline:
            data = tcp.recv(65536)
            if not data:
                break
            got += len(reader.feed(data))
        return got


def oversized_message(host: str, size: int = 16 << 20, *, port: int = fci.COMMAND_PORT) -> bool:
    """Connect and send one message of ``size`` bytes (a header announcing it, then the
    bytes). Returns True if the robot hung up before all of it was sent."""
    tcp = socket.create_connection((host, port), timeout=10.0)
    with tcp:
        try:
            tcp.sendall(fci.HEADER.pack(0, 0, size))
            chunk = bytes(65536)
            for _ in range(size // len(chunk)):
                tcp.sendall(chunk)
        except OSError:
            return True
        try:
            return tcp.recv(100) == b""
        except OSError:
            return True
