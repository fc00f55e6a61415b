"""What drawing the simulated robot costs: the video recorder and the viewer beside a
realtime simulator.

Run: ``python benchmarks/bench_drawing.py [--duration 10] [--repeat 3]``.

Cases, one after another: a realtime simulator (``lockstep=False``, idle: its 1 kHz tick
runs on the wall clock) alone, with ``record=`` (offscreen EGL, 640x480, 30 frames per
simulated second), with ``viewer=True`` (on ``$DISPLAY``, or on an Xvfb the benchmark
starts) and with both. Measured from the simulator's own counters over ``--duration``
wall seconds: late ticks (starting > 0.5 ms after their deadline) and the worst
lateness, the simulator process's CPU share; from the recorder: its cost per frame
(draw and hand to ffmpeg) median / p99 / worst. Every case is repeated ``--repeat`` times;
the spread is printed. The peer is the simulator alone, in the same run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from panda_py.sim import Simulator, free_loopback_host


@contextmanager
def display() -> Iterator[str | None]:
    """``$DISPLAY``, or an Xvfb of our own, or None (no viewer cases)."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    if shutil.which("Xvfb") is None:
        yield None
        return
    number = next(
        n for n in range(100 + os.getpid() % 400, 1000)
        if not os.path.exists(f"/tmp/.X{n}-lock") and not os.path.exists(f"/tmp/.X11-unix/X{n}")
    )  # fmt: skip
    proc = subprocess.Popen(
        ["Xvfb", f":{number}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 10
        while not os.path.exists(f"/tmp/.X11-unix/X{number}"):  # its socket: it is up
            if proc.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"Xvfb did not start on :{number}")
            time.sleep(0.05)
        yield f":{number}"
    finally:
        proc.terminate()
        proc.wait(10)


def run_case(duration: float, out: Path, *, record: bool, viewer: bool) -> dict[str, Any]:
    sim = Simulator(
        free_loopback_host(), lockstep=False, viewer=viewer,
        record=out / "bench.mp4" if record else None,
    )  # fmt: skip
    with sim:
        sim.reset_stats()
        time.sleep(duration)  # a benchmark's measuring window, not a test's wait
        stats = sim.stats()
    result = {
        "late_pct": 100.0 * stats["late_ticks"] / max(1, stats["ticks"]),
        "worst_late_ms": 1e3 * stats["worst_late"],
        "cpu_pct": 100.0 * stats["cpu_time"] / stats["wall_time"],
    }
    if sim.recording is not None:
        result["frames"] = sim.recording["frames"]
        result["dropped"] = sim.recording["dropped"]
        result.update({f"frame_{k}_ms": v for k, v in sim.recording["ms_per_frame"].items()})
    return result


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=10.0, help="seconds per run")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()
    with display() as disp, tempfile.TemporaryDirectory() as tmp:
        cases = [("alone", False, False), ("record", True, False)]
        if disp is not None:
            os.environ["DISPLAY"] = disp
            cases += [("viewer", False, True), ("record+viewer", True, True)]
        else:
            print("no display and no Xvfb: the viewer cases are skipped")
        runs: dict[str, list[dict[str, Any]]] = {name: [] for name, _, _ in cases}
        for _ in range(args.repeat):  # interleaved: load drifts hit every case alike
            for name, record, viewer in cases:
                runs[name].append(run_case(args.duration, Path(tmp), record=record, viewer=viewer))
    base = np.median([r["late_pct"] for r in runs["alone"]])
    print(f"realtime simulator, {args.duration:g} s x {args.repeat}; min..max over runs")
    for name, results in runs.items():
        keys = results[0].keys()
        parts = []
        for k in keys:
            vals = [r[k] for r in results if r.get(k) is not None]
            if vals:
                parts.append(f"{k} {min(vals):.2f}..{max(vals):.2f}")
        late = np.median([r["late_pct"] for r in results])
        ratio = f"late ticks {late / base:.1f}x alone's" if base > 0 else "alone had none late"
        print(f"{name:14s} {', '.join(parts)} ({ratio})")


if __name__ == "__main__":
    main()
