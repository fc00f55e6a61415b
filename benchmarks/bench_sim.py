"""Benchmark the simulated robot (panda-sim) against franky-sim on the same client workloads.

Run: ``python benchmarks/bench_sim.py [--quick] [--duration 60] [--profile]``, or
``--idle SECONDS`` for the simulators with no client connected.

Cases (run one after another, never side by side):

* **realtime**: a torque loop (weak joint PD, every state answered) for ``--duration`` wall
  seconds against panda-sim (``lockstep=False``) and against franky-sim 1.0.4 (PyPI, the
  reference protocol-level simulator), once with our pure-Python FCI client
  (``sim_client_fci.py``, protocol v10) and once with pylibfranka 0.21.3
  (``sim_client_pylibfranka.py``, RealtimeConfig kIgnore). Measured: the simulator
  process's CPU share of one core (``/proc/<pid>/stat`` utime+stime over the client's run),
  the real-time factor (simulated ms per wall ms, from the states' ``message_id``), late
  ticks (panda-sim's own count of ticks starting > 0.5 ms after their deadline; for both,
  the share of state inter-arrival periods > 1.5 ms at the client) and the client-side
  periods and round trips (median / p99 / worst, milliseconds).
* **lockstep**: the same loop for ``--lockstep-duration`` wall seconds against panda-sim
  with ``lockstep=True`` (fci v10, fci v5, pylibfranka, and ``panda_py.libfranka`` when it
  is importable and works); the real-time factor is the speed-up. franky-sim has no
  lockstep mode; its nearest equivalent, free-running (``run_forever(realtime=False)``,
  ticks without waiting for commands), is measured with the fci client for comparison.

Targets (from the issue): realtime 1.00x with <= 0.1 % late ticks, the simulator's CPU share
at most 0.5x franky-sim's in the same run (under 50 % of one core where franky-sim is not
measured); lockstep >= 10x real time with our own client. ``--profile`` adds an in-process
breakdown of panda-sim's tick (no network) and a cProfile of it. ``--cpus 0`` runs every
process of the run on CPU 0: a lockstep pair then takes its turns on one core. franky-sim
is installed on first use into its own venv (``tests/peer_envs.py``) and is only ever bound
to a loopback address.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "tests"))

from peer_envs import PeerUnavailable, peer_python  # noqa: E402

from panda_py.sim import Simulator, free_loopback_host  # noqa: E402

CLK_TCK = os.sysconf("SC_CLK_TCK")
READY_TIMEOUT = 120.0  # [s] franky-sim start-up (MuJoCo + Pinocchio model build)

# franky-sim without its wall-clock sleep: the closest it has to a lockstep mode.
_FRANKY_FREE_RUNNING = """
import sys
from franky_sim import SimulationServer
from franky_sim.mujoco_simulator import MujocoSimulator
with MujocoSimulator(enable_visualization=False) as sim:
    robot = sim.add_robot()
    with SimulationServer(sim, hostname_candidates=[sys.argv[1]]) as server:
        print(f"Connect to the server using '{robot.hostname}'", flush=True)
        try:
            server.run_forever(realtime=False)
        except KeyboardInterrupt:
            pass
"""


def proc_cpu(pid: int) -> float:
    """User + system CPU time of process ``pid`` (all its threads) [s]."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime, stime (fields 14, 15)


# --- simulators -----------------------------------------------------------------------


class Target:
    """A running simulator: where to connect, which process to meter."""

    def __init__(self, name: str, host: str, pid: int, sim: Simulator | None = None) -> None:
        self.name = name
        self.host = host
        self.pid = pid
        self.sim = sim


@contextmanager
def panda_sim(robot: str, lockstep: bool) -> Iterator[Target]:
    host = free_loopback_host()
    with Simulator(host=host, robot=robot, lockstep=lockstep) as sim:
        yield Target("panda-sim", host, sim._process.pid, sim)


