"""Shared helpers of the conformance tests: run a real Franka client (a peer script in its
own venv) against a simulator, answer its requests, and check kinematics independently.

A peer script talks line by line on stdout/stdin (see ``peer_scripts/peer_io.py``):

* ``EVENT <name> <json>``: the peer waits; the test runs ``handlers[name](arg)`` (e.g.
  injects a reflex or teleports the arm) and answers with one JSON line on stdin.
* ``RESULT <json>``: the peer's results (one dict of scenarios), its last word.

Anything else the peer prints is kept as its log for failure messages.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

sys.path.append(str(Path(__file__).resolve().parents[1]))  # tests/ for peer_envs

from peer_envs import PeerUnavailable, peer_python

from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot

PEER_SCRIPTS = Path(__file__).resolve().parent / "peer_scripts"

# pytest-timeout of the conformance tests [s]. It includes the module fixtures: on first use
# they create the peer's venv (bounded at 900 s by peer_envs), then start the simulator and
# run the peer (bounded by run_peer's own timeout); a normal run takes a few seconds.
PEER_TEST_TIMEOUT = 1200

Handler = Callable[[Any], Any]


def peer_or_skip(name: str) -> Path:
    """The interpreter of peer ``name``; skips the test when its venv cannot be made."""
    try:
        return peer_python(name)
    except PeerUnavailable as exc:
        pytest.skip(str(exc))


class PeerError(AssertionError):
    """The peer process did not deliver a RESULT line."""


def run_peer(
    python: Path,
    script: str,
    args: list[str],
    handlers: Mapping[str, Handler] | None = None,
    timeout: float = 60.0,
) -> dict[str, Any]:
    """Run ``peer_scripts/<script>`` with ``args``; serve its events; return its RESULT."""
    handlers = handlers or {}
    with tempfile.TemporaryFile("w+") as err:
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        proc = subprocess.Popen(
            [str(python), str(PEER_SCRIPTS / script), *args],
            env=env,  # the peer must import its own panda_py, never this repository's
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            bufsize=1,
        )
        timer = threading.Timer(timeout, proc.kill)
        timer.start()
        log: list[str] = []
        result: dict[str, Any] | None = None
        try:
            assert proc.stdout is not None and proc.stdin is not None
            for line in proc.stdout:
                line = line.rstrip("\n")
                if line.startswith("EVENT "):
                    _, name, payload = line.split(" ", 2)
                    log.append(line)
                    reply = handlers[name](json.loads(payload))
                    proc.stdin.write(json.dumps(reply) + "\n")
                    proc.stdin.flush()
                elif line.startswith("RESULT "):
                    result = json.loads(line[len("RESULT ") :])
                else:
                    log.append(line)
            proc.wait()
        finally:
            timer.cancel()
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        err.seek(0)
        stderr = err.read()
    if result is None:
        raise PeerError(
            f"{script} gave no result (exit {proc.returncode}, timeout {timeout} s)\n"
            f"stdout:\n" + "\n".join(log[-40:]) + f"\nstderr:\n{stderr[-4000:]}"
        )
    result["_log"] = log
    result["_stderr"] = stderr
    return result


def scenario(result: Mapping[str, Any], name: str) -> dict[str, Any]:
    """One scenario's outcome; fails with the peer's exception if the scenario raised."""
    out = result.get(name)
    assert out is not None, f"scenario {name!r} did not run; peer said {sorted(result)}"
    assert "scenario_error" not in out, (
        f"scenario {name!r} raised in the peer: {out['scenario_error']}\n{out['traceback']}"
    )
    return dict(out)


# ---- an independent forward kinematics (modified DH, straight from the table) ----------


def _dh(alpha: float, a: float, d: float, theta: float) -> np.ndarray:
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def hand_F_T_EE() -> np.ndarray:
    """Flange -> Franka Hand TCP: TransZ(tcp_offset) RotZ(tcp_rotz)."""
    c, s = math.cos(FRANKA_HAND.tcp_rotz), math.sin(FRANKA_HAND.tcp_rotz)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[2, 3] = FRANKA_HAND.tcp_offset
    return T


def fk(q: Any, F_T_EE: np.ndarray | None = None, robot: str = "fer") -> np.ndarray:
    """O_T_EE (4x4) at ``q`` [rad] by the modified DH table; flange if ``F_T_EE`` is None."""
    dh = get_robot(robot).dh
    T = np.eye(4)
    for i in range(7):
        T = T @ _dh(dh.alpha[i], dh.a[i], dh.d[i], float(q[i]))
    T = T @ _dh(0.0, 0.0, dh.flange_d, 0.0)
    return T @ F_T_EE if F_T_EE is not None else T


def zero_jacobian(q: Any, F_T_EE: np.ndarray, robot: str = "fer", h: float = 1e-6) -> np.ndarray:
    """6x7 geometric Jacobian (linear; angular) of the EE in the base frame, by central
    differences of :func:`fk`."""
    q = np.asarray(q, dtype=float)
    J = np.zeros((6, 7))
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = h
        Tp, Tm = fk(q + dq, F_T_EE, robot), fk(q - dq, F_T_EE, robot)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ fk(q, F_T_EE, robot)[:3, :3].T
        J[3:, i] = [dR[2, 1], dR[0, 2], dR[1, 0]]
    return J


def pose_error(T: np.ndarray, T_goal: np.ndarray) -> tuple[float, float]:
    """(distance [m], rotation angle [rad]) between two poses."""
    dR = T[:3, :3].T @ T_goal[:3, :3]
    angle = math.acos(max(-1.0, min(1.0, (np.trace(dR) - 1.0) / 2.0)))
    return float(np.linalg.norm(T[:3, 3] - T_goal[:3, 3])), angle


def ik(T_goal: np.ndarray, q_init: Any = START_POSE, robot: str = "fer") -> np.ndarray:
    """Joint positions whose hand TCP is at ``T_goal`` (damped least squares from
    ``q_init``); raises if it does not converge to 0.1 mm / 1 mrad."""
    F_T_EE = hand_F_T_EE()
    q = np.array(q_init, dtype=float)
    for _ in range(100):
        T = fk(q, F_T_EE, robot)
        e = np.zeros(6)
        e[:3] = T_goal[:3, 3] - T[:3, 3]
        R = T_goal[:3, :3] @ T[:3, :3].T
        e[3:] = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        if np.linalg.norm(e[:3]) < 1e-5 and np.linalg.norm(e[3:]) < 1e-5:
            return q
        J = zero_jacobian(q, F_T_EE, robot)
        step = J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(6), e)
        q = q + step * min(1.0, 0.2 / float(np.abs(step).max()))  # small steps converge
    dist, angle = pose_error(fk(q, F_T_EE, robot), T_goal)
    if dist > 1e-4 or angle > 1e-3:
        raise AssertionError(f"test IK did not converge: {dist} m, {angle} rad")
    return q


def col_major(flat: Any) -> np.ndarray:
    """libfranka's column-major 16-vector -> 4x4."""
    return np.asarray(flat, dtype=float).reshape(4, 4).T


