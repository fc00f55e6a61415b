"""The server's compiled lockstep ticks (``sim/lockstep.py``) against its Python reference,
in lockstep: a client's torque commands give the same states byte for byte, with what
the kernel hands back on the way (a datagram of the wrong size, a late answer, a lost
command, a TCP request, the Desk's page published), the same reflex at the same tick,
the same hand's states to its client, the same final answer and the same counts of
received, lost and bad commands. The loop runs in this process (the kernel releases the
GIL)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from typing import Any

import numpy as np
import pytest

from panda_py import fci
from panda_py.fci import (
    Command,
    ControllerMode,
    ErrorRecoveryStatus,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveStatus,
    RobotMode,
)
from panda_py.robots.params import get_robot
from panda_py.sim import free_loopback_host
from panda_py.sim.config import SimConfig
from panda_py.sim.desk.link import DeskLink
from panda_py.sim.gripper import GripperCore
from panda_py.sim.probe import GripperProbe, RawClient
from panda_py.sim.server import ENGAGE_WAIT, SimServer

pytestmark = pytest.mark.timeout(300)

LOST_WAIT = 0.3  # [s] the lockstep timeout: a command not sent is lost after it
REFLEX_AT = 600  # the command that jumps: the robot's rate check refuses it
START_TICK = 100_000  # the robot's clock at each motion's start


class SyncedServer(SimServer):
    """A server whose motions start from one state whatever ran before them on the wall
    clock: at the Move request the robot is reset to its start pose, the hand made anew
    and the clock set; the motion's first command is awaited as long as the others."""

    def _cmd_move(self, conn: Any, command: Command, cid: int, f: dict[str, Any]) -> None:
        self.core.state_buffer[:] = 0.0
        self.core.reset(np.asarray(self.config.q_start))
        self.gripper = GripperCore(self.physics)
        self.tick_count = START_TICK
        super()._cmd_move(conn, command, cid, f)

    def _lockstep_wait(self) -> float:
        moving = self.core.robot_mode == RobotMode.MOVE
        return self.config.lockstep_timeout if moving else ENGAGE_WAIT


def _torques(k: int) -> np.ndarray:
    """A smooth torque command [Nm] within the rate limit, then a jump at REFLEX_AT."""
    tau = 2.0 * min(1.0, k / 200.0) * np.sin(0.01 * k + np.arange(7))
    if k >= REFLEX_AT:
        tau[0] += 30.0
    return tau


def _hand_states(hand: GripperProbe) -> list[bytes]:
    """The hand's states of the motion (from its start's tick on) its client received."""
    hand.udp.setblocking(False)
    found = []
    while True:
        try:
            data = hand.udp.recv(64)
        except BlockingIOError:
            return found
        if int.from_bytes(data[:4], "little") > START_TICK:
            found.append(data)


def _drive(host: str, version: int) -> tuple[list[bytes], Any, Any, list[bytes]]:
    """One motion driven by a raw client (the hand's client connected beside it): every
    state of the motion as received, the Move's final status, the recovery's answer and
    the hand's states."""
    hand = GripperProbe(host)
    c = RawClient(host, version)
    d = c.dialect
    assert d is not None
    try:
        generator = MoveMotionGeneratorMode.NONE if version >= 7 else (
            MoveMotionGeneratorMode.JOINT_VELOCITY)  # fmt: skip
        cid, status = c.move(MoveControllerMode.EXTERNAL_CONTROLLER, generator)
        assert status == MoveStatus.MOTION_STARTED
        while True:  # (the states before the motion's first are the clock's)
            data, robot = c.udp.recvfrom(4096)
            s = d.decode_state(data)
            if s["controller_mode"] == ControllerMode.EXTERNAL_CONTROLLER:
                break
        states = [data]
        recovery = None
        for k in range(REFLEX_AT + 10):
            s = d.decode_state(data)
            if s["robot_mode"] != RobotMode.MOVE:
                break
            rec = d.new_command()
            rec["message_id"] = s["message_id"]
            rec["tau_J_d"] = _torques(k)
            if k == 150:  # a datagram of another size: dropped and counted
                c.udp.sendto(b"\0" * 10, robot)
            if k == 250:  # a late answer first: dropped
                late = rec.copy()
                late["message_id"] = s["message_id"] - 1
                c.udp.sendto(d.encode_command(late), robot)
            if k == 400:  # a request while the motion runs: refused, nothing changed
                recovery = c.send(Command.AUTOMATIC_ERROR_RECOVERY)
            if k != 300:  # no answer: lost once the lockstep timeout passed
                c.udp.sendto(d.encode_command(rec), robot)
            data = c.udp.recvfrom(4096)[0]
            states.append(data)
        final, _ = c.response(Command.MOVE, cid)
        assert recovery is not None
        answer, _ = c.response(Command.AUTOMATIC_ERROR_RECOVERY, recovery)
        return states, final, answer, _hand_states(hand)
    finally:
        c.close()
        hand.close()


