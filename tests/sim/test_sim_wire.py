"""The simulator's datagram buffers: every field of every layout carries what the core
holds, and received commands are read back exactly (no sockets to a simulator: a core, a
socket pair and the fci codecs)."""

from __future__ import annotations

import socket

import numpy as np
import pytest

from panda_py import fci
from panda_py.fci import ControllerMode, MotionGeneratorMode, RobotMode
from panda_py.robots import FR3, START_POSE
from panda_py.sim.physics import Physics
from panda_py.sim.robot import RobotCore
from panda_py.sim.wire import CommandWire, StateWire

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def core() -> RobotCore:
    return RobotCore(FR3, Physics(FR3), np.array(START_POSE))


@pytest.mark.parametrize("version", fci.SUPPORTED_VERSIONS)
def test_state_wire_carries_every_field(core: RobotCore, version: int) -> None:
    d = fci.dialect(version)
    rng = np.random.default_rng(version)
    saved = core.state_buffer.copy()
    core.state_buffer[:] = rng.normal(size=core.state_buffer.size)
    core.mg_mode, core.ctrl_mode = (
        MotionGeneratorMode.CARTESIAN_VELOCITY,
        ControllerMode.CARTESIAN_IMPEDANCE,
    )
    core.robot_mode = RobotMode.REFLEX
    core.errors[:] = rng.integers(0, 2, core.errors.size)
    core.reflex_reason[:] = rng.integers(0, 2, core.reflex_reason.size)
    try:
        data = bytes(StateWire(d, core).fill(123456789, 0.75))
        assert len(data) == d.state_size
        rec = d.decode_state(data)
        assert int(rec["message_id"]) == 123456789
        assert int(rec["motion_generator_mode"]) == MotionGeneratorMode.CARTESIAN_VELOCITY
        assert int(rec["controller_mode"]) == ControllerMode.CARTESIAN_IMPEDANCE
        assert int(rec["robot_mode"]) == RobotMode.REFLEX
        assert float(rec["control_command_success_rate"]) == 0.75
        n = d.errors_count
        np.testing.assert_array_equal(np.asarray(rec["errors"]), core.errors[:n])
        np.testing.assert_array_equal(np.asarray(rec["reflex_reason"]), core.reflex_reason[:n])
        names = d.state_dtype.names or ()
        checked = 0
        for name, value in core.state.items():
            if name not in names:
                continue
            wire_dtype = d.state_dtype.fields[name][0].base  # type: ignore[index]
            expected = np.asarray(value, dtype=wire_dtype).reshape(np.shape(rec[name]))
            np.testing.assert_array_equal(np.asarray(rec[name]), expected, err_msg=name)
            checked += 1
        assert checked == len([n for n in core.state if n in names]) >= 35
    finally:
        core.state_buffer[:] = saved
        core.reset(np.array(START_POSE))


@pytest.mark.parametrize("version", [3, 5, 9, 10])
def test_command_wire_reads_back_what_was_sent(version: int) -> None:
    d = fci.dialect(version)
    wire = CommandWire(d)
    rng = np.random.default_rng(version)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    with rx, tx:
        rx.bind(("127.0.0.1", 0))
        rx.settimeout(5.0)
        tx.bind(("127.0.0.1", 0))
        client = tx.getsockname()
        for flags in ((True, False, True), (False, True, False)):
            cmd = d.new_command()
            cmd["message_id"] = 42
            for name in ("q_c", "dq_c", "O_T_EE_c", "O_dP_EE_c", "elbow_c", "tau_J_d"):
                cmd[name] = rng.normal(size=np.shape(cmd[name]))
            cmd["valid_elbow"], cmd["motion_generation_finished"] = flags[0], flags[1]
            if "torque_command_finished" in (d.command_dtype.names or ()):
                cmd["torque_command_finished"] = flags[2]
            tx.sendto(cmd.tobytes(), rx.getsockname())
            size, mid = wire.receive(rx, client)
            assert (size, mid) == (d.command_size, 42)
            c = wire.accept(mid)
            assert c.message_id == 42
            for name in ("q_c", "dq_c", "O_T_EE_c", "O_dP_EE_c", "elbow_c", "tau_J_d"):
                np.testing.assert_array_equal(getattr(c, name), cmd[name], err_msg=name)
            assert (c.valid_elbow, c.motion_generation_finished) == flags[:2]
            assert c.torque_command_finished == (flags[2] and version >= 9)
        # A wrong-sized datagram is reported with its size and leaves the command alone.
        before = c.tau_J_d.copy()
        tx.sendto(b"\x00" * (d.command_size + 1), rx.getsockname())
        assert wire.receive(rx, client) == (d.command_size + 1, -1)
        np.testing.assert_array_equal(c.tau_J_d, before)
        # So is a right-sized one from anywhere but the client.
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger:
            stranger.sendto(cmd.tobytes(), rx.getsockname())
            assert wire.receive(rx, client) == (d.command_size, -1)
        np.testing.assert_array_equal(c.tau_J_d, before)
        with pytest.raises(ValueError):
            c.tau_J_d[0] = 1.0  # the robot's view of a command is read-only
