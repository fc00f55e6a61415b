"""The Cobot Pump's core in process (every tick over the MuJoCo suction cup, the arm
held still): when the cup seals, how the vacuum builds and decays, what it holds, how
commands end; and the pump's model (a weld per free body of the scene)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from panda_py.fci.vacuum import VacuumStatus
from panda_py.robots.end_effectors import (
    COBOT_PUMP,
    EndEffector,
    end_effector_F_T_NE,
    end_effector_load,
    get_end_effector,
)
from panda_py.robots.mjcf import CUBE_POSITION, CUBE_SIZE, build_model
from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot
from panda_py.sim.physics import Physics
from panda_py.sim.vacuum import VacuumCore

pytestmark = pytest.mark.timeout(120)

TOP = CUBE_SIZE  # [m] the cube's top face, resting on the table (z = 0)


class Pump:
    """The pump's core on its own physics, the cup's face placed at ``at`` [m] (pointing
    down) by the simulator's IK and held there."""

    def __init__(self, at: tuple[float, float, float]) -> None:
        self.physics = ph = Physics(get_robot("fer"), scene=True, end_effector="cobot_pump")
        T = np.diag([1.0, -1.0, -1.0, 1.0])
        T[:3, 3] = at
        O_T_F = T @ np.linalg.inv(ph.F_T_NE)
        q = np.array(START_POSE)
        start = ph.flange_pose_at(q)[:3, 3]
        X = O_T_F.copy()
        for s in np.linspace(0.0, 1.0, 50):
            X[:3, 3] = start + s * (O_T_F[:3, 3] - start)
            q = ph.solve_ik(X, q, None)
        for _ in range(10):
            q = ph.solve_ik(O_T_F, q, None)
        self.q = q
        ph.reset(q)
        self.core = VacuumCore(ph)
        self.cube = ph.model.body("cube").id

    def run(self, ticks: int) -> None:
        zero = np.zeros(7)
        for _ in range(ticks):
            self.core.tick()
            self.physics.step(
                self.physics.joint_tracking_torque(self.q, zero, zero, np.ones(7)), 0.0
            )

    def finish(self, limit: int = 5000) -> tuple[VacuumStatus, int]:
        """Run until the running command ends: its status and the ticks it took."""
        for t in range(1, limit + 1):
            self.run(1)
            if self.core.completed:
                ((_, status),) = self.core.completed
                self.core.completed.clear()
                return status, t
        raise AssertionError("the command did not end")


ON_CUBE = (CUBE_POSITION[0], CUBE_POSITION[1], TOP - 0.001)


def test_on_the_cube_the_vacuum_reaches_the_setpoint_and_holds_the_cube() -> None:
    pump = Pump(ON_CUBE)
    pump.run(50)
    assert pump.core.sealed and pump.core.vacuum == 0.0  # sealed, but the pump is off
    assert pump.core.vacuum_on(1, 60, 1000, 0) is None  # 600 mbar
    status, ticks = pump.finish()
    assert status is VacuumStatus.SUCCESS and ticks < 200
    assert pump.core.in_control_range and pump.core.part_present
    assert pump.core.held_body == pump.cube
    pump.run(500)
    assert pump.core.vacuum == pytest.approx(600.0)  # control mode: it stops at H1
    assert pump.core.actual_power == 0


def test_a_setpoint_beyond_the_pumps_reach_is_its_maximum() -> None:
    pump = Pump(ON_CUBE)
    assert pump.core.vacuum_on(1, 255, 1000, 3) is None  # 2550 mbar: more than a vacuum
    assert pump.finish()[0] is VacuumStatus.SUCCESS
    pump.run(1000)
    assert pump.core.vacuum <= COBOT_PUMP.max_vacuum
    assert pump.core.actual_power == 100  # it keeps pumping towards the unreachable


def test_the_cup_off_the_cubes_face_does_not_seal() -> None:
    """Its rim half over the edge: open, whatever it touches."""
    pump = Pump((CUBE_POSITION[0] + 0.015, CUBE_POSITION[1], TOP - 0.001))
    pump.run(50)
    assert not pump.core.sealed
    assert pump.core.vacuum_on(1, 30, 300, 0) is None
    status, ticks = pump.finish()
    assert status is VacuumStatus.UNSUCCESSFUL and ticks == 300
    assert pump.core.held_body is None and not pump.core.part_present


def test_stop_switches_the_pump_off_and_the_leaking_cup_lets_go() -> None:
    pump = Pump(ON_CUBE)
    pump.core.vacuum_on(1, 50, 1000, 0)
    assert pump.finish()[0] is VacuumStatus.SUCCESS
    assert pump.core.stop() is VacuumStatus.SUCCESS
    pump.run(200)
    assert pump.core.held_body == pump.cube  # a sealed cup loses its vacuum slowly
    pump.run(2000)
    assert pump.core.held_body is None and pump.core.part_detached
    assert not pump.core.in_control_range


def test_a_new_command_aborts_the_running_one() -> None:
    pump = Pump((0.4, 0.0, 0.3))  # in the air
    pump.core.vacuum_on(1, 30, 1000, 0)
    pump.run(10)
    assert pump.core.drop_off(2, 1000) is None
    assert pump.core.completed == [(1, VacuumStatus.ABORTED)]
    pump.core.completed.clear()
    assert pump.finish() == (VacuumStatus.SUCCESS, 1)  # nothing to release


def test_drop_off_releases_the_cube_in_the_air() -> None:
    pump = Pump(ON_CUBE)
    pump.core.vacuum_on(1, 50, 1000, 0)
    assert pump.finish()[0] is VacuumStatus.SUCCESS
    assert pump.core.drop_off(2, 1000) is None
    status, ticks = pump.finish()
    assert status is VacuumStatus.SUCCESS and ticks < 100
    assert pump.core.part_detached and pump.core.held_body is None
    assert pump.core.vacuum < 1.0


# -- the model and the data ---------------------------------------------------------------


def test_the_pump_model_has_a_weld_per_free_body(tmp_path: Path) -> None:
    extra = tmp_path / "extra.xml"
    extra.write_text(
        '<mujoco><worldbody><body name="box2" pos="0.3 0.3 0.05"><freejoint/>'
        '<inertial pos="0 0 0" mass="0.1" diaginertia="3e-5 3e-5 3e-5"/>'
        '<geom type="box" size="0.02 0.02 0.02"/></body>'
        '<body name="post" pos="0.6 0.3 0.05"><geom type="box" size="0.01 0.01 0.05"/>'
        "</body></worldbody></mujoco>"
    )
    m = build_model("fer", scene=True, extra=extra, end_effector="cobot_pump")
    welds = sorted(m.equality(i).name for i in range(m.neq))
    assert welds == ["hold_box2", "hold_cube"]
    assert m.body("cobot_pump").mass[0] == pytest.approx(COBOT_PUMP.inertial.mass)
    assert build_model("fer", scene=True).neq == 1  # the hand: its fingers' coupling only


def test_end_effector_data() -> None:
    assert get_end_effector("COBOT-PUMP") is EndEffector.COBOT_PUMP
    assert end_effector_load(EndEffector.HAND) is FRANKA_HAND.inertial
    hand = end_effector_F_T_NE(EndEffector.HAND)
    assert hand[2, 3] == FRANKA_HAND.tcp_offset and hand[0, 0] == pytest.approx(np.sqrt(0.5))
    with pytest.raises(ValueError, match="end_effector: expected one of"):
        get_end_effector(EndEffector)
