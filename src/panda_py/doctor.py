"""``panda-py-doctor``: is this machine, and the robot at ``--host``, ready for 1 kHz
control? One verdict per item with the fix, as a newcomer needs them (the setup is what
goes wrong most: the realtime kernel and permission, CPU frequency scaling, the network
path, the FCI not active, a robot in a reflex).

    panda-py-doctor                      # this machine only
    panda-py-doctor --host 172.16.0.2    # and the robot

Exit code 0 when nothing blocks control (warnings may remain), 1 when something does,
2 for bad arguments.
"""

from __future__ import annotations

import argparse
import enum
import glob
import ipaddress
import json
import os
import socket
import ssl
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from panda_py import checks, fci
from panda_py.libfranka import (
    Gripper,
    RealtimeConfig,
    Robot,
    RobotMode,
    has_realtime_kernel,
    set_current_thread_to_highest_priority,
)
from panda_py.robots import robot_for_protocol

__all__ = ["Check", "Status", "machine_checks", "main", "robot_checks"]

# Lateness of a 1 kHz loop here [s]: p99 and worst below these is good; a p99 above
# JITTER_FAIL makes every other tick late for the robot's 1 ms budget.
JITTER_OK_P99, JITTER_OK_WORST, JITTER_FAIL_P99 = 100e-6, 500e-6, 500e-6
STATE_SECONDS = 1.0  # [s] of the robot's state stream watched
LATE_PERIOD = 1.5e-3  # [s] a state period above this counts as late
SPIN = 200e-6  # [s] the jitter loop sleeps until this close to a deadline, then spins


class Status(enum.Enum):
    OK = "ok"
    WARN = "warn"
    FAIL = "fail"  # blocks control


@dataclass
class Check:
    """One item: what was found and, unless it is fine, how to fix it."""

    name: str
    status: Status
    found: str
    fix: str = ""


# --- this machine ----------------------------------------------------------------------


def kernel() -> Check:
    if has_realtime_kernel():
        return Check("realtime kernel", Status.OK, "PREEMPT_RT")
    import platform

    return Check(
        "realtime kernel",
        Status.WARN,
        f"not a realtime kernel ({platform.release()})",
        "install a PREEMPT_RT kernel (FCI docs: 'Setting up the real-time kernel'); "
        "without it control works but latency spikes can abort motions",
    )


def realtime_permission() -> Check:
    """Tried on a short-lived thread, so this process keeps its own policy. The thread
    first drops to ``SCHED_OTHER``: a doctor started from a realtime thread inherits its
    policy, and a thread already at FIFO 99 may "switch" to it without any permission, so
    the answer would be the parent's, not this user's."""
    result: list[object] = []

    def attempt() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except (OSError, AttributeError):
            pass  # not on Linux: the attempt below says so
        result.append(set_current_thread_to_highest_priority())

    t = threading.Thread(target=attempt)
    t.start()
    t.join()
    if result and result[0] is not None:
        return Check("realtime permission", Status.OK, "SCHED_FIFO permitted")
    return Check(
        "realtime permission",
        Status.FAIL,
        "SCHED_FIFO not permitted (libfranka's default RealtimeConfig.kEnforce refuses to control)",
        "add your user to a 'realtime' group and put '@realtime - rtprio 99' and "
        "'@realtime - memlock 102400' in /etc/security/limits.conf, then log in "
        "again (FCI docs); or pass RealtimeConfig.kIgnore",
    )


def cpu_governor() -> Check:
    files = sorted(glob.glob("/sys/devices/system/cpu/cpu[0-9]*/cpufreq/scaling_governor"))
    if not files:
        return Check(
            "CPU governor",
            Status.WARN,
            "no CPU frequency scaling found (a VM?)",
            "on the robot PC, set the 'performance' governor",
        )
    governors = set()
    for path in files:
        try:
            with open(path) as f:
                governors.add(f.read().strip())
        except OSError:
            pass
    if governors == {"performance"}:
        return Check("CPU governor", Status.OK, "performance on every core")
    return Check(
        "CPU governor",
        Status.WARN,
        f"{', '.join(sorted(governors))}",
        "sudo cpupower frequency-set -g performance (a slowing CPU misses ticks)",
    )


