"""The environments' action spaces: joint or Cartesian targets, delta or absolute, with
or without the hand; each checked (a clear ``ValueError``, nothing sent) and turned into
a target within the robot's limits for the streamed-target controllers.

``CARTESIAN_DELTA`` (panda-gym's end-effector control): ``(dx, dy, dz)`` in [-1, 1], times
``CARTESIAN_STEP`` [m] from where the end effector is. ``CARTESIAN_ABSOLUTE``: the end
effector's position ``(x, y, z)`` [m] within :data:`WORKSPACE_LOW` .. :data:`WORKSPACE_HIGH`.
Both keep the fingers pointing down (the start pose's orientation). ``JOINT_DELTA``: seven
values in [-1, 1], times ``JOINT_STEP`` [rad] from where the joints are. ``JOINT_ABSOLUTE``:
the seven joint positions [rad] within the joint limits less ``JOINT_MARGIN``. With the
hand, a last value in [-1, 1] asks it to open (> 0) or close on what it holds (<= 0).
"""

from __future__ import annotations

import enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import checks
from panda_py.robots.params import RobotSpec

__all__ = [
    "CARTESIAN_STEP",
    "JOINT_MARGIN",
    "JOINT_STEP",
    "WORKSPACE_HIGH",
    "WORKSPACE_LOW",
    "ActionKind",
    "ActionMap",
]

FloatArray = NDArray[np.float64]

CARTESIAN_STEP = 0.05  # [m] a delta action's largest move per step (panda-gym's)
JOINT_STEP = 0.05  # [rad] a delta action's largest move per step (panda-gym's)
JOINT_MARGIN = 0.05  # [rad] targets stay this far inside the joint limits (outside the walls' zone)
# [m] where Cartesian targets may go (base frame; the table top is z = 0): in front of the
# robot, in reach with the fingers down, the TCP no lower than 1.5 cm above the table
WORKSPACE_LOW = np.array([0.25, -0.4, 0.015])
WORKSPACE_HIGH = np.array([0.75, 0.4, 0.7])
_TOLERANCE = 1e-6  # float32 rounding of the bounds


class ActionKind(enum.Enum):
    """What an action commands (see the module)."""

    CARTESIAN_DELTA = "cartesian_delta"
    CARTESIAN_ABSOLUTE = "cartesian_absolute"
    JOINT_DELTA = "joint_delta"
    JOINT_ABSOLUTE = "joint_absolute"

    @classmethod
    def parse(cls, value: Any) -> ActionKind:
        """The kind ``value`` names (a kind or its value); ValueError listing the kinds."""
        try:
            return cls(value) if not isinstance(value, cls) else value
        except ValueError:
            raise ValueError(
                f"action: expected one of {[k.value for k in cls]} (or an ActionKind), "
                f"got {value!r}"
            ) from None

    @property
    def cartesian(self) -> bool:
        """Whether it commands the end effector's position (else the joints)."""
        return self in (ActionKind.CARTESIAN_DELTA, ActionKind.CARTESIAN_ABSOLUTE)

    @property
    def delta(self) -> bool:
        """Whether it commands a change from where the arm is (else a place)."""
        return self in (ActionKind.CARTESIAN_DELTA, ActionKind.JOINT_DELTA)


class ActionMap:
    """An action kind on one robot (``spec``), with the hand or not: its bounds, its
    check and its targets."""

    def __init__(self, kind: ActionKind, spec: RobotSpec, *, hand: bool) -> None:
        self.kind, self.hand = kind, hand
        q_min = np.asarray(spec.joints.q_min) + JOINT_MARGIN
        q_max = np.asarray(spec.joints.q_max) - JOINT_MARGIN
        self.q_min, self.q_max = q_min, q_max
        n = 3 if kind.cartesian else 7
        if kind.delta:
            low, high = -np.ones(n), np.ones(n)
        elif kind.cartesian:
            low, high = WORKSPACE_LOW.copy(), WORKSPACE_HIGH.copy()
        else:
            low, high = q_min.copy(), q_max.copy()
        if hand:
            low, high = np.append(low, -1.0), np.append(high, 1.0)
        self.low, self.high = low, high
        self._low, self._high = low.tolist(), high.tolist()
        self.size = low.size

    def check(self, action: Any) -> FloatArray:
        """The action as float64 (size,); ValueError naming what is wrong with it."""
        what = f"{self.size} values ({self.kind.value}{' and the hand' if self.hand else ''})"
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"action: expected {what}, got {action!r}") from None
        if a.shape != (self.size,):
            raise ValueError(f"action: expected {what}, shape ({self.size},); got shape {a.shape}")
        # in scalars: a policy step's NumPy calls on these short arrays cost it more
        values = a.tolist()
        if not checks.all_finite(values):
            raise ValueError(f"action: expected finite values, got {values}")
        clipped = []
        for i, (v, low, high) in enumerate(zip(values, self._low, self._high, strict=True)):
            if v < low - _TOLERANCE or v > high + _TOLERANCE:
                raise ValueError(
                    f"action: expected each value within the action space; value {i} is {v}, "
                    f"outside [{low}, {high}]"
                )
            clipped.append(high if v > high else low if v < low else v)  # (np.clip's)
        return np.array(clipped)

    def check_rows(self, actions: Any, rows: int) -> FloatArray:
        """``rows`` actions (one per environment) as float64 (rows, size), by the rule of
        :meth:`check` (the bounds' tolerance; clipping is left to each environment's own
        check); ValueError naming the first bad one."""
        what = f"({rows}, {self.size}) numbers"
        try:
            a = np.array(actions, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"actions: expected {what}, got {actions!r}") from None
        if a.shape != (rows, self.size):
            raise ValueError(f"actions: expected shape ({rows}, {self.size}), got shape {a.shape}")
        bad = ~np.isfinite(a) | (a < self.low - _TOLERANCE) | (a > self.high + _TOLERANCE)
        if bad.any():
            i, j = (int(x) for x in np.argwhere(bad)[0])
            raise ValueError(
                f"actions: environment {i}'s value {j} is {a[i, j]}: expected a finite value "
                f"within [{self.low[j]}, {self.high[j]}]; nothing was sent"
            )
        return a

    def target(self, action: FloatArray, q: FloatArray, position: FloatArray) -> FloatArray:
        """The target of a checked ``action`` from the measured joints ``q`` [rad] and end
        effector ``position`` [m]: a position [m] (Cartesian) or joint positions [rad],
        within the workspace or the joint limits."""
        kind, a = self.kind, action[: 3 if self.kind.cartesian else 7]
        if kind is ActionKind.CARTESIAN_DELTA:
            return np.clip(position + CARTESIAN_STEP * a, WORKSPACE_LOW, WORKSPACE_HIGH)
        if kind is ActionKind.CARTESIAN_ABSOLUTE:
            return a.copy()
        if kind is ActionKind.JOINT_DELTA:
            return np.clip(q + JOINT_STEP * a, self.q_min, self.q_max)
        return a.copy()

    def hand_open(self, action: FloatArray) -> bool | None:
        """Whether the action opens the hand (True) or closes it (False); None without."""
        return bool(action[-1] > 0.0) if self.hand else None
