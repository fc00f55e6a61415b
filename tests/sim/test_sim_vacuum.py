"""The simulated Cobot Pump: a robot with the pump on its flange serves the vacuum
gripper protocol on 1339 (and no hand on 1338), reports the pump's load, picks the scene's
cube by suction, holds it through a lift and the paper's moves and drops it off; and
panda-py's vacuum_object example behaves against it as on a robot."""

from __future__ import annotations

import datetime
import socket
import sys
import time

import numpy as np
import pytest

import panda_py
from panda_py import fci
from panda_py import libfranka as lf
from panda_py.fci import vacuum as vp
from panda_py.kinematics import hand_F_T_EE
from panda_py.robots.end_effectors import COBOT_PUMP, EndEffector, end_effector_F_T_NE
from panda_py.robots.mjcf import CUBE_POSITION, CUBE_SIZE
from panda_py.robots.params import START_POSE
from panda_py.sim import SimConfig, Simulator, free_loopback_host
from panda_py.sim.cli import main as panda_sim

pytestmark = pytest.mark.timeout(180)

CUBE = np.array(CUBE_POSITION)
SLIP = 0.002  # [m] how far the held cube may move relative to the cup
PRESS = 0.001  # [m] the cup goes this far into the cube's top face (a firm contact)
SECOND = datetime.timedelta(seconds=1)
PUMP = EndEffector.COBOT_PUMP


@pytest.fixture(scope="module")
def pump_sim():
    """A simulator with the pump (for tests that leave the scene as they found it)."""
    with Simulator(free_loopback_host(), lockstep=True, end_effector="cobot_pump") as s:
        yield s


@pytest.fixture
def sim():
    with Simulator(free_loopback_host(), lockstep=True, end_effector="cobot-pump") as s:
        yield s


@pytest.fixture
def panda(sim):
    p = panda_py.Panda(sim.host)
    try:
        yield p
    finally:
        p.close()


def cup_at(panda: panda_py.Panda, position: np.ndarray) -> np.ndarray:
    """The TCP (the cup's face) at ``position``, pointing down as at the start pose."""
    T = panda.get_pose()
    T[:3, 3] = position
    return T


def place_cup_on_cube(panda: panda_py.Panda) -> None:
    top = CUBE + np.array([0.0, 0.0, CUBE_SIZE / 2])
    assert panda.move_to_start()
    assert panda.move_to_pose(cup_at(panda, top + np.array([0.0, 0.0, 0.1])))
    assert panda.move_to_pose(cup_at(panda, top - np.array([0.0, 0.0, PRESS])))


def cube_in_cup(sim: Simulator) -> np.ndarray:
    """The cube's centre in the TCP frame [m]."""
    s = sim.state()
    O_T_EE = np.asarray(s["O_T_EE"]).reshape(4, 4).T  # column-major
    return O_T_EE[:3, :3].T @ (np.asarray(s["cube_position"]) - O_T_EE[:3, 3])


# -- the robot with the pump ------------------------------------------------------------


def test_the_robot_reports_the_pumps_tcp_and_load(pump_sim):
    with lf.Robot(pump_sim.host) as robot:
        state = robot.read_once()
    assert state.m_ee == pytest.approx(COBOT_PUMP.inertial.mass)
    assert np.allclose(state.F_x_Cee, COBOT_PUMP.inertial.com)
    assert np.allclose(np.reshape(state.I_ee, (3, 3)), np.eye(3) * 0.001)
    F_T_NE = np.reshape(state.F_T_NE, (4, 4), order="F")
    assert np.allclose(F_T_NE[:3, :3], np.eye(3)) and F_T_NE[2, 3] == pytest.approx(0.105)
    # O_T_EE is the cup's face: 0.105 m along the flange's z
    O_T_EE = np.reshape(state.O_T_EE, (4, 4), order="F")
    flange = panda_py.fk(state.q) @ np.linalg.inv(hand_F_T_EE())
    assert np.allclose(O_T_EE, flange @ F_T_NE, atol=1e-6)


def test_the_hand_port_is_closed_with_the_pump_mounted(pump_sim):
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((pump_sim.host, fci.GRIPPER_COMMAND_PORT), timeout=5).close()
    with pytest.raises(lf.NetworkException):
        lf.Gripper(pump_sim.host)
    # and a robot with the hand serves no pump
    with Simulator(free_loopback_host(), lockstep=True) as hand_sim:
        with pytest.raises(ConnectionRefusedError):
            socket.create_connection((hand_sim.host, vp.VACUUM_COMMAND_PORT), timeout=5).close()


