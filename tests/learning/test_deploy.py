"""DROID's action contract on the lockstep simulator, with options off DROID's defaults: a
chunk of joint velocities moves the arm by their integral, joint positions are reached, the
gripper command closes and opens the hand, a policy that thinks too long has its late steps
counted, and bad input is refused with nothing sent. DROID's own numbers are in
test_droid.py."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest
from conftest import Rig

from panda_py.controllers import JointTarget
from panda_py.learning import ActionSpace, DroidActions, PolicyRunner
from panda_py.learning.deploy import DROID_MAX_JOINT_DELTA, LIMIT_MARGIN, as_chunk
from panda_py.libfranka import ControlException, RobotMode

pytestmark = pytest.mark.timeout(300)

RATE = 15.0  # [Hz]
AT_TARGET = 0.01  # [rad] the arm at rest on its target, through the impedance's error
AT_REST = 1e-3  # [rad/s]


def robot_s(rig: Rig) -> float:
    return rig.panda.get_state().time.to_sec()


def settle(rig: Rig, actions: DroidActions, seconds: float = 4.0) -> None:
    """Wait (on the robot's clock, at most ``seconds`` of it) until the reference reached
    the last target and the arm is at rest."""
    now, deadline = robot_s(rig), time.monotonic() + 120.0
    seen, end = now + 0.05, now + seconds  # [s] the loop has seen the last target by then
    while (now := robot_s(rig)) < end:
        assert time.monotonic() < deadline, "the robot's clock stopped"
        lag = getattr(actions.controller, "lag", 0.0)  # a JointTarget's reference
        if now > seen and lag < 1e-6 and np.abs(rig.panda.get_state().dq).max() < AT_REST:
            return
        time.sleep(0.002)
    raise AssertionError(f"not at rest on the target after {seconds} s")


def follower(speed_factor: float = 0.2) -> JointTarget:
    """The smooth follower these tests use (the arm reaches each target exactly)."""
    return JointTarget(speed_factor, timeout=None)


def rad_per_s(rig: Rig, **options: object) -> DroidActions:
    """Velocities in rad/s integrated from the last target, on the smooth follower: the
    options these tests take off DROID's defaults, so targets are sums they can check."""
    options.setdefault("controller", follower(0.5))
    return DroidActions(rig.panda, normalized=False, from_measured=False, **options)


def velocity_chunk(n: int) -> np.ndarray:
    """n joint-velocity actions [rad/s], hand open: joint 1 out and back a little, joints
    4 and 6 on a ramp."""
    t = np.arange(n) / n
    chunk = np.zeros((n, 8))
    chunk[:, 0] = 0.4 * np.sin(2 * np.pi * t)
    chunk[:, 3] = -0.3 * t
    chunk[:, 5] = 0.2
    return chunk


def test_a_velocity_chunk_moves_the_arm_by_its_integral(rig: Rig) -> None:
    chunk = velocity_chunk(15)
    q0, T0 = rig.panda.q, rig.panda.get_pose()
    seen: list[dict] = []

    def policy(obs: dict) -> np.ndarray:
        seen.append(obs)
        return chunk

    with rad_per_s(rig, gripper=rig.gripper) as actions:
        start = actions.target.copy()  # where the arm was at the start [rad]
        stats = PolicyRunner(actions, policy, late="fold").run(15)
        expected = start + chunk[:, :7].sum(axis=0) / RATE
        np.testing.assert_allclose(actions.target, expected, atol=1e-12)
        settle(rig, actions)
        np.testing.assert_allclose(rig.panda.q, expected, atol=AT_TARGET)
    # one call, its chunk run open loop to the end, every period on time or folded in
    assert stats.policy_calls == 1 and stats.steps == 15 and stats.held == 0
    assert len(stats.latency) + stats.skipped == 15
    obs = seen[0]
    np.testing.assert_allclose(obs["observation/joint_position"], q0, atol=1e-6)
    assert obs["observation/gripper_position"].shape == (1,)
    assert obs["observation/gripper_position"][0] < 0.05  # open
    # DROID's cartesian_position is the flange's (panda_link8), 103.4 mm behind the TCP
    position, (roll, pitch, yaw) = np.split(obs["observation/cartesian_position"], [3])
    np.testing.assert_allclose(position, T0[:3, 3] - 0.1034 * T0[:3, 2], atol=1e-5)
    c, s = np.cos, np.sin
    Rx = np.array([[1, 0, 0], [0, c(roll), -s(roll)], [0, s(roll), c(roll)]])
    Ry = np.array([[c(pitch), 0, s(pitch)], [0, 1, 0], [-s(pitch), 0, c(pitch)]])
    Rz = np.array([[c(yaw), -s(yaw), 0], [s(yaw), c(yaw), 0], [0, 0, 1]])
    F_T_EE = np.asarray(rig.panda.get_state().F_T_EE).reshape(4, 4).T  # the hand's
    np.testing.assert_allclose(Rz @ Ry @ Rx, T0[:3, :3] @ F_T_EE[:3, :3].T, atol=1e-5)


def test_droid_normalised_velocities_move_a_fifth_of_a_radian_a_step(rig: Rig) -> None:
    action = np.array([0.5, 0, 0, 0, 0, -0.25, 0, 0.0])
    with DroidActions(rig.panda, from_measured=False, controller=follower(0.5)) as actions:
        start = actions.target.copy()
        for _ in range(3):
            actions.apply(action)
        expected = start + 3 * action[:7] * DROID_MAX_JOINT_DELTA
        np.testing.assert_allclose(actions.target, expected, atol=1e-12)
        settle(rig, actions)
        np.testing.assert_allclose(rig.panda.q, expected, atol=AT_TARGET)
        with pytest.raises(ValueError, match=r"normalised joint velocities .* in \[-1, 1\]"):
            actions.check([1.2, 0, 0, 0, 0, 0, 0, 0])
    step = action[0] * DROID_MAX_JOINT_DELTA  # [rad]
    with DroidActions(rig.panda, controller=follower()) as actions:
        first, second = actions.apply(action), actions.apply(action)
        # each from where the arm is, as DROID's; it has hardly moved between the two
        assert abs(second[0] - first[0]) < 0.1 * step
        actions.controller.set_target(rig.panda.q)
        settle(rig, actions)


def test_integrated_targets_stop_short_of_the_joint_limits(rig: Rig) -> None:
    with DroidActions(rig.panda, from_measured=False, controller=follower()) as actions:
        for _ in range(40):  # 8 rad of joint 1, were it not clipped
            target = actions.apply([1.0, 0, 0, 0, 0, 0, 0, 0])
        assert target[0] == pytest.approx(actions.q_max[0] - LIMIT_MARGIN)
        actions.controller.set_target(actions.panda.q)  # not all the way there: back to rest
        settle(rig, actions)


def test_joint_position_actions_reach_their_targets(rig: Rig) -> None:
    q0 = rig.panda.q
    goals = q0 + np.outer(np.linspace(0.1, 1.0, 10), [0.3, -0.2, 0.2, 0.3, -0.3, 0.25, 0.4])
    chunk = np.hstack([goals, np.zeros((10, 1))])
    with DroidActions(rig.panda, space=ActionSpace.JOINT_POSITION,
                      controller=follower(0.5)) as actions:  # fmt: skip
        stats = PolicyRunner(actions, lambda obs: {"actions": chunk}).run(10)
        np.testing.assert_array_equal(actions.target, goals[-1])
        settle(rig, actions)
        np.testing.assert_allclose(rig.panda.q, goals[-1], atol=AT_TARGET)
    assert stats.policy_calls == 1


def test_the_gripper_command_closes_and_opens_the_hand(rig: Rig) -> None:
    gripper = rig.gripper
    hold = np.zeros(8)
    with DroidActions(rig.panda, gripper, binarize=False) as actions:
        actions.apply(hold)  # 0: open, as it is
        first = actions.gripper_future
        assert first is not None and first.result(timeout=30)
        actions.apply([*hold[:7], 0.05])  # a change under the threshold sends nothing
        assert actions.gripper_future is first
        actions.apply([*hold[:7], 0.9])  # closed: a grasp (of nothing: the fingers meet)
        closing = actions.gripper_future
        assert closing is not first
        closing.result(timeout=30)
        assert gripper.read_once().width < 0.005
        assert actions.observation()["observation/gripper_position"][0] > 0.9
        actions.apply([*hold[:7], 0.95])  # still closed: nothing new
        assert actions.gripper_future is closing
        actions.apply([*hold[:7], 0.5])  # half open: 40 mm
        assert actions.gripper_future.result(timeout=30)
        assert gripper.read_once().width == pytest.approx(0.04, abs=0.002)
        actions.apply(hold)
        assert actions.gripper_future.result(timeout=30)
        assert gripper.read_once().width == pytest.approx(0.08, abs=0.002)


def thinking(rig: Rig, chunk: np.ndarray, calls: list[float]) -> Any:
    """A policy that thinks for 3.2 periods of the robot's clock, then answers ``chunk``;
    the time of each observation it saw goes to ``calls``."""

    def slow_policy(obs: dict) -> np.ndarray:
        calls.append(obs["time"])
        until, deadline = obs["time"] + 3.2 / RATE, time.monotonic() + 60
        while robot_s(rig) < until:
            assert time.monotonic() < deadline
            time.sleep(0.001)
        return chunk

    return slow_policy


def test_a_slow_policy_makes_late_steps_and_the_chunk_keeps_its_timeline(rig: Rig) -> None:
    chunk = velocity_chunk(12)
    calls: list[float] = []
    slow_policy = thinking(rig, chunk, calls)

    with rad_per_s(rig) as actions:
        start = actions.target.copy()
        stats = PolicyRunner(actions, slow_policy, replan_every=6, late="fold").run(12)
        assert len(calls) == 2  # every 6 periods
        assert stats.late == 2 and stats.skipped >= 6  # each call skipped 3 periods or more
        # each call's 6 periods: the late ones folded into the step after the call
        expected = start + 2 * chunk[:6, :7].sum(axis=0) / RATE
        np.testing.assert_allclose(actions.target, expected, atol=1e-12)
    print("\n" + stats.summary())
    assert max(stats.latency) >= 3.2 / RATE


def test_a_slow_policy_has_its_chunk_run_in_order_as_openpi_does(rig: Rig) -> None:
    chunk = velocity_chunk(12)
    calls: list[float] = []
    slow_policy = thinking(rig, chunk, calls)

    with rad_per_s(rig) as actions:
        start = actions.target.copy()
        stats = PolicyRunner(actions, slow_policy, replan_every=6).run(12)
        assert len(calls) == 2 and stats.steps == 12
        # every action ran, one a step, the first six of each chunk: nothing skipped
        assert stats.skipped == 0 and stats.held == 0 and len(stats.latency) == 12
        expected = start + 2 * chunk[:6, :7].sum(axis=0) / RATE
        np.testing.assert_allclose(actions.target, expected, atol=1e-12)
        # the two steps after a call were late; the ones after them a period apart again
        assert stats.late == 2
        assert max(stats.latency) >= 3.2 / RATE
        assert sorted(stats.latency)[9] < 1.0 / RATE
        # the run took the 12 periods plus the two calls' delays, as openpi's loop does
        assert calls[1] - calls[0] >= (6 + 3.2 - 1) / RATE
    print("\n" + stats.summary())


def test_a_chunk_that_runs_out_holds_until_the_next_call(rig: Rig) -> None:
    chunk = np.zeros((3, 8))
    chunk[:, 0] = 0.15  # [rad/s]
    with rad_per_s(rig, controller=follower()) as actions:
        start = actions.target.copy()
        stats = PolicyRunner(actions, lambda obs: chunk, replan_every=5, late="fold").run(10)
        np.testing.assert_allclose(actions.target, start + np.array([6 * 0.01, 0, 0, 0, 0, 0, 0]))
        settle(rig, actions)
    assert stats.policy_calls == 2  # at periods 0 and 5
    # periods 3, 4, 8 and 9 had no action left (fewer if a late step jumped over one)
    assert stats.held == 4 or stats.late > 0
    assert stats.held + len(stats.latency) <= 10


def test_a_reflex_mid_run_raises_and_nothing_more_is_sent(rig: Rig) -> None:
    calls: list[np.ndarray] = []

    def policy(obs: dict) -> np.ndarray:
        calls.append(obs["observation/joint_position"])
        if len(calls) == 3:
            rig.sim.inject_reflex("joint_reflex")
            deadline = time.monotonic() + 30  # until the control process has seen it
            while rig.panda.get_state().robot_mode != RobotMode.kReflex:
                assert time.monotonic() < deadline
                time.sleep(0.001)
        return np.array([0.1, 0, 0, 0, 0, 0, 0, 0.0])

    with rad_per_s(rig, controller=follower()) as actions:
        start = actions.target.copy()
        with pytest.raises(ControlException) as raised:
            PolicyRunner(actions, policy).run(10)
        assert "joint_reflex" in raised.value.reflex_reason
        assert len(calls) == 3
        # two actions went out, the third was not
        np.testing.assert_allclose(
            actions.target, start + np.array([2 * 0.1 / RATE, 0, 0, 0, 0, 0, 0])
        )
        rig.panda.recover()
    assert rig.panda.move_to_joint_position(start)  # usable again


def test_a_camera_costs_a_lockstep_policy_no_robot_time(rig: Rig) -> None:
    """An image takes milliseconds to draw; a lockstep simulator's time stands still
    meanwhile (its camera holds the next tick), as it does while it waits for commands."""
    simulated, wall = [], []  # [s] robot and wall time across each image
    with DroidActions(rig.panda, cameras={"front": rig.sim.render}) as actions:
        for _ in range(7):
            t, w = robot_s(rig), time.perf_counter()
            actions.cameras["front"]()
            simulated.append(robot_s(rig) - t)
            wall.append(time.perf_counter() - w)
            deadline = time.monotonic() + 30.0  # between images, the clock runs on
            while robot_s(rig) < t + 0.01:
                assert time.monotonic() < deadline, "the robot's clock stopped"
                time.sleep(0.001)
    print(f"\nan image: {np.median(wall) * 1e3:.0f} ms of wall time, "
          f"{np.median(simulated) * 1e3:.0f} ms of robot time (medians)")  # fmt: skip
    # a tick or two (the one under way); the clock runs free only where this process was
    # descheduled between reading it and asking (rare on a loaded machine: the median)
    assert np.median(simulated) <= 0.002 + 1e-9


def test_bad_actions_are_refused_and_nothing_is_sent(rig: Rig) -> None:
    with rad_per_s(rig, gripper=rig.gripper, out_of_range="raise") as actions:
        target, future = actions.target.copy(), actions.gripper_future
        dq_max = actions.dq_max
        fast = np.zeros(8)
        fast[2] = dq_max[2] * 1.01
        outside = np.append(actions.q_max + 0.1, 0.0)
        nan = np.zeros((3, 8))
        nan[2, 4] = np.nan
        cases = [
            (np.zeros(7), r"shape \(8,\) or a chunk \(H, 8\).*got shape \(7,\)"),
            (np.zeros((2, 3, 8)), r"got shape \(2, 3, 8\)"),
            (np.zeros((0, 8)), r"H >= 1"),
            ("fast", r"expected numbers"),
            (nan, r"finite values; action 2 has nan at 4"),
            (fast, r"within the robot's limits; action 0, joint 3 is .* rad/s"),
            (np.array([*np.zeros(7), 1.5]), r"gripper command in \[0, 1\].*action 0 has 1.5"),
            ({"action": np.zeros(8)}, r"mapping with an 'actions' entry"),
        ]
        for bad, message in cases:
            with pytest.raises(ValueError, match=message):
                actions.apply(bad)
        with pytest.raises(ValueError, match="expected one action"):
            actions.apply(np.zeros((2, 8)))
        # a bad chunk from the policy: refused whole, though its first action is good
        chunk = np.vstack([np.zeros(8), fast])
        with pytest.raises(ValueError, match="action 1, joint 3"):
            PolicyRunner(actions, lambda obs: chunk).run(5)
        assert actions.gripper_future is future is None
        np.testing.assert_array_equal(actions.target, target)
        settle(rig, actions)
        np.testing.assert_allclose(rig.panda.q, target, atol=AT_TARGET)  # nothing moved it
    with DroidActions(rig.panda, space=ActionSpace.JOINT_POSITION, out_of_range="raise") as actions:
        with pytest.raises(ValueError, match=r"within the joint limits; action 0, joint 1"):
            actions.apply(outside)
    with pytest.raises(ValueError, match="space: expected an ActionSpace"):
        DroidActions(rig.panda, space="joint_velocity")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="rate: expected"):
        DroidActions(rig.panda, rate=0)
    with pytest.raises(ValueError, match=r"grasp_force: .*\[N\]"):
        DroidActions(rig.panda, grasp_force=500.0)
    with pytest.raises(ValueError, match="normalized: only joint velocities"):
        DroidActions(rig.panda, space=ActionSpace.JOINT_POSITION, normalized=True)
    with pytest.raises(ValueError, match="out_of_range: expected one of"):
        DroidActions(rig.panda, out_of_range="ignore")
    with pytest.raises(ValueError, match=r"controller: expected a joint controller with"):
        DroidActions(rig.panda, controller=object())
    with pytest.raises(RuntimeError, match="not started"):
        DroidActions(rig.panda).apply(np.zeros(8))


def test_as_chunk_takes_one_action_or_a_chunk() -> None:
    assert as_chunk(np.arange(8.0)).shape == (1, 8)
    assert as_chunk([[0.0] * 8] * 10).shape == (10, 8)
    assert as_chunk({"actions": np.zeros((4, 8))}).shape == (4, 8)
