"""Benchmark the moves that never block: the online generator's cost per tick and the
latency from ``move_to_*(..., asynchronous=True)`` to the new trajectory in effect.

Run: ``python benchmarks/bench_online.py [--quick]``.

* **generator**: :class:`panda_py.motion.online.OnlineGenerator` (ruckig) for 7 joints and
  :class:`~panda_py.motion.online.OnlinePose` for a pose, per step: on an unchanged target
  and on a new target every tick (a policy streaming at 1 kHz, the worst case); and the
  move laws' whole step (reference, impedance, feed-forward) while they lead in.
  Target: median <= 20 us for the generator.
* **latency** (panda-sim in real time, not lockstep): a move replaces the running one at
  a random instant; measured from the call to the tick in which the control process handed
  over (``MoveResult.end_time`` of the replaced move, on the same monotonic clock): the
  user-side checks and planning, the request, and the wait for the next tick. Joint and
  Cartesian targets alternate. Target: p99 <= 2 ms.

Each prints median, p99 and worst. The machine is a noisy 2-core VM: run it more than once.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "controllers"))


def stats(values: list[float]) -> str:
    a = np.asarray(values)
    return (f"median {np.median(a):8.2f}  p99 {np.percentile(a, 99):8.2f}  "
            f"worst {a.max():8.2f}  (n={len(a)})")  # fmt: skip


def time_calls(fn, n: int) -> list[float]:  # type: ignore[no-untyped-def]
    out = []
    for i in range(n):
        t0 = time.perf_counter()
        fn(i)
        out.append((time.perf_counter() - t0) * 1e6)
    return out


def bench_generator(n: int) -> None:
    from panda_py.motion import rotation
    from panda_py.motion.online import OnlineGenerator, OnlineLimits, OnlinePose
    from panda_py.robots.params import get_robot

    spec = get_robot("fr3")
    rng = np.random.default_rng(0)
    gen = OnlineGenerator(OnlineLimits.joints(spec, 0.5))
    gen.reset(np.zeros(7), np.zeros(7), np.zeros(7))
    gen.set_target(np.full(7, 100.0))  # far: it never arrives

    print("generator, per step [us]")
    print(f"  joints, unchanged target    {stats(time_calls(lambda i: gen.step(), n))}")
    targets = rng.uniform(-1.0, 1.0, (n, 7))

    def new_target(i: int) -> None:
        gen.set_target(targets[i])
        gen.step()

    print(f"  joints, new target a tick   {stats(time_calls(new_target, n))}")
    pose = OnlinePose(OnlineLimits.cartesian(spec, 0.5))
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    pose.reset(np.array([0.3, 0.0, 0.5]), q0, np.zeros(6), np.zeros(6))
    pose.set_target(np.array([50.0, 0.0, 0.5]), rotation.multiply(q0, rotation.exp(np.ones(3))))
    print(f"  pose, unchanged target      {stats(time_calls(lambda i: pose.step(), n))}")
    quats = [rotation.multiply(q0, rotation.exp(r)) for r in rng.uniform(-0.5, 0.5, (n, 3))]
    points = np.array([0.3, 0.0, 0.5]) + rng.uniform(-0.2, 0.2, (n, 3))

    def new_pose(i: int) -> None:
        pose.set_target(points[i], quats[i])
        pose.step()

    print(f"  pose, new target a tick     {stats(time_calls(new_pose, n))}")
    bench_laws(n)


def bench_laws(n: int) -> None:
    from test_law_steps import MODEL, Q0, make_state

    from panda_py.controllers import laws
    from panda_py.controllers.moves import JointMove, PoseMove, tracker_for
    from panda_py.panda import planning
    from panda_py.robots.params import get_robot

    laws.warmup()
    spec = get_robot("fer")
    wp, jo = planning.parse_joint_targets((Q0 + 0.3,), {})
    joint = planning.joint_move(Q0, wp, jo, spec)
    T = make_state(Q0).O_T_EE.reshape(4, 4, order="F").copy()
    T[:3, 3] += [0.1, 0.1, -0.1]
    ps, qs, po = planning.parse_pose_targets((T,), {})
    state = make_state(Q0, np.full(7, 0.1))
    pose = planning.pose_move(state.O_T_EE[12:15].copy(), laws.quat_from_matrix(state.O_T_EE), ps,
                              qs, po, Q0, spec)  # fmt: skip
    assert joint is not None and pose is not None
    print("move laws leading in, whole step [us]")
    for name, plan in (("joint", joint), ("pose", pose)):
        first = tracker_for(joint)
        law = tracker_for(plan)
        assert isinstance(law, (JointMove, PoseMove))
        first.step(state, MODEL)
        law.handover(first, state, MODEL)

        def step(i: int, law: JointMove | PoseMove = law) -> None:
            law.tick(1e-3)
            law.step(state, MODEL)

        time_calls(step, 200)  # warm
        print(f"  {name:27} {stats(time_calls(step, n))}")


def bench_latency(n: int) -> None:
    import logging

    import panda_py
    from panda_py.sim import Simulator, free_loopback_host

    logging.getLogger("panda").setLevel(logging.ERROR)
    rng = np.random.default_rng(1)
    with Simulator(free_loopback_host(), lockstep=False) as sim, panda_py.Panda(sim.host) as panda:
        panda.move_to_start()
        start, pose0 = panda.q, panda.get_pose()
        # warm every path once (first calls compile or load)
        warm = pose0.copy()
        warm[2, 3] -= 0.02
        panda.move_to_pose(warm)
        panda.move_to_start()
        joint_ms, pose_ms = [], []
        handle = panda.move_to_joint_position(start + 0.3, asynchronous=True)
        for i in range(n):
            time.sleep(rng.uniform(0.02, 0.15))
            if handle.done():  # arrived: start another to replace
                handle = panda.move_to_joint_position(
                    start + rng.uniform(-0.3, 0.3, 7), asynchronous=True
                )
                time.sleep(0.02)
            old = handle
            t0 = time.monotonic()
            if i % 2:
                p = pose0.copy()
                p[:3, 3] += rng.uniform(-0.1, 0.1, 3)
                handle = panda.move_to_pose(p, asynchronous=True)
            else:
                handle = panda.move_to_joint_position(
                    start + rng.uniform(-0.3, 0.3, 7), asynchronous=True
                )
            old.future().result(timeout=5.0)
            result = old.result
            if result is not None and "replaced" in result.reason:
                # when the control process handed over (its clock is this one)
                dt = (result.end_time - t0) * 1e3
                (pose_ms if i % 2 else joint_ms).append(dt)
        handle.wait()
        print("call -> new trajectory in effect [ms] (real time, panda-sim)")
        print(f"  move_to_joint_position      {stats(joint_ms)}")
        print(f"  move_to_pose                {stats(pose_ms)}")
        print(f"  all                         {stats(joint_ms + pose_ms)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    args = parser.parse_args()
    bench_generator(2_000 if args.quick else 20_000)
    bench_latency(40 if args.quick else 200)


if __name__ == "__main__":
    main()
