"""Protocol v10's robot-side asynchronous joint position generator: targets sent at a low
rate are reached on the robot's own limited trajectory, checked tick by tick."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import fci
from panda_py.fci import (
    Command,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveRequest,
    MoveStatus,
    RobotMode,
    TargetStatus,
)
from panda_py.robots import FER, FR3, START_POSE
from panda_py.robots.params import RobotSpec
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.command import Command as RobotCommand
from panda_py.sim.physics import DT, Physics
from panda_py.sim.probe import RawClient
from panda_py.sim.robot import RobotCore

JP = MoveMotionGeneratorMode.JOINT_POSITION
IMPEDANCE = MoveControllerMode.JOINT_IMPEDANCE
VELOCITY = np.array([0.655, 0.655, 0.655, 0.655, 1.315, 1.315, 1.315])  # pylibfranka example
DEVIATIONS = np.array(fci.DEFAULT_DEVIATION * 2)
SLACK = 1 + 1e-9  # float rounding of the discrete derivatives


def command(q_c: np.ndarray, *, finished: bool = False) -> RobotCommand:
    z = np.zeros(7)
    return RobotCommand(
        message_id=1, q_c=np.asarray(q_c, dtype=float), dq_c=z, O_T_EE_c=np.zeros(16),
        O_dP_EE_c=np.zeros(6), elbow_c=np.zeros(2), valid_elbow=False,
        motion_generation_finished=finished, tau_J_d=z, torque_command_finished=False,
    )  # fmt: skip


def start_async(spec: RobotSpec, velocity: np.ndarray = VELOCITY) -> RobotCore:
    core = RobotCore(spec, Physics(spec), np.array(START_POSE))
    status = core.request_move(
        int(IMPEDANCE), int(JP), DEVIATIONS, has_none=True, use_async=True,
        maximum_velocity=velocity,
    )  # fmt: skip
    assert status == MoveStatus.MOTION_STARTED
    return core


class Recorder:
    """Ticks the core (one 1 ms tick = one lockstep step) and checks the desired
    trajectory the state reports against the limits on every tick."""

    def __init__(self, core: RobotCore, velocity: np.ndarray) -> None:
        self.core = core
        j = core.spec.joints
        self.v_lim = np.minimum(velocity, j.dq_max) * SLACK
        self.a_lim = np.asarray(j.ddq_max) * SLACK
        self.j_lim = np.asarray(j.dddq_max) * SLACK
        self.q_d = np.array(core.state["q_d"], dtype=float)
        self.ddq_d = np.zeros(7)
        self.ticks = 0

    def tick(self, c: RobotCommand | None = None) -> None:
        core = self.core
        core.tick(c)
        self.ticks += 1
        s = core.state
        q_d, dq_d, ddq_d = (np.array(s[k], dtype=float) for k in ("q_d", "dq_d", "ddq_d"))
        assert (np.abs(dq_d) <= self.v_lim).all(), (self.ticks, dq_d)
        assert (np.abs(ddq_d) <= self.a_lim).all(), (self.ticks, ddq_d)
        assert (np.abs(ddq_d - self.ddq_d) / DT <= self.j_lim).all(), self.ticks
        if core.robot_mode == RobotMode.MOVE:  # derivatives of the reported positions
            np.testing.assert_allclose((q_d - self.q_d) / DT, dq_d, atol=1e-6)
        np.testing.assert_allclose(core.state["q"], q_d, atol=0.02)  # the arm follows
        self.q_d, self.ddq_d = q_d, ddq_d


@pytest.mark.parametrize("spec", [FR3, FER], ids=["fr3", "fer"])
def test_low_rate_targets_are_reached_within_the_limits(spec: RobotSpec) -> None:
    core = start_async(spec)
    rec = Recorder(core, VELOCITY)
    q0 = np.array(START_POSE)
    assert core.state_modes()[0] == MotionGeneratorMode.JOINT_POSITION
    # pylibfranka's example: a target 0.25 rad away on every joint, resent at 50 Hz;
    # the jump is no start-pose or discontinuity violation for this generator
    for offset, travel in ((0.25, 0.25), (-0.25, 0.5)):
        target = q0 + offset
        reached_at = None
        for k in range(1500):
            rec.tick(command(target) if k % 20 == 0 else None)
            s = core.state
            mode = core.state_modes()[2]
            status = fci.target_status(mode, s["q_d"], s["dq_d"], target)
            if status == TargetStatus.TARGET_REACHED and reached_at is None:
                reached_at = k
        assert core.robot_mode == RobotMode.MOVE  # 20 silent ticks in a row are no fault
        assert reached_at is not None
        # no faster than the Move's velocity limit allows, and without dawdling
        assert travel / 0.655 / DT < reached_at < travel / 0.655 / DT + 400
        np.testing.assert_allclose(core.state["q_d"], target, atol=1e-6)
        np.testing.assert_allclose(core.state["q"], target, atol=2e-3)
    assert not core.errors.any()


def test_new_target_mid_motion_and_finish_bring_the_arm_to_rest() -> None:
    core = start_async(FR3)
    rec = Recorder(core, VELOCITY)
    q0 = np.array(START_POSE)
    rec.tick(command(q0 + 0.4))
    peak = 0.0
    for _ in range(300):
        rec.tick()
        peak = max(peak, float(np.abs(core.state["dq_d"]).max()))
    assert peak == pytest.approx(1.315, rel=1e-6)  # wrist joints at their Move limit
    rec.tick(command(q0 - 0.1))  # reverse while moving: still smooth (Recorder checks)
    for _ in range(100):
        rec.tick()
    moving = np.array(core.state["q_d"], dtype=float)
    # libfranka's stopControl: zeros with motion_generation_finished, every tick
    while core.robot_mode == RobotMode.MOVE and rec.ticks < 2000:
        rec.tick(command(np.zeros(7), finished=True))
    assert core.pending_final == MoveStatus.SUCCESS
    assert core.robot_mode == RobotMode.IDLE
    held = np.array(core.state["q_d"], dtype=float)
    # it stopped near where it was, not at the zeros it was sent
    assert np.abs(held - moving).max() < 0.2
    assert np.linalg.norm(held) > 1.0  # (START_POSE's elbow alone is -2.36 rad)


def test_targets_beyond_the_joint_range_are_clamped() -> None:
    core = start_async(FR3, np.full(7, 10.0))  # above dq_max: capped at it
    rec = Recorder(core, np.full(7, 10.0))
    q_max = np.asarray(FR3.joints.q_max)
    for k in range(3000):
        rec.tick(command(q_max + 1.0) if k == 0 else None)
    np.testing.assert_allclose(core.state["q_d"], q_max, atol=1e-6)
    assert core.robot_mode == RobotMode.MOVE


def test_non_finite_target_aborts_with_input_error() -> None:
    core = start_async(FR3)
    core.tick(command(np.array(START_POSE)))
    bad = np.array(START_POSE)
    bad[3] = np.nan
    core.tick(command(bad))
    assert core.pending_final == MoveStatus.INPUT_ERROR_ABORTED
    assert core.robot_mode == RobotMode.IDLE


@pytest.mark.parametrize(
    ("controller", "generator", "velocity"),
    [
        (IMPEDANCE, MoveMotionGeneratorMode.JOINT_VELOCITY, VELOCITY),
        (MoveControllerMode.EXTERNAL_CONTROLLER, JP, VELOCITY),
        (IMPEDANCE, JP, np.zeros(7)),
        (IMPEDANCE, JP, np.full(7, np.nan)),
        (IMPEDANCE, JP, None),
    ],
)
def test_async_moves_the_robot_cannot_run_are_refused(controller, generator, velocity) -> None:
    core = RobotCore(FR3, Physics(FR3), np.array(START_POSE))
    status = core.request_move(
        int(controller), int(generator), DEVIATIONS, has_none=True, use_async=True,
        maximum_velocity=velocity,
    )  # fmt: skip
    assert status == MoveStatus.INVALID_ARGUMENT_REJECTED
    assert core.robot_mode == RobotMode.IDLE


@pytest.mark.timeout(60)
def test_async_motion_over_the_wire_in_lockstep() -> None:
    """A v10 client sending a handful of targets: lockstep does not wait for commands the
    asynchronous client never sends, nothing is counted lost, the robot gets there."""
    with Simulator(free_loopback_host(), robot="fr3", lockstep=True) as sim:
        c = RawClient(sim.host, 10)
        try:
            request = MoveRequest(IMPEDANCE, JP, maximum_velocity=tuple(VELOCITY))
            cid = c.send(Command.MOVE, **request.fields(fci.dialect(10)))
            status, _ = c.response(Command.MOVE, cid)
            assert status == MoveStatus.MOTION_STARTED
            s = c.wait_state(
                lambda s: s["motion_generator_mode"] == MotionGeneratorMode.JOINT_POSITION
            )
            target = np.array(s["q"], dtype=float) + 0.1
            for _ in range(3):  # a few targets, answering older states is fine
                c.command(s, q_c=target)
                s = c.state()
            s = c.wait_state(
                lambda s: (
                    fci.target_status(s["robot_mode"], s["q_d"], s["dq_d"], target)
                    == TargetStatus.TARGET_REACHED
                ),
                timeout=20.0,
            )
            assert s["robot_mode"] == RobotMode.MOVE
            while s["robot_mode"] == RobotMode.MOVE:
                c.command(s, q_c=np.zeros(7), motion_generation_finished=True)
                s = c.state()
            final, _ = c.response(Command.MOVE, cid)
            assert final == MoveStatus.SUCCESS
            s = c.wait_state(lambda s: s["robot_mode"] == RobotMode.IDLE)
            np.testing.assert_allclose(s["q"], target, atol=2e-3)
            assert not fci.dialect(10).active_errors(s["errors"])
            assert sim.stats()["commands_lost"] == 0
        finally:
            c.close()
