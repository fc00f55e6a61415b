"""The environments on the fast in-process world: Gymnasium's checker passes; a seed
gives the same episode bit for bit; bad actions are refused with nothing sent; a reflex
mid-episode truncates it with the reason and the next reset recovers; the vector API
runs them; the scripted policies succeed; every action kind runs."""

from __future__ import annotations

import subprocess
import sys

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import panda_py.learning as learning
from panda_py.controllers import TorqueController
from panda_py.learning import ActionKind, pick_and_place_policy, reach_policy
from panda_py.robots.params import START_POSE

pytestmark = pytest.mark.timeout(300)

IDS = ("PandaReach-v0", "PandaPickAndPlace-v0")
POLICIES = {"PandaReach-v0": reach_policy, "PandaPickAndPlace-v0": pick_and_place_policy}


@pytest.fixture(scope="module")
def reach() -> gymnasium.Env:
    env = gymnasium.make("PandaReach-v0")
    yield env
    env.close()


@pytest.fixture(scope="module")
def pick() -> gymnasium.Env:
    env = gymnasium.make("PandaPickAndPlace-v0")
    yield env
    env.close()


def run(env: gymnasium.Env, seed: int, policy, steps: int | None = None) -> tuple[list, dict]:
    """Observations of one episode with ``policy`` (until it ends) and its last info."""
    obs, info = env.reset(seed=seed)
    seen = [obs]
    for _ in range(steps or env.spec.max_episode_steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        seen.append(obs)
        if terminated or truncated:
            break
    return seen, info


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasiums_checker_passes(env_id: str) -> None:
    env = gymnasium.make(env_id)
    try:
        check_env(env.unwrapped)
    finally:
        env.close()


def test_the_registered_ids_make_the_tasks() -> None:
    assert set(IDS) <= set(gymnasium.registry)
    assert gymnasium.registry["PandaReach-v0"].max_episode_steps == 50
    assert gymnasium.registry["PandaPickAndPlace-v0"].max_episode_steps == 100


def test_a_seed_gives_the_same_episode_bit_for_bit(pick: gymnasium.Env) -> None:
    first, info_1 = run(pick, 7, pick_and_place_policy, steps=30)
    run(pick, 8, pick_and_place_policy, steps=5)  # another episode between
    again, info_2 = run(pick, 7, pick_and_place_policy, steps=30)
    assert len(first) == len(again)
    for a, b in zip(first, again, strict=True):
        for key in a:
            assert np.array_equal(a[key], b[key])
    assert info_1 == info_2
    other, _ = run(pick, 8, pick_and_place_policy, steps=1)
    assert not np.array_equal(other[0]["desired_goal"], first[0]["desired_goal"])


@pytest.mark.parametrize(
    ("action", "message"),
    [
        ([0.1, float("nan"), 0.0], "action: expected finite values"),
        ([0.1, 1.5, 0.0], r"value 1 is 1.5, outside \[-1.0, 1.0\]"),
        ([0.1, 0.0], r"shape \(3,\); got shape \(2,\)"),
        ("up", "action: expected 3 values"),
    ],
)
def test_a_bad_action_is_refused_and_nothing_is_sent(
    reach: gymnasium.Env, action: object, message: str
) -> None:
    env = reach.unwrapped
    env.reset(seed=1)
    env.step(np.zeros(3, dtype=np.float32))
    ctrl = env._controller
    sent, clock = ctrl.get_signal("count")[0], env.backend.time_ms()
    with pytest.raises(ValueError, match=message):
        env.step(action)
    assert ctrl.get_signal("count")[0] == sent  # no target sent
    assert env.backend.time_ms() == clock  # no time passed
    env.step(np.zeros(3, dtype=np.float32))  # the episode goes on


def test_a_reflex_truncates_the_episode_and_reset_recovers(pick: gymnasium.Env) -> None:
    env = pick.unwrapped
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        obs, *_ = env.step(pick_and_place_policy(obs))
    env.backend.inject_reflex("cartesian_reflex")
    obs, _, terminated, truncated, info = env.step(pick_and_place_policy(obs))
    assert truncated and not terminated
    assert "cartesian_reflex" in info["reflex"]
    assert not info["is_success"]
    with pytest.raises(RuntimeError, match=r"cartesian_reflex.*call reset"):
        env.step(pick_and_place_policy(obs))
    obs, info = env.reset(seed=3)
    assert "reflex" not in info
    obs, _, _, truncated, info = env.step(pick_and_place_policy(obs))
    assert not truncated and "reflex" not in info


@pytest.mark.parametrize("env_id", IDS)
def test_the_scripted_policy_succeeds(env_id: str) -> None:
    env = gymnasium.make(env_id)
    try:
        results = [run(env, seed, POLICIES[env_id])[1]["is_success"] for seed in range(5)]
    finally:
        env.close()
    print(f"{env_id} on the fast world: {sum(results)} of {len(results)} succeeded")
    assert sum(results) >= 4


@pytest.mark.parametrize("kind", list(ActionKind))
def test_every_action_kind_moves_the_arm_toward_its_target(kind: ActionKind) -> None:
    env = learning.PandaReachEnv(action=kind)
    try:
        obs, _ = env.reset(seed=0)
        q0, ee0 = obs["observation"][:7].copy(), obs["observation"][14:17].copy()
        if kind is ActionKind.CARTESIAN_DELTA:
            action, goal = np.array([1.0, 0.0, 0.0]), ee0 + np.array([0.05, 0.0, 0.0])
        elif kind is ActionKind.CARTESIAN_ABSOLUTE:
            goal = ee0 + np.array([0.1, 0.0, -0.05])
            action = goal
        elif kind is ActionKind.JOINT_DELTA:
            action, goal = np.full(7, 0.5), q0 + 0.025
        else:
            goal = q0 + 0.1
            action = goal
        for _ in range(15):
            obs, *_ = env.step(action.astype(np.float32))
        reached = obs["observation"][14:17] if kind.cartesian else obs["observation"][:7]
        start = ee0 if kind.cartesian else q0
        if kind.delta:  # each step's target one step on: it went further than one step
            moved = reached - start
            if kind.cartesian:
                assert moved[0] > 0.05 and np.abs(moved[1:]).max() < 0.01
            else:
                assert moved.min() > 0.025
        else:
            assert np.abs(reached - goal).max() < 0.01
    finally:
        env.close()


def test_the_vector_api_runs_them() -> None:
    def make() -> gymnasium.Env:
        return gymnasium.make("PandaReach-v0")

    for vector in (gymnasium.vector.SyncVectorEnv, gymnasium.vector.AsyncVectorEnv):
        envs = vector([make, make])
        try:
            obs, _ = envs.reset(seed=[1, 2])
            assert obs["observation"].shape == (2, 21)
            assert not np.array_equal(obs["desired_goal"][0], obs["desired_goal"][1])
            for _ in range(3):
                actions = np.stack([
                    reach_policy({k: v[i] for k, v in obs.items()}) for i in range(2)
                ])  # fmt: skip
                obs, reward, _, truncated, _ = envs.step(actions)
            assert reward.shape == (2,) and not truncated.any()
        finally:
            envs.close()


def test_without_gymnasium_the_environments_say_what_to_install() -> None:
    code = (
        "import sys; sys.modules['gymnasium'] = None\n"
        "import panda_py.learning\n"  # the package imports without it (deployment needs none)
        "try:\n    panda_py.learning.PandaReachEnv\nexcept ImportError as e:\n    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert 'pip install "panda-py-pure[learning]"' in out.stdout, out.stderr
    assert "gymnasium" in out.stdout


def test_any_policy_rate_keeps_its_schedule_on_the_robots_clock() -> None:
    env = learning.PandaReachEnv(policy_rate=15.0)  # DROID's: 66.7 ms, not a whole ms
    try:
        obs, info = env.reset(seed=0)
        times = [info["time"]]
        for _ in range(30):
            obs, _, _, _, info = env.step(reach_policy(obs))
            times.append(info["time"])
        assert times[-1] - times[0] == pytest.approx(2.0, abs=1e-3)  # 30 steps, 2 s: no drift
        assert set(np.round(np.diff(times), 3)) <= {0.066, 0.067}
    finally:
        env.close()
    for rate in (0.5, 200.0, float("nan")):
        with pytest.raises(ValueError, match="policy_rate: expected a rate in"):
            learning.PandaReachEnv(policy_rate=rate)


def test_the_fr3_runs_its_own_protocol_and_limits() -> None:
    env = gymnasium.make("PandaPickAndPlace-v0", robot="fr3")
    try:
        world = env.unwrapped.backend
        assert world.version == 10 and world.spec_name == "fr3"
        _, info = run(env, 0, pick_and_place_policy)
        assert info["is_success"]
    finally:
        env.close()


class Shove(TorqueController):
    """Asks joint 1 for ``tau`` [Nm] (far beyond its limit, or NaN) from the first tick."""

    def __init__(self, tau: float) -> None:
        super().__init__()
        self.tau = tau

    def step(self, state, model):  # type: ignore[no-untyped-def]
        return np.array([self.tau, 0, 0, 0, 0, 0, 0])


def test_the_fast_world_keeps_the_loops_limits_and_the_robots_reflexes() -> None:
    world = learning.FastWorld()
    try:
        world.start(Shove(1000.0))
        tau_max = np.asarray(world.spec.joints.tau_max)
        steps = []
        while world.failure() is None and world.ticks < 3000:
            world.advance(world.ticks + 1)
            tau = world.robot.tau_J_d
            assert np.all(np.abs(tau) <= tau_max + 1e-9)  # clipped to the joint's limit
            steps.append(tau[0])
        # until the reflex (which drops the command), the torque rose by at most the
        # loop's 1 Nm a tick, then libfranka's filter
        assert np.abs(np.diff(steps[:-1])).max() <= 1.0 + 1e-9
        # and the robot itself stopped the arm as it left its limits, as panda-sim does
        assert world.failure() is not None and "reflex" in world.failure()
        assert set(world.reflex_flags()) & {
            "joint_velocity_violation", "joint_position_limits_violation"
        }  # fmt: skip
        world.recover()
        world.home(np.array(START_POSE), None)
        world.start(Shove(float("nan")))
        world.advance(world.ticks + 10)
        assert "non-finite" in world.failure()
        assert np.isfinite(world.robot.tau_J_d).all()  # nothing non-finite was sent
    finally:
        world.close()


def test_picking_refuses_a_backend_without_the_hand_or_the_cube_at_once() -> None:
    world = learning.FastWorld()
    try:
        world.has_hand = False  # as RobotArm(..., hand=False)
        with pytest.raises(ValueError, match="needs the hand"):
            learning.PandaPickAndPlaceEnv(world)
        world.has_hand, world.has_cube = True, False  # as RobotArm(...) without a scene
        with pytest.raises(ValueError, match=r"place the cube.*scene="):
            learning.PandaPickAndPlaceEnv(world)
        env = learning.PandaReachEnv(world)  # reaching needs neither
        env.reset(seed=0)
        env.close()  # a backend given stays its owner's: still usable
        world.start(Shove(0.0))
        world.advance(world.ticks + 5)
        assert world.failure() is None
    finally:
        world.close()
