"""Robustness of panda-sim: hostile clients beside an honest realtime torque loop.

Run: ``python benchmarks/bench_robust.py attacks [--runs 5] [--duration 60]`` or
``python benchmarks/bench_robust.py soak [--duration 600]``.

* **attacks**: per run, a realtime panda-sim and an honest client (``--client``:
  ``panda_py.libfranka`` or ``pylibfranka``, ``sim_client_pylibfranka.py``: a torque loop
  answering every state) for ``--duration`` wall seconds; first once alone (baseline),
  then with attackers looping beside it: a slow reader (the gripper's client, requests
  never read), a gripper flood (20,000 pipelined Stops), 16 MiB messages on both TCP ports.
  Reported per run: the simulator's late ticks (> 0.5 ms after the deadline) as a share,
  its worst lateness, commands lost / excused, and whether the honest motion completed.
  Target (issue 11): late ticks <= 0.1 % and the honest motion completes.
* **soak**: ``--duration`` seconds of seeded random fuzzing of both TCP ports and the
  robot's UDP socket (the generators of ``tests/sim/test_sim_fuzz.py``, without
  Hypothesis) beside one honest realtime motion. Target: 0 crashes (the simulator
  keeps serving), 0 aborts of the honest client.

Medians, p99 and worst over runs are printed at the end; the machine's load average is
printed with every figure (the figures are only comparable at the same load).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from peer_envs import peer_python  # noqa: E402

from panda_py import fci  # noqa: E402
from panda_py.sim import Simulator, free_loopback_host  # noqa: E402
from panda_py.sim.probe import gripper_flood, oversized_message, slow_reader  # noqa: E402


def _load() -> str:
    return "load {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def _client(library: str, host: str, duration: float) -> subprocess.Popen[str]:
    python = sys.executable if library == "panda_py.libfranka" else str(peer_python(library))
    cmd = [python, str(HERE / "sim_client_pylibfranka.py"), host, "--duration", str(duration),
           "--library", library]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(proc: subprocess.Popen[str], timeout: float) -> dict[str, Any]:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()  # a hung client (SCHED_FIFO 99 in pylibfranka) would starve the machine
        proc.communicate()
        return {"final_status": "CLIENT HUNG", "aborted": [f"no result after {timeout:g} s"]}
    try:
        return dict(json.loads(out.strip().splitlines()[-1]))
    except (IndexError, json.JSONDecodeError):
        return {"final_status": "CLIENT FAILED", "aborted": [err.strip()[-500:]]}


def _udp_ports(host: str) -> list[int]:
    """The UDP ports bound to exactly ``host``: the simulator's (its robot and gripper
    sockets). Clients bind 0.0.0.0, so spraying random ports would hit the honest
    client too, and a real libfranka waits forever after one datagram with a huge
    message id (the weakness issue 11 fixed in panda_py.libfranka); the soak is about
    the simulator."""
    want = socket.inet_aton(host)[::-1].hex().upper()  # /proc/net/udp: little-endian hex
    ports = []
    with open("/proc/net/udp") as f:
        next(f)
        for line in f:
            address, port = line.split()[1].split(":")
            if address == want:
                ports.append(int(port, 16))
    return ports


class _Attackers:
    """Attack loops in threads until :meth:`stop`; counts rounds and unexpected errors."""

    def __init__(self, host: str, kinds: list[str], seed: int = 0) -> None:
        self.host = host
        self.rounds: dict[str, int] = dict.fromkeys(kinds, 0)
        self.errors: list[str] = []
        self._stop = threading.Event()
        self._rng = np.random.default_rng(seed)
        self._threads = [threading.Thread(target=self._loop, args=(k,), daemon=True)
                         for k in kinds]  # fmt: skip
        for t in self._threads:
            t.start()

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(30)

    def _loop(self, kind: str) -> None:
        attack = getattr(self, f"_{kind}")
        while not self._stop.is_set():
            try:
                attack()
            except OSError:
                pass  # refused or reset: the robot defending itself
            except Exception as exc:  # reported; the soak goes on
                self.errors.append(f"{kind}: {type(exc).__name__}: {exc}")
            self.rounds[kind] += 1
            self._stop.wait(0.05)

    # -- the attacks -------------------------------------------------------------------

    def _slow_reader(self) -> None:
        # The honest client holds the FCI port (a second client there hears "busy"):
        # the slow reader is the gripper's client, 50,000 Stops never read, held 2 s.
        with slow_reader(self.host, requests=50000, port=fci.GRIPPER_COMMAND_PORT):
            self._stop.wait(2.0)

    def _gripper_flood(self) -> None:
        gripper_flood(self.host, requests=20000)

    def _oversized(self) -> None:
        oversized_message(self.host, port=fci.GRIPPER_COMMAND_PORT)
        oversized_message(self.host, port=fci.COMMAND_PORT)

    def _fuzz_tcp(self) -> None:
        rng = self._rng
        port = fci.COMMAND_PORT if rng.random() < 0.5 else fci.GRIPPER_COMMAND_PORT
        parts = []
        for _ in range(int(rng.integers(1, 8))):
            payload = rng.bytes(int(rng.integers(0, 600)))
            if rng.random() < 0.5:
                size = (12 if port == fci.COMMAND_PORT else 10) + len(payload)
                head = (struct.pack("<III", int(rng.integers(0, 40)), 0, size)
                        if port == fci.COMMAND_PORT
                        else struct.pack("<HII", int(rng.integers(0, 8)), 0, size))  # fmt: skip
                parts.append(head + payload)
            else:
                parts.append(payload)
        with socket.create_connection((self.host, port), timeout=2.0) as s:
            if rng.random() < 0.5:
                s.sendall(fci.encode_connect_request(10, 9) if port == fci.COMMAND_PORT
                          else fci.encode_gripper_connect_request(9))  # fmt: skip
            s.sendall(b"".join(parts))
            s.settimeout(0.05)
            try:
                while s.recv(65536):
                    pass
            except OSError:
                pass

    def _fuzz_udp(self) -> None:
        rng = self._rng
        ports = _udp_ports(self.host)
        if not ports:
            return
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _ in range(50):
                port = ports[int(rng.integers(0, len(ports)))]
                s.sendto(rng.bytes(int(rng.integers(1, 2000))), (self.host, port))


def _run(library: str, duration: float, kinds: list[str], seed: int) -> dict[str, Any]:
    with Simulator(free_loopback_host(), robot="fr3") as sim:
        proc = _client(library, sim.host, duration)
        time.sleep(1.0)  # the client holds the robot before the attackers come
        sim.reset_stats()
        attackers = _Attackers(sim.host, kinds, seed) if kinds else None
        try:
            result = _finish(proc, duration + 120)
        finally:
            if attackers is not None:
                attackers.stop()
        stats = sim.stats()
        robot_mode = int(sim.state()["robot_mode"])  # the process still answers
        alive = True
    return {
        "attacks": kinds,
        "completed": result.get("final_status") == "SUCCESS",
        "aborted": result.get("aborted", []),
        "late_share": stats["late_ticks"] / max(1, stats["ticks"]),
        "worst_late_ms": 1e3 * stats["worst_late"],
        "lost": stats["commands_lost"],
        "excused": stats["commands_excused"],
        "dropped_clients": stats["clients_dropped"],
        "resyncs": stats["resyncs"],
        "rounds": attackers.rounds if attackers else {},
        "attacker_errors": attackers.errors[:5] if attackers else [],
        "sim_alive": alive,
        "robot_mode_after": robot_mode,
        "load": _load(),
    }


def _print(row: dict[str, Any]) -> None:
    print(
        f"  {'+'.join(row['attacks']) or 'baseline':40s} completed={row['completed']!s:5s} "
        f"late={100 * row['late_share']:.3f}% worst={row['worst_late_ms']:.2f} ms "
        f"lost={row['lost']} excused={row['excused']} dropped={row['dropped_clients']} "
        f"rounds={row['rounds']} [{row['load']}]",
        flush=True,
    )
    for a in row["aborted"] + row["attacker_errors"]:
        print(f"    !! {a}", flush=True)


def _spread(name: str, values: list[float], unit: str) -> None:
    v = np.array(values)
    print(f"  {name}: median {np.median(v):.3f}{unit}, p99 {np.percentile(v, 99):.3f}{unit}, "
          f"worst {v.max():.3f}{unit} (n={v.size})")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("mode", choices=("attacks", "soak"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--duration", type=float, default=None, help="[s] per run (60 / 600)")
    parser.add_argument("--client", default="panda_py.libfranka",
                        choices=("panda_py.libfranka", "pylibfranka"))  # fmt: skip
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    rows: list[dict[str, Any]] = []
    if args.mode == "attacks":
        duration = args.duration or 60.0
        kinds = ["slow_reader", "gripper_flood", "oversized"]
        for i in range(args.runs):
            print(f"run {i + 1}/{args.runs} ({duration:g} s, {args.client}):", flush=True)
            for attack in ([], kinds):
                row = _run(args.client, duration, attack, seed=i)
                _print(row)
                rows.append(row)
    else:
        duration = args.duration or 600.0
        kinds = ["fuzz_tcp", "fuzz_udp", "gripper_flood", "oversized", "slow_reader"]
        print(f"soak ({duration:g} s, {args.client}):", flush=True)
        row = _run(args.client, duration, kinds, seed=11)
        _print(row)
        rows.append(row)
        print(f"  crashes: {0 if row['sim_alive'] else 1}, honest aborts: "
              f"{0 if row['completed'] else 1}")  # fmt: skip
    attacked = [r for r in rows if r["attacks"]]
    base = [r for r in rows if not r["attacks"]]
    for label, group in (("baseline", base), ("under attack", attacked)):
        if group:
            print(f"{label}: {sum(r['completed'] for r in group)}/{len(group)} completed")
            _spread("late ticks", [100 * r["late_share"] for r in group], " %")
            _spread("worst lateness", [r["worst_late_ms"] for r in group], " ms")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
