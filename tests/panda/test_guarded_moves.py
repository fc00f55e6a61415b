"""Guarded moves: a condition on the robot's state, evaluated every tick in the control
process, ends the move gently when it holds (or hands over to another motion), and the
result says which condition and when."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import panda_py
from panda_py.conditions import Elapsed, Force
from panda_py.robots.params import START_POSE, get_robot

pytestmark = pytest.mark.timeout(300)


@pytest.fixture
def panda(reset_panda: panda_py.Panda) -> panda_py.Panda:
    """The module's Panda, reset before each test (conftest.reset_panda): no test here
    needs a fresh process or simulator, and starting them took about 2 s a test."""
    return reset_panda


FER = get_robot("fer")
ABOVE_TABLE = (0.45, 0.25, 0.04)  # [m] the TCP 4 cm above the table, away from the cube


class PressingDown:
    """The robot presses down with more than ``newtons``: libfranka's O_F_ext_hat_K is
    the robot's force on the environment, so its z is negative then. A user's own
    condition class, sent to the control process by value like a user's controller."""

    def __init__(self, newtons: float) -> None:
        self.newtons = newtons

    def holds(self, state: Any, progress: Any) -> bool:
        return bool(state.O_F_ext_hat_K[2] < -self.newtons)

    def __repr__(self) -> str:
        return f"pressing down > {self.newtons} N"


def above_table() -> np.ndarray:
    pose = panda_py.fk(np.array(START_POSE))
    pose[:3, 3] = ABOVE_TABLE
    return pose


IMPACT = 0.03  # [s] the impact's transient, over before the contact force is judged
CONTACT_THRESHOLD = 60.0  # [N], [Nm] the reflex thresholds of a contact task (example 16)


def allow_contact(panda: panda_py.Panda) -> None:
    """Collision thresholds for a contact task, as on a real robot: touching a table at
    5 cm/s is an impact whose estimated force peaks at about 22 N (10 cm/s: 46 N), above
    the default reflex thresholds (20 N)."""
    t = CONTACT_THRESHOLD
    panda.get_robot().set_collision_behavior(
        [t] * 7, [t] * 7, [t] * 7, [t] * 7, [t] * 6, [t] * 6, [t] * 6, [t] * 6
    )


def descend_onto_the_table(panda: panda_py.Panda, speed: float) -> tuple[Any, np.ndarray, float]:
    """Down at ``speed`` [m/s] from 4 cm above the table toward 3 cm inside it until the
    robot presses with 5 N (example 16's guarded place, without the cube): the move's
    handle, the logged push on the table [N] (``-O_F_ext_hat_K`` z) and the descent's
    speed when it first touched [m/s]."""
    panda.move_to_start()
    allow_contact(panda)
    start = above_table()
    assert panda.move_to_pose(start)
    panda.enable_logging(30_000)
    goal = start.copy()
    goal[2, 3] = -0.03
    factor = speed / FER.cartesian.translation_velocity
    handle = panda.move_to_pose(goal, speed_factor=factor, until=(Force.z < -5.0) | (Elapsed > 5.0),
                                asynchronous=True)  # fmt: skip
    handle.wait()
    log = panda.get_log()
    panda.disable_logging()
    push = -np.array(log["O_F_ext_hat_K"])[:, 2]
    z = np.array(log["O_T_EE"])[:, 14]
    touching = np.flatnonzero(push > 1.0)
    assert touching.size, "never touched the table"
    first = touching[0]
    return handle, push, float(z[first - 6] - z[first - 1]) / 5e-3


@pytest.mark.parametrize("speed", [0.02, 0.05, 0.10])
def test_a_guarded_approach_stops_on_the_table_without_a_reflex(
    panda: panda_py.Panda, speed: float
) -> None:
    """At the speeds users approach surfaces with, the impact's estimated force stays
    below the 60 N reflex thresholds of a contact task: the move ends by its condition."""
    handle, push, touched_at = descend_onto_the_table(panda, speed)
    assert touched_at > 0.9 * speed  # it hit the table at the speed it was meant to
    result = handle.result
    assert result is not None and result.error is None, result
    assert result.condition == "Force.z < -5.0"
    assert 5.0 < push.max() < CONTACT_THRESHOLD
    assert not panda.get_state().last_motion_errors


