"""Trajectory durations against panda-python 1.1.1 (the real panda-py, in its own venv).

Where the two agree: single straight moves in joint space, and Cartesian moves along one
axis or pure rotations (panda-py bounds each translation axis separately, we bound the
norm as Franka specifies it, so the two agree only on axis-aligned moves).

Where they differ, and why:
- ``max_deviation=0`` with several waypoints: panda-py does not stop at the corners; its
  velocity jumps there (sampled at 1 kHz its accelerations exceed the bounds by orders of
  magnitude), ours stops, so ours is longer.
- Blends: ours are bounded in short stretches with constant bounds (a conservative
  simplification of the phase-plane integration on arcs), so ours is a few percent longer.
"""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from peer_envs import PeerUnavailable, peer_environ, peer_python

from panda_py.motion import CartesianTrajectory, JointTrajectory
from panda_py.robots.params import FER, START_POSE

pytestmark = [pytest.mark.peer, pytest.mark.timeout(300)]

PEER_SCRIPT = r"""
import json, sys
import numpy as np
from panda_py.motion import JointTrajectory, CartesianTrajectory
out = []
for case in json.load(sys.stdin):
    if case["kind"] == "joint":
        t = JointTrajectory([np.array(w) for w in case["waypoints"]], case["sf"], case["dev"])
    else:
        pos = [np.array(p) for p in case["positions"]]
        ori = [np.array(q) for q in case["orientations"]]
        t = CartesianTrajectory(pos, ori, case["sf"], case["dev"])
    res = {"duration": t.get_duration()}
    if case.get("sample"):
        ts = np.arange(0.0, t.get_duration(), 1e-3)
        res["q"] = [t.get_joint_positions(x).tolist() for x in ts]
    out.append(res)
json.dump(out, sys.stdout)
"""


@pytest.fixture(scope="module")
def peer() -> object:
    try:
        python = peer_python("panda-python")
    except PeerUnavailable as exc:
        pytest.skip(str(exc))

    def run(cases: list[dict[str, object]]) -> list[dict[str, object]]:
        proc = subprocess.run(
            [str(python), "-c", PEER_SCRIPT],
            env=peer_environ(),
            input=json.dumps(cases),
            capture_output=True,
            text=True,
            check=True,
            timeout=240,
        )
        return json.loads(proc.stdout)  # type: ignore[no-any-return]

    return run


def _in_limits(rng: np.random.Generator, n: int, spread: float) -> list[list[float]]:
    lo, hi = np.array(FER.joints.q_min), np.array(FER.joints.q_max)
    q = np.array(START_POSE) + rng.uniform(-spread, spread, size=(n, 7))
    return np.clip(q, lo, hi).tolist()


def test_single_joint_segments_match(peer) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(31)
    cases = [
        {"kind": "joint", "waypoints": _in_limits(rng, 2, s), "sf": sf, "dev": 0.0}
        for s in (0.01, 0.3, 1.0)
        for sf in (0.1, 0.2, 0.7, 1.0)
    ]
    for case, theirs in zip(cases, peer(cases), strict=True):
        ours = JointTrajectory(case["waypoints"], case["sf"], case["dev"]).get_duration()
        assert ours == pytest.approx(theirs["duration"], rel=1e-4)


def test_axis_aligned_cartesian_moves_match(peer) -> None:  # type: ignore[no-untyped-def]
    p0 = [0.4, 0.0, 0.4]
    q0 = [1.0, 0.0, 0.0, 0.0]
    cases = []
    for sf in (0.2, 1.0):
        for axis in range(3):
            for d in (0.005, 0.2):
                p1 = list(p0)
                p1[axis] += d
                cases.append({"positions": [p0, p1], "orientations": [q0, q0], "sf": sf})
        for angle in (0.05, 1.0):
            q1 = [np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)]  # q0 then about z
            cases.append({"positions": [p0, p0], "orientations": [q0, q1], "sf": sf})
    for c in cases:
        c.update(kind="cartesian", dev=0.0)
    for case, theirs in zip(cases, peer(cases), strict=True):
        ours = CartesianTrajectory(case["positions"], case["orientations"], case["sf"])
        assert ours.get_duration() == pytest.approx(theirs["duration"], rel=1e-4)


def test_blended_joint_paths_are_close(peer) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(32)
    cases = [
        {"kind": "joint", "waypoints": _in_limits(rng, 5, 0.6), "sf": sf, "dev": dev}
        for dev in (0.02, 0.1)
        for sf in (0.2, 1.0)
        for _ in range(3)
    ]
    ratios = []
    for case, theirs in zip(cases, peer(cases), strict=True):
        ours = JointTrajectory(case["waypoints"], case["sf"], case["dev"]).get_duration()
        ratios.append(ours / theirs["duration"])
    # panda-py overshoots its bounds by up to ~1 % on blends; ours keeps them
    assert 0.99 <= min(ratios) and max(ratios) <= 1.10, ratios


def test_panda_py_jumps_velocity_at_unblended_corners(peer) -> None:  # type: ignore[no-untyped-def]
    """Why our stopping paths are longer: panda-py's are not feasible."""
    rng = np.random.default_rng(33)
    case = {"kind": "joint", "waypoints": _in_limits(rng, 4, 0.5), "sf": 0.5, "dev": 0.0}
    (theirs,) = peer([dict(case, sample=True)])
    amax = 0.5 * np.array(FER.joints.ddq_max)
    q = np.array(theirs["q"])
    peer_peak = (np.abs(np.diff(q, 2, axis=0)) / 1e-6 / amax).max()
    ours = JointTrajectory(case["waypoints"], 0.5)
    q_ours = ours.sample(np.arange(0.0, ours.get_duration(), 1e-3)).positions
    our_peak = (np.abs(np.diff(q_ours, 2, axis=0)) / 1e-6 / amax).max()
    assert peer_peak > 10.0
    assert our_peak <= 1.0 + 1e-6
    assert ours.get_duration() > theirs["duration"]