@contextmanager
def franky_sim(free_running: bool = False) -> Iterator[Target]:
    python = peer_python("franky-sim")
    host = free_loopback_host()  # franky-sim binds TCP 1337 and 1338 on exactly this address
    if free_running:
        cmd = [str(python), "-c", _FRANKY_FREE_RUNNING, host]
    else:
        script = python.parent / "franky-sim"
        cmd = [str(python), str(script), "--simulator", "mujoco", "--hostname", host]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env
    )
    try:
        deadline = time.monotonic() + READY_TIMEOUT
        seen: list[str] = []
        assert proc.stdout is not None
        for line in proc.stdout:
            seen.append(line.rstrip())
            if "Connect to the server using" in line:
                if f"'{host}'" not in line:
                    raise RuntimeError(f"franky-sim bound another address: {line.strip()}")
                break
            if time.monotonic() > deadline:
                raise RuntimeError("franky-sim did not start in time")
        else:
            raise RuntimeError("franky-sim exited on start:\n" + "\n".join(seen[-20:]))
        yield Target("franky-sim" + (" (free-running)" if free_running else ""), host, proc.pid)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        if proc.stdout is not None:
            proc.stdout.close()


# --- clients --------------------------------------------------------------------------


def client_command(client: str, host: str, duration: float) -> list[str]:
    args = [host, "--duration", str(duration)]
    if client in ("fci-v10", "fci-v5"):
        version = client.rsplit("v", 1)[1]
        return [sys.executable, str(HERE / "sim_client_fci.py"), *args, "--version", version]
    if client == "pylibfranka":
        return [str(peer_python("pylibfranka")), str(HERE / "sim_client_pylibfranka.py"), *args]
    if client == "panda_py.libfranka":
        script = HERE / "sim_client_pylibfranka.py"
        return [sys.executable, str(script), *args, "--library", "panda_py.libfranka"]
    raise ValueError(f"client: unknown workload {client!r}")


def run_case(
    mode: str, target: Target, client: str, duration: float, quiet: bool = False
) -> dict[str, Any]:
    """Run one client workload against ``target`` and meter the simulator meanwhile."""
    cmd = client_command(client, target.host, duration)
    if target.sim is not None:
        target.sim.reset_stats()
    cpu0, t0 = proc_cpu(target.pid), time.monotonic()
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=duration + 120)
    cpu1, t1 = proc_cpu(target.pid), time.monotonic()
    row: dict[str, Any] = {"mode": mode, "sim": target.name, "client": client}
    row["sim_cpu_share"] = (cpu1 - cpu0) / (t1 - t0)
    row["metered_wall_s"] = t1 - t0
    if target.sim is not None:
        st = target.sim.stats()
        row["server"] = st
        row["late_tick_share"] = st["late_ticks"] / max(1, st["ticks"])
    try:
        result = json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        row["error"] = f"client failed (exit {out.returncode}): {out.stderr.strip()[-800:]}"
        if not quiet:
            print(f"  !! {target.name} / {client}: {row['error']}", file=sys.stderr)
        return row
    row.update(result)
    return row


# --- report ---------------------------------------------------------------------------


def _fmt_stats(s: dict[str, Any] | None) -> str:
    if not s or not s.get("n"):
        return "-"
    return f"{s['median']:.3f}/{s['p99']:.3f}/{s['max']:.2f}"


def print_table(rows: list[dict[str, Any]]) -> None:
    head = (
        f"{'mode':9s} {'simulator':27s} {'client':18s} {'RTF':>6s} {'CPU%':>6s} "
        f"{'late%srv':>8s} {'>1.5ms%':>8s} {'period med/p99/max':>20s} "
        f"{'round trip med/p99/max':>22s} {'skip':>6s} {'end':>8s}"
    )
    print(head)
    print("-" * len(head))
    for r in rows:
        if "error" in r:
            print(f"{r['mode']:9s} {r['sim']:27s} {r['client']:18s} ERROR {r['error'][:90]}")
            continue
        late = f"{100 * r['late_tick_share']:.3f}" if "late_tick_share" in r else "n/a"
        per = r.get("periods", {})
        print(
            f"{r['mode']:9s} {r['sim']:27s} {r['client']:18s} {r['rtf']:6.3f} "
            f"{100 * r['sim_cpu_share']:6.1f} {late:>8s} "
            f"{100 * per.get('late_share', float('nan')):8.3f} {_fmt_stats(per):>20s} "
            f"{_fmt_stats(r.get('round_trip')):>22s} {r.get('skipped', 0):6d} "
            f"{str(r.get('final_status'))[:8]:>8s}"
        )


