"""Benchmark the learning environments: environment steps per second on one core, on the
fast in-process world and on ``panda-sim`` in lockstep, and panda-gym's PyBullet
``PandaReach-v3`` in the same run where it installs (a peer virtual environment:
``tests/peer_envs.py``; the package never imports it).

Run: ``python benchmarks/bench_learning.py [--steps N]``.

All at panda-gym's policy rate, 25 Hz (a step is 40 ms of simulated time), reaching random
goals with the proportional policy (panda-gym: with its own equivalent, the same gain on
its end effector). Each prints the time a step takes (median, p99, worst [ms]), the steps
per second and the real-time factor (simulated over wall time), and the ratio to
panda-gym's steps per second. Resets are timed apart. Rates per CPU-second (this process's
CPU time) are what the ratios compare: on a shared machine wall time counts the
neighbours' work too. Beside the fast world, the bound ``mj_step`` alone sets (its ticks of
a step, nothing else, with the collision detection skipped where the world skips it).
The issue's targets: the fast world >= 1.2x panda-gym's steps per CPU-second, 2 vector
workers >= 1.8x one; panda-sim >= 10x real time.
The machine is a noisy 2-core VM: run it more than once.

``--vector N`` adds the fast world vectorised with 1 and with N workers, in Gymnasium's
``AsyncVectorEnv`` and in ours (``PandaVectorEnv``, ``gymnasium.make_vec``'s default for
the ids), beside N independent single-world processes started together (the machine's
own bound for N workers: nothing shared, nothing waited for); steps of all environments
per second and the ratios to one worker, in alternating rounds (``--rounds``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

RATE = 25.0  # [Hz] panda-gym's (its step: 20 PyBullet steps of 2 ms)
PERIOD = 1.0 / RATE  # [s]

PEER_SCRIPT = """
import json, sys, time
import numpy as np
import gymnasium, panda_gym  # noqa: F401 (registers the environments)

steps = int(sys.argv[1])
env = gymnasium.make("PandaReach-v3")
times, cpu, resets = [], [], []
obs, _ = env.reset(seed=0)
episode = 0
while len(times) < steps:
    action = np.clip((obs["desired_goal"] - obs["achieved_goal"]) / 0.05, -1.0, 1.0)
    c0, t0 = time.process_time(), time.perf_counter()
    obs, _, terminated, truncated, _ = env.step(action.astype(np.float32))
    times.append(time.perf_counter() - t0)
    cpu.append(time.process_time() - c0)
    if terminated or truncated:
        episode += 1
        t0 = time.perf_counter()
        obs, _ = env.reset(seed=episode)
        resets.append(time.perf_counter() - t0)
