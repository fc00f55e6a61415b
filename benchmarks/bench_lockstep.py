"""``panda-sim`` in lockstep with our own ``Panda`` as the client: how many times faster
than real time the simulated robot's clock runs while the client's control process drives
it (learning rollouts on the protocol-faithful simulator, and the test suite, wait on it).

Run: ``python benchmarks/bench_lockstep.py [--seconds 10] [--rounds 3]``.

Each round, in fresh processes (the client's control loop as installed, then with its
compiled ticks off, ``PANDA_PY_FAST_TICKS=0``, alternating): a lockstep FER simulator, a
``Panda`` holding ``CartesianImpedance`` for ``--seconds`` of robot time (the user's process
setting its target at 100 Hz of wall time), then the paper's two ``move_to_pose`` paths
back and forth and a ``move_to_joint_position``; then, in a third process,
``panda_py.libfranka``'s own loop as the client (``Robot.control`` with a torque callback
in the user's process) for ``--seconds``. Printed: the real-time factor (robot seconds over
wall seconds) of the controller's part, of the moves' (their planning in the user's
process included, as a user waits for it) and of libfranka's loop, and the simulator's
CPU time per tick [us] in each. The machine is a noisy 2-core VM: run it more than once.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np


def _cpu(pid: int) -> float:
    """The CPU time [s] process ``pid`` has used (Linux's /proc; NaN elsewhere)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _libfranka(seconds: float) -> dict[str, float]:
    """One round of ``panda_py.libfranka``'s loop as the client: its factor and the
    simulator's CPU per tick [us] (the first 200 ticks, the loop's start, not counted)."""
    from panda_py import libfranka as lf
    from panda_py.sim import Simulator, free_loopback_host

    n = int(seconds * 1000)
    marks: list[tuple[float, float]] = []
    with Simulator(free_loopback_host(), robot="fer", lockstep=True) as sim:
        pid = sim._process.pid
        with lf.Robot(sim.host) as robot:
            ticks = 0

            def torque(state: lf.RobotState, dt: lf.Duration) -> lf.Torques:
                nonlocal ticks
                ticks += 1
                if ticks in (200, 200 + n):
                    marks.append((time.monotonic(), _cpu(pid)))
                hold = lf.Torques(np.zeros(7))
                return lf.motion_finished(hold) if ticks >= 200 + n else hold

            robot.control(torque)
    (t0, c0), (t1, c1) = marks
    return {"libfranka": seconds / (t1 - t0), "libfranka_sim_us": 1e3 * (c1 - c0) / seconds}


def _client(seconds: float) -> dict[str, float]:
    """One round in this process: the factors of the controller's and the moves' part,
    and the simulator's CPU per tick [us] in the controller's."""
    import panda_py
    from panda_py import constants, controllers
    from panda_py.sim import Simulator, free_loopback_host

    with Simulator(free_loopback_host(), robot="fer", lockstep=True) as sim:
        with panda_py.Panda(sim.host) as panda:
            panda.move_to_start()
            ctrl = controllers.CartesianImpedance(filter_coeff=1.0)
            x0, q0 = panda.get_position(), panda.get_orientation()
            panda.start_controller(ctrl)
            t0, c0 = time.monotonic(), _cpu(sim._process.pid)
            while ctrl.get_time() < seconds:
                ctrl.set_control(x0, q0)
                time.sleep(0.01)
            wall = time.monotonic() - t0
            robot = ctrl.get_time()
            sim_us = 1e3 * (_cpu(sim._process.pid) - c0) / robot
            panda.stop_controller()
            T0 = panda_py.fk(constants.JOINT_POSITION_START)
            T0[1, 3] = 0.25
            T1 = T0.copy()
            T1[1, 3] = -0.25
            panda.move_to_pose(T0)
            s0, t0 = panda.get_state().time.to_sec(), time.monotonic()
            ok = panda.move_to_pose(T1) and panda.move_to_pose(T0)
            q = panda.q.copy()
            q[0] += 0.4
            ok = panda.move_to_joint_position(q) and ok
            moves_wall = time.monotonic() - t0
            moves_robot = panda.get_state().time.to_sec() - s0
    return {"controller": robot / wall, "moves": moves_robot / moves_wall, "ok": float(ok),
            "sim_us": sim_us}  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--client", choices=("panda", "libfranka"), help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.client:
        run = _client if a.client == "panda" else _libfranka
        print("RESULT " + json.dumps(run(a.seconds)), flush=True)
        return
    print(f"panda-sim lockstep with a Panda client, {a.rounds} rounds; CartesianImpedance "
          f"for {a.seconds:g} s of robot time, then three moves; libfranka's loop")  # fmt: skip
    rows: dict[str, list[dict[str, float]]] = {"compiled ticks": [], "Python ticks": []}
    lf_rows: list[dict[str, float]] = []

    def client(kind: str, fast: str) -> dict[str, float]:
        out = subprocess.run(
            [sys.executable, __file__, "--client", kind, "--seconds", str(a.seconds)],
            env=dict(os.environ, PANDA_PY_FAST_TICKS=fast), capture_output=True, text=True,
            check=True, timeout=1200,
        ).stdout  # fmt: skip
        result: dict[str, float] = json.loads(out.split("RESULT ", 1)[1])
        return result

    for r in range(a.rounds):
        for label, fast in (("compiled ticks", "1"), ("Python ticks", "0")):
            res = client("panda", fast)
            rows[label].append(res)
            ok = bool(res["ok"])
            print(f"  round {r + 1}, {label:<14}: controller {res['controller']:5.2f}x real "
                  f"time (simulator {res['sim_us']:5.1f} us CPU a tick), moves "
                  f"{res['moves']:5.2f}x (all succeeded: {ok})")  # fmt: skip
        res = client("libfranka", "1")
        lf_rows.append(res)
        print(f"  round {r + 1}, {'libfranka loop':<14}: {res['libfranka']:5.2f}x real time "
              f"(simulator {res['libfranka_sim_us']:5.1f} us CPU a tick)")  # fmt: skip
    for label, results in rows.items():
        c = [x["controller"] for x in results]
        m = [x["moves"] for x in results]
        print(f"  {label:<14}: controller median {np.median(c):.2f}x "
              f"({min(c):.2f}-{max(c):.2f}), moves median {np.median(m):.2f}x "
              f"({min(m):.2f}-{max(m):.2f}); target >= 10x")  # fmt: skip
    f = [x["libfranka"] for x in lf_rows]
    print(f"  {'libfranka loop':<14}: median {np.median(f):.2f}x ({min(f):.2f}-{max(f):.2f})")


if __name__ == "__main__":
    main()