def test_vacuum_in_the_air_is_unsuccessful_and_the_state_says_why(pump_sim):
    with lf.VacuumGripper(pump_sim.host) as pump:
        assert pump.server_version() == vp.VACUUM_VERSION
        idle = pump.read_once()
        assert not (idle.part_present or idle.in_control_range or idle.part_detached)
        assert idle.device_status == lf.VacuumGripperDeviceStatus.kGreen
        assert idle.vacuum == 0
        start = pump.read_once().time.to_msec()
        assert pump.vacuum(3, datetime.timedelta(milliseconds=300)) is False
        waited = pump.read_once().time.to_msec() - start
        assert waited >= 300  # it sucked for the whole timeout
        sucking = pump.read_once()
        assert sucking.actual_power == 100  # the pump keeps running into the open cup
        assert not (sucking.part_present or sucking.in_control_range) and sucking.vacuum == 0
        assert pump.stop() is True
        assert pump.read_once().actual_power == 0


def test_an_incompatible_client_hears_the_pumps_version(pump_sim):
    with socket.create_connection((pump_sim.host, vp.VACUUM_COMMAND_PORT), timeout=5) as s:
        s.sendall(fci.encode_gripper_connect_request(9, version=2, command_id=4))
        cid, status, version = fci.decode_gripper_connect_response(_recv(s, 14))
    assert (cid, status, version) == (
        4, fci.GripperConnectStatus.INCOMPATIBLE_LIBRARY_VERSION, vp.VACUUM_VERSION,
    )  # fmt: skip


def test_bad_setpoints_fail_the_command(pump_sim):
    with socket.create_connection((pump_sim.host, vp.VACUUM_COMMAND_PORT), timeout=5) as s:
        s.sendall(fci.encode_gripper_connect_request(9, version=vp.VACUUM_VERSION))
        assert fci.decode_gripper_connect_response(_recv(s, 14))[1] == 0
        for cid, fields in enumerate(
            [dict(vacuum=0, profile=0, timeout=100), dict(vacuum=10, profile=4, timeout=100),
             dict(vacuum=10, profile=0, timeout=-1)], start=1,
        ):  # fmt: skip
            payload = vp.VACUUM_REQUESTS[vp.VacuumCommand.VACUUM].encode(**fields)
            s.sendall(vp.encode_vacuum_message(vp.VacuumCommand.VACUUM, cid, payload))
            answer = _recv(s, 12)
            assert vp.VACUUM_HEADER.unpack(answer[:10])[1] == cid
            assert vp.decode_vacuum_status(answer[10:]) is vp.VacuumStatus.FAIL, fields


