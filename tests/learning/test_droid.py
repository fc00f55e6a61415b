"""DROID's contract, against DROID's and openpi's own numbers (droid-dataset/droid at
1548722, Physical-Intelligence/openpi's examples/droid/main.py at 15a9616; each test names
the lines it follows): the normalised joint velocities and their integration from the
measured joints, openpi's clipping and gripper binarisation, the home pose, the flange's
pose, a DROID episode replayed through the adapter, polymetis's controller with DROID's
gains on the simulator, and bad input refused with nothing sent."""

from __future__ import annotations

import math
import time
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from conftest import Rig

from panda_py.controllers import HybridJointImpedance
from panda_py.controllers.setpoints import DROID_KQ, DROID_KQD, DROID_KX, DROID_KXD
from panda_py.learning import DroidActions, PolicyRunner, droid
from panda_py.libfranka import RobotMode
from panda_py.robots.params import get_robot

pytestmark = pytest.mark.timeout(300)

RATE = 15.0  # [Hz]


# --- DROID's code, transcribed (the reference these tests hold ours to) -----------------


def droid_joint_velocity_to_delta(joint_velocity: np.ndarray) -> np.ndarray:
    """droid/robot_ik/robot_ik_solver.py lines 88-100 (relative_max_joint_delta 0.2 each,
    max_joint_delta its largest: lines 10-11)."""
    relative_max_joint_delta = np.array([0.2] * 7)
    max_joint_delta = relative_max_joint_delta.max()
    relative_max_joint_vel = relative_max_joint_delta / max_joint_delta
    max_joint_vel_norm = (np.abs(joint_velocity) / relative_max_joint_vel).max()
    if max_joint_vel_norm > 1:
        joint_velocity = joint_velocity / max_joint_vel_norm
    return joint_velocity * max_joint_delta


