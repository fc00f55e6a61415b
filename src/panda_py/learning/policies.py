"""Scripted policies for the tasks with Cartesian delta actions (the default): functions
of the observation alone, so the same one runs on any backend, in vectorised
environments too (one observation at a time). They show that what succeeds on the fast
world succeeds on ``panda-sim`` and a robot, and give a learner a baseline.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from panda_py.learning.actions import CARTESIAN_STEP

__all__ = ["pick_and_place_policy", "reach_policy"]

EE = slice(14, 17)  # the end effector's position in the observation
WIDTH = 21  # the fingers' opening (picking)
CUBE = slice(22, 25)  # the cube's centre (picking)
GRIP = np.array([0.0, 0.0, 0.005])  # [m] the TCP above the cube's centre when gripping
ABOVE = 0.08  # [m] approach from this high above the cube
ALIGNED = 0.008  # [m] the TCP this close to above the cube (horizontally) may descend
AT_GRIP = 0.006  # [m] the TCP this close to the grip point closes the hand
HELD = 0.045  # [m] fingers closed to under this with the cube between them: held
EMPTY = 0.03  # [m] fingers closed to under this: nothing between them
NEAR = 0.02  # [m] the cube this close to the grip point counts as between the fingers


def _toward(here: Any, there: Any, gain: float = 1.0) -> np.ndarray:
    """A delta action moving ``here`` toward ``there`` [m], within [-1, 1]."""
    return np.clip(gain * (np.asarray(there) - np.asarray(here)) / CARTESIAN_STEP, -1.0, 1.0)


def reach_policy(obs: dict[str, Any]) -> np.ndarray:
    """Proportional reaching: move the end effector straight toward the goal."""
    return _toward(obs["observation"][EE], obs["desired_goal"]).astype(np.float32)


def pick_and_place_policy(obs: dict[str, Any]) -> np.ndarray:
    """Above the cube, down, close, then carry it to the goal; open and retry if the
    hand closed on nothing."""
    o = obs["observation"]
    ee, width, cube = o[EE].astype(float), float(o[WIDTH]), o[CUBE].astype(float)
    grip = cube + GRIP
    between = np.linalg.norm(ee - grip) < NEAR
    if between and width < HELD and width > EMPTY:  # held: carry (the cube to the goal)
        move, hand = _toward(ee, obs["desired_goal"] + GRIP), -1.0
    elif between and width >= HELD and np.linalg.norm(ee - grip) < AT_GRIP:
        move, hand = np.zeros(3), -1.0  # closing: hold still
    elif width <= EMPTY:
        move, hand = _toward(ee, ee + np.array([0.0, 0.0, 0.05])), 1.0  # empty-handed: open, go up
    elif np.linalg.norm((ee - grip)[:2]) > ALIGNED:
        above = grip + np.array([0.0, 0.0, ABOVE])
        if ee[2] < grip[2] + 0.5 * ABOVE:  # too low to move across: up first
            above = np.array([ee[0], ee[1], above[2]])
        move, hand = _toward(ee, above), 1.0
    else:
        move, hand = _toward(ee, grip), 1.0  # over it: down
    return np.append(move, hand).astype(np.float32)
