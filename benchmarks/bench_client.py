"""Time the pure-Python libfranka client against the simulator.

``python benchmarks/bench_client.py overhead [--ticks 5000] [--lockstep] [--repeat N]
[--kinds torque,...]``: per-tick client overhead, from the moment the newest state
datagram has been read to the moment the command datagram has been sent (decode,
RobotState, the callback, filter and rate limiter, encode, send), against a simulator on
the wall clock (a robot's 1 kHz) or in lockstep, for protocol v5 and v10 and every control
type (torques, joint positions and velocities, Cartesian pose and velocities, torques plus
a joint position generator). The target is p50 and p99 under 100 us; on a shared machine
p99 is noisy, so take ``--repeat 3`` or more and read the medians printed at the end.

``python benchmarks/bench_client.py realtime [--seconds 60] [--no-burner]``: a torque
loop against a simulator running on the wall clock (like a robot), beside a process that
burns a CPU; the simulator's main thread and the control loop run under SCHED_FIFO when
permitted. Prints the commands the simulator counted lost and the client's response time
(state read -> command sent) and state period percentiles.
"""

from __future__ import annotations

import argparse
import gc
import os
import subprocess
import sys
import time
from typing import Any

import numpy as np

from panda_py import libfranka as lf
from panda_py.sim import Simulator, free_loopback_host

TARGET_US = 100.0  # per-tick client overhead target, p50 and p99 [us]


def _instrument(robot: lf.Robot, n: int) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Per command sent: the time since the newest state was read (``response``) and the
    time that read happened (``t_read``)."""
    net = robot._conn.net
    response = np.zeros(n + 10)
    t_read = np.zeros(n + 10)
    last = [0.0]
    count = [0]
    clock = time.perf_counter
    receive, send = net.receive_newest, net.send_udp

    def receive_newest(last_id: int) -> bytes:
        data = receive(last_id)
        last[0] = clock()
        return data

    def send_udp(data: Any) -> None:
        send(data)
        i = count[0]
        if i < len(response):
            response[i] = clock() - last[0]
            t_read[i] = last[0]
        count[0] = i + 1

    net.receive_newest = receive_newest  # type: ignore[method-assign]
    net.send_udp = send_udp  # type: ignore[method-assign]
    return response, t_read, count


def _callbacks(kind: str, ticks: int) -> tuple[tuple[Any, ...], dict]:
    """(callbacks, keyword arguments) of ``Robot.control`` for one control type: a short
    motion of joint 1 or along z there and back, smooth up to the acceleration, from where
    the robot's motion generator stands at the first tick (as libfranka's examples)."""
    n = [0]
    start: dict[str, np.ndarray] = {}

    def bump(k: int) -> float:
        """0 -> 1 -> 0 over the run, smooth up to the acceleration (a quintic up and down)."""
        t = min(2.0 * k / ticks, 2.0)
        t = t if t <= 1.0 else 2.0 - t
        return t**3 * (10.0 - 15.0 * t + 6.0 * t * t)

    def torque(s: lf.RobotState, dt: lf.Duration) -> lf.Torques:
        n[0] += 1
        out = lf.Torques(-2.0 * s.dq)  # a damping controller reading the state
        out.motion_finished = n[0] >= ticks
        return out

    def tracking(s: lf.RobotState, dt: lf.Duration) -> lf.Torques:
        # a joint PD controller tracking the motion generator's desired positions
        return lf.Torques(20.0 * (s.q_d - s.q) - 2.0 * s.dq)

    def joint(s: lf.RobotState, dt: lf.Duration) -> lf.JointPositions:
        n[0] += 1
        if n[0] == 1:
            start["q"] = s.q_d
        q = start["q"].copy()
        q[0] += 0.05 * bump(n[0])
        out = lf.JointPositions(q)
        out.motion_finished = n[0] >= ticks
        return out

    def joint_velocity(s: lf.RobotState, dt: lf.Duration) -> lf.JointVelocities:
        n[0] += 1
        dq = np.zeros(7)
        dq[0] = 0.05 * bump(n[0])
        out = lf.JointVelocities(dq)
        out.motion_finished = n[0] >= ticks
        return out

    def cartesian(s: lf.RobotState, dt: lf.Duration) -> lf.CartesianPose:
        n[0] += 1
        if n[0] == 1:
            start["T"] = s.O_T_EE_c
        T = start["T"].copy()
        T[14] += 0.02 * bump(n[0])
        out = lf.CartesianPose(T)
        out.motion_finished = n[0] >= ticks
        return out

    def cartesian_velocity(s: lf.RobotState, dt: lf.Duration) -> lf.CartesianVelocities:
        n[0] += 1
        v = np.zeros(6)
        v[2] = 0.02 * bump(n[0])
        out = lf.CartesianVelocities(v)
        out.motion_finished = n[0] >= ticks
        return out

    table: dict[str, tuple[tuple[Any, ...], dict]] = {
        "torque": ((torque,), {}),
        "joint_position": ((joint,), {"motion": lf.JointPositions}),
        "joint_velocity": ((joint_velocity,), {"motion": lf.JointVelocities}),
        "cartesian_pose": ((cartesian,), {"motion": lf.CartesianPose}),
        "cartesian_velocity": ((cartesian_velocity,), {"motion": lf.CartesianVelocities}),
        "torque+joint_pos": ((tracking, joint), {}),
    }
    return table[kind]


KINDS = (
    "torque",
    "joint_position",
    "joint_velocity",
    "cartesian_pose",
    "cartesian_velocity",
    "torque+joint_pos",
)


def _fifo_simulator(sim: Simulator) -> bool:
    """Give the simulator's tick thread SCHED_FIFO (a robot is a realtime system)."""
    try:
        os.sched_setscheduler(sim._process.pid, os.SCHED_FIFO, os.sched_param(50))
    except (OSError, AttributeError):
        return False
    return True


