"""Shared by the examples that handle the cube: where it is and how the hand meets it.

panda-sim puts a 4 cm cube at x = 0.5 m, y = 0 on the table; on a real robot, put one
there first."""

import numpy as np

import panda_py
from panda_py import constants

CUBE = np.array([0.5, 0.0, 0.02])  # [m] where panda-sim's cube rests, its centre
WIDTH = 0.04  # [m] the cube's edge
GRIP = np.array([0.0, 0.0, 0.005])  # [m] the TCP above the cube's centre when gripping
ABOVE = np.array([0.0, 0.0, 0.1])  # [m] 10 cm higher


def tcp_at(position):
    """The start pose's orientation (fingers down) with the TCP at ``position`` [m]."""
    T = panda_py.fk(constants.JOINT_POSITION_START)
    T[:3, 3] = position
    return T
