"""The CPU a stream of moves costs: every 50 ms a new Cartesian goal on a circle replaces
the running move (as a policy or a teleoperation sends goals at 20 Hz), our
``move_to_pose(..., asynchronous=True)`` against franky-control 2.0.0's
``robot.move(CartesianMotion(...), asynchronous=True)``, on panda-sim in real time (FR3,
protocol v10: franky 2.0's libfranka).

Run: ``python benchmarks/bench_move_stream.py [--seconds 10] [--rounds 3]``.

Each round runs, one after the other in an order that alternates, ours with the compiled
ticks, ours with every tick in Python (``PANDA_PY_FAST_TICKS=0``: what a move's lead-ins,
the bulk of such a stream, cost before they were compiled) and franky; each on a fresh
simulator, in its own process. Measured over the window, as a user would: ours the whole
process tree less the simulator (the control process, the user's process, the warm server
the control process was forked from), franky its process (its control loop is a thread of
it). Both move at a fifth of their limits (our ``speed_factor`` 0.2, franky's
``relative_dynamics_factor`` 0.2). Prints each round and the median (range) of the shares
[% of a core], and the ratio of the medians to franky's. The machine is a noisy 2-core VM:
run it more than once.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
RADIUS = 0.05  # [m] of the goals' circle, through the start position
PERIOD = 0.05  # [s] between goals
TURN = 2.0  # [s] a turn of the circle (0.16 m/s along it)
FACTOR = 0.2


def goal(p0: np.ndarray, k: int) -> np.ndarray:
    """The k-th goal: on a circle in the horizontal plane that passes the start."""
    a = 2.0 * math.pi * k * PERIOD / TURN
    return p0 + RADIUS * np.array([math.cos(a) - 1.0, math.sin(a), 0.0])


def ours(host: str, seconds: float) -> dict[str, Any]:
    sys.path.insert(0, str(HERE))
    from bench_panda import _cpu_clock, _process_tree, _tree_cpu

    import panda_py

    with panda_py.Panda(host) as panda:
        panda.move_to_start()
        p0, rot = panda.get_position(), panda.get_orientation()
        control, me = panda._proc.proc.pid, os.getpid()
        panda.move_to_pose(goal(p0, 1), rot, speed_factor=FACTOR)  # (compiled, warm)
        rest = _process_tree(me, exclude=set()) - {me, control}
        c0, u0, r0, t0 = _cpu_clock(control), time.process_time(), _tree_cpu(rest), time.monotonic()
        k, handle = 1, None
        while time.monotonic() - t0 < seconds:
            k += 1
            handle = panda.move_to_pose(goal(p0, k), rot, speed_factor=FACTOR,
                                        asynchronous=True)  # fmt: skip
            time.sleep(max(0.0, t0 + (k - 1) * PERIOD - time.monotonic()))
        wall = time.monotonic() - t0
        c1, u1, r1 = _cpu_clock(control), time.process_time(), _tree_cpu(rest)
        assert handle is not None
        handle.wait(10.0)
        result = handle.result
        panda.raise_error()
    return {
        "control": (c1 - c0) / wall, "user": (u1 - u0) / wall,
        "rest": sum(r1[p] - r0[p] for p in r1.keys() & r0.keys()) / wall, "goals": k - 1,
        "last": None if result is None else bool(result.success),
    }  # fmt: skip


def franky(host: str, seconds: float) -> dict[str, Any]:
    from franky import Affine, CartesianMotion, RealtimeConfig, Robot

    robot = Robot(host, realtime_config=RealtimeConfig.Ignore)
    pose = robot.current_pose.end_effector_pose
    p0, quat = np.array(pose.translation), np.array(pose.quaternion)

    def move(k: int, asynchronous: bool) -> None:
        motion = CartesianMotion(Affine(goal(p0, k), quat), relative_dynamics_factor=FACTOR)
        robot.move(motion, asynchronous=asynchronous)

    move(1, False)
    u0, t0, k, reflexes = time.process_time(), time.monotonic(), 1, 0
    while time.monotonic() - t0 < seconds:
        k += 1
        try:
            move(k, True)
        except Exception:  # a reflex (reported: on our simulated FR3 franky's replacing
            reflexes += 1  # Cartesian motions trip its joint acceleration checks)
            robot.recover_from_errors()
        time.sleep(max(0.0, t0 + (k - 1) * PERIOD - time.monotonic()))
    wall = time.monotonic() - t0
    u1 = time.process_time()
    try:
        robot.join_motion()
        last = True
    except Exception:
        last = False
    return {"control": 0.0, "user": (u1 - u0) / wall, "rest": 0.0, "goals": k - 1,
            "last": last, "reflexes": reflexes}  # fmt: skip


def _run(side: str, seconds: float) -> dict[str, Any]:
    """One side on a fresh realtime simulator, in its own process."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    from peer_envs import peer_python

    from panda_py.sim import Simulator, free_loopback_host

    env = {k: v for k, v in os.environ.items() if k != "PANDA_PY_FAST_TICKS"}
    python = sys.executable
    if side == "franky":
        python = str(peer_python("franky"))
        env = {k: v for k, v in env.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    elif side == "python ticks":
        env["PANDA_PY_FAST_TICKS"] = "0"
    with Simulator(free_loopback_host(), robot="fr3") as sim:  # (franky 2.0: v10)
        proc = subprocess.run(
            [python, __file__, "--side", "franky" if side == "franky" else "ours", sim.host,
             str(seconds)], capture_output=True, text=True, env=env, timeout=120 + seconds,
        )  # fmt: skip
    lines = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"{side}: exit {proc.returncode}: {proc.stderr[-600:]}")
    out: dict[str, Any] = json.loads(lines[-1][7:])
    out["total"] = out["control"] + out["user"] + out["rest"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--side", choices=["ours", "franky"], help=argparse.SUPPRESS)
    parser.add_argument("args", nargs="*", help=argparse.SUPPRESS)
    a = parser.parse_args()
    if a.side is not None:  # a side's own process: host, seconds
        result = (ours if a.side == "ours" else franky)(a.args[0], float(a.args[1]))
        print("RESULT " + json.dumps(result), flush=True)
        return
    if not a.seconds > 0.0 or a.rounds < 1:
        parser.error(f"expected --seconds > 0 and --rounds >= 1, got {a.seconds}, {a.rounds}")
    print(f"bench_move_stream: {platform.node()}, {os.cpu_count()} CPUs, load "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, Python "
          f"{platform.python_version()}; goals every {PERIOD * 1e3:.0f} ms for "
          f"{a.seconds:g} s, {a.rounds} rounds")  # fmt: skip
    sides = ["compiled ticks", "python ticks", "franky"]
    shares: dict[str, list[float]] = {s: [] for s in sides}
    for r in range(a.rounds):
        order = sides if r % 2 == 0 else sides[::-1]
        for side in order:
            try:
                out = _run(side, a.seconds)
            except Exception as exc:  # (reported; the other sides still run)
                print(f"  round {r + 1} {side:15s} failed: {exc}")
                continue
            shares[side].append(100.0 * out["total"])
            print(f"  round {r + 1} {side:15s} {100 * out['total']:6.2f} % = control "
                  f"{100 * out['control']:5.2f} + user {100 * out['user']:5.2f} + rest "
                  f"{100 * out['rest']:5.2f}  ({out['goals']} goals, last reached: "
                  f"{out['last']}, reflexes: {out.get('reflexes', 0)})",
                  flush=True)  # fmt: skip
    print(f"done, load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    medians = {s: float(np.median(v)) for s, v in shares.items() if v}
    for side, values in shares.items():
        if values:
            ratio = ""
            if "franky" in medians and side != "franky":
                ratio = f"  {medians[side] / medians['franky']:.2f}x franky's"
            print(f"{side:15s} median {medians[side]:6.2f} % ({min(values):.2f}-"
                  f"{max(values):.2f}){ratio}")  # fmt: skip


if __name__ == "__main__":
    main()