def cube_grasp_pose(cube_position: Any) -> np.ndarray:
    """TCP pose with the fingers straddling the cube (hand pointing down, as at START_POSE)."""
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = cube_position
    T[2, 3] += 0.005  # a little above the centre keeps the finger tips off the table
    return T


# ---- checks shared by the libfranka-based peers (v5 and v10 report alike) ---------------

JOINT_TOL = 1e-3  # [rad] a motion generator's goal vs the measured end position


def check_joint_position(r: Mapping[str, Any], idle: str) -> None:
    """A 2 s cosine move of joint 1 by +0.2 rad, finished by motion_finished."""
    before, after = np.array(r["q_before"]), np.array(r["q_after"])
    assert after[0] - before[0] == pytest.approx(0.2, abs=JOINT_TOL)
    np.testing.assert_allclose(after[1:], before[1:], atol=JOINT_TOL)
    assert 1995 <= r["callbacks"] <= 2010, r["callbacks"]  # one per 1 ms tick for 2 s
    assert r["sim_time"] == pytest.approx(2.0, abs=0.005)
    assert r["robot_mode"] == idle


def check_torque(r: Mapping[str, Any], idle: str) -> None:
    """1 s PD hold (the arm stays), then 1 s of a sine pulse on joint 1 above its dry
    friction (2 Nm on a FER, 4 Nm on an FR3)."""
    assert 995 <= r["hold"]["callbacks"] <= 1010
    assert r["hold"]["max_dev"] < 1e-3
    np.testing.assert_allclose(r["q_hold_end"], r["q0"], atol=1e-3)
    assert 995 <= r["push_callbacks"] <= 1010
    push = np.array(r["q_push_end"]) - np.array(r["q_hold_end"])
    assert push[0] > 0.02, f"joint 1 did not follow the positive torque: {push[0]} rad"
    # the others' PD (60 Nm/rad) holds them, short of their dry friction's reach
    # (1.1 Nm / 60 Nm/rad = 19 mrad on an FR3)
    assert np.abs(push[1:]).max() < 0.03, push
    # After the torque motion ends the robot holds the arm where it is.
    np.testing.assert_allclose(r["q_settled"], r["q_push_end"], atol=5e-3)
    assert r["robot_mode"] == idle