print(json.dumps({"steps": times, "cpu": cpu, "resets": resets}))
"""


def stats(seconds: list[float]) -> str:
    a = np.asarray(seconds) * 1e3
    return (f"median {np.median(a):7.2f}  p99 {np.percentile(a, 99):7.2f}  "
            f"worst {a.max():7.2f} ms")  # fmt: skip


def measure(env, steps: int) -> dict[str, list[float]]:  # type: ignore[no-untyped-def]
    from panda_py.learning import reach_policy

    times: list[float] = []
    cpu: list[float] = []
    resets: list[float] = []
    episode = 0
    obs, _ = env.reset(seed=0)
    while len(times) < steps:
        action = reach_policy(obs)
        c0, t0 = time.process_time(), time.perf_counter()
        obs, _, terminated, truncated, _ = env.step(action)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        if terminated or truncated:
            episode += 1
            t0 = time.perf_counter()
            obs, _ = env.reset(seed=episode)
            resets.append(time.perf_counter() - t0)
    return {"steps": times, "cpu": cpu, "resets": resets}


def report(name: str, result: dict[str, list[float]], peer_rate: float | None) -> float:
    """Print a row; returns the steps per CPU-second (this process's CPU time: on a
    shared machine, wall time counts the neighbours' work too)."""
    steps = result["steps"]
    rate = len(steps) / sum(steps)
    cpu_rate = len(steps) / max(sum(result["cpu"]), 1e-9)
    line = (f"{name:<28} step {stats(steps)}  {rate:8.1f} steps/s  {cpu_rate:8.1f} steps/CPU-s"
            f"  {rate * PERIOD:6.1f}x real time")  # fmt: skip
    if peer_rate:
        line += f"  {cpu_rate / peer_rate:5.2f}x panda-gym (CPU)"
    print(line)
    if result["resets"]:
        print(f"{'':<28} reset {stats(result['resets'])} (n={len(result['resets'])})")
    return cpu_rate


def mj_step_bound(env, ticks: int = 4000) -> float:  # type: ignore[no-untyped-def]
    """The steps per CPU-second a fast world could reach if ``mj_step`` were all it ran:
    its physics stepped alone (on a copy of its model and data), one policy step's ticks
    each, with the collision detection off where the world's compiled ticks switch it
    off (nothing can touch: ``panda_py.sim.compiled.clear_of_contacts``)."""
    import copy

    import mujoco

    backend = env.unwrapped.backend
    physics = backend.robot.physics
    m = copy.copy(physics.model)
    d = mujoco.MjData(m)
    mujoco.mj_copyData(d, m, physics.data)
    fast = backend.robot.compiled_tick()
    if fast is not None:
        from panda_py.sim import compiled

        cull = fast.contact_cull
        if compiled.clear_of_contacts(cull):  # (it switched the world's model's off)
            compiled.restore_contacts(cull)
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    c0 = time.process_time()
    for _ in range(ticks):
        mujoco.mj_step(m, d)
    per_tick = (time.process_time() - c0) / ticks
    return 1.0 / (per_tick * round(1000.0 * PERIOD))


def peer(steps: int) -> dict[str, list[float]] | None:
    from peer_envs import PeerUnavailable, peer_python

    try:
        python = peer_python("panda-gym")
    except PeerUnavailable as exc:
        print(f"panda-gym: not installable here ({exc}); ours only")
        return None
    out = subprocess.run([str(python), "-c", PEER_SCRIPT, str(steps)], capture_output=True,
                         text=True, timeout=1800)  # fmt: skip
    if out.returncode != 0:
        print(f"panda-gym: failed to run ({out.stderr.strip().splitlines()[-1:]}); ours only")
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


SOLO_SCRIPT = """
import sys, time
import numpy as np
import gymnasium, panda_py.learning
from panda_py.learning import reach_policy

steps, rate = int(sys.argv[1]), float(sys.argv[2])
env = gymnasium.make("PandaReach-v0", policy_rate=rate)
obs, _ = env.reset(seed=int(sys.argv[3]))
for _ in range(20):
    obs, *_ = env.step(reach_policy(obs))
print("ready", flush=True)
sys.stdin.readline()
t0 = time.perf_counter()
for i in range(steps):
    obs, _, terminated, truncated, _ = env.step(reach_policy(obs))
    if terminated or truncated:
        obs, _ = env.reset()
print(steps / (time.perf_counter() - t0), flush=True)
"""


def independent(n: int, steps: int) -> float:
    """The machine's own bound for ``n`` workers: ``n`` processes, each stepping one fast
    world of its own with nothing between them, started together: their summed steps/s."""
    procs = [subprocess.Popen([sys.executable, "-c", SOLO_SCRIPT, str(steps), str(RATE), str(i)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
             for i in range(n)]  # fmt: skip
    try:
        for p in procs:
            assert p.stdout is not None and p.stdout.readline().strip() == "ready"
        for p in procs:
            assert p.stdin is not None
            p.stdin.write("go\n")
            p.stdin.flush()
        return sum(float(p.communicate(timeout=600)[0]) for p in procs)
    finally:
        for p in procs:
            p.kill() if p.poll() is None else None


def vector(workers: int, steps: int, rounds: int = 3, n_envs: int = 8) -> None:
    """Steps of all environments per second with 1 and ``workers`` workers, Gymnasium's
    ``AsyncVectorEnv`` and ours (``PandaVectorEnv``: ``gymnasium.make_vec``'s default for
    the ids) with one environment a worker and with ``n_envs`` on 1 and on ``workers``, and
    ``workers`` independent processes (the machine's bound), in alternating rounds; the
    ratios to one worker of the same kind."""
    import gymnasium

    from panda_py.learning import reach_policy
    from panda_py.learning.vector import PandaVectorEnv

    def make():  # type: ignore[no-untyped-def]
        return gymnasium.make("PandaReach-v0", policy_rate=RATE)

    kinds = {
        "AsyncVectorEnv": lambda n: gymnasium.vector.AsyncVectorEnv([make] * n),
        "PandaVectorEnv": lambda n: PandaVectorEnv("PandaReach-v0", n, workers=n,
                                                   policy_rate=RATE),
    }  # fmt: skip

    def rate(envs, n: int) -> float:  # type: ignore[no-untyped-def]
        obs, _ = envs.reset(seed=list(range(n)))
        count, t0 = 0, time.perf_counter()
        while count < steps:
            actions = np.stack([reach_policy({k: v[i] for k, v in obs.items()})
                                for i in range(n)])  # fmt: skip
            obs, *_ = envs.step(actions)  # ended environments reset themselves
            count += n
        return count / (time.perf_counter() - t0)

    fixed = f"PandaVectorEnv, {n_envs} envs"
    ratios: dict[str, list[float]] = {k: [] for k in (*kinds, fixed, "independent processes")}
    print(f"\nvectorised, {steps} steps of all environments each, {rounds} alternating rounds;"
          f" one environment a worker, and {n_envs} on 1 and on {workers} workers")  # fmt: skip

    def measure(label: str, build, sizes) -> None:  # type: ignore[no-untyped-def]
        rates = []
        for n, w in sizes:
            envs = build(n, w)
            try:
                rate(envs, n)  # (warm: the workers' first steps)
                rates.append(rate(envs, n))
            finally:
                envs.close()
        ratios[label].append(rates[1] / rates[0])
        print(f"  round {r}: {label + ',':<28} 1 worker {rates[0]:7.1f} steps/s, "
              f"{workers}: {rates[1]:7.1f}  {ratios[label][-1]:5.2f}x")  # fmt: skip

    for r in range(rounds):
        for label, build in kinds.items():
            measure(label, lambda n, w, build=build: build(n), ((1, 1), (workers, workers)))
        measure(fixed, lambda n, w: PandaVectorEnv("PandaReach-v0", n, workers=w, policy_rate=RATE),
                ((n_envs, 1), (n_envs, workers)))  # fmt: skip
        one, many = independent(1, steps), independent(workers, steps // workers)
        ratios["independent processes"].append(many / one)
        print(f"  round {r}: {'independent processes,':<28} 1 {one:7.1f} steps/s, "
              f"{workers}: {many:7.1f}  {many / one:5.2f}x (the machine's bound)")  # fmt: skip
    for label, values in ratios.items():
        print(f"{label:<28} {workers} workers against one: median {np.median(values):.2f}x "
              f"({min(values):.2f}-{max(values):.2f})")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="environment steps each")
    parser.add_argument("--vector", type=int, default=0, help="also N vectorised workers")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (--vector)")
    parser.add_argument("--envs", type=int, default=8, help="environments on 1 and N workers")
    parser.add_argument("--vector-only", action="store_true", help="skip the one-core part")
    args = parser.parse_args()
    if args.vector_only:
        vector(max(args.vector, 2), args.steps, args.rounds, args.envs)
        return
    import gymnasium

    from panda_py.learning import RobotArm
    from panda_py.sim import Simulator, free_loopback_host

    print(f"PandaReach at {RATE:.0f} Hz, {args.steps} steps each, one process (one core)")
    gym_result = peer(args.steps)
    peer_rate = None
    if gym_result is not None:
        peer_rate = report("panda-gym PandaReach-v3", gym_result, None)
    env = gymnasium.make("PandaReach-v0", policy_rate=RATE)
    env.reset(seed=0)  # the first build and compile, not timed
    report("fast world PandaReach-v0", measure(env, args.steps), peer_rate)
    bound = mj_step_bound(env)
    line = f"{'  (mj_step alone: bound)':<28} {bound:8.1f} steps/CPU-s"
    if peer_rate:
        line += f"  {bound / peer_rate:5.2f}x panda-gym"
    print(line)
    env.close()
    with Simulator(free_loopback_host(), lockstep=True) as sim:
        arm = RobotArm(sim.host, scene=sim, hand=False)
        env = gymnasium.make("PandaReach-v0", backend=arm, policy_rate=RATE)
        try:
            report("panda-sim (lockstep)", measure(env, max(args.steps // 4, 50)), peer_rate)
        finally:
            env.close()
            arm.close()
    if args.vector:
        vector(args.vector, args.steps, args.rounds, args.envs)


if __name__ == "__main__":
    main()
