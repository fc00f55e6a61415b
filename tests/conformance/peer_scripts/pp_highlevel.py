"""panda-python 1.1.1: its own high-level ``panda_py.Panda`` (torque-control loops in a
background thread, model from the LoadModelLibrary library the simulator serves).

Usage: pp_highlevel.py HOST Q_GOAL_JSON POSE_OFFSET_JSON
"""

from __future__ import annotations

import json
import sys

import numpy as np
from peer_io import Scenarios, event, floats

import panda_py
from panda_py import libfranka

HOST = sys.argv[1]
Q_GOAL = np.array(json.loads(sys.argv[2]))
OFFSET = np.array(json.loads(sys.argv[3]))  # [m] translation of the pose goal
panda = panda_py.Panda(HOST)


def model():
    m = panda.get_model()
    s = panda.get_state()
    ee = libfranka.Frame.kEndEffector
    return {
        "q": floats(s.q),
        "F_T_EE": floats(s.F_T_EE),
        "m_total": float(s.m_total),
        "F_x_Ctotal": floats(s.F_x_Ctotal),
        "I_total": floats(s.I_total),
        "pose_ee": floats(m.pose(ee, s)),
        "pose_flange": floats(m.pose(libfranka.Frame.kFlange, s)),
        "zero_jacobian_ee": floats(m.zero_jacobian(ee, s)),
        "gravity": floats(m.gravity(s)),
        "mass": floats(m.mass(s)),
    }


def joint_move():
    ok = panda.move_to_joint_position(Q_GOAL)
    out = {"returned": bool(ok), "q": floats(panda.q)}
    event("joint_move_done")
    return out


def pose_move():
    T0 = np.array(panda.get_pose())
    goal = T0.copy()
    goal[:3, 3] += OFFSET
    ok = panda.move_to_pose(goal)
    return {
        "returned": bool(ok),
        "goal": goal.tolist(),
        "pose": np.array(panda.get_pose()).tolist(),
    }


runs = Scenarios()
runs.run("model", model)
runs.run("move_to_joint_position", joint_move)
runs.run("move_to_pose", pose_move)
runs.finish()
