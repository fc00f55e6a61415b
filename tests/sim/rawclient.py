"""A deliberately small FCI client for testing the simulator at the wire level.

It uses only panda_py.fci (codecs), so simulator tests do not depend on our full client.
"""

from __future__ import annotations

import socket
import time
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.fci import Command, MoveControllerMode, MoveMotionGeneratorMode


class RawClient:
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
        while True:
            for i, m in enumerate(self.pending):
                if m.command_id == command_id:
                    return self.pending.pop(i)
            data = self.tcp.recv(65536)
            if not data:
                raise ConnectionError("server closed connection")
            self.pending += self.reader.feed(data)

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
        """The newest state datagram (drains older ones)."""
        assert self.dialect is not None
        data, self.robot_addr = self.udp.recvfrom(4096)
        self.udp.setblocking(False)
        try:
            while True:
                data, self.robot_addr = self.udp.recvfrom(4096)
        except BlockingIOError:
            pass
        finally:
            self.udp.setblocking(True)
            self.udp.settimeout(5.0)
        return self.dialect.decode_state(data).copy()

    def wait_state(self, predicate: Any, timeout: float = 5.0) -> np.void:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            s = self.state()
            if predicate(s):
                return s
        raise TimeoutError("no state matched")

    def command(self, state: np.void, **fields: Any) -> None:
        assert self.dialect is not None and self.robot_addr is not None
        rec = self.dialect.new_command()
        rec["message_id"] = state["message_id"]
        for k, v in fields.items():
            rec[k] = v
        self.udp.sendto(self.dialect.encode_command(rec), self.robot_addr)
