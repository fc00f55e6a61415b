"""Rollouts on Ray actors: episode ``i`` gets seed ``seed + i`` and the same episode
whatever the number of workers (and the same as in this process); bad input is refused
before Ray is touched; the workers' processes are gone after closing, after an error
too; with ``hosts`` a worker drives the robot (here ``panda-sim``) on the node that has
its resource; without a cluster a local Ray is started and shut down; the block of
docs/learning.md runs. One local Ray instance (2 CPUs) is shared by the module."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import gymnasium
import numpy as np
import pytest

from panda_py.learning import (
    EpisodeResult,
    RolloutWorkers,
    reach_policy,
    rollouts,
    run_rollouts,
)
from panda_py.sim import Simulator, free_loopback_host

ray = pytest.importorskip("ray")

pytestmark = pytest.mark.timeout(120)

GONE_TIMEOUT = 15.0  # [s] for a killed worker's process to exit


@pytest.fixture(scope="module")
def robot_host() -> str:
    return free_loopback_host()


@pytest.fixture(scope="module")
def cluster(robot_host: str) -> Iterator[None]:
    """A local Ray instance whose one node is also "next to" the robot at robot_host."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             resources={rollouts.ROBOT_RESOURCE.format(host=robot_host): 1})  # fmt: skip
    try:
        yield
    finally:
        ray.shutdown()


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def assert_gone(pids: list[int]) -> None:
    deadline = time.monotonic() + GONE_TIMEOUT
    while any(alive(pid) for pid in pids):
        assert time.monotonic() < deadline, f"worker processes still running: {pids}"
        time.sleep(0.05)


def local_episode(env: gymnasium.Env, seed: int) -> tuple[float, int, bool]:
    obs, _ = env.reset(seed=seed)
    total, steps = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(reach_policy(obs))
        total, steps = total + float(reward), steps + 1
        if terminated or truncated:
            return total, steps, bool(info["is_success"])


def outcome(r: EpisodeResult) -> tuple[float, int, bool]:
    return r.episode_return, r.steps, r.success


def test_the_same_seeds_give_the_same_episodes_whatever_the_workers(cluster: None) -> None:
    one = run_rollouts("PandaReach-v0", reach_policy, episodes=6, n_workers=1, seed=10)
    two = run_rollouts("PandaReach-v0", reach_policy, episodes=6, n_workers=2, seed=10)
    assert [r.index for r in two] == list(range(6))
    assert [r.seed for r in two] == list(range(10, 16))
    assert {r.worker for r in one} == {0} and {r.worker for r in two} == {0, 1}
    assert [outcome(r) for r in one] == [outcome(r) for r in two]
    assert len({outcome(r) for r in two}) > 1  # distinct seeds: distinct episodes
    env = gymnasium.make("PandaReach-v0")  # and as this process runs them
    try:
        assert [local_episode(env, s) for s in (10, 13)] == [outcome(two[0]), outcome(two[3])]
    finally:
        env.close()
    assert all(r.success for r in two)  # the scripted policy (measured: all)
    assert all(r.node and r.wall_time > 0.0 for r in two)


