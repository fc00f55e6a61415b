"""The control process never outlives the user's process, and its death is a clear error."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import panda_py
from panda_py.libfranka.realtime import fifo_permitted
from panda_py.rt import ControlProcessError
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(120)

USER_SCRIPT = textwrap.dedent(
    """
    import sys, numpy as np, panda_py
    panda = panda_py.Panda(sys.argv[1])
    print(panda._proc.proc.pid, flush=True)
    if sys.argv[2] == "move":
        q = panda_py.constants.JOINT_POSITION_START + np.array([1.0, 0, 0, 0, 0, 0, 0])
        panda.move_to_joint_position(q, speed_factor=0.05)
    """
)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (exited, not yet reaped by a dead parent's reaper) counts as gone
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def _wait_gone(pid: int, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while _alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def _user(sim: Simulator, mode: str) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen(
        [sys.executable, "-c", USER_SCRIPT, sim.host, mode], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    return proc, int(proc.stdout.readline())


def test_killing_the_user_process_mid_move_stops_the_robot(sim: Simulator) -> None:
    user, child = _user(sim, "move")
    try:
        deadline = time.monotonic() + 30
        while sim.state()["robot_mode"] != panda_py.libfranka.RobotMode.kMove.value:
            assert time.monotonic() < deadline, "the move did not start"
            time.sleep(0.01)
        user.kill()
        user.wait()
        assert _wait_gone(child), "the control process outlived the user's process"
        deadline = time.monotonic() + 10
        while sim.state()["robot_mode"] == panda_py.libfranka.RobotMode.kMove.value:
            assert time.monotonic() < deadline, "the robot still moves"
            time.sleep(0.01)
        with panda_py.Panda(sim.host) as panda:  # the robot takes the next client
            assert panda.move_to_start()
    finally:
        user.kill()


def test_a_user_process_that_exits_without_closing_leaves_no_process(sim: Simulator) -> None:
    user, child = _user(sim, "exit")
    assert user.wait(timeout=30) == 0
    assert _wait_gone(child)


def test_killing_the_control_process_is_a_clear_error(sim: Simulator) -> None:
    panda = panda_py.Panda(sim.host)
    try:
        pid = panda._proc.proc.pid
        os.kill(pid, signal.SIGKILL)
        assert _wait_gone(pid)
        deadline = time.monotonic() + 5
        while not panda._proc.dead:  # the reader notices the closed channel
            assert time.monotonic() < deadline
            time.sleep(0.01)
        for call in (lambda: panda.q, panda.move_to_start, panda.raise_error, panda.recover):
            with pytest.raises(ControlProcessError, match="SIGKILL") as raised:
                call()
            assert raised.value.exitcode == -signal.SIGKILL
    finally:
        panda.close()


def test_close_ends_the_control_process(sim: Simulator) -> None:
    panda = panda_py.Panda(sim.host)
    pid = panda._proc.proc.pid
    panda.start_controller(panda_py.controllers.JointPosition())
    panda.close()
    assert not _alive(pid)
    with pytest.raises(ControlProcessError, match="closed"):
        panda.move_to_start()
    assert sim.state()["robot_mode"] != panda_py.libfranka.RobotMode.kMove.value


def test_the_callers_thread_keeps_its_scheduling_and_the_loop_runs_fifo_where_permitted(
    sim: Simulator,
) -> None:
    """panda-python's moves run libfranka's control() in the calling thread and leave it at
    SCHED_FIFO 99 (a busy loop in it then holds a core at realtime priority); ours run in
    the control process, whose loop alone takes SCHED_FIFO."""

    def mine() -> tuple[int, int]:
        return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority

    before = mine()
    with panda_py.Panda(sim.host) as panda:
        q = panda_py.constants.JOINT_POSITION_START + np.array([0.1, 0, 0, 0, 0, 0, 0])
        assert panda.move_to_joint_position(q)
        panda.start_controller(panda_py.controllers.CartesianImpedance())
        loop = os.sched_getscheduler(panda._proc.proc.pid)
        assert mine() == before
        panda.stop_controller()
    assert mine() == before
    assert loop == (os.SCHED_FIFO if fifo_permitted() else before[0])
