"""Protocol version negotiation (both ways), connection failures and realtime policy."""

from __future__ import annotations

import os
import socket
import threading
import time
import warnings
from collections.abc import Iterator

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.libfranka import realtime as _realtime
from panda_py.robots import RobotKind
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def sim6():
    """A robot that speaks protocol v6 only (libfranka 0.10-0.13.2)."""
    with Simulator(free_loopback_host(), "fr3-pre-5.9", lockstep=True, versions=(6,)) as s:
        yield s


def test_a_robot_speaking_an_older_version_gets_that_version(sim6):
    with lf.Robot(sim6.host) as robot:  # offers v10, is told 6, reconnects with 6
        assert robot.server_version() == 6
        assert robot.robot_spec.kind is RobotKind.FR3_PRE_5_9  # v6-9: an FR3 before 5.9
        n = [0]

        def torque(state, dt):  # v6 has no "no generator": joint velocity with dq = 0
            n[0] += 1
            return (
                lf.motion_finished(lf.Torques(np.zeros(7)))
                if n[0] >= 30
                else lf.Torques(np.zeros(7))
            )

        robot.control(torque)
        assert n[0] == 30


def test_a_forced_version_the_robot_refuses_raises(sim6):
    with pytest.raises(lf.IncompatibleVersionException) as info:
        lf.Robot(sim6.host, version=5)
    assert info.value.server_version == 6 and info.value.library_version == 5
    assert "server version: 6" in str(info.value)


class _FakeRobot:
    """Answers the Connect request with ``(status, version)``; streams no states."""

    def __init__(self, status: int, version: int) -> None:
        self.host = free_loopback_host()
        self.listener = socket.create_server((self.host, fci.COMMAND_PORT))
        self.status, self.version = status, version
        self.closed = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        try:
            conn, _ = self.listener.accept()
        except OSError:
            return
        with conn:
            conn.settimeout(5)
            data = b""
            while len(data) < fci.CONNECT_REQUEST.size:
                chunk = conn.recv(64)
                if not chunk:
                    return
                data += chunk
            cid, _, _ = fci.decode_connect_request(data)
            conn.sendall(fci.CONNECT_RESPONSE.pack(0, cid, 15, self.status, self.version))
            self.closed.wait(10.0)  # holds the connection open until the test is done

    def close(self) -> None:
        self.closed.set()
        self.listener.close()
        self.thread.join(5)


@pytest.fixture
def fake() -> Iterator[type[_FakeRobot]]:
    made: list[_FakeRobot] = []

    def make(status: int, version: int) -> _FakeRobot:
        made.append(_FakeRobot(status, version))
        return made[-1]

    yield make  # type: ignore[misc]
    for f in made:
        f.close()


def test_a_robot_speaking_a_newer_version_raises_a_clear_error(fake):
    robot = fake(1, 11)  # "incompatible, I speak 11"
    with pytest.raises(lf.IncompatibleVersionException, match="server version: 11") as info:
        lf.Robot(robot.host)
    assert info.value.server_version == 11 and info.value.library_version == 10
    assert "3-10" in str(info.value)


def test_a_silent_robot_times_out_after_one_second(fake):
    robot = fake(0, 10)  # accepts, but never streams a state
    start = time.monotonic()
    with pytest.raises(lf.NetworkException, match="UDP receive: Timeout"):
        lf.Robot(robot.host)
    assert 0.9 < time.monotonic() - start < 2.5


def test_nothing_listening_is_a_network_exception():
    host = free_loopback_host()
    with pytest.raises(lf.NetworkException, match="refused"):
        lf.Robot(host)
    with pytest.raises(lf.NetworkException):
        lf.Gripper(host)


def test_enforce_without_realtime_permission_raises_before_connecting(monkeypatch):
    def refuse(*args: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    with pytest.raises(lf.RealtimeException, match="realtime"):
        lf.Robot(free_loopback_host(), lf.RealtimeConfig.kEnforce)  # nothing listens there


def test_ignore_without_permission_warns_once_and_runs(monkeypatch, sim6):
    def refuse(*args: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(_realtime, "_warned", False)
    with lf.Robot(sim6.host) as robot, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(2):
            robot.control(lambda s, dt: lf.motion_finished(lf.Torques(np.zeros(7))))
    assert [w.category for w in caught] == [RuntimeWarning]
    assert "SCHED_FIFO" in str(caught[0].message)


@pytest.mark.skipif(not _realtime.fifo_permitted(), reason="SCHED_FIFO not permitted here")
def test_control_loops_run_fifo_and_restore_the_policy(sim6):
    before = os.sched_getscheduler(0)
    seen = []
    with lf.Robot(sim6.host, lf.RealtimeConfig.kEnforce) as robot:
        robot.control(lambda s, dt: seen.append(os.sched_getscheduler(0)) or
                      lf.motion_finished(lf.Torques(np.zeros(7))))  # fmt: skip
    assert seen == [os.SCHED_FIFO]
    assert os.sched_getscheduler(0) == before


def test_set_ee_on_protocol_3_sets_the_whole_flange_to_ee_transform():
    """v3 has no nominal EE: ``set_ee`` sends SetFToEE, and the state's F_T_EE is it."""
    T = np.eye(4)
    T[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = (0.01, 0.0, 0.2)
    with (
        Simulator(free_loopback_host(), lockstep=True, versions=(3,)) as sim,
        lf.Robot(sim.host) as robot,
    ):
        assert robot.server_version() == 3
        robot.set_ee(T)
        robot.read(lambda s: not np.allclose(s.F_T_EE[12:15], (0.01, 0.0, 0.2)))
        s = robot.read_once()
        np.testing.assert_allclose(s.F_T_EE.reshape(4, 4, order="F"), T, atol=1e-12)
        bad = T.copy()
        bad[:3, :3] *= 2.0  # not a rotation
        with pytest.raises(lf.CommandException, match="invalid argument"):
            robot.set_ee(bad)
