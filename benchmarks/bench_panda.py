"""``panda_py.Panda`` against panda-python 1.1.1's ``Panda`` (protocol 5, in its own venv)
on the same simulator, in the same run. Run by hand:

    python benchmarks/bench_panda.py calls   [--n 20000]        # per call: q, get_pose, set_control
    python benchmarks/bench_panda.py latency [--seconds 10]     # set_control -> command
    python benchmarks/bench_panda.py lost    [--seconds 60] [--runs 3]  # lost commands under load
    python benchmarks/bench_panda.py moves                      # move accuracy
    python benchmarks/bench_panda.py cpu     [--seconds 10]     # loop CPU, laws' cost/tick
    python benchmarks/bench_panda.py start   [--n 20]           # Simulator start, Panda connect
    python benchmarks/bench_panda.py all

``lost``: a controller runs on a simulator on the wall clock (SCHED_FIFO when permitted),
while the user's main thread runs a busy pure-Python loop and a CPU burner runs beside;
the simulator counts the commands that did not arrive. For ours also with a user-written
Python ``step()``, and with the control loop and the simulator pinned to one core
(``Panda(host, cpus=...)``, ``Simulator(cpus=...)``: a VM's host that stalls one of its
cores then stalls both, as the peer's do when its busy main thread holds the other core at
realtime priority); panda-python's twice: with its main thread as libfranka leaves it after
a move (SCHED_FIFO 99: the busy loop then holds a core at realtime priority, and the
simulator and the control loop share the other), and put back to SCHED_OTHER, as ours is.
Each figure prints median, p99 and worst case and ours/theirs.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

import panda_py
from panda_py import constants, controllers, libfranka
from panda_py.motion.online import OnlineLimits
from panda_py.robots.params import get_robot
from panda_py.sim import Simulator, free_loopback_host

sys.path.append(str(Path(__file__).resolve().parents[1] / "tests"))
from peer_envs import PeerUnavailable, peer_environ, peer_python

PEER_SCRIPT = Path(__file__).resolve().parent / "peer_panda.py"


def _stats(values: Any) -> tuple[float, float, float]:
    a = np.asarray(values, dtype=float)
    return float(np.median(a)), float(np.percentile(a, 99)), float(a.max())


def _row(label: str, ours: Any, theirs: Any | None, unit: str = "us", peer: str = "peer") -> None:
    m, p, w = _stats(ours)
    line = f"  {label:<22} ours  median {m:9.2f} p99 {p:9.2f} worst {w:10.2f} {unit}"
    if theirs is not None:
        tm, tp, tw = _stats(theirs)
        line += (f"\n  {'':<22} {peer:<5} median {tm:9.2f} p99 {tp:9.2f} worst {tw:10.2f} {unit}"
                 f"   ratio (median) {m / tm:5.2f}x, (p99) {p / tp:5.2f}x")  # fmt: skip
    print(line)


def _fifo(pid: int) -> bool:
    try:
        os.sched_setscheduler(pid, os.SCHED_FIFO, os.sched_param(50))
    except (OSError, AttributeError):
        return False
    return True


def _policy() -> str:
    """The calling thread's scheduling policy and priority."""
    names = {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}
    policy = os.sched_getscheduler(0)
    return f"{names.get(policy, policy)} {os.sched_getparam(0).sched_priority}"


def _peer(mode: str, host: str, *args: str, on_start: Any = None) -> dict:
    python = peer_python("panda-python")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    proc = subprocess.Popen([str(python), str(PEER_SCRIPT), mode, host, *args],
                            stdout=subprocess.PIPE, text=True, env=env)  # fmt: skip
    assert proc.stdout is not None
    result: dict = {}
    for line in proc.stdout:
        if line.startswith("STARTED") and on_start is not None:
            on_start()
        if line.startswith("RESULT "):
            result = json.loads(line[7:])
    proc.wait()
    return result


def _per_call(fn: Any, n: int) -> list[float]:
    out = []
    clock = time.perf_counter_ns
    for _ in range(n):
        t0 = clock()
        fn()
        out.append((clock() - t0) * 1e-3)
    return out


