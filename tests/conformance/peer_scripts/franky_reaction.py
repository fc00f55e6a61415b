"""franky-control 2.0.0: its documented force reaction (README, "Reactions"): a Cartesian
motion down onto an obstacle, stopped when the measured force along z (libfranka's
O_F_ext_hat_K, the robot's force on the environment) drops below -5 N.

Usage: franky_reaction.py HOST
"""

from __future__ import annotations

import sys

from franky import (
    Affine,
    CartesianMotion,
    CartesianStopMotion,
    Measure,
    Reaction,
    RealtimeConfig,
    ReferenceType,
    Robot,
)
from peer_io import Scenarios, floats

robot = Robot(sys.argv[1], realtime_config=RealtimeConfig.Ignore)
robot.relative_dynamics_factor = 0.01
# The robot-wide factor slows the stop motion too: the commanded pose runs on into the
# table after the reaction fires and the robot presses there (test_conf_franky_guarded):
# thresholds high enough that the reaction, not the reflex, ends the motion.
robot.set_collision_behavior(100.0, 100.0)


def press_down():
    fired = []
    z0 = float(robot.current_pose.end_effector_pose.translation[2])
    # relative to the end effector, whose z points down (as in franky's README)
    motion = CartesianMotion(Affine([0.0, 0.0, 0.10]), ReferenceType.Relative)
    reaction = Reaction(Measure.FORCE_Z < -5.0, CartesianStopMotion())
    reaction.register_callback(lambda state, rel, abs_: fired.append(floats(state.O_F_ext_hat_K)))
    motion.add_reaction(reaction)
    error = None
    try:
        robot.move(motion)
    except Exception as exc:  # a reflex instead of the reaction: reported
        error = f"{type(exc).__name__}: {exc}"
    s = robot.state
    return {
        "fired": fired[:1],
        "error": error,
        "z_start": z0,
        "z_end": float(robot.current_pose.end_effector_pose.translation[2]),
        "O_F_ext_hat_K": floats(s.O_F_ext_hat_K),
        "has_errors": bool(robot.has_errors),
    }


runs = Scenarios()
runs.run("press_down", press_down)
runs.finish()
