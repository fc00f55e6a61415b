"""pylibfranka 0.21.3 (protocol v10): its joint impedance example's behaviour, written from
what the example documents: active torque control (``start_torque_control``, then
``readOnce``/``writeOnce`` in the caller's loop) rendering a spring-damper of 50 Nm/rad and
2 sqrt(50) Nm s/rad on every joint plus the model's Coriolis torques, whose equilibrium
follows minimum-jerk paths of 3 s (wall clock) through target configurations, waiting
0.5 s at each; collision thresholds 100 on everything. Without the drives' rotor inertia the
wrist's damping at 1 ms diverged within 0.1 s (``controller_torque_discontinuity``).

Usage: plf_joint_impedance.py HOST. See test_conf_pylibfranka_impedance.py for the asserts.
"""

from __future__ import annotations

import math
import sys
import time

import pylibfranka as plf
from peer_io import Scenarios, floats

HOST = sys.argv[1]
STIFFNESS = 50.0  # [Nm/rad] on every joint
DAMPING = 2.0 * math.sqrt(STIFFNESS)  # [Nm s/rad]
SEGMENT = 3.0  # [s] of each minimum-jerk path
WAIT = 0.5  # [s] at each target
# the first targets of the example's sequence: its home, then the arm to the right
TARGETS = [
    [0.0, -0.3, 0.0, -1.8, 0.0, 1.5, 0.0],
    [0.5, -0.3, 0.0, -1.8, 0.0, 1.5, 0.0],
]


def smooth(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def example() -> dict:
    robot = plf.Robot(HOST, plf.RealtimeConfig.kIgnore)
    robot.set_collision_behavior([100.0] * 7, [100.0] * 7, [100.0] * 6, [100.0] * 6)
    start = floats(robot.read_once().q)
    control = robot.start_torque_control()
    model = robot.load_model()
    worst_error = [0.0] * len(TARGETS)
    final_error, peak_speed, ticks = [], 0.0, 0
    error = None
    try:
        for i, goal in enumerate(TARGETS):
            t0 = time.monotonic()
            while True:
                state, _ = control.readOnce()
                ticks += 1
                t = time.monotonic() - t0
                s = smooth(t / SEGMENT)
                q_eq = [a + s * (b - a) for a, b in zip(start, goal, strict=True)]
                q, dq = floats(state.q), floats(state.dq)
                coriolis = floats(model.coriolis(state))
                tau = [
                    -STIFFNESS * (q[j] - q_eq[j]) - DAMPING * dq[j] + coriolis[j] for j in range(7)
                ]
                command = plf.Torques(tau)
                last = t >= SEGMENT + WAIT and i == len(TARGETS) - 1
                command.motion_finished = last
                control.writeOnce(command)
                peak_speed = max(peak_speed, max(abs(v) for v in dq))
                off = max(abs(a - b) for a, b in zip(q, goal, strict=True))
                if t >= SEGMENT:
                    worst_error[i] = max(worst_error[i], off)
                if t >= SEGMENT + WAIT:
                    final_error.append(off)
                    start = list(goal)
                    break
    except Exception as exc:  # the example prints it and stops the robot
        error = f"{type(exc).__name__}: {exc}"
        robot.stop()
    state = robot.read_once()
    return {
        "error": error,
        "ticks": ticks,
        "final_error": final_error,
        "settled_error": worst_error,
        "peak_speed": peak_speed,
        "mode_after": state.robot_mode.name,
        "errors_after": bool(state.current_errors),
    }


if __name__ == "__main__":
    scenarios = Scenarios()
    scenarios.run("example", example)
    scenarios.finish()