def isolated_cpus(path: str = "/sys/devices/system/cpu/isolated") -> Check:
    """The cores the kernel keeps free of other work (``isolcpus``): the place for the
    control loop, pinned there with ``Panda(host, cpus=...)``."""
    try:
        with open(path) as f:
            isolated = sorted(checks.cpu_set(f.read()))
    except (OSError, ValueError):
        isolated = []
    if isolated:
        return Check(
            "isolated CPUs",
            Status.OK,
            f"{', '.join(map(str, isolated))}: pin the control loop there with "
            f"Panda(host, cpus={{{isolated[-1]}}})",
        )
    return Check(  # optional: fine without, better with
        "isolated CPUs",
        Status.OK,
        "none (optional: isolcpus=N on the kernel's command line keeps core N free of other "
        "work, then Panda(host, cpus={N}) pins the control loop there)",
    )


def jitter(seconds: float = 2.0) -> Check:
    """Lateness of a 1 kHz loop on absolute deadlines (sleep, then spin) in this thread."""
    period, n = fci.PERIOD, max(1, int(seconds / fci.PERIOD))
    late = np.empty(n)
    clock = time.perf_counter
    deadline = clock()
    for i in range(n):
        deadline += period
        remaining = deadline - clock()
        if remaining > SPIN:
            time.sleep(remaining - SPIN)
        while clock() < deadline:
            pass
        late[i] = clock() - deadline
    p50, p99, worst = np.median(late), np.percentile(late, 99), late.max()
    found = (
        f"1 kHz loop late by {1e6 * p50:.0f} us median, {1e6 * p99:.0f} us p99, "
        f"{1e6 * worst:.0f} us worst over {seconds:g} s"
    )
    if p99 <= JITTER_OK_P99 and worst <= JITTER_OK_WORST:
        return Check("timing jitter", Status.OK, found)
    fix = (
        "a realtime kernel, the 'performance' governor and fewer busy processes beside "
        "the control loop"
    )
    return Check("timing jitter", Status.FAIL if p99 > JITTER_FAIL_P99 else Status.WARN, found, fix)


def machine_checks(jitter_seconds: float = 2.0) -> list[Check]:
    found = [kernel(), realtime_permission(), cpu_governor(), isolated_cpus()]
    if jitter_seconds > 0:
        found.append(jitter(jitter_seconds))
    return found


# --- the robot ---------------------------------------------------------------------------

_MODE_VERDICTS = {
    RobotMode.kIdle: (Status.OK, "idle, ready", ""),
    RobotMode.kMove: (Status.WARN, "moving (another client controls it?)", "stop the other client"),
    RobotMode.kGuiding: (Status.WARN, "in hand guiding", "release the guiding button"),
    RobotMode.kReflex: (
        Status.WARN,
        "in a reflex",
        "panda.recover() or Robot.automatic_error_recovery(), after clearing what caused it",
    ),
    RobotMode.kUserStopped: (Status.FAIL, "user stop pressed", "release the user stop"),
    RobotMode.kAutomaticErrorRecovery: (Status.WARN, "recovering from an error", "wait"),
    RobotMode.kOther: (
        Status.FAIL,
        "brakes locked or not ready",
        "unlock the brakes in Desk (panda_py.Desk(...).unlock())",
    ),
}


def robot_checks(host: str, *, timeout: float = 3.0) -> list[Check]:
    checks: list[Check] = []
    t0 = time.monotonic()
    try:
        robot = Robot(host, RealtimeConfig.kIgnore, timeout=timeout)
    except Exception as exc:  # every failure is a verdict here
        checks.append(
            Check(
                "FCI connection",
                Status.FAIL,
                f"{host}:{fci.COMMAND_PORT}: {exc}",
                "activate FCI in Desk (panda_py.Desk(host, user, password)"
                ".activate_fci()) and check the cable and address (ping "
                f"{host})",
            )
        )
    else:
        with robot:
            checks.extend(_connected(robot, time.monotonic() - t0))
    checks.append(_gripper(host, timeout))
    checks.append(_desk(host, timeout))
    return checks


