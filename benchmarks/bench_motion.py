"""Trajectory planning and sampling time, ours against panda-python 1.1.1 in the same run.

Construction of JointTrajectory and CartesianTrajectory through 5 random in-limit
waypoints (speed_factor 0.2; max_deviation 0 as panda-py's default, and 0.05), and the
time of one get_joint_positions(t) / get_position(t) call at a random t. The peer runs in
its own virtual environment (tests/peer_envs.py) as a subprocess on the same waypoints.

    python benchmarks/bench_motion.py [--sets 200] [--samples 20000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from panda_py.motion import CartesianTrajectory, JointTrajectory
from panda_py.robots.params import FER

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

N_WAYPOINTS = 5

# Shared by both sides: reads {"joint": [...], "cart": [...], "samples": n, "dev": [...]},
# prints {name: [seconds, ...]}. Kept free of our package so the peer can run it.
TIMING_SCRIPT = r"""
import json, sys, time
import numpy as np
from panda_py.motion import JointTrajectory, CartesianTrajectory

def timed(fn, items):
    out = []
    for item in items:
        t0 = time.perf_counter(); fn(item); out.append(time.perf_counter() - t0)
    return out

cfg = json.load(sys.stdin)
joint = [[np.array(w) for w in ws] for ws in cfg["joint"]]
cart = [([np.array(p) for p in ps], [np.array(q) for q in qs]) for ps, qs in cfg["cart"]]
res = {}
for dev in cfg["dev"]:
    res[f"JointTrajectory(dev={dev})"] = timed(lambda w: JointTrajectory(w, 0.2, dev), joint)
    res[f"CartesianTrajectory(dev={dev})"] = timed(
        lambda c: CartesianTrajectory(c[0], c[1], 0.2, dev), cart)
traj = JointTrajectory(joint[0], 0.2, 0.0)
ts = list(np.random.default_rng(0).uniform(0, traj.get_duration(), cfg["samples"]))
get = traj.get_joint_positions
per = []
for chunk in range(20):
    part = ts[chunk::20]
    t0 = time.perf_counter()
    for t in part:
        get(t)
    per.append((time.perf_counter() - t0) / len(part))
res["get_joint_positions(t)"] = per
ctraj = CartesianTrajectory(cart[0][0], cart[0][1], 0.2, 0.0)
getp = ctraj.get_position
per = []
for chunk in range(20):
    part = ts[chunk::20]
    t0 = time.perf_counter()
    for t in part:
        getp(t)
    per.append((time.perf_counter() - t0) / len(part))
res["get_position(t)"] = per
json.dump(res, sys.stdout)
"""


def waypoint_sets(sets: int) -> dict[str, object]:
    rng = np.random.default_rng(1)
    lo, hi = np.array(FER.joints.q_min), np.array(FER.joints.q_max)
    joint = rng.uniform(lo, hi, size=(sets, N_WAYPOINTS, 7)).tolist()
    cart = []
    for _ in range(sets):
        positions = rng.uniform([0.3, -0.3, 0.1], [0.7, 0.3, 0.7], size=(N_WAYPOINTS, 3))
        quats = rng.normal(size=(N_WAYPOINTS, 4))
        quats /= np.linalg.norm(quats, axis=1, keepdims=True)
        cart.append((positions.tolist(), quats.tolist()))
    return {"joint": joint, "cart": cart}


def run_ours(cfg: dict[str, object]) -> dict[str, list[float]]:
    out = subprocess.run(
        [sys.executable, "-c", TIMING_SCRIPT],
        input=json.dumps(cfg),
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)  # type: ignore[no-any-return]


def run_peer(cfg: dict[str, object]) -> dict[str, list[float]] | None:
    try:
        from peer_envs import PeerUnavailable, peer_python

        python = peer_python("panda-python")
    except (ImportError, PeerUnavailable) as exc:
        print(f"peer unavailable: {exc}")
        return None
    out = subprocess.run(
        [str(python), "-c", TIMING_SCRIPT],
        input=json.dumps(cfg),
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)  # type: ignore[no-any-return]


def stats(values: list[float]) -> tuple[float, float, float, float]:
    a = np.array(values)
    return float(np.median(a)), float(a.mean()), float(np.percentile(a, 99)), float(a.max())


def fmt(seconds: float) -> str:
    return f"{seconds * 1e6:9.2f} us" if seconds < 1e-3 else f"{seconds * 1e3:9.3f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=200, help="waypoint sets per case")
    parser.add_argument("--samples", type=int, default=20000, help="timed get_*(t) calls")
    args = parser.parse_args()
    cfg = waypoint_sets(args.sets)
    cfg.update(samples=args.samples, dev=[0.0, 0.05])
    # sanity: the same sets plan on our side without error
    JointTrajectory(cfg["joint"][0])  # type: ignore[index]
    CartesianTrajectory(*cfg["cart"][0])  # type: ignore[index]
    theirs = run_peer(cfg)
    ours = run_ours(cfg)
    header = (
        f"{'case':34} {'ours median':>12} {'p99':>12} {'worst':>12}"
        f" {'panda-py median':>16} {'p99':>12} {'worst':>12} {'ratio':>7}"
    )
    print(f"{N_WAYPOINTS} random in-limit waypoints, {args.sets} sets, speed_factor 0.2")
    print(header)
    for name, values in ours.items():
        med, _, p99, worst = stats(values)
        line = f"{name:34} {fmt(med):>12} {fmt(p99):>12} {fmt(worst):>12}"
        if theirs is not None and name in theirs:
            tmed, _, tp99, tworst = stats(theirs[name])
            line += f" {fmt(tmed):>16} {fmt(tp99):>12} {fmt(tworst):>12} {med / tmed:7.3f}"
        print(line)
    print("ratio = ours / panda-py (median); sampling rows are per call")


if __name__ == "__main__":
    main()