def calls(n: int) -> None:
    print(f"per call [us], {n} calls, realtime simulator (FER, protocol 5)")
    with Simulator(free_loopback_host(), robot="fer", versions=(5,)) as sim:
        _fifo(sim._process.pid)
        with panda_py.Panda(sim.host) as panda:
            panda.move_to_start()
            ours = {"q (idle)": _per_call(lambda: panda.q, min(n, 2000))}
            ctrl = controllers.CartesianImpedance()
            panda.start_controller(ctrl)
            time.sleep(0.2)
            x, o = panda.get_position(), panda.get_orientation()
            ours["q"] = _per_call(lambda: panda.q, n)
            ours["get_pose"] = _per_call(panda.get_pose, n)
            ours["set_control"] = _per_call(lambda: ctrl.set_control(x, o), n)
            panda.stop_controller()
        theirs = _peer("calls", sim.host, str(n))
    for key, values in ours.items():
        _row(key, values, theirs.get(key))


class Stamp(controllers.TorqueController):
    """Holds the arm; histograms the time from a ``set_signals(stamp=...)`` in the user's
    process to the step that computes the command carrying it (bins of 25 us)."""

    signals: ClassVar[dict[str, int]] = {"stamp": 1}
    outputs: ClassVar[dict[str, int]] = {"hist": 200}

    def start(self, state: Any, model: Any) -> None:
        self.q0 = state.q.copy()
        self.last = 0.0
        self.hist = np.zeros(200)

    def step(self, state: Any, model: Any) -> Any:
        stamp = self.signal("stamp")[0]
        if stamp != self.last:
            self.last = stamp
            k = min(int((time.perf_counter() - stamp) / 25e-6), 199)
            self.hist[k] += 1
            self.set_output("hist", self.hist)
        return 400.0 * (self.q0 - state.q) - 20.0 * state.dq


def latency(seconds: float) -> None:
    print(f"input-to-command latency, {seconds:.0f} s, realtime simulator, stamps at ~2 kHz")
    with Simulator(free_loopback_host(), robot="fer") as sim:
        _fifo(sim._process.pid)
        with panda_py.Panda(sim.host) as panda:
            ctrl = Stamp()
            panda.start_controller(ctrl)
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                ctrl.set_signals(stamp=time.perf_counter())
                time.sleep(0.0005)
            hist = ctrl.get_output("hist")
            panda.stop_controller()
    edges = (np.arange(200) + 1) * 25.0
    c = np.cumsum(hist) / max(1.0, hist.sum())
    p50, p99 = edges[np.searchsorted(c, 0.5)], edges[np.searchsorted(c, 0.99)]
    worst = edges[np.flatnonzero(hist)[-1]] if hist.any() else float("nan")
    print(f"  samples {int(hist.sum())}: median <= {p50:.0f} us, p99 <= {p99:.0f} us, "
          f"worst <= {worst:.0f} us (target p99 <= 1000 us)")  # fmt: skip


class Hold(controllers.TorqueController):
    """A user-written joint spring, run by the control process at 1 kHz."""

    def start(self, state: Any, model: Any) -> None:
        self.q0 = state.q.copy()

    def step(self, state: Any, model: Any) -> Any:
        return 300.0 * (self.q0 - state.q) - 15.0 * state.dq


def _lost_run(sim: Simulator, seconds: float, controller: Any, cpus: Any = None) -> dict:
    with panda_py.Panda(sim.host, cpus=cpus) as panda:
        panda.move_to_start()
        ctrl = controller()
        panda.start_controller(ctrl)
        set_control = getattr(ctrl, "set_control", None)
        x, o = panda.get_position(), panda.get_orientation()
        sim.reset_stats()
        end = time.monotonic() + seconds
        busy = 0
        while time.monotonic() < end:  # the user's busy pure-Python main thread
            for _ in range(1000):
                busy += 1
            if set_control is not None:
                set_control(x, o)
        stats = sim.stats()
        error = None
        try:
            panda.raise_error()
        except Exception as exc:
            error = str(exc)
        panda.stop_controller()
    return {**stats, "error": error, "main_thread": _policy()}


