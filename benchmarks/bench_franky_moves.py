"""Benchmark our non-blocking Cartesian moves side by side with franky-control 2.0.0, both
against panda-sim (FR3, protocol v10) in real time (``lockstep=False``).

Run: ``python benchmarks/bench_franky_moves.py [--quick] [--runs 5] [--factor 0.2]
[--cpus 1]`` (``--cpus``: the simulator and each library's control loop on those CPUs, the
setting with which ``bench_panda.py lost`` lost no commands on a VM).

Cases (each run: a fresh simulator per library, the libraries alternating which goes first;
both start from the start pose at rest and read the start pose from the robot's state):

* **path**: three waypoints (offsets ``WAYPOINTS`` [m] from the start position, 12-13 cm
  apart, the start orientation kept; the last one 5 cm up: 5 cm down, franky's waypoint
  motion trips the simulated FR3's joint 4 acceleration limit even at factor 0.15). Ours:
  one ``move_to_pose(positions, orientations, max_deviation=0.02, asynchronous=True)`` (a
  time-optimal path through them that cuts each corner by up to ``--max-deviation``
  instead of stopping there; 0, panda-py's, stops at each); franky: one
  ``CartesianWaypointMotion`` of three ``CartesianWaypoint`` with its defaults (it comes to
  rest at each waypoint). Measured: from the call until the arm is at rest at the last
  waypoint.
* **preempt**: a move to goal A (``GOAL_A``) started asynchronously and, ``--preempt-ms``
  later, replaced by a move to goal B (``GOAL_B``): ours ``move_to_pose(B,
  asynchronous=True)`` while the first runs, franky ``robot.move(CartesianMotion(B),
  asynchronous=True)`` while its first runs. Measured: from the replacing call until the arm
  is at rest at B; also the distance to B at the call and the largest after it, and the
  fastest any trajectory could reach B at rest from the arm's position and velocity at the
  call (``fastest_to_rest``): for ours within our limits (what they allow at all; also
  with our numbers bounding each axis apart, as franky's ruckig bounds its coordinates),
  for franky within its limits in effect, per axis.

"At rest" is the same for both (``sim_client_franky_moves.watch_rest``, polled every 0.5 ms
from the state each library gives the user, ``panda.get_state()`` and ``robot.state``):
every joint slower than 0.005 rad/s and the end effector within ``--rest-mm`` (2 mm) of
the goal, held for 50 ms; the time is the start of that stretch. Also printed: the final
distance; when the library itself ended the move (our ``MotionHandle.done()``, franky's
``is_in_control`` turning False; "-" if not within the 50 ms the test holds); our path's planned
trajectory duration; per intermediate waypoint, the lowest joint speed seen within 5 mm of
it (about 0: the arm stopped there).

Speed settings: the same factor (``--factor``, default 0.2) for both, our ``speed_factor``
and franky's ``relative_dynamics_factor``. They scale different things: ours the robot's
Cartesian velocity and acceleration limits (panda-py's FR3 ones: 3.0 m/s, 9.0 m/s^2), franky
velocity, acceleration and jerk of its own Cartesian limits (libfranka's constants, 1.7 m/s,
13 m/s^2, 6500 m/s^3, the same for every robot); the limits in effect are printed.
``--franky-factor`` sets franky's apart. At 0.3 franky's start on this path asks the
simulated FR3's joints for more than their 10 rad/s^2 (reflex
``cartesian_motion_generator_joint_velocity_discontinuity``), hence the default 0.2.

Targets (from the issue): our three-waypoint path at rest sooner than franky's (ratio
ours/franky < 1), our preempted move at rest at its new goal no later than franky's (<= 1).
franky runs in its own venv (``tests/peer_envs.py``, installed on first use), driven by
``sim_client_franky_moves.py``; only one client is ever connected to a simulator.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(HERE))

from peer_envs import PeerUnavailable, peer_environ, peer_python  # noqa: E402
from sim_client_franky_moves import watch_rest  # noqa: E402

from panda_py import MotionHandle, Panda, checks  # noqa: E402
from panda_py.libfranka import Frame  # noqa: E402
from panda_py.robots.params import get_robot  # noqa: E402
from panda_py.sim import Simulator, free_loopback_host  # noqa: E402

WAYPOINTS = [[0.12, 0.0, 0.0], [0.12, 0.12, 0.0], [0.0, 0.12, 0.05]]  # [m] from the start
GOAL_A = [0.15, 0.0, 0.0]  # [m] from the start
GOAL_B = [0.0, 0.15, 0.0]  # [m] from the start
CASES = ("path", "preempt")


def fastest_to_rest(p: np.ndarray, v: np.ndarray, v_max: float, a_max: float,
                    per_axis: bool = False) -> float:  # fmt: skip
    """The shortest time [s] from position ``p`` [m] relative to the goal and velocity
    ``v`` [m/s] (3,) to rest at the goal with speed <= ``v_max`` and acceleration <=
    ``a_max``: norms (ours), or with ``per_axis`` each base axis's component (franky's, as
    ruckig bounds each coordinate). To within a few milliseconds, what no trajectory under
    those limits can beat: jerk and the joints' limits are left out, each norm ball is
    replaced by the 32-sided polygon round it in the plane of ``p`` and ``v`` (both allow
    more), and the accelerations are piecewise constant over 100 steps (allowing a little
    less: a few ms on a second). A linear program, bisected to 1 ms; needs SciPy (a
    dependency of the examples extra)."""

    from scipy.optimize import linprog

    if per_axis:  # the axes apart: no plane to choose
        p0, v0 = np.asarray(p, dtype=float), np.asarray(v, dtype=float)
        normals = np.vstack([np.eye(3), -np.eye(3)])
    else:
        e1 = v / np.linalg.norm(v) if np.linalg.norm(v) > 1e-9 else p / np.linalg.norm(p)
        rest = p - (p @ e1) * e1
        e2 = rest / np.linalg.norm(rest) if np.linalg.norm(rest) > 1e-9 else np.zeros(3)
        p0, v0 = np.array([p @ e1, p @ e2]), np.array([v @ e1, v @ e2])
        angles = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
        normals = np.c_[np.cos(angles), np.sin(angles)]
    d, n = p0.size, 100

    def feasible(t: float) -> bool:
        dt = t / n
        rows, bounds = [], []
        for k in range(n):
            for m in normals:
                acc = np.zeros(d * n)
                acc[d * k : d * k + d] = m
                rows.append(acc)
                bounds.append(a_max)
                vel = np.zeros(d * n)
                vel[: d * k + d] = np.tile(m * dt, k + 1)
                rows.append(vel)
                bounds.append(v_max - m @ v0)
        eq, target = [], []
        for c in range(d):
            final_v = np.zeros(d * n)
            final_v[c::d] = dt
            final_p = np.zeros(d * n)
            final_p[c::d] = dt * dt * (n - np.arange(n) - 0.5)
            eq += [final_v, final_p]
            target += [-v0[c], -p0[c] - v0[c] * t]
        res = linprog(np.zeros(d * n), A_ub=np.array(rows), b_ub=bounds, A_eq=np.array(eq),
                      b_eq=target, bounds=(None, None), method="highs")  # fmt: skip
        return bool(res.status == 0)

    lo, hi = 0.0, 5.0
    while hi - lo > 1e-3:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if feasible(mid) else (mid, hi)
    return hi


def running(handle: MotionHandle) -> bool:
    """Whether the move of ``handle`` still runs; raises the error that aborted it."""
    result = handle.result
    if result is not None and result.error is not None:
        raise RuntimeError(f"the move was aborted: {result.error}")
    return result is None


def run_ours(host: str, spec: dict[str, Any]) -> dict[str, Any]:
    """Both cases with our Panda, in this process (its control process beside it, on the
    CPUs ``spec["cpus"]`` where given)."""
    factor, rest = spec["factor"], spec["rest_distance"]
    out: dict[str, Any] = {}
    with Panda(host, cpus=spec["cpus"]) as panda:
        q_start = panda.q
        p0 = panda.get_position()
        quat = panda.get_orientation()  # x, y, z, w

        def read() -> tuple[np.ndarray, np.ndarray]:
            s = panda.get_state()
            return s.dq, s.O_T_EE[12:15]

        def path() -> dict[str, Any]:
            points = [p0 + np.array(o) for o in spec["waypoints"]]
            t0 = time.monotonic()
            handle = panda.move_to_pose(points, [quat] * len(points), speed_factor=factor,
                                        max_deviation=spec["max_deviation"],
                                        asynchronous=True)  # fmt: skip
            r = watch_rest(read, points[-1], t0, points[:-1], lambda: running(handle), rest)
            handle.wait()
            assert handle.result is not None
            r["planned"] = handle.result.duration  # [s] the trajectory's
            return r

        def preempt() -> dict[str, Any]:
            panda.move_to_pose(p0 + np.array(spec["goal_a"]), quat, speed_factor=factor,
                               asynchronous=True)  # fmt: skip
            time.sleep(spec["preempt_ms"] * 1e-3)
            t0 = time.monotonic()
            handle = panda.move_to_pose(p0 + np.array(spec["goal_b"]), quat,
                                        speed_factor=factor, asynchronous=True)  # fmt: skip
            state = panda.get_state()  # the arm just after the call (within a tick of it)
            goal = p0 + np.array(spec["goal_b"])
            r = watch_rest(read, goal, t0, None, lambda: running(handle), rest)
            handle.wait()
            J = panda.get_model().zero_jacobian(Frame.kEndEffector, state)
            twist = np.asarray(J).reshape(6, 7, order="F") @ state.dq
            limits = get_robot("fr3").cartesian
            at_call = state.O_T_EE[12:15] - goal, twist[:3]
            r["call"] = [at_call[0].tolist(), at_call[1].tolist()]  # for the report's bounds
            v_max, a_max = (factor * limits.translation_velocity,
                            factor * limits.translation_acceleration)  # fmt: skip
            try:
                r["bound"] = fastest_to_rest(*at_call, v_max, a_max)
                r["bound_axis"] = fastest_to_rest(*at_call, v_max, a_max, per_axis=True)
            except ImportError:  # no SciPy: no bound
                pass
            return r

        for name, case in (("path", path), ("preempt", preempt)):
            try:
                out[name] = case()
            except Exception as exc:  # report it; the other case still runs
                out[name] = {"error": f"{type(exc).__name__}: {exc}"}
            panda.move_to_joint_position(q_start)
    return out


def run_franky(python: Path, host: str, spec: dict[str, Any]) -> dict[str, Any]:
    """Both cases with franky's client in its venv (the whole process on the CPUs
    ``spec["cpus"]`` where given: its control thread cannot be told from its others)."""
    cmd = [str(python), str(HERE / "sim_client_franky_moves.py"), host, json.dumps(spec)]
    cpus = spec["cpus"]
    pin = None if cpus is None else (lambda: os.sched_setaffinity(0, cpus))
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=180, env=peer_environ(),
                         preexec_fn=pin)  # fmt: skip
    try:
        result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        err = f"client failed (exit {out.returncode}): {out.stderr.strip()[-600:]}"
        return {name: {"error": err} for name in CASES}
    return result


def one_run(library: str, spec: dict[str, Any], python: Path | None) -> dict[str, Any]:
    """A fresh simulator, one library's client, both cases."""
    with Simulator(host=free_loopback_host(), robot="fr3", lockstep=False, versions=(10,),
                   cpus=spec["cpus"]) as sim:  # fmt: skip
        if library == "ours":
            return run_ours(sim.host, spec)
        assert python is not None
        return run_franky(python, sim.host, spec)


