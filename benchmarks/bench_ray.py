"""Benchmark rollouts on Ray: episodes per second with 1 and with 2 rollout workers
(:class:`panda_py.learning.RolloutWorkers` on the fast world) in the same run, on a local
Ray instance with 2 CPUs, and the ratio of the two (the issue's target: 2 workers >= 1.6x
one on a 2-core machine).

Run: ``python benchmarks/bench_ray.py [--episodes N] [--env PandaReach-v0]``.

Both run the same seeded episodes (seeds 0..N-1) with the scripted policy, so they do the
same work; starting the workers (Ray placing the actors, each making its environment) is
timed apart, and one warm-up episode per worker runs first. Each prints the wall time of
an episode inside its worker (median, p99, worst [ms]), episodes and environment steps
per second of the driver's wall time. The machine is a noisy 2-core VM shared with other
work, and the driver and Ray's own processes run on the same two cores: run it more than
once. ``--plain`` adds the same episodes on 1 and 2 plain processes without Ray (the
ratio the machine gives at that moment, to compare with).
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from typing import Any

import numpy as np
import ray

from panda_py.learning import RolloutWorkers, pick_and_place_policy, reach_policy

_barrier: Any = None  # in a plain process: the start, shared by all of them
POLICIES = {"PandaReach-v0": reach_policy, "PandaPickAndPlace-v0": pick_and_place_policy}


def stats(seconds: list[float]) -> str:
    a = np.asarray(seconds) * 1e3
    return (f"median {np.median(a):7.2f}  p99 {np.percentile(a, 99):7.2f}  "
            f"worst {a.max():7.2f} ms")  # fmt: skip


def measure(env_id: str, workers: int, episodes: int) -> float:
    """Run ``episodes`` episodes on ``workers`` workers; print and return episodes/s."""
    policy = POLICIES[env_id]
    t0 = time.perf_counter()
    with RolloutWorkers(env_id, n_workers=workers) as pool:
        started = time.perf_counter() - t0
        list(pool.run(policy, workers, seed=10**6))  # warm-up, other seeds
        t0 = time.perf_counter()
        results = list(pool.run(policy, episodes, seed=0))
        wall = time.perf_counter() - t0
    steps = sum(r.steps for r in results)
    rate = len(results) / wall
    busy = sum(r.wall_time for r in results) / (wall * workers)  # in episodes, of the wall
    success = np.mean([r.success for r in results])
    print(f"{workers} worker(s): episode {stats([r.wall_time for r in results])}  "
          f"{rate:6.1f} episodes/s  {steps / wall:7.0f} steps/s  (start {started:.1f} s, "
          f"{steps} steps, workers busy {busy:.0%}, success {success:.0%})")  # fmt: skip
    return rate


def plain(env_id: str, seeds: list[int]) -> tuple[int, float]:
    """In a process of its own: make the environment, run one warm-up episode, wait for
    the start, then run ``seeds``' episodes; their steps and the wall time [s]."""
    import gymnasium

    import panda_py.learning  # noqa: F401 (registers the environments)

    env, policy = gymnasium.make(env_id), POLICIES[env_id]
    steps = 0
    for i, seed in enumerate([10**6, *seeds]):
        if i == 1:
            _barrier.wait()
            start = time.perf_counter()
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(policy(obs))
            done = terminated or truncated
            steps += i > 0
    return steps, time.perf_counter() - start


def _init(barrier: object) -> None:
    global _barrier
    _barrier = barrier


def measure_plain(env_id: str, workers: int, episodes: int) -> float:
    """The machine's own ratio, without Ray: ``workers`` processes of the standard library,
    each with its share of the same episodes; returns episodes/s."""
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(workers)
    with ctx.Pool(workers, initializer=_init, initargs=(barrier,)) as pool:
        shares = [(env_id, list(range(k, episodes, workers))) for k in range(workers)]
        done = pool.starmap(plain, shares)
    wall = max(t for _, t in done)
    rate = episodes / wall
    print(f"{workers} process(es) without Ray: {rate:6.1f} episodes/s  "
          f"{sum(n for n, _ in done) / wall:7.0f} steps/s")  # fmt: skip
    return rate


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200, help="episodes per measurement")
    parser.add_argument("--env", default="PandaReach-v0", choices=sorted(POLICIES))
    parser.add_argument(
        "--plain",
        action="store_true",
        help="also 1 and 2 plain processes without Ray (the machine's ratio)",
    )
    args = parser.parse_args()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        print(f"{args.env}, {args.episodes} episodes, local Ray with 2 CPUs")
        one = measure(args.env, 1, args.episodes)
        two = measure(args.env, 2, args.episodes)
        print(f"2 workers / 1 worker: {two / one:.2f}x (target >= 1.6x)")
        if args.plain:
            plain_one = measure_plain(args.env, 1, args.episodes)
            plain_two = measure_plain(args.env, 2, args.episodes)
            print(f"without Ray, 2 processes / 1: {plain_two / plain_one:.2f}x (what the "
                  "machine gives now)")  # fmt: skip
    finally:
        ray.shutdown()