def _run(version: int, *, compiled: bool) -> tuple[Any, ...]:
    robot = "fer" if version in get_robot("fer").protocol_versions else "fr3"
    desk = DeskLink.create(locked=False)  # (its page's ticks are Python's)
    srv = SyncedServer(SimConfig(host=free_loopback_host(), robot=robot, lockstep=True,
                                 lockstep_timeout=LOST_WAIT, desk_link=desk.array))  # fmt: skip
    if compiled and srv._lockstep is None:
        srv.close()
        pytest.skip("no compiled ticks here (numba missing or PANDA_PY_NO_JIT=1)")
    if not compiled:
        srv._lockstep = None
    loop = threading.Thread(target=srv.serve_forever, daemon=True)
    loop.start()
    try:
        states, final, answer, hand = _drive(srv.config.host, version)
        st = srv.stats
        counts = (st.commands_received, st.commands_lost, st.bad_datagrams)
        ran = srv._lockstep.ticks_run if srv._lockstep is not None else 0
    finally:
        srv.shutdown()
        loop.join(10)
    assert not loop.is_alive()
    return states, final, answer, counts, ran, hand


@pytest.mark.parametrize("version", [5, 10])
def test_the_compiled_lockstep_sends_the_reference_states(version: int) -> None:
    fast, f_final, f_answer, f_counts, ran, f_hand = _run(version, compiled=True)
    slow, s_final, s_answer, s_counts, _, s_hand = _run(version, compiled=False)
    assert ran > 400  # most ticks ran compiled
    assert f_final == s_final == MoveStatus.REFLEX_ABORTED
    assert f_answer == s_answer == ErrorRecoveryStatus.COMMAND_NOT_POSSIBLE_REJECTED
    # the commands received (the one before the lost one's timeout and the reflex's too),
    # the one lost, the bad datagram
    assert f_counts == s_counts
    assert f_counts[1] == 1 and f_counts[2] == 1
    assert len(fast) == len(slow) == REFLEX_AT + 2
    d = fci.dialect(version)
    modes = [int(d.decode_state(b)["robot_mode"]) for b in fast]
    assert modes[-2] == RobotMode.MOVE and modes[-1] == RobotMode.REFLEX
    ids = [int(d.decode_state(b)["message_id"]) for b in fast]
    assert ids == list(range(ids[0], ids[0] + len(ids)))  # a tick per state, none skipped
    for k, (a, b) in enumerate(zip(fast, slow, strict=True)):
        assert a == b, f"state {k} of the motion"
    # the hand's state every 10 ticks, the same too (its id the tick's)
    assert len(f_hand) >= REFLEX_AT // 10 and f_hand == s_hand


def test_without_the_jit_lockstep_runs_the_reference() -> None:
    code = (
        "from panda_py.sim.server import SimServer; from panda_py.sim.config import SimConfig;"
        "from panda_py.sim import free_loopback_host;"
        "s = SimServer(SimConfig(host=free_loopback_host(), lockstep=True));"
        "print(s._lockstep is None, s._fast is None); s.close()"
    )
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PANDA_PY_NO_JIT": "1"},
                         capture_output=True, text=True, timeout=240, check=True)  # fmt: skip
    assert out.stdout.split() == ["True", "True"]


def test_a_datagram_from_elsewhere_is_not_a_command() -> None:
    """The kernel takes a command only from the client's address: the same bytes from
    another socket are counted bad and the motion waits on (then loses the command)."""
    srv = SyncedServer(SimConfig(host=free_loopback_host(), robot="fr3", lockstep=True,
                                 lockstep_timeout=LOST_WAIT))  # fmt: skip
    if srv._lockstep is None:
        srv.close()
        pytest.skip("no compiled ticks here (numba missing or PANDA_PY_NO_JIT=1)")
    loop = threading.Thread(target=srv.serve_forever, daemon=True)
    loop.start()
    other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    c = RawClient(srv.config.host, 10)
    d = c.dialect
    assert d is not None
    try:
        _, status = c.move(MoveControllerMode.EXTERNAL_CONTROLLER, MoveMotionGeneratorMode.NONE)
        assert status == MoveStatus.MOTION_STARTED
        for k in range(300):
            data, robot = c.udp.recvfrom(4096)
            s = d.decode_state(data)
            if s["controller_mode"] != ControllerMode.EXTERNAL_CONTROLLER:
                continue
            rec = d.new_command()
            rec["message_id"] = s["message_id"]
            (other if k == 200 else c.udp).sendto(d.encode_command(rec), robot)
        assert srv._lockstep.ticks_run > 100
        assert srv.stats.bad_datagrams == 1 and srv.stats.commands_lost == 1
    finally:
        c.close()
        other.close()
        srv.shutdown()
        loop.join(10)
    assert not loop.is_alive()