# --- report ---------------------------------------------------------------------------


def summary(values: list[float]) -> str:
    if not values:
        return "n/a"
    a = np.asarray(values) * 1e3
    return (f"median {np.median(a):7.0f}  p99 {np.percentile(a, 99):7.0f}  "
            f"worst {a.max():7.0f} ms  (n={a.size})")  # fmt: skip


def ms_list(values: Sequence[float | None]) -> str:
    """Milliseconds, "-" for a value not seen."""
    return ", ".join("-" if v is None else f"{v * 1e3:.0f}" for v in values) or "-"


def _franky_bounds(rows: dict[str, list[dict[str, Any]]], v_ours: float,
                   a_ours: float) -> dict[str, list[float]]:  # fmt: skip
    """For each franky run, from its own state at the replacing call, the fastest to rest
    at B: under its limits in effect per axis (as its ruckig bounds each coordinate,
    ``theirs``), and under ours (``v_ours`` [m/s], ``a_ours`` [m/s^2]) on the norm and per
    axis: whether our limits could match its time even from its state. Empty without
    SciPy."""
    out: dict[str, list[float]] = {"theirs": [], "ours": [], "ours_axis": []}
    for run in rows["franky"]:
        call, lim = run.get("preempt", {}).get("call"), run.get("limits")
        if call is None or lim is None:
            continue
        p, v = np.array(call[0]), np.array(call[1])
        try:
            out["theirs"].append(fastest_to_rest(p, v, lim["translation_velocity"],
                                                 lim["translation_acceleration"],
                                                 per_axis=True))  # fmt: skip
            out["ours"].append(fastest_to_rest(p, v, v_ours, a_ours))
            out["ours_axis"].append(fastest_to_rest(p, v, v_ours, a_ours, per_axis=True))
        except ImportError:  # no SciPy
            return {}
    return out


