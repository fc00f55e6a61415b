"""Guarded approaches onto the simulated table: the robot's estimate of the push at the
impact, and whether the reflex fired, ours and franky's on the same simulator.

Run: ``python benchmarks/bench_contact.py [--speeds 0.02 0.05 0.1 0.3] [--robot fr3]
[--no-franky]`` (franky: FR3 only, its libfranka speaks no older protocol).

Per approach point (``POINTS``: six places on the table, away from the cube, where the
arm's effective mass at the hand differs) and speed, from 6 cm above the table, the
collision thresholds at 60 N / 60 Nm as a contact task sets them (examples/16):

* **ours**: ``Panda.move_to_pose`` straight down toward 3 cm inside the table at the
  speed (``speed_factor``) ``until=Force.z < -5.0``;
* **franky**: franky 2.0.0's ``Reaction(Measure.FORCE_Z < -5.0, CartesianStopMotion())``
  on a motion 10 cm down (``tests/conformance/peer_scripts/franky_guarded.py``), the
  speed its own ``relative_dynamics_factor``, the stop braking at 0.3 of the robot's
  dynamics;
* **franky README**: the same with the speed set robot-wide as franky's README does,
  which slows the stop motion as much.

Measured: the largest push on the table in the robot's estimate (``-O_F_ext_hat_K`` z,
every tick: our log, franky's motion callbacks), whether the move ended in the robot's
contact reflex (``cartesian_reflex`` or ``joint_reflex``; any other error is listed), and
the speed at which the hand met the table. Printed per speed: median, p99 and worst of the
peak over the points, and the number of contact reflexes. The simulator runs in lockstep, so the
figures do not depend on the machine's load (they differ between points, not runs).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "conformance"))

from conf_support import run_peer  # noqa: E402
from peer_envs import PeerUnavailable, peer_python  # noqa: E402

import panda_py  # noqa: E402
from panda_py.conditions import Elapsed, Force  # noqa: E402
from panda_py.robots.params import START_POSE, get_robot  # noqa: E402
from panda_py.sim import Simulator, free_loopback_host  # noqa: E402

POINTS = [(0.35, 0.25), (0.45, 0.25), (0.55, 0.25), (0.35, -0.25), (0.45, -0.25),
          (0.55, -0.25)]  # fmt: skip  # [m] where the hand comes down (x, y)
HEIGHT = 0.06  # [m] the end effector above the table at the start
THRESHOLD = 60.0  # [N], [Nm] the collision thresholds of a contact task
BRAKING = 0.3  # franky's stop motion's relative dynamics factor (tests/conformance)


def start_pose(x: float, y: float) -> np.ndarray:
    pose = panda_py.fk(np.array(START_POSE))
    pose[:3, 3] = (x, y, HEIGHT)
    return pose


def ours(host: str, robot: str, speeds: list[float]) -> list[dict[str, Any]]:
    spec = get_robot(robot)
    rows = []
    with panda_py.Panda(host) as panda:
        for point in POINTS:
            for speed in speeds:
                panda.set_default_behavior()  # (recovers a reflex of the last approach)
                t = THRESHOLD
                panda.get_robot().set_collision_behavior(
                    [t] * 7, [t] * 7, [t] * 7, [t] * 7, [t] * 6, [t] * 6, [t] * 6, [t] * 6
                )
                start = start_pose(*point)
                assert panda.move_to_pose(start), "could not reach the start"
                panda.enable_logging(30_000)
                goal = start.copy()
                goal[2, 3] = -0.03
                factor = speed / spec.cartesian.translation_velocity
                handle = panda.move_to_pose(goal, speed_factor=factor,
                                            until=(Force.z < -5.0) | (Elapsed > 5.0),
                                            asynchronous=True)  # fmt: skip
                handle.wait()
                log = panda.get_log()
                panda.disable_logging()
                push = -np.array(log["O_F_ext_hat_K"])[:, 2]
                z = np.array(log["O_T_EE"])[:, 14]
                first = int(np.argmax(push > 1.0))
                error = handle.result.error if handle.result is not None else "no result"
                rows.append({"point": point, "speed": speed, "peak": float(push.max()),
                             "error": None if error is None else str(error),
                             "met": float(z[first - 6] - z[first - 1]) / 5e-3})  # fmt: skip
                if error is not None:  # the reflex holds the arm pressed on the table
                    panda.recover()
                    panda.move_to_pose(start)
    return rows


def franky(sim: Simulator, mode: str, speeds: list[float]) -> list[dict[str, Any]]:
    python = peer_python("franky")
    rows = []
    for point in POINTS:
        q = panda_py.ik(start_pose(*point), np.array(START_POSE)).tolist()

        def place(_: object, q: list[float] = q) -> None:
            sim.set_joint_positions(q)

        out = run_peer(python, "franky_guarded.py", [sim.host, mode, *map(str, speeds)],
                       {"place": place}, timeout=600)  # fmt: skip
        for speed in speeds:
            r = out[f"approach {speed}"]
            if "scenario_error" in r:
                raise RuntimeError(f"franky at {point}, {speed} m/s: {r['scenario_error']}")
            rows.append({"point": point, "speed": speed, "peak": r["peak"],
                         "error": r["error"], "met": r["descent"]})  # fmt: skip
    return rows


def contact_reflex(error: str | None) -> bool:
    """Whether a move's error is the robot's contact reflex (not, say, a motion
    generator's discontinuity)."""
    return error is not None and ("cartesian_reflex" in error or "joint_reflex" in error)


def report(name: str, rows: list[dict[str, Any]], speeds: list[float]) -> None:
    print(f"{name}: peak push in the estimate [N] over {len(POINTS)} points; contact reflexes")
    for speed in speeds:
        at = [r for r in rows if r["speed"] == speed]
        peak = np.array([r["peak"] for r in at])
        met = np.array([r["met"] for r in at])
        reflexes = sum(contact_reflex(r["error"]) for r in at)
        print(f"  {speed * 100:4.0f} cm/s: median {np.median(peak):6.1f}  p99 "
              f"{np.percentile(peak, 99):6.1f}  worst {peak.max():6.1f}   reflex "
              f"{reflexes}/{len(at)}   met the table at {met.min() * 100:.1f}-"
              f"{met.max() * 100:.1f} cm/s")  # fmt: skip
        for r in at:
            if r["error"] is not None and not contact_reflex(r["error"]):
                reason = r["error"].splitlines()[0][-80:]
                print(f"      {r['point']}: ended otherwise: {reason}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--speeds", type=float, nargs="+", default=[0.02, 0.05, 0.1, 0.3],
                   help="approach speeds [m/s]")  # fmt: skip
    p.add_argument("--robot", default="fr3", choices=("fer", "fr3"))
    p.add_argument("--no-franky", action="store_true", help="ours only")
    args = p.parse_args()
    print(f"{platform.node()} {platform.machine()} Python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M')}, {args.robot}, thresholds {THRESHOLD:.0f} N, "
          f"lockstep")  # fmt: skip
    with Simulator(free_loopback_host(), robot=args.robot, lockstep=True) as sim:
        report(
            "ours (Panda.move_to_pose until Force.z < -5)",
            ours(sim.host, args.robot, args.speeds),
            args.speeds,
        )
    if args.no_franky:
        return
    if args.robot != "fr3":  # franky 2.0.0's libfranka speaks the FR3's protocol only
        print("franky: not run (FR3 only)")
        return
    try:
        peer_python("franky")
    except PeerUnavailable as exc:
        print(f"franky: not run ({exc})")
        return
    for mode, name in ((str(BRAKING), f"franky 2.0.0 (motion's factor, stop at {BRAKING})"),
                       ("robot", "franky 2.0.0 README (robot-wide factor)")):  # fmt: skip
        with Simulator(free_loopback_host(), robot=args.robot, lockstep=True,
                       versions=(10,)) as sim:  # fmt: skip
            report(name, franky(sim, mode, args.speeds), args.speeds)


if __name__ == "__main__":
    main()