def lost(seconds: float, runs: int = 1) -> None:
    print(f"lost commands over {seconds:.0f} s: controller running, busy user main thread, "
          "CPU burner beside, realtime simulator")  # fmt: skip
    print("  panda-python's main thread runs its moves, and libfranka's control() leaves the "
          "calling thread at SCHED_FIFO 99:\n  its busy main thread then holds a core at "
          "realtime priority. 'normal' puts it back to SCHED_OTHER after move_to_start,\n"
          "  as ours is (our moves run in the control process, the user's threads keep their "
          "scheduling).")  # fmt: skip
    counts: dict[str, list[int]] = {}
    burn = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        for run in range(runs):
            rows = []
            core = (max(os.sched_getaffinity(0)),)
            for label, ctrl, cpus in (
                ("CartesianImpedance", controllers.CartesianImpedance, None),
                ("user step() (Python)", Hold, None),
                (f"CartesianImpedance, cpus={core}", controllers.CartesianImpedance, core),
            ):  # fmt: skip
                with Simulator(free_loopback_host(), robot="fer", versions=(5,),
                               cpus=cpus) as sim:  # fmt: skip
                    _fifo(sim._process.pid)
                    rows.append((f"ours, {label}", _lost_run(sim, seconds, ctrl, cpus)))
            for main_thread in ("as-left", "normal"):
                with Simulator(free_loopback_host(), robot="fer", versions=(5,)) as sim:
                    _fifo(sim._process.pid)
                    theirs = _peer("lost", sim.host, str(seconds), main_thread,
                                   on_start=sim.reset_stats)  # fmt: skip
                    label = f"panda-python, main thread {main_thread}"
                    rows.append((label, {**sim.stats(), **theirs}))
            print(f" run {run + 1} of {runs}")
            for label, st in rows:
                total = st["commands_lost"] + st["commands_received"]
                counts.setdefault(label, []).append(st["commands_lost"])
                thread = st["main_thread"]
                print(f"  {label:<40} lost {st['commands_lost']:6d} of {total:7d}; late ticks "
                      f"{st['late_ticks']:3d}; user's main thread {thread}; "
                      f"error: {st.get('error')}")  # fmt: skip
    finally:
        burn.kill()
        burn.wait()
    if runs > 1:
        print(" lost commands per run:")
        for label, values in counts.items():
            print(f"  {label:<40} {values}")


def _deviation(path: np.ndarray, goal: np.ndarray) -> float:
    a, b = path[0], goal
    d = np.linalg.norm(np.cross(path - a, b - a), axis=1) / np.linalg.norm(b - a)
    return float(d.max())


def moves() -> None:
    print("move accuracy on the same targets (lockstep simulator, FER, protocol 5)")
    with Simulator(free_loopback_host(), robot="fer", versions=(5,), lockstep=True) as sim:
        with panda_py.Panda(sim.host) as panda:
            ours: dict[str, Any] = {}
            panda.move_to_start()
            q_goal = constants.JOINT_POSITION_START + np.array(
                [0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.3]
            )
            panda.move_to_joint_position(q_goal)
            ours["joint_final"] = float(np.abs(panda.q - q_goal).max())
            for label, offset in (("pose_y", [0, -0.1, 0]), ("pose_xyz", [0.1, 0.1, -0.15])):
                panda.move_to_start()
                pose = panda.get_pose()
                pose[:3, 3] += offset
                panda.enable_logging(20000)
                panda.move_to_pose(pose)
                panda.disable_logging()
                p = np.array(panda.get_log()["O_T_EE"])[:, 12:15]
                ours[label] = {
                    "final": float(np.linalg.norm(panda.get_pose()[:3, 3] - pose[:3, 3])),
                    "deviation": _deviation(p, pose[:3, 3]),
                }
        theirs = _peer("moves", sim.host)
    print(f"  move_to_joint_position final error [rad]: ours {ours['joint_final']:.2e}, "
          f"panda-python {theirs['joint_final']:.2e}")  # fmt: skip
    for label in ("pose_y", "pose_xyz"):
        t = theirs[label]
        dev = _deviation(np.array(t["path"]), np.array(t["goal"]))
        print(f"  move_to_pose {label:<9} final error [m]: ours {ours[label]['final']:.2e}, "
              f"panda-python {t['final']:.2e}; largest deviation from the line [m]: "
              f"ours {ours[label]['deviation']:.2e}, panda-python {dev:.2e}")  # fmt: skip