def report(rows: dict[str, list[dict[str, Any]]], spec: dict[str, Any]) -> None:
    ours_limits = get_robot("fr3").cartesian
    f_ours = spec["factor"]
    print(
        f"\nlimits in effect: ours (speed_factor {f_ours}) "
        f"{f_ours * ours_limits.translation_velocity:.2f} m/s, "
        f"{f_ours * ours_limits.translation_acceleration:.2f} m/s^2 (jerk: the impedance's); "
        f"franky (relative_dynamics_factor {spec['franky_factor']})",
        end="",
    )
    lim = next((r["limits"] for r in rows["franky"] if "limits" in r), None)
    if lim:
        print(f" {lim['translation_velocity']:.2f} m/s, "
              f"{lim['translation_acceleration']:.2f} m/s^2, "
              f"{lim['translation_jerk']:.0f} m/s^3")  # fmt: skip
    else:
        print(" (no run reported them)")
    medians: dict[tuple[str, str], float] = {}
    for case in CASES:
        if case == "path":
            label = "path: call -> at rest at the last of 3 waypoints"
        else:
            label = f"preempt: replacing call ({spec['preempt_ms']:g} ms in) -> at rest at B"
        print(f"\n{label}")
        for lib in ("ours", "franky"):
            results = [r.get(case, {}) for r in rows[lib]]
            ok = [r for r in results if "at_rest" in r]
            times = [r["at_rest"] for r in ok]
            print(f"  {lib:7s} {summary(times)}")
            if times:
                medians[(case, lib)] = float(np.median(times))
                each = ms_list(times)
                err = max(r["error_m"] for r in ok) * 1e3
                print(f"          each [ms]: {each}; worst final error {err:.2f} mm")
                ended = [r.get("ended") for r in ok]
                line = f"          the library's own end of the move [ms]: {ms_list(ended)}"
                if case == "preempt":
                    first = np.median([r["first_m"] for r in ok]) * 1e3
                    far = np.median([r["farthest_m"] for r in ok]) * 1e3
                    line += f"; from B at the call {first:.0f} mm, farthest {far:.0f} mm"
                bounds = [r["bound"] for r in ok if "bound" in r]
                if case == "preempt" and bounds:
                    axis = [r["bound_axis"] for r in ok if "bound_axis" in r]
                    line += (f"; fastest possible under our limits from the state at the "
                             f"call [ms]: {ms_list(bounds)} (our numbers per axis "
                             f"{ms_list(axis)})")  # fmt: skip
                if case == "preempt" and lib == "franky":
                    b = _franky_bounds(rows, f_ours * ours_limits.translation_velocity,
                                       f_ours * ours_limits.translation_acceleration)  # fmt: skip
                    if b.get("theirs"):
                        line += (f"; fastest possible from its state at the call [ms]: under "
                                 f"its limits per axis {ms_list(b['theirs'])}, under "
                                 f"ours {ms_list(b['ours'])} (our numbers per axis "
                                 f"{ms_list(b['ours_axis'])})")  # fmt: skip
                if case == "path" and lib == "ours":
                    line += f"; planned trajectory {ms_list([r['planned'] for r in ok])}"
                print(line)
            if case == "path" and ok:
                slow = np.array([r["slowest_at_marks"] for r in ok])
                print("          lowest joint speed near waypoints 1, 2 [rad/s] (median): "
                      + ", ".join(f"{v:.3f}" for v in np.median(slow, axis=0)))  # fmt: skip
            for r in results:
                if "error" in r:
                    print(f"          ERROR {r['error'][:300]}")
    print("\nratios ours/franky (medians), targets:")
    for case, target, op in (("path", "< 1", float.__lt__), ("preempt", "<= 1", float.__le__)):
        a, b = medians.get((case, "ours")), medians.get((case, "franky"))
        if a is None or b is None:
            print(f"  {case:8s} n/a (a library has no successful run)")
            continue
        ratio = a / b
        verdict = "ok" if op(ratio, 1.0) else "MISSED"
        print(f"  {case:8s} {ratio:.2f}  ({a * 1e3:.0f} vs {b * 1e3:.0f} ms)  "
              f"target {target} [{verdict}]")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="2 runs per library")
    parser.add_argument("--runs", type=int, default=None, help="runs per library (5)")
    parser.add_argument(
        "--factor", type=float, default=0.2,
        help="our speed_factor and franky's relative_dynamics_factor (0.2)",
    )  # fmt: skip
    parser.add_argument(
        "--franky-factor", type=float, default=None,
        help="franky's relative_dynamics_factor apart (default: --factor)",
    )  # fmt: skip
    parser.add_argument("--preempt-ms", type=float, default=300.0,
                        help="when the move to B replaces the one to A [ms] (300)")  # fmt: skip
    parser.add_argument(
        "--rest-mm", type=float, default=2.0,
        help="at rest: this close to the goal [mm] (2)",
    )  # fmt: skip
    parser.add_argument(
        "--max-deviation", type=float, default=0.02,
        help="our path's corner cut at each waypoint [m] (0.02; 0 stops there, as franky)",
    )  # fmt: skip
    parser.add_argument(
        "--cpus", type=checks.cpu_set, default=None,
        help="pin the simulator and each library's control loop to these CPUs (e.g. 1): "
        "ours its control process, franky its whole client (default: unpinned)",
    )  # fmt: skip
    parser.add_argument("--no-franky", action="store_true", help="our side only")
    parser.add_argument("--json", type=Path, default=None, help="write all results here")
    args = parser.parse_args()
    runs = args.runs or (2 if args.quick else 5)
    franky_factor = args.franky_factor if args.franky_factor is not None else args.factor
    if runs < 1:
        parser.error(f"--runs must be >= 1, got {runs}")
    for name, value in (("--factor", args.factor), ("--franky-factor", franky_factor)):
        if not 0.0 < value <= 1.0:
            parser.error(f"{name} must be in (0, 1], got {value}")
    if not args.rest_mm > 0.0:
        parser.error(f"--rest-mm must be > 0, got {args.rest_mm}")
    if not args.preempt_ms >= 0.0:
        parser.error(f"--preempt-ms must be >= 0, got {args.preempt_ms}")
    spec: dict[str, Any] = {
        "factor": args.factor, "franky_factor": franky_factor, "waypoints": WAYPOINTS,
        "goal_a": GOAL_A, "goal_b": GOAL_B, "preempt_ms": args.preempt_ms,
        "rest_distance": args.rest_mm * 1e-3, "max_deviation": args.max_deviation,
        "cpus": sorted(args.cpus) if args.cpus else None,
    }  # fmt: skip
    python: Path | None = None
    if not args.no_franky:
        try:
            python = peer_python("franky")
        except PeerUnavailable as exc:
            print(f"(franky skipped: {exc})")
    libraries = ["ours"] + (["franky"] if python is not None else [])
    print(
        f"bench_franky_moves: {platform.node()}, {os.cpu_count()} CPUs, load average "
        f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, Python {platform.python_version()}; "
        f"{runs} runs per library, factor {args.factor} (franky {franky_factor}), "
        f"preempt at {args.preempt_ms:g} ms, "
        + ("unpinned" if spec["cpus"] is None else f"pinned to CPUs {spec['cpus']}")
    )
    rows: dict[str, list[dict[str, Any]]] = {"ours": [], "franky": []}
    for i in range(runs):
        order = libraries if i % 2 == 0 else libraries[::-1]
        for lib in order:
            lib_spec = {**spec, "factor": franky_factor} if lib == "franky" else spec
            print(f"  run {i + 1}/{runs} {lib:7s} ...", end=" ", flush=True)
            try:
                result = one_run(lib, lib_spec, python)
            except Exception as exc:  # one broken run must not lose the others
                result = {name: {"error": f"{type(exc).__name__}: {exc}"} for name in CASES}
            rows[lib].append(result)
            print(", ".join(
                f"{c} {result[c]['at_rest'] * 1e3:.0f} ms" if "at_rest" in result.get(c, {})
                else f"{c} ERROR" for c in CASES))  # fmt: skip
    report(rows, spec)
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))
        print(f"\nraw results: {args.json}")


if __name__ == "__main__":
    main()
