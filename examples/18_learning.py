"""One policy, unchanged, on the fast training world and on a robot: the Gymnasium
environments ``PandaReach-v0`` and ``PandaPickAndPlace-v0`` run in this process on the fast
world (the simulator's robot core stepped at 1 kHz by the same streamed-target controllers
a Panda runs), then on ``panda-sim`` in lockstep through a ``Panda``; the scripted
policies reach and pick-and-place on both, and the success rates are printed for each.

``--host 172.16.0.2`` runs the second half on that robot instead: reaching only (no one
places the cube there; see ``panda_py.learning.RobotArm``'s ``scene``). Needs the
``learning`` extra (``pip install "panda-py-pure[learning]"``)."""

import argparse
import time

import gymnasium

import panda_py.learning  # registers the environments
from panda_py.learning import RobotArm, pick_and_place_policy, reach_policy

POLICIES = {"PandaReach-v0": reach_policy, "PandaPickAndPlace-v0": pick_and_place_policy}


def success_rate(env, policy, episodes):
    """Run ``episodes`` seeded episodes of ``policy``: the share that succeeded, and the
    environment steps per second of wall time."""
    successes, steps, start = 0, 0, time.perf_counter()
    for seed in range(episodes):
        obs, info = env.reset(seed=seed)
        for _ in range(env.spec.max_episode_steps):
            obs, _, terminated, truncated, info = env.step(policy(obs))
            steps += 1
            if terminated or truncated:
                break
        successes += info["is_success"]
    return successes / episodes, steps / (time.perf_counter() - start)


def run_all(ids, episodes, where, **options):
    for env_id in ids:
        env = gymnasium.make(env_id, **options)
        rate, speed = success_rate(env, POLICIES[env_id], episodes)
        print(f"{env_id:<22} on {where:<16} succeeded {rate:4.0%} of {episodes} "
              f"episodes ({speed:.0f} steps/s)")  # fmt: skip
        env.close()  # a backend given stays open: its owner closes it


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", help="a robot's FCI address (default: panda-sim here)")
    parser.add_argument("--episodes", type=int, default=5, help="episodes per environment")
    args = parser.parse_args()
    print(f"environments: {', '.join(panda_py.learning.ENVIRONMENTS)}")
    run_all(POLICIES, args.episodes, "the fast world")
    if args.host:
        with RobotArm(args.host, hand=False) as arm:
            run_all(["PandaReach-v0"], args.episodes, args.host, backend=arm)
    else:
        from panda_py.sim import Simulator, free_loopback_host

        with (
            Simulator(free_loopback_host(), lockstep=True) as sim,
            RobotArm(sim.host, scene=sim) as arm,  # the simulator places the cube
        ):
            run_all(POLICIES, args.episodes, "panda-sim", backend=arm)
