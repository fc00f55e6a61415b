"""The panda-python 1.1.1 side of ``bench_panda.py``; runs in the peer's venv (its own
``panda_py``), prints one JSON line. Not part of the package.

    python peer_panda.py calls HOST N
    python peer_panda.py lost HOST SECONDS [normal]
    python peer_panda.py moves HOST
    python peer_panda.py cpu HOST SECONDS
    python peer_panda.py connect HOST N
"""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

import panda_py
from panda_py import controllers


def _per_call(fn, n: int) -> list[float]:
    out = []
    clock = time.perf_counter_ns
    for _ in range(n):
        t0 = clock()
        fn()
        out.append((clock() - t0) * 1e-3)
    return out


def calls(host: str, n: int) -> dict:
    panda = panda_py.Panda(host)
    panda.move_to_start()
    idle_q = _per_call(lambda: panda.q, min(n, 2000))
    ctrl = controllers.CartesianImpedance()
    panda.start_controller(ctrl)
    time.sleep(0.2)
    x, o = panda.get_position(), panda.get_orientation()
    result = {
        "q (idle)": idle_q,
        "q": _per_call(lambda: panda.q, n),
        "get_pose": _per_call(panda.get_pose, n),
        "set_control": _per_call(lambda: ctrl.set_control(x, o), n),
    }
    panda.stop_controller()
    return result


def _policy() -> str:
    names = {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}
    policy = os.sched_getscheduler(0)
    return f"{names.get(policy, policy)} {os.sched_getparam(0).sched_priority}"


def lost(host: str, seconds: float, main_thread: str = "as-left") -> dict:
    """``main_thread``: "as-left", the user's main thread as libfranka leaves it after a
    move (its control() raises the calling thread to SCHED_FIFO 99 and never lowers it
    again); "normal", put back to SCHED_OTHER, as it was before the move."""
    panda = panda_py.Panda(host)
    try:  # the simulator starts there; panda-python's planner fails on a null move
        panda.move_to_start()
    except RuntimeError:
        pass
    left = _policy()
    if main_thread == "normal":
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    ctrl = controllers.CartesianImpedance()
    panda.start_controller(ctrl)
    x, o = panda.get_position(), panda.get_orientation()
    print("STARTED", flush=True)
    end = time.monotonic() + seconds
    busy = 0
    while time.monotonic() < end:  # the user's busy pure-Python main thread
        for _ in range(1000):
            busy += 1
        ctrl.set_control(x, o)
    error = None
    try:
        panda.raise_error()
    except Exception as exc:
        error = str(exc)
    panda.stop_controller()
    return {"error": error, "busy": busy, "main_thread_left": left, "main_thread": _policy()}


def moves(host: str) -> dict:
    from panda_py import constants

    panda = panda_py.Panda(host)
    out = {}
    panda.move_to_start()
    q_goal = constants.JOINT_POSITION_START + np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.3])
    panda.enable_logging(20000)
    panda.move_to_joint_position(q_goal)
    panda.disable_logging()
    out["joint_final"] = float(np.abs(panda.q - q_goal).max())
    for label, offset in (("pose_y", [0, -0.1, 0]), ("pose_xyz", [0.1, 0.1, -0.15])):
        panda.move_to_start()
        pose = panda.get_pose()
        pose[:3, 3] += offset
        panda.enable_logging(20000)
        panda.move_to_pose(pose)
        panda.disable_logging()
        log = panda.get_log()
        p = np.array(log["O_T_EE"])[:, 12:15]
        out[label] = {
            "final": float(np.linalg.norm(panda.get_pose()[:3, 3] - pose[:3, 3])),
            "path": p.tolist(),
            "goal": pose[:3, 3].tolist(),
        }
    return out


def cpu(host: str, seconds: float) -> dict:
    """CPU share of this process (panda-python runs its 1 kHz loop in a thread of it)
    with CartesianImpedance running, the main thread setting its target at 100 Hz."""
    panda = panda_py.Panda(host)
    panda.move_to_start()
    ctrl = controllers.CartesianImpedance(filter_coeff=1.0)
    x0, q0 = panda.get_position(), panda.get_orientation()
    panda.start_controller(ctrl)
    time.sleep(0.5)
    c0, t0 = time.process_time(), time.monotonic()
    while time.monotonic() - t0 < seconds:
        ctrl.set_control(x0, q0)
        time.sleep(0.01)
    share = (time.process_time() - c0) / (time.monotonic() - t0)
    panda.stop_controller()
    return {"cpu": share}


def connect(host: str, n: int) -> dict:
    """Wall time [s] of ``Panda(host)`` (connected and ready), n times, each closed by
    dropping it before the next."""
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        panda = panda_py.Panda(host)
        out.append(time.perf_counter() - t0)
        del panda
    return {"connect": out}


if __name__ == "__main__":
    mode, host = sys.argv[1], sys.argv[2]
    if mode == "cpu":
        print("RESULT " + json.dumps(cpu(host, float(sys.argv[3]))), flush=True)
        sys.exit(0)
    if mode == "calls":
        res = calls(host, int(sys.argv[3]))
    elif mode == "lost":
        res = lost(host, float(sys.argv[3]), *sys.argv[4:5])
    elif mode == "connect":
        res = connect(host, int(sys.argv[3]))
    else:
        res = moves(host)
    print("RESULT " + json.dumps(res), flush=True)