def _find(rows: list[dict[str, Any]], mode: str, sim: str, client: str) -> dict[str, Any] | None:
    for r in rows:
        if r["mode"] == mode and r["sim"] == sim and r["client"] == client and "error" not in r:
            return r
    return None


def _ratio(a: float, b: float) -> str:
    return f"{a / b:.2f}x" if b else "n/a"


def print_comparison(rows: list[dict[str, Any]]) -> None:
    print("\nRatios panda-sim / franky-sim (same run, same client workload):")
    for client in ("fci-v10", "pylibfranka"):
        ours = _find(rows, "realtime", "panda-sim", client)
        theirs = _find(rows, "realtime", "franky-sim", client)
        if ours is None or theirs is None:
            print(f"  realtime {client:12s}: n/a (a case is missing)")
            continue
        cpu_ratio = _ratio(ours["sim_cpu_share"], theirs["sim_cpu_share"])
        print(
            f"  realtime {client:12s}: CPU share {cpu_ratio}"
            f" ({100 * ours['sim_cpu_share']:.1f} % vs {100 * theirs['sim_cpu_share']:.1f} %),"
            f" real-time factor {_ratio(ours['rtf'], theirs['rtf'])}"
            f" ({ours['rtf']:.4f} vs {theirs['rtf']:.4f}),"
            f" periods > 1.5 ms {100 * ours['periods']['late_share']:.3f} %"
            f" vs {100 * theirs['periods']['late_share']:.3f} %"
        )
    ours = _find(rows, "lockstep", "panda-sim", "fci-v10")
    theirs = _find(rows, "free-run", "franky-sim (free-running)", "fci-v10")
    if ours is not None and theirs is not None:
        print(
            f"  lockstep fci-v10     : speed {ours['rtf']:.2f}x vs franky-sim free-running "
            f"{theirs['rtf']:.2f}x (franky-sim has no lockstep mode) = "
            f"{_ratio(ours['rtf'], theirs['rtf'])}; CPU share "
            f"{100 * ours['sim_cpu_share']:.1f} % vs {100 * theirs['sim_cpu_share']:.1f} %"
        )


CPU_RATIO_TARGET = 0.5  # panda-sim's CPU share / franky-sim's, realtime, same run
LOCKSTEP_TARGET = 10.0  # lockstep speed [x real time] with our own client


def print_targets(rows: list[dict[str, Any]]) -> None:
    print("\nTargets:")
    for client in ("fci-v10", "pylibfranka"):
        r = _find(rows, "realtime", "panda-sim", client)
        if r is None:
            continue
        resyncs = r["server"]["resyncs"]
        ok_rtf = abs(r["rtf"] - 1.0) < 0.005 and resyncs == 0
        ok_late = r["late_tick_share"] <= 0.001
        peer = _find(rows, "realtime", "franky-sim", client)
        if peer is not None and peer["sim_cpu_share"] > 0:
            ratio = r["sim_cpu_share"] / peer["sim_cpu_share"]
            ok_cpu = ratio <= CPU_RATIO_TARGET
            cpu_note = f"{ratio:.2f}x franky-sim's, target <= {CPU_RATIO_TARGET}x"
        else:
            ok_cpu = r["sim_cpu_share"] < 0.5
            cpu_note = "no franky-sim: target < 50 % of one core"
        print(
            f"  realtime {client:12s}: RTF {r['rtf']:.4f}, {resyncs} resyncs "
            f"[{'ok' if ok_rtf else 'MISSED'}], "
            f"late ticks {100 * r['late_tick_share']:.3f} % "
            f"({r['server']['late_ticks']}/{r['server']['ticks']}) "
            f"[{'ok' if ok_late else 'MISSED'}], CPU {100 * r['sim_cpu_share']:.1f} % "
            f"({cpu_note}) [{'ok' if ok_cpu else 'MISSED'}]"
        )
    for client in ("fci-v10", "fci-v5", "pylibfranka", "panda_py.libfranka"):
        r = _find(rows, "lockstep", "panda-sim", client)
        if r is not None:
            print(
                f"  lockstep {client:12s}: {r['rtf']:.2f}x real time "
                f"[{'ok' if r['rtf'] >= LOCKSTEP_TARGET else 'MISSED'} "
                f"(target {LOCKSTEP_TARGET:g}x)]"
            )


