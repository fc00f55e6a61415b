"""Rollouts on Ray: the scripted reaching policy runs ``PandaReach-v0`` on 2 rollout
workers (Ray actors, each a process with its own fast training world) of a local Ray
instance started here with 2 CPUs; episode ``i`` is seeded ``i`` whichever worker runs
it. Prints each episode as it finishes, then the success rate and the throughput.

``--address auto`` (or ``ray://...``) runs the workers on the Ray cluster this machine has
joined instead (``ray start --head`` / ``ray start --address=...``: see
docs/learning-cluster.md); ``--host 172.16.0.2 --host 172.16.0.3`` gives each worker a
robot (one worker per host, reaching, with the arm's 1 kHz loop on the worker's node).
Needs the ``learning`` extra (``pip install "panda-py-pure[learning]"``)."""

import argparse
import time

import ray

from panda_py.learning import RolloutWorkers, reach_policy

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--address", help="a Ray cluster to join (default: a local one)")
    parser.add_argument("--host", action="append", help="a robot's FCI address (repeatable)")
    parser.add_argument("--workers", type=int, default=2, help="rollout workers (fast world)")
    parser.add_argument("--episodes", type=int, default=8, help="episodes to run")
    args = parser.parse_args()
    if args.address:
        ray.init(address=args.address, log_to_driver=False)
    else:  # a small local instance: 2 CPUs, no dashboard, quick to start
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        start = time.perf_counter()
        with RolloutWorkers("PandaReach-v0", n_workers=args.workers, hosts=args.host) as workers:
            ready, n = time.perf_counter(), workers.n_workers
            print(f"{n} workers ready on {sorted(set(workers.nodes))} in "
                  f"{ready - start:.1f} s")  # fmt: skip
            results = []
            for result in workers.run(reach_policy, args.episodes, seed=0):
                results.append(result)
                print(f"episode {result.index} (seed {result.seed}) on worker {result.worker}: "
                      f"{result.steps} steps, return {result.episode_return:.0f}, "
                      f"success {result.success}")  # fmt: skip
            wall = time.perf_counter() - ready
        successes = sum(r.success for r in results)
        steps = sum(r.steps for r in results)
        print(f"succeeded {successes / len(results):.0%} of {len(results)} episodes "
              f"({successes} of {len(results)})")  # fmt: skip
        print(f"throughput: {len(results) / wall:.1f} episodes/s, {steps / wall:.0f} steps/s "
              f"on {n} workers")  # fmt: skip
    finally:
        ray.shutdown()