def overhead(ticks: int, lockstep: bool, repeat: int, kinds: tuple[str, ...]) -> None:
    clock = "lockstep" if lockstep else "1 kHz wall-clock"
    print(f"per-tick client overhead [us] over {ticks} ticks ({clock} simulator), "
          f"{repeat} run(s)")  # fmt: skip
    header = f"{'version':>7} {'control':>18} {'mean':>7} {'p50':>7} {'p99':>7} {'worst':>8}"
    print(header)
    rows: dict[tuple[int, str], list[tuple[float, float, float]]] = {}
    # a FER speaks protocol 5 (systems up to 4.2), an FR3 from 5.x speaks 10
    with (
        Simulator(free_loopback_host(), robot="fer", lockstep=lockstep) as fer,
        Simulator(free_loopback_host(), robot="fr3", lockstep=lockstep) as fr3,
    ):
        for _ in range(repeat):
            for version, sim in ((5, fer), (10, fr3)):
                for kind in kinds:
                    with lf.Robot(sim.host, version=version, robot=sim.config.robot) as robot:
                        callbacks, kw = _callbacks(kind, ticks)
                        response, _, count = _instrument(robot, ticks)
                        gc.collect()
                        try:
                            robot.control(*callbacks, **kw)
                        except lf.ControlException as exc:  # e.g. commands lost under load
                            reason = str(exc).splitlines()[0]
                            print(f"{version:>7} {kind:>18} failed: {reason}")
                            robot.automatic_error_recovery()
                            continue
                    # the last commands are the finish phase (no callback): leave them out
                    us = response[: min(count[0], ticks) - 1] * 1e6
                    p50, p99, worst = np.percentile(us, 50), np.percentile(us, 99), us.max()
                    rows.setdefault((version, kind), []).append((p50, p99, worst))
                    print(f"{version:>7} {kind:>18} {us.mean():7.1f} {p50:7.1f} {p99:7.1f} "
                          f"{worst:8.1f}")  # fmt: skip
    if repeat > 1:
        print(f"median over runs [us] (target: p50 and p99 < {TARGET_US:.0f})")
        print(f"{'version':>7} {'control':>18} {'runs':>4} {'p50':>7} {'p99':>7} {'worst':>8}")
        for (version, kind), values in rows.items():
            p50, p99, worst = np.median(np.array(values), axis=0)
            print(f"{version:>7} {kind:>18} {len(values):>4} {p50:7.1f} {p99:7.1f} "
                  f"{worst:8.1f}")  # fmt: skip


def realtime(seconds: float, burner: bool) -> None:
    ticks = int(seconds * 1000)
    with Simulator(free_loopback_host(), robot="fer", lockstep=False) as sim:
        sim_fifo = _fifo_simulator(sim)
        burn = None
        if burner:
            burn = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        try:
            config = lf.RealtimeConfig.kIgnore
            if lf.set_current_thread_to_highest_priority() is not None:
                config = lf.RealtimeConfig.kEnforce
            with lf.Robot(sim.host, config, version=10, robot="fer") as robot:
                callbacks, kw = _callbacks("torque", ticks)
                response, t_read, count = _instrument(robot, ticks)
                gc.collect()
                gc.freeze()
                gc.disable()
                sim.reset_stats()
                robot.control(*callbacks, **kw)
                gc.enable()
                stats = sim.stats()
        finally:
            if burn is not None:
                burn.kill()
                burn.wait()
        k = min(count[0], ticks) - 1
        response = response[:k] * 1e6
        period = np.diff(t_read[:k]) * 1e3
        print(f"realtime torque loop, {k} ticks, burner={'on' if burner else 'off'}, "
              f"client SCHED_FIFO={config == lf.RealtimeConfig.kEnforce}, "
              f"simulator SCHED_FIFO={sim_fifo}")  # fmt: skip
        print(f"  commands lost (simulator): {stats['commands_lost']} of "
              f"{stats['commands_lost'] + stats['commands_received']}; late ticks "
              f"{stats['late_ticks']}")  # fmt: skip
        print(f"  response (state read -> command sent) [us]: p50 {np.percentile(response, 50):.1f}"
              f" p99 {np.percentile(response, 99):.1f} worst {response.max():.1f}")  # fmt: skip
        print(f"  state period [ms]: p50 {np.percentile(period, 50):.3f} p99 "
              f"{np.percentile(period, 99):.3f} worst {period.max():.3f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    sub = parser.add_subparsers(dest="what", required=True)
    p = sub.add_parser("overhead")
    p.add_argument("--ticks", type=int, default=5000)
    p.add_argument("--lockstep", action="store_true", help="simulated time per command")
    p.add_argument("--repeat", type=int, default=1, help="runs; medians printed at the end")
    p.add_argument("--kinds", default=",".join(KINDS), help="comma-separated control types")
    p = sub.add_parser("realtime")
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--no-burner", action="store_true")
    args = parser.parse_args()
    if args.what == "overhead":
        kinds = tuple(k for k in args.kinds.split(",") if k)
        unknown = [k for k in kinds if k not in KINDS]
        if unknown:
            parser.error(f"--kinds: unknown {unknown}; expected some of {list(KINDS)}")
        overhead(args.ticks, args.lockstep, args.repeat, kinds)
    else:
        realtime(args.seconds, not args.no_burner)


if __name__ == "__main__":
    main()