# --- in-process tick profile ------------------------------------------------------------


def profile_tick(robot: str, n: int = 3000) -> None:
    """Time the parts of panda-sim's tick in this process (no network, no client): a
    torque motion (external controller, generator NONE, protocol v10) fed a zero-torque
    command every tick, its states sent to a local UDP sink."""
    import cProfile
    import pstats
    import socket

    import numpy as np

    from panda_py import fci
    from panda_py.sim.connections import RobotConnection
    from panda_py.sim.server import SimConfig, SimServer
    from panda_py.sim.wire import CommandWire, StateWire

    host = free_loopback_host()
    srv = SimServer(SimConfig(host=host, robot=robot))
    core = srv.core
    d = fci.dialect(10)
    status = core.request_move(2, 4, np.array(fci.DEFAULT_DEVIATION * 2), has_none=True)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind((host, 0))
    sink.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx.bind((host, 0))
    tx.setblocking(False)  # as the server's: its realtime tick reads it (nothing queued)
    conn = RobotConnection(socket.socket(), (host, 0))
    conn.dialect = d
    conn.state_wire, conn.command_wire = StateWire(d, core), CommandWire(d)
    conn.udp, conn.udp_target = tx, sink.getsockname()
    srv.robot_conn = conn
    # The server's own UDP reader decodes the command datagrams: feed it through a pair.
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind((host, 0))
    rx.setblocking(False)
    feeder = sink  # the client: states arrive at and commands leave from one socket
    command = d.new_command()
    mid = [0]

    def receive_command() -> None:
        mid[0] = srv.tick_count + 1
        command["message_id"] = mid[0]
        feeder.sendto(command.tobytes(), rx.getsockname())
        conn.udp, udp = rx, conn.udp
        conn.last_sent_id = mid[0]  # it answers the state just sent
        srv._read_robot_udp(conn)
        conn.udp = udp

    def full_tick(_: int) -> None:
        receive_command()
        conn.awaiting = True
        srv._tick(time.monotonic(), late=False)
        try:
            while True:
                sink.recv(4096, socket.MSG_DONTWAIT)
        except BlockingIOError:
            pass

    ph = core.physics
    zero = np.zeros(7)
    parts: list[tuple[str, Callable[[int], object]]] = [
        ("server tick, all of it (+ UDP in/out)", full_tick),
        ("  _read_robot_udp (+ feeder sendto)", lambda i: receive_command()),
        ("  RobotCore.tick (motion + physics + state)", lambda i: core.tick(conn.command)),
        ("    physics.step (mj_step)", lambda i: ph.step(zero, 0.0)),
        ("    RobotCore._fill_state", lambda i: core._fill_state()),
        ("      (its NumPy reference)", lambda i: core._fill_state_reference()),
        ("      _fill_contacts", lambda i: core._fill_contacts(np.eye(4))),
        ("      physics.flange_pose_at", lambda i: ph.flange_pose_at(core.joint.q)),
        ("  _send_state (state record + sendto)", lambda i: srv._send_state(conn)),
        ("  gripper.tick", lambda i: srv.gripper.tick()),
    ]
    print(f"\nIn-process tick profile ({robot}, {n} ticks each, microseconds; move: {status}):")
    print(f"  {'part':46s} {'median':>8s} {'mean':>8s} {'p99':>8s}")
    clock = time.perf_counter
    for name, fn in parts:
        samples = np.empty(n)
        for i in range(n):
            t0 = clock()
            fn(i)
            samples[i] = clock() - t0
        us = samples * 1e6
        print(f"  {name:46s} {np.median(us):8.1f} {us.mean():8.1f} {np.percentile(us, 99):8.1f}")
    # CPU time (this process's): what a busy machine's preemptions leave out of the above
    cpu_runs = []
    for _ in range(3):
        c0 = time.process_time()
        for i in range(n):
            full_tick(i)
        cpu_runs.append((time.process_time() - c0) / n * 1e6)
    print(f"  server tick, all of it: CPU {min(cpu_runs):.1f}-{max(cpu_runs):.1f} us a tick "
          f"(3 x {n} ticks; <= {1e3 / min(cpu_runs):.1f}-{1e3 / max(cpu_runs):.1f}x real "
          "time for the simulator alone)")  # fmt: skip
    prof = cProfile.Profile()
    prof.enable()
    for i in range(n):
        full_tick(i)
    prof.disable()
    print(f"\ncProfile of {n} full ticks (by own time):")
    stats = pstats.Stats(prof, stream=sys.stdout)
    stats.sort_stats("tottime").print_stats(20)
    stats.sort_stats("cumtime").print_callees(r"\((_motion_tick|_accept|_fill_state)\)")
    print(f"robot mode after profiling: {core.robot_mode.name}")
    srv.close()


