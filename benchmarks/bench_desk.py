"""Does the simulated Desk disturb the simulator's 1 kHz loop?

Run: ``python benchmarks/bench_desk.py [--duration 20] [--repeat 3] [--rate 20]``.

A realtime panda-sim (FR3, Desk ready) runs our pure-Python FCI torque client
(``sim_client_fci.py``, v10) for ``--duration`` s under three conditions, interleaved and
repeated: **no Desk** (``Simulator(desk=None)``), **Desk idle** (running, nobody talks to
it), **Desk loaded** (``--rate`` requests/s from a client thread, a mix of legacy and v1
reads and a control round trip, plus the Desk page open in headless chromium, which
streams ``/desk/api/robot/configuration`` at 10 Hz; a plain websocket client instead if
there is no browser). Reported per condition: late ticks (the simulator's count of ticks
starting > 0.5 ms after their deadline) over ticks, the client's state periods (median /
p99 / worst, ms, share > 1.5 ms), and under load the Desk's request latency (median / p99
/ worst, ms), and the stalls (the simulator fell > 100 ms behind and re-synchronised:
the machine, not the simulator, stopped it; the runs this hits end in a reflex).
Target: no measurable difference between the conditions.
"""

from __future__ import annotations

import argparse
import base64
import http.client
import json
import os
import shutil
import ssl
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from panda_py.libfranka import Robot
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.desk import DeskConfig

HERE = Path(__file__).resolve().parent
BASIC = {"Authorization": "Basic " + base64.b64encode(b"franka:franka123").decode()}


def _context() -> ssl.SSLContext:
    ctx = ssl.create_default_context()
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE  # the simulator's own self-signed certificate
    return ctx


class Load:
    """``rate`` Desk requests per second from a thread, on an absolute schedule."""

    def __init__(self, host: str, port: int, rate: float) -> None:
        self.host, self.port, self.rate = host, port, rate
        self.latencies: list[float] = []
        self.errors = 0
        self._conn: http.client.HTTPSConnection | None = None
        self._token: dict[str, Any] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _call(self, method: str, path: str, body: Any = None, token: str | None = None) -> Any:
        """One request on a kept-alive connection (as franky's session keeps one)."""
        if self._conn is None:
            self._conn = http.client.HTTPSConnection(
                self.host, self.port, context=_context(), timeout=5
            )
        h = dict(BASIC)
        if token is not None:
            h["X-Control-Token"] = token
        data = None
        if body is not None:
            data = json.dumps(body).encode()
            h["Content-Type"] = "application/json"
        t0 = time.perf_counter()
        try:
            self._conn.request(method, path, body=data, headers=h)
            res = self._conn.getresponse()
            text = res.read()
        except (OSError, http.client.HTTPException):
            self._conn.close()
            self._conn = None
            self.errors += 1
            return None
        self.latencies.append(time.perf_counter() - t0)
        if res.status >= 400:
            self.errors += 1
        return json.loads(text) if text and res.status < 300 else None

    def _run(self) -> None:
        period = 1.0 / self.rate
        next_t = time.monotonic()
        i = 0
        while not self._stop.is_set():
            kind = i % 5
            if kind == 0:
                self._call("GET", "/admin/api/system-status")
            elif kind == 1:
                self._call("GET", "/api/system")
            elif kind == 2:
                self._call("GET", "/api/arm/joints")
            elif kind == 3:
                self._token = self._call(
                    "POST", "/api/system/control-token:take", {"owner": "bench", "timeout": 1}
                )
            else:
                token = (self._token or {}).get("token", "")
                self._call("POST", "/api/system/control-token:release", token=token)
            i += 1
            next_t += period
            self._stop.wait(max(0.0, next_t - time.monotonic()))

    def __enter__(self) -> Load:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(10)


@contextmanager
def page_open(url: str) -> Iterator[str]:
    """The Desk page logged in and streaming in headless chromium (else a websocket)."""
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        sync_playwright = None  # type: ignore[assignment]
    if sync_playwright is not None and os.path.exists(chromium):
        with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
            ctx = pw.chromium.launch_persistent_context(
                profile,
                executable_path=chromium,
                headless=True,
                ignore_https_errors=True,
                args=["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                      "--disable-background-networking", "--disable-component-update",
                      "--disable-sync"],
            )  # fmt: skip
            page = ctx.new_page()
            page.goto(url + "/")
            page.fill("#login-user", "franka")
            page.fill("#login-password", "franka123")
            page.click("#login-button")
            page.wait_for_selector("#joints li", timeout=10000)
            try:
                yield "chromium page"
            finally:
                ctx.close()
        return
    from websockets.sync.client import connect

    host = url.removeprefix("https://")
    stop = threading.Event()
    ws = connect(
        f"wss://{host}/desk/api/robot/configuration", ssl=_context(), additional_headers=BASIC
    )

    def read() -> None:
        while not stop.is_set():
            try:
                ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            except Exception:
                return

    t = threading.Thread(target=read, daemon=True)
    t.start()
    try:
        yield "websocket"
    finally:
        stop.set()
        t.join(2)
        ws.close()


