"""The reaching world: the fast world without the cube (a task that never uses it), whose
compiled ticks skip MuJoCo's collision detection while the arm is clear of the table.
The arm moves as in the world with the cube (the same joint trajectory to rounding), the
compiled ticks equal the Python reference bit for bit (with the detection skipped or
not), and a contact with the table is found as before (the same reflex at the same tick)."""

from __future__ import annotations

import math
from typing import Any

import gymnasium
import mujoco
import numpy as np
import pytest

from panda_py.controllers import CartesianTarget
from panda_py.learning import reach_policy
from panda_py.learning.world import FastWorld
from panda_py.robots.params import START_POSE

pytestmark = pytest.mark.timeout(600)

# [rad] the joint trajectories with and without the cube agree to this (measured: 3e-14;
# MuJoCo solves the cube's contacts with the arm's joint friction, one solve)
SAME_JOINTS = 1e-9


def _compiled_or_skip() -> None:
    world = FastWorld(cube=False)
    try:
        if world._fast is None:
            pytest.skip("the fast world runs without numba here (PANDA_PY_NO_JIT or none)")
    finally:
        world.close()


def _reach(world: FastWorld, steps: int) -> tuple[np.ndarray, np.ndarray, list[bool]]:
    """Joint positions after every step, the state buffers, the episodes' ends: reaching
    episodes from seed 3 on at 25 Hz with the proportional policy."""
    env = gymnasium.make("PandaReach-v0", backend=world, policy_rate=25.0)
    qs, states, ends = [], [], []
    seed = 3
    obs, _ = env.reset(seed=seed)
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(reach_policy(obs))
        qs.append(world.robot.q)
        states.append(world.robot.core.state_buffer.copy())
        ends.append(terminated or truncated)
        if terminated or truncated:
            seed += 1
            obs, _ = env.reset(seed=seed)
    env.close()
    return np.array(qs), np.array(states), ends


def test_the_arm_reaches_as_in_the_world_with_the_cube() -> None:
    """The same episodes with and without the cube (compiled where numba runs, as a
    user's environment runs): the same joint trajectory to SAME_JOINTS, the same
    episode ends."""
    with_cube = FastWorld(cube=True)
    without = FastWorld(cube=False)
    q_a, _, ends_a = _reach(with_cube, 250)
    q_b, _, ends_b = _reach(without, 250)
    assert ends_a == ends_b and sum(ends_a) >= 3
    assert np.abs(q_a - q_b).max() <= SAME_JOINTS
    assert without.robot.physics.model.nbody == with_cube.robot.physics.model.nbody - 1


def test_the_search_for_islands_left_out_changes_nothing() -> None:
    """The world without the cube solves its constraints without MuJoCo's search for
    islands (one island: the robot): the same episodes, bit for bit, as with it."""
    island = int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
    without = FastWorld(cube=False)
    searched = FastWorld(cube=False)
    assert without.robot.physics.model.opt.disableflags & island
    searched.robot.physics.model.opt.disableflags &= ~island
    q_a, states_a, ends_a = _reach(without, 150)
    q_b, states_b, ends_b = _reach(searched, 150)
    assert np.array_equal(q_a, q_b) and np.array_equal(states_a, states_b)
    assert ends_a == ends_b


def test_the_compiled_ticks_skip_the_collision_detection_and_equal_the_reference() -> None:
    _compiled_or_skip()
    fast, slow = FastWorld(cube=False), FastWorld(cube=False, compiled=False)
    q_a, states_a, ends_a = _reach(fast, 200)
    q_b, states_b, ends_b = _reach(slow, 200)
    assert slow._fast is None and fast._fast is not None
    assert np.array_equal(q_a, q_b) and np.array_equal(states_a, states_b)
    assert ends_a == ends_b
    culled = fast._fast.robot.contact_cull[-1][1]
    # every compiled tick of these episodes is clear of the table (the goals are 15 cm
    # above it at the lowest)
    assert culled == fast._fast.compiled_ticks > 7000
    # and the detection is on again after every tick
    contact = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    assert not fast.robot.physics.model.opt.disableflags & contact


