"""franky-control 2.0.0 (libfranka 0.21.2, protocol v10): construct (realtime checks off),
read the state, and a JointMotion with a small relative dynamics factor.

Usage: franky_basic.py HOST Q_GOAL_JSON
"""

from __future__ import annotations

import json
import sys
import time

from franky import JointMotion, RealtimeConfig, Robot
from peer_io import Scenarios, floats

HOST = sys.argv[1]
Q_GOAL = json.loads(sys.argv[2])
robot = Robot(HOST, realtime_config=RealtimeConfig.Ignore)


def state():
    s = robot.state
    return {
        "q": floats(s.q),
        "robot_mode": str(s.robot_mode),
        "O_T_EE": [floats(row) for row in robot.current_pose.end_effector_pose.matrix],
        "has_errors": bool(robot.has_errors),
    }


def joint_motion():
    start = time.monotonic()
    robot.move(JointMotion(Q_GOAL, relative_dynamics_factor=0.1))
    return {"q": floats(robot.current_joint_positions), "wall": time.monotonic() - start}


runs = Scenarios()
runs.run("state", state)
runs.run("joint_motion", joint_motion)
runs.finish()