# --- main -------------------------------------------------------------------------------


def idle_cpu(target: Target, seconds: float) -> list[float]:
    """The simulator's CPU share [% of a core] in 1 s windows while no client is connected
    (after a second to settle)."""
    time.sleep(1.0)
    shares = []
    c0, t0 = proc_cpu(target.pid), time.monotonic()
    for _ in range(max(1, int(seconds))):
        time.sleep(1.0)
        c1, t1 = proc_cpu(target.pid), time.monotonic()
        shares.append(100.0 * (c1 - c0) / (t1 - t0))
        c0, t0 = c1, t1
    return shares


def idle(robot: str, seconds: float, franky: bool) -> None:
    """``--idle``: each simulator left alone (no client) for ``seconds``, one after another."""
    import numpy as np

    print(f"idle, no client connected, {seconds:g} s each: the simulator's CPU, % of a core "
          "in 1 s windows")  # fmt: skip
    cases: list[tuple[str, Any]] = [
        ("panda-sim realtime", panda_sim(robot, False)),
        ("panda-sim lockstep", panda_sim(robot, True)),
    ]
    if franky:
        cases.append(("franky-sim", franky_sim()))
    medians: dict[str, float] = {}
    for label, ctx in cases:
        with ctx as target:
            shares = np.asarray(idle_cpu(target, seconds))
        medians[label] = float(np.median(shares))
        print(f"  {label:20s} median {np.median(shares):5.1f}  p99 "
              f"{np.percentile(shares, 99):5.1f}  worst {shares.max():5.1f} %")  # fmt: skip
    if "franky-sim" in medians:
        for label in ("panda-sim realtime", "panda-sim lockstep"):
            print(f"  {label} / franky-sim (medians): "
                  f"{medians[label] / medians['franky-sim']:.2f}x")  # fmt: skip


