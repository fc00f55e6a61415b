"""Deploying a learned policy: DROID's action contract on a Franka.

:class:`DroidActions` executes actions as DROID's robots did when the data its policies
learned from was recorded (:mod:`panda_py.learning.droid` says where DROID and openpi
define each convention): normalised joint velocities, 0.2 rad a step at 1, integrated from
the measured joints at 15 Hz, followed by polymetis's hybrid joint impedance with DROID's
gains (:class:`~panda_py.controllers.HybridJointImpedance`); the gripper command binarised
and every value clipped as openpi's DROID client does, the clipped actions counted; the
observations under openpi's DROID names, the flange's pose as ``cartesian_position``.
:class:`~panda_py.learning.policy_runner.PolicyRunner` calls a policy
``observation -> action or chunk`` at the policy rate on the robot's clock and runs its
chunks.

Options leave DROID's contract where a policy was trained otherwise: joint velocities in
rad/s (``normalized=False``), joint positions (``space``), targets integrated from the last
target (``from_measured=False``), a smoother follower (``controller=JointTarget(...)``),
out-of-range actions refused (``out_of_range="raise"``). Every action is checked before
anything of it is sent: a wrong shape or a NaN raise ValueError and nothing is sent.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from panda_py import checks
from panda_py.controllers import HybridJointImpedance
from panda_py.learning import droid
from panda_py.learning.droid import (
    ACTION_SIZE,
    DROID_HOME,
    DROID_MAX_JOINT_DELTA,
    GRIPPER_CLOSE,
    GRIPPER_SPEED,
    POLICY_RATE,
    as_chunk,
)
from panda_py.libfranka import Gripper
from panda_py.libfranka.gripper import CommandFuture
from panda_py.panda import Panda
from panda_py.robots.params import FRANKA_HAND

__all__ = [
    "ACTION_SIZE",
    "DROID_HOME",
    "DROID_MAX_JOINT_DELTA",
    "GRIPPER_CLOSE",
    "GRIPPER_THRESHOLD",
    "LIMIT_MARGIN",
    "POLICY_RATE",
    "ActionSpace",
    "DroidActions",
    "as_chunk",
]

# Without binarising: an opening command that moved less than this from the last one sent
# sends nothing (the hand runs one action at a time: each new one aborts the running one)
GRIPPER_THRESHOLD = 0.1
GRASP_FORCE = 20.0  # [N]
# [rad] integrated velocity targets stay this far inside the joint limits (the robot's
# reflex trips at the limits; the impedance tracking overshoots the target a little)
LIMIT_MARGIN = 0.05
OUT_OF_RANGE = ("clip", "raise")


class ActionSpace(enum.Enum):
    """What an action's first 7 numbers are (DROID's names)."""

    JOINT_VELOCITY = "joint_velocity"  # DROID's normalised [-1, 1], or [rad/s]
    JOINT_POSITION = "joint_position"  # [rad]


class DroidActions:
    """DROID's action contract on ``panda`` (and its ``gripper``, optional): while
    running (``start``/``stop``, or ``with``), :meth:`apply` turns an action into a joint
    setpoint for the ``controller`` and, when the gripper command changes, a hand action.

    By default, DROID's and openpi's (:mod:`panda_py.learning.droid`): ``space`` joint
    velocities, ``normalized`` (1 = :data:`DROID_MAX_JOINT_DELTA` rad a period, a vector
    beyond 1 scaled down by its largest), integrated at ``rate`` [Hz] ``from_measured``
    joints (else from the last target), clipped to the joint limits less
    :data:`LIMIT_MARGIN`; the ``controller`` a
    :class:`~panda_py.controllers.HybridJointImpedance` with DROID's gains (any controller
    with ``set_target(q)`` will do, e.g. a
    :class:`~panda_py.controllers.JointTarget`); ``out_of_range`` actions clipped as
    openpi's client clips them (counted in :attr:`clipped`) or refused (``"raise"``).
    Joint positions [rad] (``space``) are taken within the joint limits.

    The gripper command (0 open, 1 closed) is binarised at :data:`GRIPPER_CLOSE`
    (``binarize``, openpi's); closing grasps with ``grasp_force`` [N] (a Franka Hand
    holds nothing by moving: DROID's Robotiq does), opening moves to
    ``max_width * (1 - command)`` at DROID's :data:`~panda_py.learning.droid.GRIPPER_SPEED`;
    without binarising, a new opening command is sent when it moved by
    ``gripper_threshold``.

    ``cameras`` (name -> a call returning an (H, W, 3) uint8 image, e.g.
    ``{"exterior_image_1_left": sim.render}``) add images to :meth:`observation`."""

    def __init__(
        self,
        panda: Panda,
        gripper: Gripper | None = None,
        *,
        space: ActionSpace = ActionSpace.JOINT_VELOCITY,
        rate: float = POLICY_RATE,
        normalized: bool | None = None,
        from_measured: bool = True,
        controller: Any = None,
        out_of_range: str = "clip",
        binarize: bool = True,
        grasp_force: float = GRASP_FORCE,
        gripper_threshold: float = GRIPPER_THRESHOLD,
        cameras: Mapping[str, Callable[[], np.ndarray]] | None = None,
    ) -> None:
        if not isinstance(space, ActionSpace):
            raise ValueError(f"space: expected an ActionSpace {list(ActionSpace)}, got {space!r}")
        if not (isinstance(rate, (int, float)) and 1.0 <= rate <= 1000.0):
            raise ValueError(f"rate: expected a policy rate in 1..1000 Hz, got {rate!r}")
        if out_of_range not in OUT_OF_RANGE:
            raise ValueError(f"out_of_range: expected one of {OUT_OF_RANGE}, got {out_of_range!r}")
        if controller is None:
            controller = HybridJointImpedance()
        elif not callable(getattr(controller, "set_target", None)):
            raise ValueError(
                f"controller: expected a joint controller with set_target(q) (e.g. "
                f"HybridJointImpedance, JointTarget), got {controller!r}"
            )
        gripper_threshold = checks.number(
            "gripper_threshold", gripper_threshold, low=0.0, low_open=True, high=1.0
        )
        grasp_force = checks.number(
            "grasp_force", grasp_force, "[N]", low=0.0, high=FRANKA_HAND.peak_force
        )
        velocities = space is ActionSpace.JOINT_VELOCITY
        if normalized and not velocities:
            raise ValueError("normalized: only joint velocities are normalised (DROID's)")
        self.panda, self.gripper = panda, gripper
        self.space, self.rate = space, float(rate)
        self.normalized = velocities and normalized is not False
        self.from_measured = bool(from_measured)
        self.out_of_range, self.binarize = out_of_range, bool(binarize)
        self.grasp_force = grasp_force
        self.gripper_threshold = float(gripper_threshold)
        self.cameras = dict(cameras or {})
        self.controller = controller
        self.q_min = np.asarray(panda.get_joint_limits_lower())
        self.q_max = np.asarray(panda.get_joint_limits_upper())
        self.dq_max = np.asarray(panda.get_model().spec.joints.dq_max)  # [rad/s]
        self.max_width = 0.0  # [m] the hand's, read at start
        self.target: np.ndarray | None = None  # the last joint target sent [rad]
        self.clipped = 0  # actions with a value clipped (out_of_range="clip"), all told
        self._gripper_sent: float | None = None  # the last gripper command sent
        self.gripper_future: CommandFuture | None = None  # the hand's running action

    # --- lifecycle ----------------------------------------------------------------------

    def start(self) -> DroidActions:
        """Start the controller where the arm is."""
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

    def reset(self, speed_factor: float = 0.2) -> None:
        """DROID's reset (``droid/robot_env.py`` lines 65-73): the hand opened, then the arm
        moved to :data:`DROID_HOME`; the controller, if it ran, starts again there."""
        running = self.target is not None
        self.stop()
        if self.gripper is not None:
            width = self.gripper.read_once().max_width
            self.gripper.move(width, GRIPPER_SPEED)
        self.panda.move_to_joint_position(DROID_HOME, speed_factor=speed_factor)
        if running:
            self.start()

    def __enter__(self) -> DroidActions:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # --- actions ------------------------------------------------------------------------

    @property
    def period(self) -> float:
        """The policy period [s]."""
        return 1.0 / self.rate

    def _joint_range(self) -> tuple[np.ndarray, np.ndarray, str, str]:
        """The joints' allowed values: low, high, what they are, their unit."""
        if self.space is ActionSpace.JOINT_POSITION:
            return self.q_min, self.q_max, "joint positions within the joint limits", " rad"
        if self.normalized:
            high = np.ones(7)
            return -high, high, "normalised joint velocities (DROID's) in [-1, 1]", ""
        return -self.dq_max, self.dq_max, "joint velocities within the robot's limits", " rad/s"

    def check(self, actions: Any) -> np.ndarray:
        """``actions`` (an (8,) action, an (H, 8) chunk or openpi's ``{"actions": ...}``)
        checked strictly against this contract, as an (H, 8) array; ValueError (what,
        expected, given) for anything out of range. Sends nothing."""
        chunk = as_chunk(actions)
        joints, grip = chunk[:, :7], chunk[:, 7]
        bad = np.argwhere((grip < 0.0) | (grip > 1.0))
        if bad.size:
            i = int(bad[0, 0])
            raise ValueError(
                f"actions: expected a gripper command in [0, 1] (0 open, 1 closed) as the "
                f"8th value; action {i} has {grip[i]}"
            )
        low, high, what, unit = self._joint_range()
        outside = np.argwhere((joints < low) | (joints > high))
        if outside.size:
            i, j = (int(v) for v in outside[0])
            raise ValueError(
                f"actions: expected {what}; action {i}, joint {j + 1} is {joints[i, j]}{unit}, "
                f"outside [{low[j]}, {high[j]}]{unit}"
            )
        return chunk

    def prepare(self, actions: Any) -> tuple[np.ndarray, int]:
        """``actions`` as they will run: a wrong shape or a non-finite value raise
        ValueError; with ``out_of_range="clip"`` the gripper binarised (``binarize``) and
        every value clipped as openpi's client does (the count of actions clipped
        returned too, and added to :attr:`clipped`), else checked strictly (:meth:`check`)
        and binarised. Sends nothing."""
        if self.out_of_range == "raise":
            chunk, clipped = self.check(actions), 0
            if self.binarize:
                chunk[:, 7] = (chunk[:, 7] > GRIPPER_CLOSE).astype(np.float64)
        else:
            low, high, _, _ = self._joint_range()
            chunk, clipped = droid.conform(as_chunk(actions), low, high, binarize=self.binarize)
        self.clipped += clipped
        return chunk, clipped

    def apply(self, action: Any) -> np.ndarray:
        """Execute one action (8,) now: the new joint target [rad] is sent (and returned),
        the gripper commanded if its command changed enough."""
        chunk, _ = self.prepare(action)
        if chunk.shape[0] != 1:
            raise ValueError(
                f"action: expected one action of shape ({ACTION_SIZE},), got a chunk of "
                f"{chunk.shape[0]} (PolicyRunner executes chunks)"
            )
        return self.apply_checked(chunk)

    def apply_checked(self, rows: np.ndarray) -> np.ndarray:
        """Execute prepared rows (from :meth:`prepare`) as one step: the last row's target
        (velocities: all rows' moves summed, e.g. the periods a late step folded in) and its
        gripper command. Returns the joint target sent [rad]."""
        if self.target is None:
            raise RuntimeError("DroidActions: not started (start() or use it in a with)")
        last = rows[-1]
        if self.space is ActionSpace.JOINT_POSITION:
            target = last[:7].copy()
        else:
            if self.normalized:
                delta = droid.joint_velocity_to_delta(rows[:, :7]).sum(axis=0)
            else:
                delta = rows[:, :7].sum(axis=0) * self.period
            base = self.panda.q if self.from_measured else self.target
            target = np.clip(base + delta, self.q_min + LIMIT_MARGIN, self.q_max - LIMIT_MARGIN)
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
        (6,) (the flange's position [m] and extrinsic x-y-z Euler angles [rad], DROID's
        ``panda_link8``: :func:`~panda_py.learning.droid.flange_pose`),
        ``observation/<camera>`` images, and ``time`` [s] of the robot's clock."""
        state = self.panda.get_state()
        if self.gripper is not None:
            closed = 1.0 - self.gripper.read_once().width / self.max_width
        else:
            closed = 0.0
        obs: dict[str, Any] = {
            "observation/joint_position": np.array(state.q),
            "observation/joint_velocity": np.array(state.dq),
            "observation/gripper_position": np.array([min(1.0, max(0.0, closed))]),
            "observation/cartesian_position": droid.flange_pose(state.O_T_EE, state.F_T_EE),
            "time": state.time.to_sec(),
        }
        for name, camera in self.cameras.items():
            obs[f"observation/{name}"] = np.asarray(camera())
        return obs
