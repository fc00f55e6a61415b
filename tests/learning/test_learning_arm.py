"""RobotArm's reset on a stand-in for a Panda (what it asks of the robot, in order): a
move home that a reflex ends is recovered from and tried once more; a second failure
is an error that says what to do, and no cube is placed."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from panda_py.learning import RobotArm
from panda_py.robots.params import START_POSE


class StandIn:
    """Answers the calls RobotArm.home makes, the moves home with ``outcomes``."""

    def __init__(self, outcomes: list[bool]) -> None:
        self.outcomes = outcomes
        self.calls: list[str] = []

    def get_model(self) -> SimpleNamespace:
        return SimpleNamespace(spec=SimpleNamespace(name="fer"))

    def recover(self) -> None:
        self.calls.append("recover")

    def move_to_joint_position(self, q: np.ndarray, speed_factor: float) -> bool:
        self.calls.append("move")
        return self.outcomes.pop(0)

    def stop_controller(self) -> None:
        self.calls.append("stop")


class Scene:
    def __init__(self) -> None:
        self.placed: list[list[float]] = []

    def place_cube(self, position: object) -> None:
        self.placed.append(list(position))  # type: ignore[call-overload]

    def cube_position(self) -> np.ndarray:
        return np.zeros(3)


def test_a_move_home_ended_by_a_reflex_is_recovered_and_tried_again() -> None:
    panda, scene = StandIn([False, True]), Scene()
    arm = RobotArm("unused", panda=panda, hand=False, scene=scene)  # type: ignore[arg-type]
    arm.home(np.array(START_POSE), np.array([0.5, 0.0, 0.02]))
    assert panda.calls == ["recover", "move", "recover", "move"]
    assert scene.placed == [[0.5, 0.0, 0.02]]


def test_a_second_failure_says_so_and_places_nothing() -> None:
    panda, scene = StandIn([False, False]), Scene()
    arm = RobotArm("unused", panda=panda, hand=False, scene=scene)  # type: ignore[arg-type]
    with pytest.raises(RuntimeError, match=r"did not reach its home pose.*clear its way"):
        arm.home(np.array(START_POSE), np.array([0.5, 0.0, 0.02]))
    assert scene.placed == []