def droid_joint_target(action: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
    """droid/franka/robot.py lines 233-238: joint_velocity action space."""
    return droid_joint_velocity_to_delta(action[:-1]) + joint_positions


def openpi_client_action(action: np.ndarray) -> np.ndarray:
    """openpi examples/droid/main.py lines 140-149: binarise the gripper, clip to [-1, 1]."""
    if action[-1].item() > 0.5:
        action = np.concatenate([action[:-1], np.ones((1,))])
    else:
        action = np.concatenate([action[:-1], np.zeros((1,))])
    return np.clip(action, -1, 1)


# --- a stand-in robot that reads back what DROID's state would be ---------------------


class ReplayedPanda:
    """What DroidActions asks of a Panda, answering with a recorded episode's joints: each
    read of ``q`` the joints of the current step (``step`` moves on)."""

    def __init__(self, joints: np.ndarray) -> None:
        spec = get_robot("fer")
        self.joints, self.step, self.spec = joints, 0, spec
        self.controller: Any = None

    @property
    def q(self) -> np.ndarray:
        return self.joints[self.step].copy()

    def get_joint_limits_lower(self) -> np.ndarray:
        return np.array(self.spec.joints.q_min)

    def get_joint_limits_upper(self) -> np.ndarray:
        return np.array(self.spec.joints.q_max)

    def get_model(self) -> Any:
        return SimpleNamespace(spec=self.spec)

    def start_controller(self, controller: Any) -> None:
        self.controller = controller

    def stop_controller(self) -> None:
        self.controller = None


class Setpoints:
    """A joint controller that keeps what it was sent."""

    def __init__(self) -> None:
        self.sent: list[np.ndarray] = []

    def set_target(self, q: Any) -> None:
        self.sent.append(np.array(q, dtype=float))


def droid_episode(n: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A synthetic DROID episode: n states' joint positions near the home pose and n
    normalised joint-velocity actions, a few beyond [-1, 1] (as a policy's raw output)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None] / RATE
    joints = np.array(droid.DROID_HOME) + 0.15 * np.sin(t * rng.uniform(0.5, 2.0, 7))
    actions = np.hstack([rng.uniform(-1.3, 1.3, (n, 7)), rng.uniform(0, 1, (n, 1))])
    return joints, actions


# --- the conventions ------------------------------------------------------------------


def test_droid_numbers() -> None:
    # droid/robot_env.py line 27 (reset_joints), line 31 (control_hz)
    np.testing.assert_array_equal(
        droid.DROID_HOME,
        [0, -1 / 5 * np.pi, 0, -4 / 5 * np.pi, 0, 3 / 5 * np.pi, 0.0],
    )
    assert droid.POLICY_RATE == 15 and droid.DROID_MAX_JOINT_DELTA == 0.2
    assert droid.OPEN_LOOP_HORIZON == 8 and droid.GRIPPER_CLOSE == 0.5  # openpi's
    # droid config/panda/franka_hardware.yaml lines 10-13 (config/fr3: the same)
    assert DROID_KQ == (40, 30, 50, 25, 35, 25, 10) and DROID_KQD == (4, 6, 5, 5, 3, 2, 1)
    assert DROID_KX == (400, 400, 400, 15, 15, 15) and DROID_KXD == (37, 37, 37, 2, 2, 2)
    controller = HybridJointImpedance()
    np.testing.assert_array_equal(controller.Kq, DROID_KQ)
    np.testing.assert_array_equal(controller.Kxd, DROID_KXD)


def test_normalised_velocities_as_droid_scales_them() -> None:
    rng = np.random.default_rng(0)
    for v in [*rng.uniform(-1, 1, (20, 7)), *rng.uniform(-3, 3, (20, 7)), np.zeros(7)]:
        np.testing.assert_allclose(
            droid.joint_velocity_to_delta(v), droid_joint_velocity_to_delta(v), atol=1e-15
        )
    # 0.2 on joint 1 is 0.04 rad a step: 0.6 rad over 15 steps (1 s), not 0.2
    assert droid.joint_velocity_to_delta(np.array([0.2, 0, 0, 0, 0, 0, 0]))[0] * 15 == (
        pytest.approx(0.6)
    )


def test_openpi_clipping_and_binarising() -> None:
    rng = np.random.default_rng(1)
    chunk = np.hstack([rng.uniform(-1.5, 1.5, (10, 7)), rng.uniform(-0.2, 1.2, (10, 1))])
    chunk[0] = [0.1] * 7 + [0.5]  # in range; 0.5 is open (> 0.5 closes)
    ones = np.ones(7)
    ours, clipped = droid.conform(chunk, -ones, ones)
    expected = np.array([openpi_client_action(a) for a in chunk])
    np.testing.assert_array_equal(ours, expected)
    assert ours[0, 7] == 0.0
    # an action counts as clipped when a joint value was out of range (a gripper command
    # binarised is not clipped unless it was outside [0, 1])
    outside = (np.abs(chunk[:, :7]) > 1).any(axis=1) | (chunk[:, 7] < 0) | (chunk[:, 7] > 1)
    assert clipped == int(outside.sum()) > 0


def test_a_droid_episode_replays_to_droids_own_targets() -> None:
    """DROID's targets for an episode (its measured joints and normalised actions, through
    openpi's client and DROID's create_action_dict) against ours: within 1 mrad."""
    joints, actions = droid_episode(60)
    panda = ReplayedPanda(joints)
    controller = Setpoints()
    arm = DroidActions(panda, controller=controller)  # type: ignore[arg-type]
    with arm:
        for k, action in enumerate(actions):
            panda.step = k
            arm.apply(action)
    ours = np.array(controller.sent)
    theirs = np.array(
        [
            droid_joint_target(openpi_client_action(a), q)
            for a, q in zip(actions, joints, strict=True)
        ]
    )
    # DROID's targets are not kept off the joint limits; these stay well inside them
    limits = panda.spec.joints
    assert np.all((theirs > np.array(limits.q_min) + 0.1) & (theirs < np.array(limits.q_max) - 0.1))
    assert np.abs(ours - theirs).max() < 1e-3
    assert arm.clipped == int((np.abs(actions[:, :7]) > 1).any(axis=1).sum()) > 0


def test_the_flange_pose_is_droids_cartesian_position(rig: Rig) -> None:
    state = rig.panda.get_state()
    pose = droid.flange_pose(state.O_T_EE, state.F_T_EE)
    # the flange's frame from the arm's own kinematics with no end effector
    from panda_py.kinematics import get_kinematics

    T = get_kinematics("fer", np.eye(4)).fk(state.q)
    np.testing.assert_allclose(pose[:3], T[:3, 3], atol=1e-9)
    roll, pitch, yaw = pose[3:]
    c, s = math.cos, math.sin
    R = (
        np.array([[c(yaw), -s(yaw), 0], [s(yaw), c(yaw), 0], [0, 0, 1]])
        @ np.array([[c(pitch), 0, s(pitch)], [0, 1, 0], [-s(pitch), 0, c(pitch)]])
        @ np.array([[1, 0, 0], [0, c(roll), -s(roll)], [0, s(roll), c(roll)]])
    )  # scipy's as_euler("xyz"): extrinsic x, then y, then z
    np.testing.assert_allclose(R, T[:3, :3], atol=1e-9)


# --- on the simulator, DROID's defaults -----------------------------------------------


def robot_s(rig: Rig) -> float:
    return rig.panda.get_state().time.to_sec()


def wait(rig: Rig, seconds: float) -> None:
    until, deadline = robot_s(rig) + seconds, time.monotonic() + 120
    while robot_s(rig) < until:
        assert time.monotonic() < deadline, "the robot's clock stopped"
        time.sleep(0.001)


class Measured:
    """The rig's Panda, keeping each ``q`` DroidActions reads (its integration base)."""

    def __init__(self, panda: Any) -> None:
        self._panda, self.reads = panda, []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._panda, name)

    @property
    def q(self) -> np.ndarray:
        q = self._panda.q
        self.reads.append(q)
        return q


def test_a_droid_policys_step_is_integrated_from_the_measured_joints(rig: Rig) -> None:
    """0.2 on joint 1 for 15 steps: each step's setpoint is the joints as measured then
    plus 0.04 rad (DROID's), and the arm moves on under DROID's soft gains."""
    panda = Measured(rig.panda)
    action = np.array([0.2, 0, 0, 0, 0, 0, 0, 0.0])
    q0 = rig.panda.q
    with DroidActions(panda) as arm:  # type: ignore[arg-type]
        assert isinstance(arm.controller, HybridJointImpedance)
        for _ in range(15):
            panda.reads.clear()
            target = arm.apply(action)
            (base,) = panda.reads
            step = np.array([0.04, 0, 0, 0, 0, 0, 0])  # [rad] DROID's 0.2 x 0.2
            np.testing.assert_allclose(target, base + step, atol=1e-12)
            wait(rig, 1 / RATE)
        moved = rig.panda.q - q0
        np.testing.assert_allclose(arm.controller.target, target, atol=1e-12)
    # the arm followed: joint 1 on its way (the soft gains lag the setpoints), the others
    # held where they were
    assert moved[0] > 0.2, moved
    assert np.abs(moved[1:]).max() < 0.01, moved


def test_full_scale_actions_stay_within_the_limits_reflex_free(rig: Rig) -> None:
    """A policy at openpi's clip on every joint for a second: the arm moves fast, below
    its velocity limits, and no reflex ends the controller."""
    dq_max = np.array(get_robot("fer").joints.dq_max)
    peak = np.zeros(7)
    action = np.array([1.0, -1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    with DroidActions(rig.panda) as arm:
        for k in range(15):
            arm.apply(action if k < 8 else -action * [1, 1, 1, 1, 1, 1, 1, 0])
            until, deadline = robot_s(rig) + 1 / RATE, time.monotonic() + 60
            while (state := rig.panda.get_state()).time.to_sec() < until:
                assert time.monotonic() < deadline
                peak = np.maximum(peak, np.abs(state.dq))
                time.sleep(0.0005)
        rig.panda.raise_error()
        assert rig.panda.get_state().robot_mode == RobotMode.kMove
    assert (peak < dq_max).all(), peak
    assert peak.max() > 1.0  # it did move fast


def test_the_runner_clips_as_openpi_and_counts_or_refuses(rig: Rig) -> None:
    chunk = np.zeros((10, 8))
    chunk[:, 0] = 0.3
    chunk[2, 0] = 1.4  # beyond openpi's clip: runs as 1
    chunk[5, 7] = 1.2  # a gripper command beyond 1: a grasp
    with DroidActions(rig.panda, rig.gripper) as arm:
        stats = PolicyRunner(arm, lambda obs: chunk).run(10)
        assert stats.clipped == 2 and arm.clipped == 2
        assert stats.policy_calls == 1 and stats.skipped == 0
        assert arm.gripper_future is not None and arm.gripper_future.result(timeout=30)
    with DroidActions(rig.panda, rig.gripper, out_of_range="raise") as arm:
        target = arm.target.copy()
        with pytest.raises(ValueError, match=r"gripper command in \[0, 1\].* action 5 has 1.2"):
            PolicyRunner(arm, lambda obs: chunk).run(10)
        np.testing.assert_array_equal(arm.target, target)
        np.testing.assert_array_equal(arm.controller.target, target)  # nothing was sent


def test_the_gripper_command_is_binarised_at_a_half(rig: Rig) -> None:
    hold = np.zeros(7)
    with DroidActions(rig.panda, rig.gripper) as arm:
        arm.apply([*hold, 0.55])  # closes: a grasp (of nothing: the fingers meet)
        assert arm.gripper_future is not None and arm.gripper_future.result(timeout=30)
        assert rig.gripper.read_once().width < 0.005
        closing = arm.gripper_future
        arm.apply([*hold, 0.9])  # still closed: nothing new
        assert arm.gripper_future is closing
        arm.apply([*hold, 0.45])  # open: all the way, as DROID's max_width * (1 - 0)
        assert arm.gripper_future is not closing and arm.gripper_future.result(timeout=30)
        assert rig.gripper.read_once().width == pytest.approx(0.08, abs=0.002)


def test_reset_opens_the_hand_and_goes_home(rig: Rig) -> None:
    rig.gripper.move(0.02, 0.1)
    with DroidActions(rig.panda, rig.gripper) as arm:
        arm.reset()
        assert arm.target is not None  # running again, from home
        np.testing.assert_allclose(arm.target, droid.DROID_HOME, atol=1e-3)
    np.testing.assert_allclose(rig.panda.q, droid.DROID_HOME, atol=1e-3)
    assert rig.gripper.read_once().width == pytest.approx(0.08, abs=0.002)


def test_bad_input_under_droids_defaults_is_refused_and_nothing_moves(rig: Rig) -> None:
    nan = np.zeros((3, 8))
    nan[1, 2] = np.nan
    cases = [
        (nan, r"finite values; action 1 has nan at 2"),
        (np.zeros((10, 7)), r"got shape \(10, 7\)"),
        (np.zeros((0, 8)), r"H >= 1"),
        ({"actions": np.zeros((0, 8))}, r"H >= 1"),
    ]
    with DroidActions(rig.panda, rig.gripper) as arm:
        target = arm.target.copy()
        for bad, message in cases:
            with pytest.raises(ValueError, match=message):
                arm.apply(bad)
            with pytest.raises(ValueError, match=message):
                PolicyRunner(arm, lambda obs, bad=bad: bad).run(3)
        with pytest.raises(ValueError, match=r"within the robot's joint limits; joint 1 is"):
            arm.controller.set_target(arm.q_max + 0.1)
        assert arm.gripper_future is None and arm.clipped == 0
        np.testing.assert_array_equal(arm.controller.target, target)
        wait(rig, 0.2)
        np.testing.assert_allclose(rig.panda.q, target, atol=2e-3)
    with pytest.raises(ValueError, match="Kq: "):
        HybridJointImpedance(Kq=[-1.0] * 7)
    with pytest.raises(ValueError, match="Kx: "):
        HybridJointImpedance(Kx=[1.0] * 7)