def run_client(host: str, duration: float) -> dict[str, Any]:
    cmd = [sys.executable, str(HERE / "sim_client_fci.py"), host, "--duration", str(duration)]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=duration + 120)
    try:
        return dict(json.loads(out.stdout.strip().splitlines()[-1]))
    except (IndexError, json.JSONDecodeError):
        return {"error": out.stderr.strip()[-500:]}


def measure(sim: Simulator, duration: float) -> dict[str, Any]:
    # A stall of the machine may have ended the previous run in a reflex: clear it first.
    with Robot(sim.host) as robot:
        robot.automatic_error_recovery()
    sim.reset_stats()
    client = run_client(sim.host, duration)
    st = sim.stats()
    if "error" in client:
        print(f"  !! the FCI client failed: {client['error']}", file=sys.stderr)
    return {
        "late": st["late_ticks"], "ticks": st["ticks"], "resyncs": st["resyncs"], "client": client
    }  # fmt: skip


def proc_cpu(pid: int) -> float:
    """User + system CPU time of process ``pid`` [s]."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def ms(values: list[float]) -> str:
    if not values:
        return "n/a"
    v = sorted(values)
    p99 = v[min(len(v) - 1, int(0.99 * len(v)))]
    return f"{1e3 * statistics.median(v):.2f} / {1e3 * p99:.2f} / {1e3 * v[-1]:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=20.0, help="seconds per run")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rate", type=float, default=20.0, help="Desk requests per second")
    args = ap.parse_args()
    rows: dict[str, list[dict[str, Any]]] = {"no Desk": [], "Desk idle": [], "Desk loaded": []}
    latencies: list[float] = []
    desk_cpu: list[float] = []
    errors = 0
    how = ""
    with tempfile.TemporaryDirectory() as certs:
        desk = DeskConfig(port=0, cert_dir=certs)
        for r in range(args.repeat):
            with Simulator(free_loopback_host(), robot="fr3") as plain:
                rows["no Desk"].append(measure(plain, args.duration))
            with Simulator(free_loopback_host(), robot="fr3", desk=desk) as sim:
                assert sim.desk is not None
                desk_pid = sim.desk._process.pid
                rows["Desk idle"].append(measure(sim, args.duration))
                with (
                    page_open(sim.desk.url) as how,
                    Load(sim.host, sim.desk.port, args.rate) as load,
                ):
                    cpu0, t0 = proc_cpu(desk_pid), time.monotonic()
                    rows["Desk loaded"].append(measure(sim, args.duration))
                    desk_cpu.append((proc_cpu(desk_pid) - cpu0) / (time.monotonic() - t0))
                latencies += load.latencies
                errors += load.errors
            print(f"repeat {r + 1}/{args.repeat} done", file=sys.stderr)
    print(f"\n{args.repeat} x {args.duration:.0f} s per condition, realtime FR3, FCI torque "
          f"client v10; load: {args.rate:.0f} Desk requests/s + {how}")  # fmt: skip
    print(f"{'condition':12s} {'late ticks':>22s} {'periods ms med/p99/max':>24s} "
          f"{'>1.5ms %':>9s} {'stalls':>6s}  client runs ended early")  # fmt: skip
    for name, runs in rows.items():
        late = sum(x["late"] for x in runs)
        ticks = sum(x["ticks"] for x in runs)
        per = [x["client"].get("periods", {}) for x in runs]
        med = max((p.get("median", float("nan")) for p in per), default=float("nan"))
        p99 = max((p.get("p99", float("nan")) for p in per), default=float("nan"))
        worst = max((p.get("max", float("nan")) for p in per), default=float("nan"))
        share = max((p.get("late_share", float("nan")) for p in per), default=float("nan"))
        early = [
            x["client"].get("final_status", x["client"].get("error", "?"))
            for x in runs
            if x["client"].get("final_status") != "SUCCESS" or x["client"].get("aborted")
        ]
        print(
            f"{name:12s} {late:6d}/{ticks:7d} ({100 * late / max(1, ticks):.3f} %) "
            f"{med:8.3f} /{p99:6.3f} /{worst:7.3f} {100 * share:9.3f} "
            f"{sum(x['resyncs'] for x in runs):6d}  {len(early)} {early}"
        )
    print(f"Desk request latency med/p99/max ms: {ms(latencies)} ({len(latencies)} requests, "
          f"{errors} answered >= 400); the Desk process's CPU under load: "
          f"{100 * statistics.mean(desk_cpu):.1f} % of one core")  # fmt: skip


if __name__ == "__main__":
    main()