def check_reflex_recovery(r: Mapping[str, Any], modes: Mapping[str, str]) -> None:
    assert r["exception_type"] is not None, "the motion ran on through the reflex"
    assert "joint_reflex" in r["exception"]
    assert "reflex" in r["exception"]
    assert r["mode_after_reflex"] == modes["reflex"]
    assert "joint_reflex" in r["errors_after_reflex"]
    assert "joint_reflex" in r["last_motion_errors"]
    assert r["mode_after_recovery"] == modes["idle"]
    assert r["errors_after_recovery"] is False
    moved = np.array(r["q_after_new_motion"]) - np.array(r["q_before_new_motion"])
    assert moved[0] == pytest.approx(-0.05, abs=JOINT_TOL)
    assert 495 <= r["new_motion_callbacks"] <= 510


# The values the setter scenarios send (see peer_scripts/*_lowlevel.py).
SET_NE_T_EE = col_major([1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0.01, 0.0, 0.02, 1.0])
SET_EE_T_K = col_major([1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0.0, 0.0, 0.05, 1.0])


def check_setters(
    r: Mapping[str, Any], sim_state: Mapping[str, Any], idle: str, atol: float
) -> None:
    """The peer's and the simulator's view of set_ee / set_k / set_load."""
    F_T_EE = hand_F_T_EE() @ SET_NE_T_EE
    np.testing.assert_allclose(col_major(r["F_T_EE"]), F_T_EE, atol=atol)
    np.testing.assert_allclose(col_major(r["EE_T_K"]), SET_EE_T_K, atol=atol)
    assert r["m_load"] == pytest.approx(0.5, abs=atol)
    np.testing.assert_allclose(r["F_x_Cload"], [0.0, 0.0, 0.05], atol=atol)
    assert r["robot_mode"] == idle
    np.testing.assert_allclose(col_major(sim_state["NE_T_EE"]), SET_NE_T_EE, atol=1e-12)
    np.testing.assert_allclose(col_major(sim_state["F_T_EE"]), F_T_EE, atol=1e-12)
    np.testing.assert_allclose(col_major(sim_state["EE_T_K"]), SET_EE_T_K, atol=1e-12)
    assert float(sim_state["m_load"][0]) == 0.5


def check_gripper(r: Mapping[str, Any], cube_before: Any, cube_after: Any) -> None:
    assert r["server_version"] == 3
    assert r["homing"] is True
    assert r["width_homed"] == pytest.approx(FRANKA_HAND.max_width, abs=1e-3)
    assert r["max_width"] == pytest.approx(FRANKA_HAND.max_width, abs=1e-6)
    assert r["move"] is True
    assert r["width_moved"] == pytest.approx(0.05, abs=2e-3)
    assert r["grasp_air"] is False, "grasping thin air must report failure"
    assert r["width_air"] < 0.005
    assert r["open"] is True
    assert r["grasp_cube"] is True, "the grasp of the 4 cm cube failed"
    assert 0.035 < r["width_cube"] < 0.042, r["width_cube"]
    assert r["is_grasped"] is True
    assert r["release"] is True
    assert r["width_released"] == pytest.approx(FRANKA_HAND.max_width, abs=2e-3)
    # The cube was held, not knocked off the table.
    np.testing.assert_allclose(cube_after, cube_before, atol=0.01)


class LowLevelHandlers:
    """Test-side answers to the low-level peer scripts' events, recording what the
    simulator showed at each."""

    def __init__(self, sim: Any, model_q: list[list[float]] | None = None) -> None:
        self.sim = sim
        self.model_q = model_q or []
        self.seen: dict[str, Any] = {}

    def handlers(self) -> dict[str, Handler]:
        return {
            "in_motion": self.in_motion,
            "setters_applied": self.setters_applied,
            "teleport_to_cube": self.teleport_to_cube,
            "teleport_home": self.teleport_home,
            "model_pose": self.model_pose,
        }

    def in_motion(self, arg: Any) -> None:
        self.seen["mode_before_reflex"] = int(self.sim.state()["robot_mode"])
        self.sim.inject_reflex("joint_reflex")

    def setters_applied(self, arg: Any) -> None:
        self.seen["setters_state"] = self.sim.state()

    def teleport_to_cube(self, arg: Any) -> None:
        cube = self.sim.state()["cube_position"]
        self.seen["cube_before"] = cube
        q = ik(cube_grasp_pose(cube), robot=self.sim.config.robot)
        self.sim.set_joint_positions(q.tolist())

    def teleport_home(self, arg: Any) -> None:
        self.seen["cube_after"] = self.sim.state()["cube_position"]
        self.sim.set_joint_positions(START_POSE)

    def model_pose(self, i: int) -> None:
        self.sim.set_joint_positions(self.model_q[i])