def _cpu_seconds(pid: int) -> float:
    """User plus system CPU time of process ``pid`` so far [s] (Linux /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _law_costs(n: int) -> dict[str, list[float]]:
    """Per-call cost [us] of the laws' tick and step on a recorded state, in this process,
    on the state type the loop hands them (TickState) and a controller fed through a
    signal slot, as in the control process."""
    from panda_py.controllers.model import ControlModel
    from panda_py.controllers.moves import JointMove, PoseMove
    from panda_py.controllers.plans import JointPlan, PosePlan
    from panda_py.libfranka.state import TickState
    from panda_py.rt.shm import SharedBlock

    with Simulator(free_loopback_host(), robot="fr3", lockstep=True) as sim:
        with libfranka.Robot(sim.host) as robot:
            state = robot.read_once()
    model = ControlModel("fr3")

    def fresh() -> Any:  # a new state each tick, as the loop has
        return robot.decode_state(state.raw, TickState)

    ctrl = controllers.CartesianImpedance(filter_coeff=1.0)
    ctrl.start(fresh(), model)
    block, fd = SharedBlock.create()
    os.close(fd)
    ctrl.open_slot(block)
    k = 2000
    p = np.tile(np.asarray(state.O_T_EE)[12:15], (k, 1))
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
    pose = PoseMove(PosePlan(p, quat, np.zeros((k, 6)), np.zeros((k, 6)), np.asarray(state.q),
                             np.diag([600.0] * 3 + [30.0] * 3), 1.0, 10.0, 0.01, 0.01, 0.05,
                             OnlineLimits.cartesian(get_robot('fer'), 1.0)))  # fmt: skip
    joint = JointMove(JointPlan(np.tile(np.asarray(state.q), (k, 1)), np.zeros((k, 7)),
                                np.zeros((k, 7)), np.full(7, 600.0), np.full(7, 50.0), 0.01,
                                0.01, OnlineLimits.joints(get_robot('fer'), 1.0)))  # fmt: skip
    pose.t = joint.t = 0.5
    pose.dt = joint.dt = 1e-3
    out = {}
    for label, law in (("CartesianImpedance", ctrl), ("move_to_pose", pose),
                       ("move_to_joint_position", joint)):  # fmt: skip

        def tick(law: Any = law) -> None:
            law.tick(0.0)  # (dt 0: a move stays at its sample)
            law.step(fresh(), model)

        for _ in range(300):
            tick()
        out[label] = _per_call(tick, n)
    return out


def _process_tree(root: int, exclude: set[int]) -> set[int]:
    """``root`` and every process under it (Linux /proc), less the subtrees of ``exclude``."""
    children: dict[int, list[int]] = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):  # (it ended meanwhile)
                continue
            children.setdefault(ppid, []).append(int(name))
    tree, todo = set(), [root]
    while todo:
        pid = todo.pop()
        if pid not in exclude:
            tree.add(pid)
            todo.extend(children.get(pid, ()))
    return tree


def _cpu_clock(pid: int) -> float:
    """CPU time of process ``pid``, all its threads, so far [s], to the nanosecond: its
    CLOCK_PROCESS_CPUTIME_ID (what ``time.process_time`` reads for this process), whose id
    is glibc's clock_getcpuclockid(3), MAKE_PROCESS_CPUCLOCK(pid, CPUCLOCK_SCHED) of
    Linux's include/linux/posix-timers.h; /proc's 10 ms ticks where that fails."""
    try:
        return time.clock_gettime(((~pid) << 3) | 2)
    except OSError:
        return _cpu_seconds(pid)


def _tree_cpu(pids: set[int]) -> dict[int, float]:
    out = {}
    for pid in pids:
        try:
            out[pid] = _cpu_clock(pid)
        except OSError:  # (it ended meanwhile)
            continue
    return out


STOP_TIMEOUT = 10.0  # [s] for stop_controller, measured in tens of ms when it works


def _stop(panda: Any, control: int) -> str | None:
    """``panda.stop_controller()``; where it has not returned within STOP_TIMEOUT, the
    control process is killed (the Panda then closes as after a crash) and what happened
    is returned. Seen on this machine under load: a stop request that arrives while a
    state is already queued leaves the loop alternating between rt/child.py's
    _await_state (which returns first for a readable state) and rt/_tick.py's _wait
    (which returns first for a readable request): neither takes anything, no command is
    sent, the control process spins at its realtime priority and the call never returns."""
    failed: list[BaseException] = []

    def stop() -> None:
        try:
            panda.stop_controller()
        except Exception as exc:  # (reported below: the measurement is already taken)
            failed.append(exc)

    thread = threading.Thread(target=stop, daemon=True)
    thread.start()
    thread.join(STOP_TIMEOUT)
    if not thread.is_alive():
        return f"stop_controller raised {failed[0]!r}" if failed else None
    cpu0 = _cpu_clock(control)
    time.sleep(1.0)
    spin = _cpu_clock(control) - cpu0
    os.kill(control, signal.SIGKILL)
    thread.join(5.0)
    return (f"stop_controller had not returned after {STOP_TIMEOUT:g} s, the control "
            f"process spinning ({100 * spin:.0f} % of a core): killed")  # fmt: skip


def _our_cpu(sim: Any, seconds: float) -> dict[str, Any]:
    """CPU shares [cores] with CartesianImpedance held at the start pose, the user's
    process setting its target at 100 Hz (as the peers' main threads do), over one window:
    as a user sees it, the whole tree of the user's process (this one) less the simulator's
    process, which a user with a robot does not have: the control process, this process
    (all its threads) and the rest (the warm server the control process was forked from,
    multiprocessing's resource tracker). The simulator's own share is returned too, to
    show it is apart."""
    with panda_py.Panda(sim.host) as panda:
        panda.move_to_start()
        ctrl = controllers.CartesianImpedance(filter_coeff=1.0)
        x0, q0 = panda.get_position(), panda.get_orientation()
        panda.start_controller(ctrl)
        control, me, sim_pid = panda._proc.proc.pid, os.getpid(), sim._process.pid
        time.sleep(0.5)
        rest = _process_tree(me, exclude={sim_pid}) - {me, control}
        sim.reset_stats()
        c0, u0, r0 = _cpu_clock(control), time.process_time(), _tree_cpu(rest)
        s0, t0 = _cpu_clock(sim_pid), time.monotonic()
        while time.monotonic() - t0 < seconds:
            ctrl.set_control(x0, q0)
            time.sleep(0.01)
        wall = time.monotonic() - t0
        c1, u1, r1 = _cpu_clock(control), time.process_time(), _tree_cpu(rest)
        s1 = _cpu_clock(sim_pid)
        stats = sim.stats()
        error = None
        try:  # a loop that ended in the window (a reflex under load) measured less than it
            panda.raise_error()
        except Exception as exc:
            error = str(exc)
        stuck = _stop(panda, control)
    if stuck is not None or error is not None:  # the robot is left in a reflex
        with libfranka.Robot(sim.host) as robot:
            robot.automatic_error_recovery()
    out: dict[str, Any] = {
        "control": (c1 - c0) / wall,
        "user": (u1 - u0) / wall,
        "rest": sum(r1[p] - r0[p] for p in r1.keys() & r0.keys()) / wall,
        "rest_n": len(rest),
        "simulator": (s1 - s0) / wall,
        "received": stats["commands_received"] / wall,
        "lost": stats["commands_lost"],
        "stuck": stuck,
        "error": error,
    }
    out["total"] = out["control"] + out["user"] + out["rest"]
    return out


def _franka_rs(host: str, seconds: float) -> dict:
    """franka-rs 0.4.0's process (benchmarks/peer_franka_rs.py, in its own venv): its
    ``RESULT``, or ``{"error": why}``."""
    script = Path(__file__).resolve().parent / "peer_franka_rs.py"
    try:
        python = peer_python("franka-rs")
    except PeerUnavailable as exc:
        return {"error": str(exc)}
    try:
        proc = subprocess.run([str(python), str(script), "cpu", host, str(seconds)],
                              capture_output=True, text=True, env=peer_environ(),
                              timeout=seconds + 120)  # fmt: skip
    except subprocess.TimeoutExpired as exc:
        return {"error": f"no answer within {exc.timeout:g} s"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    tail = (proc.stderr.strip().splitlines() or ["(nothing on stderr)"])[-1]
    return {"error": f"exit code {proc.returncode}: {tail}"}


def _load() -> str:
    """The machine's load averages over 1, 5 and 15 minutes."""
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def _spread(label: str, values: list[float], unit: str = "%") -> None:
    a = np.asarray(values, dtype=float)
    scale = 100.0 if unit == "%" else 1.0
    med, lo, hi = (f"{scale * v:.2f}" for v in (np.median(a), a.min(), a.max()))
    print(f"  {label:<34} median {med} {unit}, range {lo}-{hi} {unit} over {len(a)} rounds")


def cpu(seconds: float, n: int, rounds: int = 3) -> None:
    """The control loop's CPU share with CartesianImpedance running as a user sees it,
    ours (control process plus the user's process) against panda-python's process and
    franka-rs 0.4.0's process, on the same (realtime) simulated FER, v5, unpinned, in
    rounds (this machine's load drifts over a minute: each round's three sides are
    measured back to back), and the laws' cost per tick."""
    print(f"control loop CPU with CartesianImpedance, {rounds} rounds of {seconds:g} s each "
          "side, realtime simulator (FER, v5), unpinned; shares of one core")  # fmt: skip
    print(f"  load average: {_load()} (2 cores)")
    rows: dict[str, list[float]] = {}
    with Simulator(free_loopback_host(), robot="fer", versions=(5,)) as sim:
        for r in range(rounds):
            ours = _our_cpu(sim, seconds)
            sim.reset_stats()  # (the peers' whole runs: a reflex shows as lost commands)
            theirs = _peer("cpu", sim.host, str(seconds))["cpu"]
            theirs_lost = sim.stats()["commands_lost"]
            sim.reset_stats()
            rs = _franka_rs(sim.host, seconds)
            rs_lost = sim.stats()["commands_lost"]
            print(f"  round {r + 1}: ours {100 * ours['total']:5.2f} % = control process "
                  f"{100 * ours['control']:5.2f} % + user's process {100 * ours['user']:4.2f} "
                  f"% + the rest of its tree ({ours['rest_n']} processes) "
                  f"{100 * ours['rest']:4.2f} %;\n"
                  f"    (not counted: the simulator's process {100 * ours['simulator']:5.1f} %; "
                  f"it received {ours['received']:.0f} commands/s, lost {ours['lost']})\n"
                  f"    panda-python (its process) {100 * theirs:5.2f} % (its run lost "
                  f"{theirs_lost} commands), ours / panda-python "
                  f"{ours['total'] / theirs:.2f}x")  # fmt: skip
            if ours["stuck"]:
                print(f"    after ours' window: {ours['stuck']}")
            if ours["error"]:
                print(f"    ours' loop ended in the window, round left out: {ours['error']}")
            else:
                for key in ("total", "control", "user", "rest"):
                    rows.setdefault(f"ours, {key}", []).append(ours[key])
                rows.setdefault("panda-python", []).append(theirs)
                rows.setdefault("ours / panda-python", []).append(ours["total"] / theirs)
            if "cpu" in rs and not rs["running"]:
                rs["error"] = "its loop had ended at the window's end"
            if "cpu" in rs and rs["running"]:
                if not ours["error"]:
                    rows.setdefault("franka-rs", []).append(rs["cpu"])
                    rows.setdefault("ours / franka-rs", []).append(ours["total"] / rs["cpu"])
                print(f"    franka-rs (its process, {len(rs['threads'])} threads, "
                      f"FCI v{rs['fci_version']}) {100 * rs['cpu']:5.2f} %, ours / franka-rs "
                      f"{ours['total'] / rs['cpu']:.2f}x; its loop saw {rs['robot_time']:.3f} s "
                      f"of robot time, success rate {rs['success_rate']:.3f} (its run lost "
                      f"{rs_lost} commands)")  # fmt: skip
            else:
                print(f"    franka-rs: no result, left out: {rs['error']}")
    if rs.get("controller"):
        print(f"  franka-rs ran: {rs['controller']}; its threads: {', '.join(rs['threads'])}")
    print(f"  over the rounds measured whole (load average now: {_load()}):")
    for label, values in rows.items():
        _spread(label, values, "x" if "/" in label else "%")
    print("  target: ours / panda-python <= 1.0x")
    print(f"the laws' step per tick, in process, {n} calls [us]")
    for label, values in _law_costs(n).items():
        med, p99, worst = _stats(values)
        print(f"  {label:<24} median {med:6.1f}  p99 {p99:6.1f}  worst {worst:7.1f}")


def _starts(n: int) -> tuple[list[float], list[float]]:
    """Wall times [s] of n Simulator starts and n Panda connects (each Panda on its own
    simulator, both closed before the next)."""
    sims, pandas = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        sim = Simulator(free_loopback_host(), robot="fer", versions=(5,)).start()
        t1 = time.perf_counter()
        try:
            with panda_py.Panda(sim.host):
                t2 = time.perf_counter()
        finally:
            sim.stop()
        sims.append(t1 - t0)
        pandas.append(t2 - t1)
    return sims, pandas


def start(n: int) -> None:
    """How long a Simulator takes to start and a Panda to connect: ours forked from the
    warm server (panda_py.warmstart), the first of a process starting that server too, and
    ours spawned as a new interpreter each (as before the warm server), against
    panda-python's Panda on the same simulator."""
    import multiprocessing

    from panda_py import warmstart

    print(f"start-up [ms], {n} each (realtime simulator, FER, v5); the first of a process "
          "apart")  # fmt: skip
    sims, pandas = _starts(n + 1)
    warm = warmstart.context
    warmstart.context = lambda: multiprocessing.get_context("spawn")  # type: ignore[assignment]
    try:
        spawned_sims, spawned_pandas = _starts(n)
    finally:
        warmstart.context = warm  # type: ignore[assignment]
    with Simulator(free_loopback_host(), robot="fer", versions=(5,)) as sim:
        theirs = _peer("connect", sim.host, str(n + 1))["connect"]
    ms = lambda v: np.asarray(v) * 1e3  # noqa: E731
    print(f"  first of the process: Simulator {1e3 * sims[0]:.0f}, Panda {1e3 * pandas[0]:.0f}; "
          f"panda-python's first Panda {1e3 * theirs[0]:.0f}")  # fmt: skip
    print("  (spawn: ours started as a new interpreter each, as before the warm server)")
    _row("Simulator start", ms(sims[1:]), ms(spawned_sims), "ms", "spawn")
    _row("Panda connect", ms(pandas[1:]), ms(spawned_pandas), "ms", "spawn")
    _row("Panda connect", ms(pandas[1:]), ms(theirs[1:]), "ms", "peer")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("mode", choices=("calls", "latency", "lost", "moves", "cpu", "start", "all"))
    p.add_argument("--n", type=int, default=20000)
    p.add_argument("--seconds", type=float, default=None)
    p.add_argument("--runs", type=int, default=1, help="lost: repeat the whole comparison")
    a = p.parse_args()
    if a.mode in ("calls", "all"):
        calls(a.n)
    if a.mode in ("latency", "all"):
        latency(a.seconds or 10.0)
    if a.mode in ("moves", "all"):
        moves()
    if a.mode in ("lost", "all"):
        lost(a.seconds or 60.0, a.runs)
    if a.mode in ("cpu", "all"):
        cpu(a.seconds or 10.0, min(a.n, 5000))
    if a.mode in ("start", "all"):
        start(min(a.n, 20))


if __name__ == "__main__":
    main()
