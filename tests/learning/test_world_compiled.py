"""The fast world's compiled ticks against its Python reference (``FastWorld(...,
compiled=False)``) on the same episodes: the same observations, the same torques sent,
the same reflexes and the same final states, bit for bit (the compiled ticks run the
same kernels in the same order); and the compiled ticks do run. Skipped where numba is
absent or ``PANDA_PY_NO_JIT=1`` (the reference alone runs there, under the other tests)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
import pytest

from panda_py.controllers import CartesianTarget, JointTarget
from panda_py.learning import ActionKind, pick_and_place_policy, reach_policy
from panda_py.learning.world import FastWorld
from panda_py.robots.params import START_POSE

pytestmark = pytest.mark.timeout(600)


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    world = FastWorld()
    try:
        if world._fast is None:
            pytest.skip("the fast world runs without numba here (PANDA_PY_NO_JIT or none)")
        # its warm-up ran both controllers compiled: nothing loads in an episode's step
        assert world._fast.compiled_ticks >= 30
    finally:
        world.close()


def _random_joints(seed: int) -> Callable[[Any], np.ndarray]:
    rng = np.random.default_rng(seed)
    return lambda obs: rng.uniform(-1.0, 1.0, 7).astype(np.float32)


def _episodes(
    env_id: str, compiled: bool, *, robot: str, action: str | None, steps: int
) -> tuple[list[dict[str, np.ndarray]], list[np.ndarray], list[Any], FastWorld]:
    """Observations, torques sent after each step, infos; episodes from seed 3 on."""
    world = FastWorld(robot, compiled=compiled)
    kw = {} if action is None else {"action": action}
    env = gymnasium.make(env_id, backend=world, **kw)
    policy = reach_policy if "Reach" in env_id else pick_and_place_policy
    if action is not None:
        policy = _random_joints(3)
    seen, taus, infos = [], [], []
    obs, _ = env.reset(seed=3)
    seen.append(obs)
    seed = 3
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        seen.append(obs)
        taus.append(world.robot.tau_J_d)
        infos.append(info)
        if terminated or truncated:
            seed += 1
            obs, _ = env.reset(seed=seed)
            seen.append(obs)
    env.close()
    return seen, taus, infos, world


@pytest.mark.parametrize(
    ("env_id", "robot", "action"),
    [
        ("PandaReach-v0", "fer", None),  # CartesianTarget, protocol 5 (a velocity generator)
        ("PandaReach-v0", "fr3", None),  # protocol 10: the state's float32 fields
        ("PandaReach-v0", "fer", ActionKind.JOINT_DELTA.value),  # JointTarget
        ("PandaPickAndPlace-v0", "fer", None),  # the hand, the cube in it: contacts
    ],
)
def test_the_compiled_ticks_equal_the_python_ones(env_id: str, robot: str, action: Any) -> None:
    fast = _episodes(env_id, True, robot=robot, action=action, steps=60)
    slow = _episodes(env_id, False, robot=robot, action=action, steps=60)
    assert fast[3]._fast is not None and fast[3]._fast.compiled_ticks > 1000
    assert slow[3]._fast is None
    assert len(fast[0]) == len(slow[0])
    for a, b in zip(fast[0], slow[0], strict=True):
        for key in a:
            assert np.array_equal(a[key], b[key]), key
    for a, b in zip(fast[1], slow[1], strict=True):
        assert np.array_equal(a, b)
    assert fast[2] == slow[2]
    assert fast[3].ticks == slow[3].ticks
    assert np.array_equal(fast[3].robot.core.state_buffer, slow[3].robot.core.state_buffer)


def test_a_reflex_comes_at_the_same_tick_with_the_same_flags() -> None:
    """A streamed pose target under the table: the arm presses on it until the robot's
    contact reflex, on both paths alike."""
    results = []
    for compiled in (True, False):
        world = FastWorld(compiled=compiled)
        try:
            ctrl = CartesianTarget(0.5, timeout=None)
            world.start(ctrl)
            T = world.robot.O_T_EE
            ctrl.set_target(T[:3, 3] + np.array([0.1, 0.0, -0.6]), np.array([1.0, 0, 0, 0]))
            world.advance(6000)
            results.append((world.failure(), world.ticks, world.robot.q, world.robot.tau_J_d,
                            world.robot.core.state_buffer.copy()))  # fmt: skip
            assert world.failure() is not None and "reflex" in world.failure()
            assert not compiled or world._fast.compiled_ticks > 100
            world.recover()
            world.home(np.asarray(START_POSE), None)
        finally:
            world.close()
    (fail_a, ticks_a, q_a, tau_a, state_a), (fail_b, ticks_b, q_b, tau_b, state_b) = results
    assert fail_a == fail_b
    assert ticks_a == ticks_b
    assert np.array_equal(q_a, q_b) and np.array_equal(tau_a, tau_b)
    assert np.array_equal(state_a, state_b)


@pytest.mark.parametrize("kind", ["pose", "joints"])
def test_only_a_controllers_first_tick_runs_in_python(kind: str) -> None:
    """New targets every 40 ms, then none (the targets go stale): every tick but the
    controller's first runs compiled (a new target's generator step through the
    controller's ``compiled_news``), with the same states as the reference."""
    states = []
    for compiled in (True, False):
        world = FastWorld(compiled=compiled)
        try:
            ctrl: Any = (CartesianTarget if kind == "pose" else JointTarget)(0.3, timeout=0.1)
            world.start(ctrl)
            before = 0 if world._fast is None else world._fast.compiled_ticks
            T, q = world.robot.O_T_EE, world.robot.q
            for i in range(10):
                if kind == "pose":
                    ctrl.set_target(T[:3, 3] + 0.004 * i, np.array([1.0, 0.0, 0.0, 0.0]))
                else:
                    ctrl.set_target(q + 0.004 * i)
                world.advance(world.ticks + 40)
            world.advance(world.ticks + 300)  # stale after 100 ms: brought to rest
            assert world.failure() is None
            assert ctrl.stale
            if compiled:
                assert world._fast is not None
                assert world._fast.compiled_ticks - before == 10 * 40 + 300 - 1
            states.append(world.robot.core.state_buffer.copy())
        finally:
            world.close()
    assert np.array_equal(states[0], states[1])
