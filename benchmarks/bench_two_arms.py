"""The cost of a second arm on one PC: ``CartesianImpedance`` on one realtime simulated FER,
then on two at once (one ``Panda`` and control process each, fed from one user loop), for
``--seconds`` each, ``--runs`` times. Run by hand:

    python benchmarks/bench_two_arms.py [--seconds 20] [--runs 3]

Printed per run: each control process's CPU share of a core, the commands each simulator
counted lost and its late ticks, and the user loop's cost per iteration (one
``set_control`` and one ``get_position`` per arm) as median / p99 / worst [us]; then the
second arm's cost as the ratio of the two-arm figures to the one-arm ones. Each simulator
gets SCHED_FIFO where permitted, as a robot's controller has its own hardware.
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import ExitStack
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_panda import _cpu_seconds, _fifo, _stats

import panda_py
from panda_py import controllers
from panda_py.sim import Simulator, free_loopback_host


def run(arms: int, seconds: float) -> dict:
    with ExitStack() as stack:
        sims = [
            stack.enter_context(Simulator(free_loopback_host(), robot="fer", versions=(5,)))
            for _ in range(arms)
        ]
        for sim in sims:
            _fifo(sim._process.pid)
        pandas = [stack.enter_context(panda_py.Panda(sim.host)) for sim in sims]
        for p in pandas:
            p.move_to_start()
        ctrls = [controllers.CartesianImpedance(filter_coeff=1.0) for _ in pandas]
        x0 = [p.get_position() for p in pandas]
        q0 = [p.get_orientation() for p in pandas]
        for p, c in zip(pandas, ctrls, strict=True):
            p.start_controller(c)
        time.sleep(0.5)
        pids = [p._proc.proc.pid for p in pandas]
        cpu0 = [_cpu_seconds(pid) for pid in pids]
        for sim in sims:
            sim.reset_stats()
        t0 = time.monotonic()
        loop = []
        clock = time.perf_counter_ns
        with pandas[0].create_context(frequency=1e3, max_runtime=seconds) as ctx:
            while ctx.ok():
                a = clock()
                s = 0.05 * np.sin(ctrls[0].get_time())
                for i, (p, c) in enumerate(zip(pandas, ctrls, strict=True)):
                    x_d = x0[i].copy()
                    x_d[1] += s
                    c.set_control(x_d, q0[i])
                    p.get_position()
                loop.append((clock() - a) * 1e-3)
        wall = time.monotonic() - t0
        cpu = [(_cpu_seconds(pid) - c0) / wall for pid, c0 in zip(pids, cpu0, strict=True)]
        stats = [sim.stats() for sim in sims]
        for p in pandas:
            p.stop_controller()
    return {
        "cpu": cpu,
        "lost": [s["commands_lost"] for s in stats],
        "late": [s["late_ticks"] for s in stats],
        "loop": _stats(loop),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--runs", type=int, default=3)
    a = ap.parse_args()
    print(f"CartesianImpedance on realtime simulated FERs, {a.seconds:g} s per case")
    for r in range(a.runs):
        one, two = run(1, a.seconds), run(2, a.seconds)
        for label, res in (("one arm", one), ("two arms", two)):
            cpu = ", ".join(f"{100 * c:.1f} %" for c in res["cpu"])
            m, p, w = res["loop"]
            print(
                f"  run {r + 1} {label:<9} control CPU {cpu}; lost {res['lost']}; late ticks "
                f"{res['late']}; user loop median {m:.1f} p99 {p:.1f} worst {w:.1f} us"
            )
        cpu_ratio = sum(two["cpu"]) / sum(one["cpu"])
        loop_ratio = two["loop"][0] / one["loop"][0]
        print(
            f"  run {r + 1} second arm: control CPU {cpu_ratio:.2f}x the one arm's, "
            f"user loop median {loop_ratio:.2f}x"
        )


if __name__ == "__main__":
    main()