def test_a_contact_with_the_table_is_found_as_before() -> None:
    """A streamed pose target under the table, as in the world with the cube: the arm
    comes down (the detection skipped while it is clear), touches the table (found) and
    presses on it until the robot's contact reflex, at the same tick with the same
    state on both paths."""
    _compiled_or_skip()
    results = []
    for compiled in (True, False):
        world = FastWorld(compiled=compiled, cube=False)
        ctrl = CartesianTarget(0.5, timeout=None)
        world.start(ctrl)
        T = world.robot.O_T_EE
        ctrl.set_target(T[:3, 3] + np.array([0.1, 0.0, -0.6]), np.array([1.0, 0, 0, 0]))
        world.advance(6000)
        failure = world.failure()
        assert failure is not None and "reflex" in failure
        if compiled:
            assert world._fast is not None
            culled = world._fast.robot.contact_cull[-1][1]
            assert 100 < culled < world._fast.compiled_ticks
        results.append((failure, world.ticks, world.robot.q, world.robot.core.state_buffer))
        world.recover()
        world.home(np.asarray(START_POSE), None)
        world.close()
    (fail_a, ticks_a, q_a, state_a), (fail_b, ticks_b, q_b, state_b) = results
    assert fail_a == fail_b and ticks_a == ticks_b
    assert np.array_equal(q_a, q_b) and np.array_equal(state_a, state_b)


def test_the_detection_is_never_skipped_beside_the_cube() -> None:
    """With the cube (it rests on the table, and the robot may touch it) no tick is clear."""
    _compiled_or_skip()
    world = FastWorld(cube=True)
    assert world._fast is not None
    cull = world._fast.robot.contact_cull
    assert math.isinf(cull[-1][0])
    _reach(world, 30)
    assert cull[-1][1] == 0
    assert world.robot.physics.data.ncon > 0  # (the cube's contacts with the table)


def test_a_free_body_beside_the_robot_is_never_culled(tmp_path: Any) -> None:
    """A scene with a free body of its own (it may touch the robot and the table): the
    floor is infinite, no tick is clear; the robot and the table alone: the table top."""
    from panda_py.robots.params import get_robot
    from panda_py.sim.physics import Physics

    # (the cull is the compiled ticks': none without numba or with PANDA_PY_NO_JIT=1)
    compiled = pytest.importorskip("panda_py.sim.compiled", exc_type=ImportError)
    extra = tmp_path / "ball.xml"
    extra.write_text('<mujoco><worldbody><body name="ball" pos="0.5 0.3 0.05"><freejoint/>'
                     '<inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>'
                     '<geom type="sphere" size="0.05"/></body></worldbody></mujoco>')  # fmt: skip
    for path, floor in ((extra, math.inf), (None, 0.0)):
        ph = Physics(get_robot("fer"), cube=False, extra=path)
        cull = compiled.contact_cull(ph.model, ph.data)
        assert cull[-1][0] == floor


def test_the_environments_make_their_worlds_with_the_cube_where_they_use_it() -> None:
    reach = gymnasium.make("PandaReach-v0")
    pick = gymnasium.make("PandaPickAndPlace-v0")
    try:
        r, p = reach.unwrapped.backend, pick.unwrapped.backend
        assert not r.has_cube and p.has_cube
        reach.reset(seed=0)
        assert r.snapshot().cube is None
        with pytest.raises(ValueError, match="no cube"):
            r.place_cube((0.5, 0.0, 0.02))
        with pytest.raises(ValueError, match="expected a body of the scene"):
            r.robot.body_position("cube")
        m = r.robot.physics.model
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cube") == -1
    finally:
        reach.close()
        pick.close()
