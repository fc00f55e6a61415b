"""The client against a careless or hostile network and caller: stray and spoofed state
datagrams, bogus message ids, bad timeouts and elbows; every wait ends, no socket leaks."""

from __future__ import annotations

import os
import socket
import struct
import time

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fer", lockstep=True) as s:
        yield s


def _open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def _spoof(robot: lf.Robot, source: str, message_id: int) -> None:
    """A state datagram of the right size with ``message_id``, sent from ``source``."""
    net = robot._conn.net
    data = bytearray(robot._conn.dialect.state_size)
    struct.pack_into("<Q", data, 0, message_id)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((source, 0))
        for _ in range(5):
            s.sendto(data, ("127.0.0.1", net.udp_port))


@pytest.mark.parametrize("version", [5, 10])
def test_spoofed_states_are_dropped_from_any_address_but_the_robots(sim_for_version, version):
    sim = sim_for_version(version)
    with lf.Robot(sim.host, version=version) as robot:
        before = robot.read_once().time.to_msec()
        # from another address, and from the robot's own address but another port
        for source in ("127.0.0.1", sim.host):
            _spoof(robot, source, 2**63)
            state = robot.read_once()
            assert before < state.time.to_msec() < 2**40
        # the socket is connected to where the states come from: the kernel dropped them
        net = robot._conn.net
        assert net._udp.getpeername() == net._udp_peer and net.foreign_datagrams == 0
        # the commands still go to the robot: a short motion runs
        robot.control(lambda s, d: lf.motion_finished(lf.Torques(np.zeros(7))))


def test_datagrams_before_the_first_state_are_checked_by_their_sender() -> None:
    """Until the socket is connected (at the first state) and what was queued before is
    read, each datagram's sender is checked: another address, then the robot's address
    from another port, are counted and dropped; after that the kernel drops them."""
    from panda_py.libfranka import _network

    net = _network.Network.__new__(_network.Network)  # its UDP side only
    net._udp_size, net._next_due, net.spin = 8, 0.0, False
    net._robot_ip, net._udp_peer, net._checked, net.foreign_datagrams = "127.0.0.2", None, False, 0
    with (
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as robot,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as neighbour,
    ):
        udp.bind(("127.0.0.1", 0))
        udp.setblocking(False)
        net._udp = udp
        robot.bind(("127.0.0.2", 0))
        stranger.bind(("127.0.0.3", 0))
        neighbour.bind(("127.0.0.2", 0))  # the robot's address, another port
        to = udp.getsockname()

        def send(sock: socket.socket, tag: bytes) -> None:
            sock.sendto(tag * 8, to)
            time.sleep(0.01)  # queued in this order

        send(stranger, b"s")
        send(robot, b"a")
        send(neighbour, b"n")
        send(robot, b"b")
        assert net._recv_udp(block=False) == b"a" * 8  # the stranger's first: dropped
        assert udp.getpeername() == robot.getsockname() and not net._checked
        assert net._recv_udp(block=False) == b"b" * 8  # the neighbour's: dropped
        assert net.foreign_datagrams == 2 and net._checked
        send(stranger, b"t")  # now dropped by the kernel
        send(robot, b"c")
        assert net._recv_udp(block=False) == b"c" * 8
        assert net._recv_udp(block=False) is None
        net.send_udp(b"command")
        assert robot.recv(64) == b"command"


def test_a_bogus_newest_id_ends_in_a_timeout_not_a_hang(sim):
    """Every real state is then "older"; the wait still ends at its deadline."""
    with lf.Robot(sim.host) as robot:
        robot._conn.last_id = 2**64 - 1  # as after a state with the largest id
        t0 = time.monotonic()
        with pytest.raises(lf.NetworkException, match="UDP receive: Timeout"):
            robot._conn.receive_state()
        # the 1 s UDP timeout, and the rest a loaded machine adds (measured up to 2.2 s)
        assert time.monotonic() - t0 < 1.0 + 3.0


def test_a_motion_cancelled_after_a_bogus_id_returns_in_bounded_time(sim):
    with lf.Robot(sim.host) as robot:
        calls = 0

        def torque(state, dt):
            nonlocal calls
            calls += 1
            if calls == 3:
                robot._conn.last_id = 2**64 - 1
            return lf.Torques(np.zeros(7))

        t0 = time.monotonic()
        with pytest.raises(lf.NetworkException):
            robot.control(torque)
        assert time.monotonic() - t0 < 5.0  # receive (1 s) + StopMove + idle wait, bounded
    with lf.Robot(sim.host) as robot:  # the robot is usable again
        robot.automatic_error_recovery()
        assert robot.read_once().robot_mode == lf.RobotMode.kIdle


@pytest.mark.parametrize("timeout", [float("inf"), 1e300, float("nan"), 0.0, -1.0, "10"])
def test_robot_refuses_a_bad_timeout_before_opening_a_socket(sim, timeout):
    fds = _open_fds()
    with pytest.raises(ValueError, match="timeout"):
        lf.Robot(sim.host, timeout=timeout)
    assert _open_fds() == fds


def test_no_socket_is_left_open_when_connecting_fails(sim):
    fds = _open_fds()
    with Simulator(free_loopback_host(), robot="fr3", lockstep=True, versions=(10,)) as only10:
        fds_sim = _open_fds()
        with pytest.raises(lf.IncompatibleVersionException):
            lf.Robot(only10.host, version=5)
        assert _open_fds() == fds_sim
    with pytest.raises(lf.NetworkException):
        lf.Robot(free_loopback_host())  # nothing listens there
    assert _open_fds() == fds


@pytest.mark.parametrize("cls, value", [(lf.CartesianPose, np.eye(4)),
                                        (lf.CartesianVelocities, np.zeros(6))])  # fmt: skip
def test_elbow_is_checked_where_it_is_assigned(cls, value):
    cmd = cls(value)
    assert cmd.elbow is None
    cmd.elbow = [0.3, 1.0]  # a list is fine: kept as an array
    assert isinstance(cmd.elbow, np.ndarray) and cmd.elbow.tolist() == [0.3, 1.0]
    assert cmd.has_elbow()
    for bad, what in (([0.3, 0.5], r"elbow\[1\] must be \+1 or -1"), ("x", "elbow: expected"),
                      ([0.3], r"shape \(2,\)"), ([np.nan, 1.0], "infinite or NaN")):  # fmt: skip
        with pytest.raises(ValueError, match=what):
            cmd.elbow = bad
        assert cmd.elbow.tolist() == [0.3, 1.0]  # unchanged
    cmd.elbow = None
    assert not cmd.has_elbow()


def test_errors_pickle_with_their_fields():
    """Errors cross the control process's boundary: every one survives pickling."""
    import pickle

    from panda_py import fci

    errors = [
        lf.IncompatibleVersionException("v", server_version=5, library_version=10),
        lf.CommandException("c", command="Move", status=fci.MoveStatus.ABORTED),
        lf.ControlException("x", reflex_reason=("joint_reflex",), success_rate=0.5),
        lf.NetworkException("libfranka: robot busy: another client is connected"),
        fci.ProtocolError("TCP message size", "12..428 bytes", "16777216 bytes"),
    ]
    for err in errors:
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err)
        assert vars(back) == vars(err)
