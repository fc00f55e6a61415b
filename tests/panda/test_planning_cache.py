"""What a move's planning keeps between calls (panda.planning): panda-py's default options,
checked once and shared read-only, and the online generator's limits per robot and speed
factor, so a move that replaces a running one does as little as it can before it is sent."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from panda_py.motion.online import OnlineLimits
from panda_py.panda import move_args, planning
from panda_py.robots.params import get_robot

Q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def test_the_default_joint_options_are_checked_once_and_shared_read_only() -> None:
    _, a = move_args.parse_joint_targets((Q,), {})
    _, b = move_args.parse_joint_targets((Q + 0.1,), {})
    assert a is b
    with pytest.raises(ValueError, match="read-only"):
        a.stiffness[0] = 0.0
    _, c = move_args.parse_joint_targets((Q,), {"speed_factor": 0.5})
    assert c is not a and c.speed_factor == 0.5
    assert np.array_equal(c.stiffness, a.stiffness)
    with pytest.raises(ValueError, match=r"speed_factor: expected a number in \(0, 1\]"):
        move_args.parse_joint_targets((Q,), {"speed_factor": 2.0})


def test_the_online_limits_are_kept_per_robot_and_speed_factor() -> None:
    fer, fr3 = get_robot("fer"), get_robot("fr3")
    assert planning.joint_online(fr3, 0.2) is planning.joint_online(fr3, 0.2)
    assert planning.joint_online(fr3, 0.2) is not planning.joint_online(fr3, 0.3)
    assert planning.joint_online(fer, 0.2) != planning.joint_online(fr3, 0.2)
    assert planning.pose_online(fr3, 0.2).limits.velocity[0] == pytest.approx(0.6)
    # a robot of the same name but other limits gets its own
    slow = dataclasses.replace(fr3, joints=dataclasses.replace(
        fr3.joints, dq_max=tuple(0.5 * v for v in fr3.joints.dq_max)))  # fmt: skip
    assert planning.joint_online(slow, 0.2).limits.velocity[0] == pytest.approx(
        0.5 * planning.joint_online(fr3, 0.2).limits.velocity[0]
    )
    # the stop's limits: at least STOP_SPEED_FACTOR of the robot's, at the robot's jerk
    assert planning.joint_online(fr3, 0.1).stop_limits == OnlineLimits.joints(
        fr3, planning.STOP_SPEED_FACTOR
    )
    # a lead-in's acceleration ramps over at least RAMP_TIME (its jerk at most a / RAMP_TIME)
    lead = planning.joint_online(fr3, 0.2).limits
    assert lead.acceleration == OnlineLimits.joints(fr3, 0.2).acceleration
    assert all(j * planning.RAMP_TIME <= a * (1 + 1e-12)
               for j, a in zip(lead.jerk, lead.acceleration, strict=True))  # fmt: skip
