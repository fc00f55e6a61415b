"""The franka-rs 0.4.0 side of ``bench_panda.py cpu``; runs in the peer's venv (its
``franka`` package, the 1 kHz loop on a Rust thread), prints one JSON line. Not part of the
package.

    python peer_franka_rs.py cpu HOST SECONDS

What it runs: ``Robot.cartesian_targets()`` with its defaults, ``backend="impedance"``:
the crate's own Cartesian impedance law sending joint torques (750 N/m, 15 Nm/rad), its
target the pose the arm has when the loop starts, the main thread writing that same target
(position and quaternion, ``move_to``) every 10 ms. ``realtime="ignore"``: its default,
"enforce", refuses a kernel without PREEMPT_RT ("Running kernel does not have realtime
capabilities"), as libfranka does. Even so, ``Robot()`` raises the calling thread to
SCHED_FIFO 99 where it may (root), and the loop's threads inherit it: the result lists
each thread's policy.

It speaks FCI v10 (FR3) and v5 (FER): it asks for v10 first and reconnects with v5 when
the robot answers that it speaks another version.
"""

from __future__ import annotations

import json
import os
import sys
import time

import franka

CONTROLLER = (
    "Robot.cartesian_targets(backend='impedance'), defaults: the crate's Cartesian "
    "impedance torques (750 N/m, 15 Nm/rad), holding its start pose, move_to(same 7-vector "
    "target) at 100 Hz"
)
_POLICIES = {0: "SCHED_OTHER", 1: "SCHED_FIFO", 2: "SCHED_RR"}


def _stat(path: str) -> list[str]:
    """The fields of a /proc stat file after the command name."""
    with open(path) as f:
        return f.read().rsplit(")", 1)[1].split()


def _threads() -> list[str]:
    """Each thread of this process: its name and scheduling policy (rt priority)."""
    out = []
    for tid in sorted(os.listdir("/proc/self/task"), key=int):
        with open(f"/proc/self/task/{tid}/comm") as f:
            name = f.read().strip()
        fields = _stat(f"/proc/self/task/{tid}/stat")
        policy = _POLICIES.get(int(fields[38]), fields[38])
        out.append(f"{name} {policy} {fields[37]}")
    return out


def _children() -> int:
    """How many processes this one has started (their CPU would not be counted)."""
    me, n = str(os.getpid()), 0
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            n += _stat(f"/proc/{pid}/stat")[1] == me
        except OSError:
            continue
    return n


def cpu(host: str, seconds: float) -> dict:
    """CPU share of this process (all threads) over a window of ``seconds`` with the
    target loop holding the start pose."""
    robot = franka.Robot(host, realtime="ignore")
    result: dict = {"controller": CONTROLLER, "fci_version": robot.fci_version,
                    "server_version": robot.server_version}  # fmt: skip
    with robot.cartesian_targets() as arm:
        target = arm.target()
        time.sleep(0.5)
        print("STARTED", flush=True)
        s0 = arm.state()
        c0, t0 = time.process_time(), time.monotonic()  # (all threads of the process)
        while time.monotonic() - t0 < seconds:
            arm.move_to(target)
            time.sleep(0.01)
        share = (time.process_time() - c0) / (time.monotonic() - t0)
        s1 = arm.state()
        result.update(
            cpu=share,
            running=arm.running,
            robot_time=s1.time - s0.time,  # [s] of robot time the loop saw in the window
            success_rate=s1.control_command_success_rate,
            position_error=float(abs(s1.O_T_EE[:3, 3] - target[:3]).max()),  # [m]
            threads=_threads(),
            children=_children(),
        )
    return result


if __name__ == "__main__":
    mode, host = sys.argv[1], sys.argv[2]
    if mode != "cpu":
        raise SystemExit(f"mode: expected 'cpu', got {mode!r}")
    print("RESULT " + json.dumps(cpu(host, float(sys.argv[3]))), flush=True)
