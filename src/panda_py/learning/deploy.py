"""Deploying a learned policy: DROID's action contract on the streamed-target control.

DROID's robots, and the policies trained on its data (openpi's pi0-FAST-DROID and
pi0.5-DROID among them), act at 15 Hz with an action of 8 numbers: 7 joint velocities or
joint positions, then a gripper command in [0, 1], 0 open and 1 closed (droid-dataset/droid,
``droid/franka/robot.py``: ``create_action_dict`` with the action spaces
``joint_velocity``/``joint_position`` and the gripper space ``position``; the fingers go
to ``max_width * (1 - command)``). Such policies emit action CHUNKS, (H, 8) arrays of the
next H actions, of which the robot runs a few open loop before it asks again (openpi's
``examples/droid/main.py``: chunks of 10 or 15, ``open_loop_horizon`` 8).

:class:`DroidActions` maps those actions onto :class:`~panda_py.controllers.JointTarget`
(a jerk-limited reference toward the newest target at 1 kHz, under joint impedance) and
the Franka Hand's asynchronous ``move``/``grasp``; :class:`PolicyRunner` calls a policy
``observation -> action or chunk`` at the policy rate on the robot's clock and executes
the chunks, one action per period. Every action is checked before anything of it is
sent: a wrong shape, a NaN, a velocity beyond the robot's limits, a position outside its
joint limits or a gripper command outside [0, 1] raise ValueError and nothing is sent.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from panda_py import checks
from panda_py.controllers import JointTarget, streaming
from panda_py.libfranka import Gripper
from panda_py.libfranka.gripper import CommandFuture
from panda_py.panda import Panda
from panda_py.robots.params import FRANKA_HAND

__all__ = [
    "ACTION_SIZE",
    "DROID_MAX_JOINT_DELTA",
    "GRIPPER_CLOSE",
    "GRIPPER_THRESHOLD",
    "LIMIT_MARGIN",
    "POLICY_RATE",
    "ActionSpace",
    "DroidActions",
    "as_chunk",
]

POLICY_RATE = 15.0  # [Hz] DROID's control frequency (droid/robot_ik/robot_ik_solver.py)
ACTION_SIZE = 8  # 7 joints, then the gripper
# [rad] a step's joint move at a normalised velocity of 1: DROID's RobotIKSolver
# max_joint_delta (joint_velocity_to_delta: delta = velocity * 0.2 per 1/15 s step)
DROID_MAX_JOINT_DELTA = 0.2
# A gripper command above this closes the hand (a grasp); openpi's DROID client binarises
# the policy's gripper output at 0.5 the same way (examples/droid/main.py)
GRIPPER_CLOSE = 0.5
# An opening command that moved less than this from the last one sent sends nothing (the
# hand runs one action at a time: each new one aborts the running one)
GRIPPER_THRESHOLD = 0.1
GRIPPER_SPEED = 0.1  # [m/s] the hand's fastest
GRASP_FORCE = 20.0  # [N]
# [rad] integrated velocity targets stay this far inside the joint limits (the robot's
# reflex trips at the limits; the impedance tracking overshoots the reference a little)
LIMIT_MARGIN = 0.05


class ActionSpace(enum.Enum):
    """What an action's first 7 numbers are (DROID's names)."""

    JOINT_VELOCITY = "joint_velocity"  # [rad/s], or DROID's normalised [-1, 1]
    JOINT_POSITION = "joint_position"  # [rad]


def as_chunk(actions: Any) -> np.ndarray:
    """An action (8,) or a chunk (H, 8) as a float (H, 8) array; a mapping with an
    ``"actions"`` entry (what openpi's policy client returns) gives that entry."""
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


class DroidActions:
    """DROID's action contract on ``panda`` (and its ``gripper``, optional): while
    running (``start``/``stop``, or ``with``), :meth:`apply` turns an action into a joint
    target for :class:`~panda_py.controllers.JointTarget` and, when the gripper command
    changes, a hand action.

    ``space``: joint velocities [rad/s] (``normalized``: DROID's [-1, 1], times
    :data:`DROID_MAX_JOINT_DELTA` rad a period) integrated at ``rate`` [Hz] from the last
    target (``from_measured``: from the measured joints, as DROID does; its targets then
    lag the integral by the tracking error), clipped to the joint limits less
    :data:`LIMIT_MARGIN`; or joint positions [rad] within the joint limits. The gripper:
    above :data:`GRIPPER_CLOSE` a grasp with ``grasp_force`` [N], else a move to
    ``max_width * (1 - command)``; sent when the command crosses that line or moves by
    ``gripper_threshold``. ``speed_factor`` and ``timeout`` [s] are the JointTarget's: a
    policy that stops acting brings the arm to rest after ``timeout``.

    ``cameras`` (name -> a call returning an (H, W, 3) uint8 image, e.g.
    ``{"exterior_image_1_left": sim.render}``) add images to :meth:`observation`."""

    def __init__(
        self,
        panda: Panda,
        gripper: Gripper | None = None,
        *,
        space: ActionSpace = ActionSpace.JOINT_VELOCITY,
        rate: float = POLICY_RATE,
        normalized: bool = False,
        from_measured: bool = False,
        speed_factor: float = streaming.SPEED_FACTOR,
        timeout: float | None = streaming.TIMEOUT,
        grasp_force: float = GRASP_FORCE,
        gripper_threshold: float = GRIPPER_THRESHOLD,
        cameras: Mapping[str, Callable[[], np.ndarray]] | None = None,
    ) -> None:
        if not isinstance(space, ActionSpace):
            raise ValueError(f"space: expected an ActionSpace {list(ActionSpace)}, got {space!r}")
        if not (isinstance(rate, (int, float)) and 1.0 <= rate <= 1000.0):
            raise ValueError(f"rate: expected a policy rate in 1..1000 Hz, got {rate!r}")
        gripper_threshold = checks.number(
            "gripper_threshold", gripper_threshold, low=0.0, low_open=True, high=1.0
        )
        grasp_force = checks.number(
            "grasp_force", grasp_force, "[N]", low=0.0, high=FRANKA_HAND.peak_force
        )
        if normalized and space is not ActionSpace.JOINT_VELOCITY:
            raise ValueError("normalized: only joint velocities are normalised (DROID's)")
        self.panda, self.gripper = panda, gripper
        self.space, self.rate = space, float(rate)
        self.normalized, self.from_measured = bool(normalized), bool(from_measured)
        self.grasp_force = grasp_force
        self.gripper_threshold = float(gripper_threshold)
        self.cameras = dict(cameras or {})
        self.controller = JointTarget(speed_factor, timeout=timeout)
        self.q_min = np.asarray(panda.get_joint_limits_lower())
        self.q_max = np.asarray(panda.get_joint_limits_upper())
        self.dq_max = np.asarray(panda.get_model().spec.joints.dq_max)  # [rad/s]
        self.max_width = 0.0  # [m] the hand's, read at start
        self.target: np.ndarray | None = None  # the last joint target sent [rad]
        self._gripper_sent: float | None = None  # the last gripper command sent
        self.gripper_future: CommandFuture | None = None  # the hand's running action

    # --- lifecycle ----------------------------------------------------------------------

    def start(self) -> DroidActions:
        """Start the streamed-target controller where the arm is."""
        if self.gripper is not None:
            self.max_width = self.gripper.read_once().max_width
            if not self.max_width > 0.0:  # a Franka Hand learns its stroke by homing
                raise RuntimeError(
                    "gripper: the hand reports no maximum width; home it first (gripper.homing())"
                )
        self.panda.start_controller(self.controller)
        self.target = self.panda.q
        self._gripper_sent = None
        return self

    def stop(self) -> None:
        """Stop the controller (the robot holds its position)."""
        if self.target is not None:
            self.target = None
            self.panda.stop_controller()

    def __enter__(self) -> DroidActions:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # --- actions ------------------------------------------------------------------------

    @property
    def period(self) -> float:
        """The policy period [s]."""
        return 1.0 / self.rate

    def check(self, actions: Any) -> np.ndarray:
        """``actions`` (an (8,) action, an (H, 8) chunk or openpi's ``{"actions": ...}``)
        checked against this contract, as an (H, 8) array; ValueError (what, expected,
        given) otherwise. Sends nothing."""
        chunk = as_chunk(actions)
        joints, grip = chunk[:, :7], chunk[:, 7]
        bad = np.argwhere((grip < 0.0) | (grip > 1.0))
        if bad.size:
            i = int(bad[0, 0])
            raise ValueError(
                f"actions: expected a gripper command in [0, 1] (0 open, 1 closed) as the "
                f"8th value; action {i} has {grip[i]}"
            )
        if self.space is ActionSpace.JOINT_POSITION:
            low, high, what = self.q_min, self.q_max, "joint positions within the joint limits"
            unit = " rad"
        elif self.normalized:
            high = np.ones(7)
            low, what, unit = -high, "normalised joint velocities (DROID's) in [-1, 1]", ""
        else:
            high = self.dq_max
            low, what, unit = -high, "joint velocities within the robot's limits", " rad/s"
        outside = np.argwhere((joints < low) | (joints > high))
        if outside.size:
            i, j = (int(v) for v in outside[0])
            raise ValueError(
                f"actions: expected {what}; action {i}, joint {j + 1} is {joints[i, j]}{unit}, "
                f"outside [{low[j]}, {high[j]}]{unit}"
            )
        return chunk

    def apply(self, action: Any) -> np.ndarray:
        """Execute one action (8,) now: the new joint target [rad] is sent (and returned),
        the gripper commanded if its command changed enough."""
        chunk = self.check(action)
        if chunk.shape[0] != 1:
            raise ValueError(
                f"action: expected one action of shape ({ACTION_SIZE},), got a chunk of "
                f"{chunk.shape[0]} (PolicyRunner executes chunks)"
            )
        return self.apply_checked(chunk)

    def apply_checked(self, rows: np.ndarray) -> np.ndarray:
        """Execute checked rows (from :meth:`check`) as one step: the last row's target
        (velocities: all rows' moves summed, e.g. the periods a late step skipped) and its
        gripper command. Returns the joint target sent [rad]."""
        if self.target is None:
            raise RuntimeError("DroidActions: not started (start() or use it in a with)")
        last = rows[-1]
        if self.space is ActionSpace.JOINT_POSITION:
            target = last[:7].copy()
        else:
            scale = DROID_MAX_JOINT_DELTA if self.normalized else self.period
            base = self.panda.q if self.from_measured else self.target
            target = np.clip(
                base + rows[:, :7].sum(axis=0) * scale,
                self.q_min + LIMIT_MARGIN,
                self.q_max - LIMIT_MARGIN,
            )
        self.controller.set_target(target)
        self.target = target
        self._command_gripper(float(last[7]))
        return target

    def _command_gripper(self, command: float) -> None:
        gripper, sent = self.gripper, self._gripper_sent
        if gripper is None:
            return
        close = command > GRIPPER_CLOSE
        if sent is not None:
            was_closed = sent > GRIPPER_CLOSE
            if close == was_closed and (close or abs(command - sent) < self.gripper_threshold):
                return
        if close:  # whatever is between the fingers, held with the force
            self.gripper_future = gripper.grasp(
                0.0, GRIPPER_SPEED, self.grasp_force, 0.0, self.max_width, asynchronous=True
            )
        else:
            width = self.max_width * (1.0 - command)
            self.gripper_future = gripper.move(width, GRIPPER_SPEED, asynchronous=True)
        self._gripper_sent = command

    # --- observations -------------------------------------------------------------------

    def observation(self) -> dict[str, Any]:
        """The robot as a policy sees it, under openpi's DROID names:
        ``observation/joint_position`` (7,) [rad], ``observation/joint_velocity`` (7,)
        [rad/s], ``observation/gripper_position`` (1,) (0 open, 1 closed; DROID's
        ``1 - width / max_width``; 0 without a hand), ``observation/cartesian_position``
        (6,) (end effector [m] and extrinsic x-y-z Euler angles [rad], DROID's),
        ``observation/<camera>`` images, and ``time`` [s] of the robot's clock."""
        state = self.panda.get_state()
        T = np.asarray(state.O_T_EE).reshape(4, 4).T
        R = T[:3, :3]
        euler = (
            math.atan2(R[2, 1], R[2, 2]),
            -math.asin(max(-1.0, min(1.0, R[2, 0]))),
            math.atan2(R[1, 0], R[0, 0]),
        )
        if self.gripper is not None:
            closed = 1.0 - self.gripper.read_once().width / self.max_width
        else:
            closed = 0.0
        obs: dict[str, Any] = {
            "observation/joint_position": np.array(state.q),
            "observation/joint_velocity": np.array(state.dq),
            "observation/gripper_position": np.array([min(1.0, max(0.0, closed))]),
            "observation/cartesian_position": np.concatenate([T[:3, 3], euler]),
            "time": state.time.to_sec(),
        }
        for name, camera in self.cameras.items():
            obs[f"observation/{name}"] = np.asarray(camera())
        return obs