def _connected(robot: Robot, connect_s: float) -> list[Check]:
    version = robot.server_version()
    spec = robot_for_protocol(version)
    out = [
        Check(
            "FCI connection",
            Status.OK,
            f"protocol v{version} ({spec.name}), connected in {1e3 * connect_s:.0f} ms",
        )
    ]
    ids, times, passed = [], [], []

    def watch(state: object) -> bool:
        ids.append(state.time.to_msec())  # type: ignore[attr-defined]
        times.append(time.perf_counter())
        # counted from the first state on: the states queued before the read began are
        # passed over before it, and are not in the gaps
        passed.append(robot.skipped_states)
        return times[-1] - times[0] < STATE_SECONDS

    try:
        robot.read(watch)
    except Exception as exc:
        out.append(
            Check(
                "state stream",
                Status.FAIL,
                f"no states: {exc}",
                "check the network path (a direct cable, no firewall on UDP)",
            )
        )
        return out
    # a gap in the robot's clock is a state this process passed over (it was late: the
    # read hands the newest) or one that never came (the network, or the robot)
    skipped = passed[-1] - passed[0] if passed else 0
    gaps = np.diff(ids) if len(ids) > 1 else np.zeros(1)
    missing = max(0, int(np.sum(gaps - 1)) - skipped)
    late = int(np.sum(np.diff(times) > LATE_PERIOD)) if len(times) > 1 else 0
    found = (
        f"{len(ids)} states in {STATE_SECONDS:g} s, {missing} missing, {skipped} passed over "
        f"(this process late), {late} periods > 1.5 ms"
    )
    if missing > 0.05 * len(ids):
        out.append(
            Check(
                "state stream",
                Status.FAIL,
                found,
                "a direct cable to the robot, no switch or Wi-Fi in between",
            )
        )
    elif missing or skipped or late > 0.01 * len(ids):
        out.append(Check("state stream", Status.WARN, found, "see the timing items above"))
    else:
        out.append(Check("state stream", Status.OK, found))
    state = robot.read_once()
    status, what, fix = _MODE_VERDICTS.get(state.robot_mode, (Status.WARN, "unknown mode", ""))
    errors = ", ".join(state.current_errors.active) if state.current_errors else ""
    out.append(Check("robot mode", status, what + (f" ({errors})" if errors else ""), fix))
    return out


def _gripper(host: str, timeout: float) -> Check:
    try:
        with Gripper(host) as gripper:
            width = gripper.read_once().width
    except Exception as exc:
        return Check(
            "gripper",
            Status.WARN,
            f"no Franka Hand on {host}:1338 ({exc})",
            "only needed for the hand: check it is mounted and configured in Desk",
        )
    return Check("gripper", Status.OK, f"Franka Hand, {1e3 * width:.1f} mm open")


def _desk(host: str, timeout: float) -> Check:
    context = ssl.create_default_context()
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE  # a robot's Desk has a self-signed certificate
    try:
        with socket.create_connection((host, 443), timeout=timeout) as raw:
            with context.wrap_socket(raw, server_hostname=host) as tls:
                version = tls.version()
    except OSError as exc:
        return Check(
            "Desk",
            Status.WARN,
            f"no HTTPS on {host}:443 ({exc})",
            "only needed to unlock and activate FCI from scripts: check the address",
        )
    return Check("Desk", Status.OK, f"HTTPS answers ({version})")


# --- command line ------------------------------------------------------------------------

_MARKS = {Status.OK: ("✓", "ok"), Status.WARN: ("!", "!!"), Status.FAIL: ("✗", "XX")}


def _host(value: str) -> str:
    try:
        ipaddress.ip_address(value)
        return value
    except ValueError:
        pass
    labels = value.split(".")
    if (
        not value
        or len(value) > 253
        or not all(
            label and len(label) <= 63 and label.replace("-", "").isalnum() for label in labels
        )
    ):
        raise argparse.ArgumentTypeError(f"expected an IP address or host name, got {value!r}")
    return value


def report(checks: Sequence[Check], unicode: bool = True) -> str:
    lines = []
    for c in checks:
        mark = _MARKS[c.status][0 if unicode else 1]
        lines.append(f"{mark} {c.name}: {c.found}")
        if c.status != Status.OK and c.fix:
            lines.append(f"    fix: {c.fix}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="panda-py-doctor", description=__doc__.split("\n\n")[0])
    p.add_argument("--host", type=_host, help="the robot's FCI address (e.g. 172.16.0.2)")
    p.add_argument(
        "--jitter-seconds",
        type=float,
        default=2.0,
        help="how long to time a 1 kHz loop here (0: skip; default %(default)s)",
    )
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    args = p.parse_args(argv)  # exits with 2 on bad arguments
    if not 0.0 <= args.jitter_seconds <= 60.0:
        p.error(f"--jitter-seconds: expected 0..60 s, got {args.jitter_seconds}")
    checks = machine_checks(args.jitter_seconds)
    if args.host:
        checks += robot_checks(args.host)
    if args.json:
        print(json.dumps([{**asdict(c), "status": c.status.value} for c in checks], indent=1))
    else:
        encoding = (getattr(sys.stdout, "encoding", None) or "").lower()
        print(report(checks, unicode=encoding.replace("-", "") == "utf8"))
    return 1 if any(c.status == Status.FAIL for c in checks) else 0


if __name__ == "__main__":
    sys.exit(main())
