"""Hostile and careless clients against a realtime simulator: none of them may stall the
1 kHz loop (its worst lateness stays far below the 100 ms at which it would re-anchor,
where a blocking send used to stall it for a second), none may hold the robot, and the
robot stays usable for an honest client afterwards."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.probe import GripperProbe, gripper_flood, oversized_message, slow_reader

pytestmark = pytest.mark.timeout(120)

# [s] worst tick lateness tolerated under attack. Without attacks, a loaded 2-core
# machine shows a few ms at worst, rarely a scheduling stall of 100 ms or more (then the
# loop re-anchors); the blocking sends this guards against stalled it for up to 1.2 s.
WORST_LATE = 0.25


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fr3", connect_timeout=0.5) as s:
        yield s


def _quiet_stats(sim) -> dict:
    sim.reset_stats()
    return sim.stats()


def _assert_on_time(sim) -> None:
    st = sim.stats()
    assert st["worst_late"] < WORST_LATE, st


def _assert_honest_client_works(sim) -> None:
    with lf.Robot(sim.host) as robot:
        robot.automatic_error_recovery()
        assert robot.read_once().robot_mode == lf.RobotMode.kIdle


def test_a_client_that_never_reads_is_disconnected_without_stalling_the_loop(sim):
    _quiet_stats(sim)
    t0 = time.monotonic()
    with slow_reader(sim.host, requests=3000):
        while sim.stats()["clients_dropped"] < 1:  # it reads nothing meanwhile
            assert time.monotonic() - t0 < 10.0, sim.stats()
            time.sleep(0.05)
    _assert_on_time(sim)
    _assert_honest_client_works(sim)


def test_a_gripper_flood_is_answered_in_full_without_stalling_the_loop(sim):
    _quiet_stats(sim)
    assert gripper_flood(sim.host, requests=20000) == 20000
    _assert_on_time(sim)
    g = GripperProbe(sim.host)
    try:
        assert g.request(fci.GripperCommand.HOMING) == fci.GripperStatus.SUCCESS
    finally:
        g.close()


@pytest.mark.parametrize("port", [fci.COMMAND_PORT, fci.GRIPPER_COMMAND_PORT])
def test_a_16_mib_message_is_refused_at_its_header(sim, port):
    _quiet_stats(sim)
    t0 = time.monotonic()
    assert oversized_message(sim.host, port=port)
    assert time.monotonic() - t0 < 5.0
    _assert_on_time(sim)
    _assert_honest_client_works(sim)


def test_a_connection_that_never_connects_is_closed_and_a_second_client_hears_busy(sim):
    idle = socket.create_connection((sim.host, fci.COMMAND_PORT), timeout=5.0)
    with idle:
        time.sleep(0.05)  # accepted first
        with pytest.raises(lf.NetworkException, match="robot busy: another client"):
            lf.Robot(sim.host)
        assert idle.recv(100) == b""  # closed after connect_timeout (0.5 s)
    _assert_honest_client_works(sim)
    holder = lf.Robot(sim.host)
    try:
        with pytest.raises(lf.NetworkException, match="robot busy"):
            lf.Robot(sim.host)
        with lf.Gripper(sim.host):
            with pytest.raises(lf.NetworkException, match="gripper: robot busy"):
                lf.Gripper(sim.host)
    finally:
        holder.close()


def test_udp_garbage_during_a_motion_is_counted_and_the_motion_completes(sim):
    """Wrong-size and spoofed datagrams at the robot's command socket while a torque
    motion runs: dropped and counted; the honest motion ends normally."""
    stop = threading.Event()

    def spray(target: tuple[str, int]) -> None:
        rng = np.random.default_rng(7)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            while not stop.is_set():
                s.sendto(rng.bytes(int(rng.integers(1, 2000))), target)
                time.sleep(0.0002)

    with lf.Robot(sim.host) as robot:
        robot.automatic_error_recovery()
        before = sim.stats()["bad_datagrams"]
        threads: list[threading.Thread] = []
        ticks = 0

        def torque(state, dt):
            nonlocal ticks
            ticks += 1
            if ticks == 2:
                peer = robot._conn.net._udp_peer
                t = threading.Thread(target=spray, args=(peer,), daemon=True)
                t.start()
                threads.append(t)
            out = lf.Torques(np.zeros(7))
            return lf.motion_finished(out) if ticks >= 500 else out

        try:
            robot.control(torque)
        finally:
            stop.set()
            for t in threads:
                t.join()
        assert sim.stats()["bad_datagrams"] > before


def test_model_libraries_are_built_off_the_loop(sim_for_version):
    """LoadModelLibrary for every platform (some compile, some cannot): each is answered,
    success or kError, and the loop keeps time while compilers run (a FER: protocol 5 has
    the request)."""
    from panda_py.sim.probe import RawClient

    sim = sim_for_version(5, lockstep=False, connect_timeout=0.5)
    _quiet_stats(sim)
    c = RawClient(sim.host, 5)
    try:
        cids = [
            c.send(fci.Command.LOAD_MODEL_LIBRARY, architecture=int(a), system=int(s))
            for a in fci.ModelLibraryArchitecture
            for s in fci.ModelLibrarySystem
        ]
        c.tcp.settimeout(120.0)
        statuses = {c.response(fci.Command.LOAD_MODEL_LIBRARY, cid)[0] for cid in cids}
    finally:
        c.close()
    assert statuses <= {fci.LoadModelLibraryStatus.SUCCESS, fci.LoadModelLibraryStatus.ERROR}
    assert fci.LoadModelLibraryStatus.ERROR in statuses  # Windows, at least
    _assert_on_time(sim)