def test_results_arrive_as_they_finish_and_the_workers_are_reused(cluster: None) -> None:
    with RolloutWorkers("PandaReach-v0", n_workers=2) as workers:
        first = list(workers.run(reach_policy, 4, seed=0))
        again = list(workers.run(reach_policy, 4, seed=0))
        for _ in workers.run(reach_policy, 20, seed=0):
            break  # the rest is dropped: the workers go on with the next run
        after = list(workers.run(reach_policy, 4, seed=0))
        pids = workers.pids
        assert all(alive(pid) for pid in pids)
    assert sorted(outcome(r) for r in first) == sorted(outcome(r) for r in again)
    assert sorted((r.index, outcome(r)) for r in after) == sorted(
        (r.index, outcome(r)) for r in first
    )
    assert sorted(r.index for r in first) == [0, 1, 2, 3]
    assert_gone(pids)
    with pytest.raises(RuntimeError, match="closed"):
        workers.run(reach_policy, 1)


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda: RolloutWorkers("PandaReach-v0", n_workers=0), "n_workers"),
        (lambda: RolloutWorkers("PandaReach-v0", n_workers=1.5), "n_workers"),  # type: ignore[arg-type]
        (lambda: RolloutWorkers("CartPole-v1"), "env_id"),
        (lambda: RolloutWorkers("PandaReach-v0", hosts=[]), "hosts"),
        (lambda: RolloutWorkers("PandaReach-v0", hosts=["a", "a"]), "hosts"),
        (lambda: RolloutWorkers("PandaReach-v0", env_kwargs=[("reward", "dense")]), "env_kwargs"),  # type: ignore[arg-type]
        (lambda: RolloutWorkers("PandaPickAndPlace-v0", hosts=["172.16.0.2"]), "env_id"),
        (lambda: RolloutWorkers("PandaReach-v0", env_kwargs={"backend": "fast"}), "env_kwargs"),
        (lambda: run_rollouts("PandaReach-v0", reach_policy, episodes=0), "episodes"),
        (lambda: run_rollouts("PandaReach-v0", reach_policy, episodes=2, seed=-1), "seed"),
        (lambda: run_rollouts("PandaReach-v0", None, episodes=2), "policy"),  # type: ignore[arg-type]
    ],
)
def test_bad_input_is_refused_before_ray_is_touched(
    call: object, argument: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    def touched() -> None:
        raise AssertionError("Ray was used before the input was checked")

    monkeypatch.setattr(rollouts, "_ray", touched)
    with pytest.raises(ValueError, match=rf"^{argument}: expected"):
        call()  # type: ignore[operator]


def test_bad_episodes_on_running_workers_hand_out_nothing(cluster: None) -> None:
    with RolloutWorkers("PandaReach-v0", n_workers=1) as workers:
        with pytest.raises(ValueError, match=r"^episodes: expected an integer >= 1, got 0"):
            workers.run(reach_policy, 0)
        assert [r.index for r in workers.run(reach_policy, 1)] == [0]  # still usable


def test_an_error_in_an_episode_is_raised_and_the_workers_are_closed(cluster: None) -> None:
    workers = RolloutWorkers("PandaReach-v0", n_workers=2)
    pids = workers.pids
    # a NaN action: the environment's error, through Ray (a lambda travels by value)
    with pytest.raises(ValueError, match=r"^action: "):
        list(workers.run(lambda obs: np.full(3, np.nan, dtype=np.float32), 4))
    assert_gone(pids)
    assert workers.n_workers == 0


# the policy's answers reach a lockstep robot as fast as the worker's process makes them: a
# loaded machine (the suite's other processes, or three CPU burners, on this change and the
# one before it alike) makes them late in each step and the reach fails to arrive in time
@pytest.mark.exclusive
def test_a_worker_drives_the_robot_at_its_host(cluster: None, robot_host: str) -> None:
    place = rollouts.ROBOT_RESOURCE.format(host=robot_host)
    with (
        Simulator(robot_host, lockstep=True) as sim,
        RolloutWorkers("PandaReach-v0", hosts=[sim.host]) as workers,
    ):
        # the worker holds the resource of the node next to the robot (Ray's view of the
        # resources is updated asynchronously: wait for it)
        deadline = time.monotonic() + GONE_TIMEOUT
        while ray.available_resources().get(place, 0.0) != 0.0:
            assert time.monotonic() < deadline, ray.available_resources()
            time.sleep(0.05)
        results = sorted(workers.run(reach_policy, 2), key=lambda r: r.index)
        pids = workers.pids
    assert workers.n_workers == 0 and [r.worker for r in results] == [0, 0]
    assert all(r.success for r in results)  # measured: both
    assert [r.seed for r in results] == [0, 1]
    assert_gone(pids)  # and with it its control process (which exits with its parent)


def test_the_docs_block_runs_and_says_what_it_did(
    cluster: None, capsys: pytest.CaptureFixture[str]
) -> None:
    page = Path(__file__).resolve().parents[2] / "docs" / "learning.md"
    section = page.read_text().split("## Rollouts beyond one machine")[1]
    (block,) = re.findall(r"```python\n(.*?)```", section.split("\n## ")[0], flags=re.S)
    exec(block, {})
    assert capsys.readouterr().out == "8 of 8 reached their goal\n"  # measured: all


OWN_RAY = """
import ray
from panda_py.learning import RolloutWorkers, reach_policy

with RolloutWorkers("PandaReach-v0", n_workers=1) as workers:
    print("started", ray.is_initialized(), len(list(workers.run(reach_policy, 2))))
print("after", ray.is_initialized(), workers.pids[0])
"""


def test_without_a_cluster_a_local_ray_is_started_and_shut_down() -> None:
    # in a process of its own: this module's shared instance would be used otherwise
    src = str(Path(rollouts.__file__).resolve().parents[2])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    env.pop("RAY_ADDRESS", None)
    done = subprocess.run([sys.executable, "-c", OWN_RAY], env=env, capture_output=True,
                          text=True, timeout=100)  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "started True 2"
    assert lines[1].startswith("after False ")
    assert_gone([int(lines[1].split()[2])])
