"""A libfranka-API client running a torque loop: pylibfranka 0.21.3 (the real libfranka,
protocol v10) or, with ``--library panda_py.libfranka``, our pure-Python libfranka.

For pylibfranka it runs inside the peer venv (``tests/peer_envs.py``) and never imports
panda_py. Connects with ``RealtimeConfig.kIgnore``, starts torque control and answers every
``readOnce`` with the torques of a weak joint PD holding the start pose for ``--duration``
wall seconds, then finishes the motion. Prints the same JSON summary as
``sim_client_fci.py`` (times in milliseconds; the simulated time comes from
``RobotState.time``, which libfranka derives from the state's ``message_id``).

Run: ``<pylibfranka venv>/bin/python benchmarks/sim_client_pylibfranka.py HOST``.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import json
import sys
import time
from typing import Any

import numpy as np

LATE_PERIOD = 1.5e-3  # [s] a state arriving this long after the previous one counts as late


def _summary(values_s: np.ndarray) -> dict[str, float]:
    if values_s.size == 0:
        return {"n": 0}
    ms = values_s * 1e3
    return {
        "n": int(ms.size),
        "median": float(np.median(ms)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
    }


def run(library: str, host: str, duration: float, kp: float, kd: float) -> dict[str, Any]:
    plf: Any = importlib.import_module(library)
    robot = plf.Robot(host, plf.RealtimeConfig.kIgnore)
    q0 = np.array(robot.read_once().q)
    ctrl = robot.start_torque_control()
    t_recv: list[float] = []
    t_send: list[float] = []
    ids: list[int] = []
    clock = time.perf_counter
    aborted = ""
    cpu0 = time.process_time()
    gc.collect()
    gc.disable()
    t_end = clock() + duration
    try:
        while True:
            state, _ = ctrl.readOnce()
            tr = clock()
            tau = kp * (q0 - np.array(state.q)) - kd * np.array(state.dq)
            command = plf.Torques(tau.tolist())
            done = tr >= t_end
            if done:
                command.motion_finished = True
            ctrl.writeOnce(command)
            ts = clock()
            if done:
                break
            t_recv.append(tr)
            t_send.append(ts)
            ids.append(round(state.time.to_sec() * 1000.0))
    except plf.ControlException as exc:
        aborted = str(exc)
    finally:
        gc.enable()
    cpu = time.process_time() - cpu0
    robot.stop()
    tr_a, ts_a, id_a = np.array(t_recv), np.array(t_send), np.array(ids, dtype=np.int64)
    periods = np.diff(tr_a)
    wall = float(tr_a[-1] - tr_a[0]) if tr_a.size > 1 else 0.0
    sim_ms = int(id_a[-1] - id_a[0]) if id_a.size > 1 else 0
    return {
        "client": library,
        "states": int(tr_a.size),
        "wall_s": wall,
        "sim_s": sim_ms / 1000.0,
        "rtf": (sim_ms / 1000.0) / wall if wall > 0 else 0.0,
        "skipped": int(sim_ms + 1 - id_a.size) if id_a.size else 0,
        "periods": {**_summary(periods), "late_share": float(np.mean(periods > LATE_PERIOD))}
        if periods.size
        else {"n": 0},
        "response": _summary(ts_a - tr_a),
        "round_trip": _summary(tr_a[1:] - ts_a[:-1]),
        "client_cpu_s": cpu,
        "final_status": "ABORTED" if aborted else "SUCCESS",
        "aborted": [aborted] if aborted else [],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("host", help="robot address (a loopback address)")
    parser.add_argument(
        "--library", default="pylibfranka", choices=("pylibfranka", "panda_py.libfranka")
    )
    parser.add_argument("--duration", type=float, default=10.0, help="control time [wall s]")
    parser.add_argument("--kp", type=float, default=10.0, help="PD stiffness [Nm/rad]")
    parser.add_argument("--kd", type=float, default=1.0, help="PD damping [Nm s/rad]")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s, got {args.duration}")
    json.dump(run(args.library, args.host, args.duration, args.kp, args.kd), sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