def libfranka_workload_available() -> bool:
    try:
        import panda_py.libfranka  # noqa: F401
    except Exception:
        return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="10 s realtime, 5 s lockstep")
    parser.add_argument("--duration", type=float, default=None, help="realtime cases [s] (60)")
    parser.add_argument(
        "--lockstep-duration", type=float, default=None, help="lockstep cases [wall s] (20)"
    )
    parser.add_argument("--robot", default="fr3", choices=("fer", "fr3"),
                        help="panda-sim's robot (franky-sim simulates an FR3)")  # fmt: skip
    parser.add_argument("--no-franky", action="store_true", help="skip franky-sim")
    parser.add_argument("--no-pylibfranka", action="store_true", help="skip pylibfranka")
    parser.add_argument("--profile", action="store_true", help="add the tick profile")
    parser.add_argument("--profile-only", action="store_true", help="only the tick profile")
    parser.add_argument(
        "--lockstep-only", action="store_true", help="only panda-sim's lockstep cases"
    )
    parser.add_argument("--json", type=Path, default=None, help="write all results here")
    parser.add_argument("--idle", type=float, default=None, metavar="SECONDS",
                        help="only the idle simulators (no client), this long each")  # fmt: skip
    parser.add_argument("--cpus", default=None,
                        help="run every process of the run on these CPUs (e.g. 0: a lockstep "
                             "simulator and its client on one core)")  # fmt: skip
    args = parser.parse_args()
    if args.cpus is not None:
        try:
            cpus = {int(c) for c in args.cpus.split(",")}
            os.sched_setaffinity(0, cpus)  # inherited by every process started from here
        except (ValueError, OSError, AttributeError) as exc:
            parser.error(f"--cpus: expected CPU numbers of this machine like 0 or 0,1, "
                         f"got {args.cpus!r} ({exc})")  # fmt: skip
    duration = args.duration or (10.0 if args.quick else 60.0)
    lock_duration = args.lockstep_duration or (5.0 if args.quick else 20.0)
    if duration <= 0 or lock_duration <= 0:
        parser.error("durations must be > 0 s")

    if args.profile_only:
        profile_tick(args.robot)
        return
    if args.idle is not None:
        if not args.idle >= 1.0:
            parser.error(f"--idle: expected at least 1 s, got {args.idle}")
        franky = False
        if not args.no_franky:
            try:
                peer_python("franky-sim")
                franky = True
            except PeerUnavailable as exc:
                print(f"(franky-sim skipped: {exc})")
        idle(args.robot, args.idle, franky)
        return

    rev = subprocess.run(
        ["git", "-C", str(REPO), "log", "-1", "--format=%h", "--", "src/panda_py/sim"],
        capture_output=True,
        text=True,
    ).stdout.strip()
    print(
        f"bench_sim: panda-sim at {rev or '?'}; {platform.node()}, {os.cpu_count()} CPUs, "
        f"load average "
        f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, Python {platform.python_version()}; "
        f"realtime {duration:g} s, lockstep {lock_duration:g} s, panda-sim robot {args.robot}"
        + (
            f"; on CPUs {','.join(map(str, sorted(os.sched_getaffinity(0))))}"
            if hasattr(os, "sched_getaffinity")
            else ""
        )  # (Linux only)
    )
    clients = ["fci-v10"]
    if not args.no_pylibfranka:
        try:
            peer_python("pylibfranka")
            clients.append("pylibfranka")
        except PeerUnavailable as exc:
            print(f"(pylibfranka skipped: {exc})")
    franky = not args.no_franky
    if franky:
        try:
            peer_python("franky-sim")
        except PeerUnavailable as exc:
            print(f"(franky-sim skipped: {exc})")
            franky = False

    rows: list[dict[str, Any]] = []

    def run(mode: str, ctx: Any, client: str, seconds: float) -> None:
        print(f"  {mode:9s} {client:18s} ...", end=" ", flush=True)
        try:
            with ctx as target:
                row = run_case(mode, target, client, seconds)
        except Exception as exc:  # one broken case must not lose the others
            row = {"mode": mode, "sim": "?", "client": client, "error": repr(exc)}
        rows.append(row)
        line = f"RTF {row['rtf']:.3f}" if "rtf" in row else "ERROR"
        if "rtf" in row and row["rtf"] > 0:  # the simulator's CPU per simulated ms
            per_tick = 1e3 * row["sim_cpu_share"] / row["rtf"]
            line += f", simulator CPU {per_tick:.0f} us/tick (<= {1e3 / per_tick:.1f}x real time)"
        print(f"{row['sim']}: " + line)

    if args.lockstep_only:
        franky = False
    print("Running:")
    for client in clients if not args.lockstep_only else ():
        run("realtime", panda_sim(args.robot, False), client, duration)
        if franky:
            run("realtime", franky_sim(), client, duration)
    lock_clients = ["fci-v10", "fci-v5"] + [c for c in clients if c != "fci-v10"]
    if libfranka_workload_available():
        lock_clients.append("panda_py.libfranka")
    for client in lock_clients:
        robot = "fer" if client == "fci-v5" else args.robot  # a FER's systems speak v5
        run("lockstep", panda_sim(robot, True), client, lock_duration)
    if franky:
        run("free-run", franky_sim(free_running=True), "fci-v10", lock_duration)

    print()
    print("RTF = simulated / wall time; CPU% = simulator process, % of one core; late%srv =")
    print("panda-sim's ticks > 0.5 ms late; >1.5ms% = state periods > 1.5 ms at the client;")
    print("periods, round trips (command sent -> next state) in ms; skip = states not answered.")
    print_table(rows)
    print_comparison(rows)
    print_targets(rows)
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))
        print(f"\nraw results: {args.json}")
    if args.profile:
        profile_tick(args.robot)


if __name__ == "__main__":
    main()
