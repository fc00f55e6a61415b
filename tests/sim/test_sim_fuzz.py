"""Property-based fuzzing of the simulator's inputs: the FCI port (TCP 1337), the
gripper port (TCP 1338), the Cobot Pump's port (TCP 1339, a robot with the pump) and the
robot's UDP command socket. Whatever arrives, the
simulator keeps serving: an honest client connects and reads a state afterwards, and a
robot that took garbage for a command recovers with automatic error recovery.

Seeded and bounded (``derandomize``, a fixed number of examples), so the suite stays
deterministic and quick; ``benchmarks/soak_fuzz.py`` runs the same attacks for minutes.
"""

from __future__ import annotations

import socket
import struct
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.fci import Command, MoveControllerMode, MoveMotionGeneratorMode
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.probe import RawClient

pytestmark = pytest.mark.timeout(300)

FUZZ = settings(
    max_examples=40,
    derandomize=True,  # the same examples every run
    database=None,  # nothing written to the work tree
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fer", lockstep=True, connect_timeout=1.0) as s:
        yield s


def _robot_message(command: int, command_id: int, payload: bytes) -> bytes:
    return fci.HEADER.pack(command, command_id, fci.HEADER.size + len(payload)) + payload


def _gripper_message(command: int, command_id: int, payload: bytes) -> bytes:
    return struct.pack("<HII", command, command_id, 10 + len(payload)) + payload


def _messages(frame, commands: int) -> st.SearchStrategy[bytes]:
    """Well-framed messages with any command id and payload, or raw bytes."""
    framed = st.builds(
        frame,
        st.integers(0, commands),
        st.integers(0, 2**32 - 1),
        st.binary(max_size=600),
    )
    return st.lists(st.one_of(framed, st.binary(min_size=1, max_size=300)), max_size=8).map(
        b"".join
    )


def _exchange(host: str, port: int, connect: bytes | None, data: bytes) -> None:
    """Send ``connect`` (if any) then ``data`` on a new connection, read what comes back
    for a moment, close."""
    with socket.create_connection((host, port), timeout=2.0) as s:
        try:
            if connect is not None:
                s.sendall(connect)
            s.sendall(data)
            s.settimeout(0.02)
            while s.recv(65536):
                pass
        except OSError:
            pass  # the robot hung up on garbage, or there was nothing to read


def _still_serving(host: str) -> None:
    """An honest client gets in (waiting out a fuzzer's connection the robot has not yet
    seen close) and reads a state."""
    deadline = time.monotonic() + 5.0
    while True:
        try:
            with lf.Robot(host) as robot:
                robot.automatic_error_recovery()
                assert robot.read_once().robot_mode == lf.RobotMode.kIdle
                return
        except lf.NetworkException as exc:
            if "busy" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


@FUZZ
@given(version=st.sampled_from([5, 10]), connect=st.booleans(), data=_messages(_robot_message, 40))
def test_fci_port_survives_any_stream(sim_for_version, version, connect, data):
    sim = sim_for_version(version, connect_timeout=1.0)
    hello = fci.encode_connect_request(version, 9) if connect else None
    _exchange(sim.host, fci.COMMAND_PORT, hello, data)
    _still_serving(sim.host)


@FUZZ
@given(connect=st.booleans(), data=_messages(_gripper_message, 8))
def test_gripper_port_survives_any_stream(sim, connect, data):
    from panda_py.fci import gripper as g

    hello = g.encode_gripper_connect_request(9) if connect else None
    _exchange(sim.host, fci.GRIPPER_COMMAND_PORT, hello, data)
    with lf.Gripper(sim.host) as gripper:
        assert gripper.read_once().max_width > 0.0


@pytest.fixture(scope="module")
def pump_sim():
    with Simulator(
        free_loopback_host(), lockstep=True, connect_timeout=1.0, end_effector="cobot_pump"
    ) as s:
        yield s


@FUZZ
@given(connect=st.booleans(), data=_messages(_gripper_message, 5))
def test_vacuum_port_survives_any_stream(pump_sim, connect, data):
    from panda_py.fci import gripper as g

    hello = g.encode_gripper_connect_request(9, version=1) if connect else None
    _exchange(pump_sim.host, 1339, hello, data)
    deadline = time.monotonic() + 5.0
    while True:  # the fuzzer's connection may not have been seen closed yet
        try:
            with lf.VacuumGripper(pump_sim.host) as pump:
                assert pump.read_once().device_status == lf.VacuumGripperDeviceStatus.kGreen
                assert pump.stop() is True
                return
        except lf.NetworkException as exc:
            if "busy" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


@FUZZ
@given(
    version=st.sampled_from([5, 10]),
    datagrams=st.lists(
        st.one_of(
            st.binary(max_size=2000),
            st.integers(0, 2**31).map(lambda n: n.to_bytes(4, "little")),
        ),
        max_size=6,
    ),
    right_size=st.lists(st.binary(min_size=64, max_size=64), max_size=3),
)
def test_udp_command_socket_survives_any_datagram(sim_for_version, version, datagrams, right_size):
    """Garbage and right-sized random commands from the client's own UDP socket during a
    joint position motion: the robot keeps streaming states and ends the motion (normally or by
    a reflex), and recovers."""
    sim = sim_for_version(version, connect_timeout=1.0)
    c = RawClient(sim.host, version)
    try:
        _, status = c.move(
            MoveControllerMode.JOINT_IMPEDANCE, MoveMotionGeneratorMode.JOINT_POSITION
        )
        assert status == fci.MoveStatus.MOTION_STARTED
        s = c.state()
        size = c.dialect.command_size
        for d in datagrams:
            c.udp.sendto(d, c.robot_addr)
        for noise in right_size:  # random bytes of the right size answering this state
            body = (noise * (size // len(noise) + 1))[:size]
            c.udp.sendto(struct.pack("<Q", int(s["message_id"])) + body[8:], c.robot_addr)
        for _ in range(5):
            s = c.state()
            c.command(s, q_c=np.array(s["q_d"], dtype=float))
        c.request(Command.STOP_MOVE)
        assert c.state()["message_id"] > 0  # still streaming
    finally:
        c.close()
    _still_serving(sim.host)


@FUZZ
@given(datagrams=st.lists(st.binary(max_size=3000), min_size=1, max_size=10))
def test_client_ignores_any_datagram_from_elsewhere(sim, datagrams):
    with lf.Robot(sim.host) as robot:
        port = robot._conn.net.udp_port
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger:
            for d in datagrams:
                stranger.sendto(d, ("127.0.0.1", port))
        state = robot.read_once()
        assert state.robot_mode == lf.RobotMode.kIdle
        assert 0 < state.time.to_msec() < 2**40