def _recv(s: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = s.recv(n - len(data))
        assert chunk, "connection closed"
        data += chunk
    return data


# -- picking the cube -------------------------------------------------------------------


def test_the_pump_picks_lifts_holds_and_drops_the_cube(sim, panda):
    with lf.VacuumGripper(sim.host) as pump:
        place_cup_on_cube(panda)
        assert pump.vacuum(50, SECOND) is True  # 500 mbar
        held = pump.read_once()
        assert held.part_present and held.in_control_range and not held.part_detached
        assert held.vacuum >= 400 and held.device_status == lf.VacuumGripperDeviceStatus.kGreen
        at_grasp = cube_in_cup(sim)
        z0 = sim.state()["cube_position"][2]
        pose = panda.get_pose()
        pose[2, 3] += 0.1
        assert panda.move_to_pose(pose)  # lift 10 cm
        assert sim.state()["cube_position"][2] - z0 == pytest.approx(0.1, abs=0.002)
        assert panda.move_to_start()  # the paper's moves: start, 10 cm down and up, aside
        pose = panda.get_pose()
        pose[2, 3] -= 0.1
        assert panda.move_to_pose(pose)
        pose[1, 3] += 0.1
        assert panda.move_to_pose(pose)
        slip = float(np.linalg.norm(cube_in_cup(sim) - at_grasp))
        assert slip < SLIP, f"the cube moved {slip * 1000:.1f} mm on the cup"
        carried = pump.read_once()
        assert carried.part_present and carried.in_control_range
        assert sim.state()["vacuum_held"] == "cube"
        assert pump.drop_off(SECOND) is True
        dropped = pump.read_once()
        assert dropped.part_detached and not dropped.part_present
        assert not dropped.in_control_range and dropped.vacuum == 0
        assert sim.state()["vacuum_held"] is None
        assert panda.move_to_start()  # the cup leaves; the cube fell onto the table
        assert sim.state()["cube_position"][2] < CUBE_SIZE
        assert pump.stop() is True


def test_the_table_seals_the_cup_but_is_not_held(sim):
    """The cup on the table (beside the cube): the vacuum builds, nothing is held. The arm
    is placed there (a move's settling would press the cup into the rigid table until a
    Cartesian reflex), 0.2 mm into the table: a touch of a few N."""
    F_T_NE = end_effector_F_T_NE(PUMP)
    O_T_EE = panda_py.fk(np.array(START_POSE), F_T_EE=F_T_NE)  # pointing down
    O_T_EE[:3, 3] = (0.45, 0.2, -0.0002)
    q = panda_py.ik(O_T_EE, np.array(START_POSE), np.pi / 4, F_T_EE=F_T_NE)
    assert np.all(np.isfinite(q))
    sim.set_joint_positions(q)
    with lf.VacuumGripper(sim.host) as pump:
        assert pump.vacuum(20, SECOND) is True
        state = pump.read_once()
        assert state.in_control_range and state.part_present  # the table, as a part
        assert sim.state()["vacuum_held"] is None
        assert pump.stop() is True


# -- panda-py's vacuum_object example ---------------------------------------------------


def vacuum_object(host: str, out: list[str], hold: float = 3.0) -> None:
    """What panda-py's ``examples/vacuum_object.py`` (panda-python 1.1.1) does, in our
    words: print the pump's state, vacuum at level 3 with a 1 s timeout (an exception
    means "Failed to grab object."), wait 3 s, fail with "Object lost." unless the vacuum
    is still in its control range, drop the object off within 1 s, and always stop the
    pump at the end."""
    pump = panda_py.libfranka.VacuumGripper(host)
    try:
        s = pump.read_once()
        out.append(
            f"in control range {s.in_control_range}, detached {s.part_detached}, present "
            f"{s.part_present}, {s.device_status}, power {s.actual_power}, vacuum {s.vacuum}"
        )
        try:
            pump.vacuum(3, SECOND)
        except Exception as exc:
            raise RuntimeError("Failed to grab object.") from exc
        out.append("Grabbed object.")
        time.sleep(hold)
        if not pump.read_once().in_control_range:
            raise RuntimeError("Object lost.")
        try:
            pump.drop_off(SECOND)
        except Exception as exc:
            raise RuntimeError("Failed to drop object off.") from exc
        out.append("Released object.")
    finally:
        pump.stop()
        pump.close()


def test_vacuum_object_picks_the_cube_and_lets_it_go(sim, panda):
    place_cup_on_cube(panda)
    out: list[str] = []
    vacuum_object(sim.host, out)
    assert out[0].startswith("in control range False, detached False, present False")
    assert out[1:] == ["Grabbed object.", "Released object."]
    with lf.VacuumGripper(sim.host) as pump:
        after = pump.read_once()
    assert after.part_detached and not after.part_present and after.actual_power == 0


def test_vacuum_object_in_the_air_loses_the_object(pump_sim):
    out: list[str] = []
    with pytest.raises(RuntimeError, match=r"Object lost\."):
        vacuum_object(pump_sim.host, out, hold=0.0)
    assert out[1:] == ["Grabbed object."]
    with lf.VacuumGripper(pump_sim.host) as pump:
        assert pump.read_once().actual_power == 0  # its finally stopped the pump


# -- configuration ----------------------------------------------------------------------


def test_the_end_effector_is_validated():
    assert SimConfig(end_effector="Cobot-Pump").end_effector is EndEffector.COBOT_PUMP
    assert SimConfig().end_effector is EndEffector.HAND
    for bad in ("gripper", "", 3, None):
        with pytest.raises(ValueError, match=r"end_effector: expected one of 'hand', .* got"):
            SimConfig(end_effector=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="end_effector"):
        Simulator("127.0.0.1", end_effector="suction")


def test_panda_sim_rejects_an_unknown_end_effector(capsys, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["panda-sim"])
    with pytest.raises(SystemExit) as info:
        panda_sim(["--end-effector", "suction"])
    assert info.value.code == 2
    assert "invalid choice: 'suction'" in capsys.readouterr().err
