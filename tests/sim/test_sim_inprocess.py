"""The in-process robot: its compiled tick (``panda_py.sim.compiled.torque_tick``, the
server's and the fast world's) against the Python reference on the same torque commands
-- the same states bit for bit, the same reflex at the same tick -- and its requests."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py.fci import MoveStatus, RobotMode
from panda_py.sim.inprocess import InProcessRobot

pytestmark = pytest.mark.timeout(300)


def _torques(i: int) -> np.ndarray:
    """A smooth torque command [Nm] (well within the rate limit), then at tick 700 a
    jump the robot's rate check refuses with a reflex."""
    tau = 2.0 * min(1.0, i / 200.0) * np.sin(0.01 * i + np.arange(7))
    if i >= 700:
        tau[0] += 30.0
    return tau


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_the_compiled_tick_equals_the_reference(robot: str) -> None:
    runs = []
    for compiled in (True, False):
        r = InProcessRobot(robot, compiled=compiled)
        fast = r.compiled_tick()
        if compiled and fast is None:
            pytest.skip("no compiled tick here (numba missing or PANDA_PY_NO_JIT=1)")
        assert r.start_torque_control() == MoveStatus.MOTION_STARTED
        r.hand_move(1, 0.07, 0.1)  # the hand moving (its ticks in Python), then holding
        states, modes = [], []
        for i in range(900):
            r.tick(_torques(i))
            states.append(bytes(r.read()))
            modes.append(r.robot_mode)
        runs.append((states, modes, r.reflex_flags()))
        assert not compiled or fast.ticks_run > 400  # type: ignore[union-attr]
    (fast, fast_modes, fast_flags), (slow, slow_modes, slow_flags) = runs
    assert fast_modes == slow_modes
    assert fast_modes[699] == RobotMode.MOVE and fast_modes[700] == RobotMode.REFLEX
    assert fast_flags == slow_flags == ["controller_torque_discontinuity"]
    for i, (a, b) in enumerate(zip(fast, slow, strict=True)):
        assert a == b, f"tick {i}"


def test_the_robot_answers_requests_as_a_client_sees_them() -> None:
    r = InProcessRobot("fer")
    assert r.robot_mode == RobotMode.IDLE and r.ticks == 0
    assert r.start_torque_control() == MoveStatus.MOTION_STARTED
    assert r.start_torque_control() == MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED
    r.tick(np.zeros(7))
    assert r.ticks == 1 and r.robot_mode == RobotMode.MOVE
    r.inject_reflex("joint_reflex")
    assert r.robot_mode == RobotMode.REFLEX and r.reflex_flags() == ["joint_reflex"]
    r.recover()
    assert r.robot_mode == RobotMode.IDLE
    r.place_body("cube", [0.4, 0.1, 0.02])
    assert np.allclose(r.body_position("cube"), [0.4, 0.1, 0.02])
    r.reset(r.q)
    assert r.ticks == 0 and r.gripper_width == pytest.approx(r.hand_max_width, abs=1e-4)