def test_an_impact_at_speed_ends_in_a_reflex(panda: panda_py.Panda) -> None:
    """At 30 cm/s the same approach is an impact the robot's reflex stops."""
    handle, push, touched_at = descend_onto_the_table(panda, 0.30)
    assert touched_at > 0.27
    assert handle.result is not None and handle.result.error is not None
    assert push.max() > CONTACT_THRESHOLD
    assert "cartesian_reflex" in panda.get_state().last_motion_errors
    assert lift_off(panda)  # the reflex held the arm pressed on the table


def lift_off(panda: panda_py.Panda, tries: int = 3) -> bool:
    """After a reflex that left the arm pressed on the table: recover and lift it back above
    the table under the contact task's thresholds (the push it starts with is above the
    default ones); again if the lift itself ended in a reflex (a suite run on a loaded
    machine saw one), so the module's next test finds the arm free."""
    for _ in range(tries):
        panda.recover()
        allow_contact(panda)
        if panda.move_to_pose(above_table()):
            return True
    return False


def test_a_guarded_descent_stops_on_contact_gently(panda: panda_py.Panda) -> None:
    """Down at 5 cm/s toward a point 3 cm inside the table until the robot presses with
    10 N: once the impact is over it presses with at most 15 N, and it stops at most 5 mm
    past first contact."""
    panda.move_to_start()
    allow_contact(panda)
    start = above_table()
    assert panda.move_to_pose(start)
    panda.enable_logging(30_000)
    goal = start.copy()
    goal[2, 3] = -0.03
    speed = 0.05 / FER.cartesian.translation_velocity  # 5 cm/s on a straight line
    handle = panda.move_to_pose(goal, speed_factor=speed, until=Force.z < -10.0,
                                asynchronous=True)  # fmt: skip
    assert handle.wait() is True  # ended by its condition, as asked
    result = handle.result
    assert result is not None and result.condition == "Force.z < -10.0"
    assert 0.3 < result.condition_time < 2.0
    assert result.position_error > 0.02  # it did not go on to the goal inside the table
    log = panda.get_log()
    force = -np.array(log["O_F_ext_hat_K"])[:, 2]  # [N] the robot's push on the table
    z = np.array(log["O_T_EE"])[:, 14]
    touching = np.flatnonzero(force > 1.0)
    assert touching.size, "never touched the table"
    first = touching[0]
    after = force[first + round(IMPACT * 1e3) :]
    assert after.size > 100 and after.max() <= 15.0, f"pressed with {after.max():.1f} N"
    assert z[first] - z[-1] <= 0.005, f"{(z[first] - z[-1]) * 1000:.1f} mm past first contact"
    assert not panda.get_state().current_errors


def test_a_condition_can_hand_over_to_another_motion(panda: panda_py.Panda) -> None:
    panda.move_to_start()
    allow_contact(panda)
    start = above_table()
    assert panda.move_to_pose(start)
    goal = start.copy()
    goal[2, 3] = -0.03
    back_up = panda_py.PoseMotion(start)
    speed = 0.05 / FER.cartesian.translation_velocity
    # a user's own condition class works as well
    ok = panda.move_to_pose(goal, speed_factor=speed, until=PressingDown(5.0), then=back_up)
    assert ok is True
    np.testing.assert_allclose(panda.get_position(), ABOVE_TABLE, atol=0.003)
    force = -panda.get_state().O_F_ext_hat_K[2]
    assert abs(force) < 2.0  # lifted off the table again


class Broken:
    def holds(self, state: Any, progress: Any) -> bool:
        raise RuntimeError("my condition is broken")


def test_a_condition_that_raises_aborts_the_move_with_its_error(
    panda: panda_py.Panda,
) -> None:
    panda.move_to_start()
    handle = panda.move_to_joint_position(panda.q + 0.1, until=Broken(), asynchronous=True)
    assert handle.wait() is False
    result = handle.result
    assert result is not None and isinstance(result.error, RuntimeError)
    assert "my condition is broken" in result.reason
    panda.recover()
    assert panda.move_to_start()


def test_a_time_condition_ends_a_move_on_the_way(panda: panda_py.Panda) -> None:
    panda.move_to_start()
    start = panda.q
    handle = panda.move_to_joint_position(start + 0.4, until=Elapsed > 0.3, asynchronous=True)
    assert handle.wait() is True
    result = handle.result
    assert result is not None and result.condition == "Elapsed > 0.3"
    assert 0.3 < result.condition_time < 0.31
    assert 0.01 < np.abs(panda.q - start).max() < 0.35  # stopped on the way
