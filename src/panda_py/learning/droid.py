"""DROID's conventions, as DROID and openpi's DROID client define them, line by line.

A policy trained on DROID's data (openpi's pi0-FAST-DROID and pi0.5-DROID among them) acts
right only where its actions mean what they meant when the data was recorded. Each
convention here cites where DROID (droid-dataset/droid, commit 1548722) or openpi
(Physical-Intelligence/openpi, ``examples/droid/main.py``, commit 15a9616) defines it:

- the rate: 15 Hz (``droid/robot_env.py`` line 31, ``control_hz``; openpi ``main.py``
  line 23, ``DROID_CONTROL_FREQUENCY``);
- an action: 7 joint velocities then a gripper position, 8 numbers (openpi ``main.py``
  line 80: ``action_space="joint_velocity", gripper_action_space="position"``; line 132:
  chunks of (10, 8));
- the joint velocities are normalised: 1 is :data:`DROID_MAX_JOINT_DELTA` = 0.2 rad a step,
  and a vector with a component beyond 1 is scaled down whole by its largest
  (``droid/robot_ik/robot_ik_solver.py`` lines 10-11 and 88-100,
  ``joint_velocity_to_delta``): :func:`joint_velocity_to_delta`;
- integrated from the MEASURED joints: ``joint_delta + robot_state["joint_positions"]``
  (``droid/franka/robot.py`` lines 236-238, ``create_action_dict``; the state read there,
  line 194);
- openpi's client binarises the gripper at 0.5 (``main.py`` lines 140-146) and clips every
  value to [-1, 1] (line 149): :func:`conform`;
- the gripper goes to ``max_width * (1 - command)`` (``droid/franka/robot.py`` lines
  122-123, ``update_gripper``; DROID's is a Robotiq 2F-85 through polymetis, ``goto`` at
  ``speed=0.05``);
- the proprioception: ``gripper_position`` is ``1 - width / max_width`` (``robot.py``
  line 151); ``cartesian_position`` is ``panda_link8``'s (the flange's) position and
  extrinsic x-y-z Euler angles (``robot.py`` lines 161-162; ``ee_link_name: panda_link8``
  in ``config/panda/franka_panda.yaml``; ``droid/misc/transformations.py`` line 7,
  ``as_euler("xyz")``): :func:`flange_pose`;
- the home pose [0, -pi/5, 0, -4pi/5, 0, 3pi/5, 0] (``droid/robot_env.py`` line 27,
  ``reset_joints``): :data:`DROID_HOME`;
- a chunk's actions run in order, one a period, 8 of them before the policy is asked again
  (``main.py`` lines 42, 114-138); a late step runs the next action, not a later one
  (:class:`~panda_py.learning.policy_runner.PolicyRunner`'s ``late="in_order"``);
- the controller: polymetis's ``HybridJointImpedanceControl`` with DROID's gains
  (:class:`~panda_py.controllers.HybridJointImpedance`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = [
    "ACTION_SIZE",
    "DROID_HOME",
    "DROID_MAX_JOINT_DELTA",
    "GRIPPER_CLOSE",
    "GRIPPER_SPEED",
    "OPEN_LOOP_HORIZON",
    "POLICY_RATE",
    "as_chunk",
    "conform",
    "flange_pose",
    "joint_velocity_to_delta",
]

POLICY_RATE = 15.0  # [Hz] (droid/robot_env.py line 31)
ACTION_SIZE = 8  # 7 joints, then the gripper
# [rad] a step's joint move at a normalised velocity of 1 (robot_ik_solver.py lines 10-11)
DROID_MAX_JOINT_DELTA = 0.2
#: DROID's home pose [rad] (droid/robot_env.py line 27, ``reset_joints``)
DROID_HOME = (0.0, -math.pi / 5, 0.0, -4 * math.pi / 5, 0.0, 3 * math.pi / 5, 0.0)
# a gripper command above this closes the hand (openpi examples/droid/main.py line 141)
GRIPPER_CLOSE = 0.5
GRIPPER_SPEED = 0.05  # [m/s] DROID's (droid/franka/robot.py line 123)
OPEN_LOOP_HORIZON = 8  # actions of a chunk run before the next call (openpi main.py line 42)


def as_chunk(actions: Any) -> np.ndarray:
    """An action (8,) or a chunk (H, 8) as a float (H, 8) array; a mapping with an
    ``"actions"`` entry (what openpi's policy client returns) gives that entry. ValueError
    (what, expected, given) for anything else, or a value that is not finite."""
    if isinstance(actions, Mapping):
        if "actions" not in actions:
            raise ValueError(
                f"actions: expected an array, or a mapping with an 'actions' entry (as "
                f"openpi's policies return); got a mapping of {sorted(map(str, actions))}"
            )
        actions = actions["actions"]
    try:
        chunk = np.array(actions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"actions: expected numbers, an (8,) action or an (H, 8) chunk; got {actions!r}"
        ) from exc
    if chunk.ndim == 1:
        chunk = chunk[None, :]
    if chunk.ndim != 2 or chunk.shape[1] != ACTION_SIZE or chunk.shape[0] == 0:
        raise ValueError(
            f"actions: expected an action of shape ({ACTION_SIZE},) or a chunk (H, "
            f"{ACTION_SIZE}), H >= 1: 7 joint values and a gripper command; got shape "
            f"{np.shape(actions)}"
        )
    if not np.isfinite(chunk).all():
        row, col = np.argwhere(~np.isfinite(chunk))[0]
        raise ValueError(
            f"actions: expected finite values; action {row} has {chunk[row, col]} at {col}"
        )
    return chunk


def joint_velocity_to_delta(velocity: np.ndarray) -> np.ndarray:
    """DROID's normalised joint velocities (H, 7) or (7,) as joint moves [rad] a step:
    ``velocity * 0.2``, a vector with a component beyond 1 first scaled down whole by its
    largest (robot_ik_solver.py lines 88-100)."""
    v = np.asarray(velocity, dtype=np.float64)
    largest = np.abs(v).max(axis=-1, keepdims=True)
    return v / np.maximum(largest, 1.0) * DROID_MAX_JOINT_DELTA


def conform(
    chunk: np.ndarray, low: np.ndarray, high: np.ndarray, *, binarize: bool = True
) -> tuple[np.ndarray, int]:
    """openpi's DROID client on a checked (H, 8) chunk: the gripper command binarised at
    :data:`GRIPPER_CLOSE` (with ``binarize``), then every value clipped: the joints to
    [``low``, ``high``] (openpi's [-1, 1] for normalised velocities), the gripper to
    [0, 1]. Returns the new chunk and how many actions had a value clipped."""
    out = chunk.copy()
    if binarize:
        out[:, 7] = (out[:, 7] > GRIPPER_CLOSE).astype(np.float64)
    np.clip(out[:, :7], low, high, out=out[:, :7])
    np.clip(out[:, 7], 0.0, 1.0, out=out[:, 7])
    bounded = (
        np.concatenate([np.broadcast_to(low, 7), [0.0]]),
        np.concatenate([np.broadcast_to(high, 7), [1.0]]),
    )
    outside = (chunk < bounded[0]) | (chunk > bounded[1])
    if binarize:
        outside[:, 7] = (chunk[:, 7] < 0.0) | (chunk[:, 7] > 1.0)
    return out, int(outside.any(axis=1).sum())


def flange_pose(O_T_EE: Any, F_T_EE: Any) -> np.ndarray:
    """DROID's ``cartesian_position`` (6,): the flange's (``panda_link8``'s) position [m]
    and extrinsic x-y-z Euler angles [rad] (scipy's ``as_euler("xyz")``), from a state's
    ``O_T_EE`` and ``F_T_EE`` (column-major 4x4, libfranka's)."""
    O_T_EE = np.asarray(O_T_EE, dtype=np.float64).reshape(4, 4).T
    F_T_EE = np.asarray(F_T_EE, dtype=np.float64).reshape(4, 4).T
    T = O_T_EE @ np.linalg.inv(F_T_EE)  # O_T_F
    R = T[:3, :3]
    euler = (
        math.atan2(R[2, 1], R[2, 2]),
        -math.asin(max(-1.0, min(1.0, R[2, 0]))),
        math.atan2(R[1, 0], R[0, 0]),
    )
    return np.concatenate([T[:3, 3], euler])
