"""franky-control 2.0.0's side of ``bench_franky_moves.py``, and the at-rest watch both sides
share.

Runs inside franky's venv (``tests/peer_envs.py``) and never imports panda_py: connects to
the robot at HOST (``RealtimeConfig.Ignore``), then

* **path**: a ``CartesianWaypointMotion`` through the waypoints (``CartesianWaypoint`` of an
  ``Affine``, franky's defaults otherwise: it stops at each waypoint) with
  ``relative_dynamics_factor=FACTOR``, started asynchronously; the time from the call until
  the arm is at rest at the last waypoint (:func:`watch_rest`);
* back to the start joint positions (a ``JointMotion``, untimed);
* **preempt**: a ``CartesianMotion`` to goal A started asynchronously, replaced after
  ``preempt_ms`` (wall clock) by ``robot.move`` of a ``CartesianMotion`` to goal B (franky
  queues it and it takes over the running one); the time from the replacing call until the
  arm rests at B, and the arm's position relative to B and velocity just after the call.

Geometry and thresholds come as one JSON argument (offsets [m] from the start position,
orientation kept). Prints one JSON line: per case the durations [s], or the error.

Run: ``<franky venv>/bin/python benchmarks/sim_client_franky_moves.py HOST SPEC_JSON``.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

REST_SPEED = 0.005  # [rad/s] every joint slower than this ...
REST_DISTANCE = 2e-3  # [m] ... and the end effector this close to the goal ...
REST_HOLD = 0.05  # [s] ... for this long (wall clock) counts as at rest
POLL = 5e-4  # [s] between two looks at the state
WATCH_TIMEOUT = 20.0  # [s]

Reader = Callable[[], tuple[np.ndarray, np.ndarray]]  # -> (dq [rad/s], position [m])


def watch_rest(
    read: Reader,
    goal: np.ndarray,
    start: float,
    marks: list[np.ndarray] | None = None,
    check: Callable[[], bool] | None = None,
    rest_distance: float = REST_DISTANCE,
) -> dict[str, Any]:
    """Poll ``read`` until the arm has been at rest within ``rest_distance`` [m] of ``goal``
    for REST_HOLD; ``check``, called on every look, tells whether the library still runs
    the move (and raises if the move failed). Returns, in seconds after ``start`` (a
    ``time.monotonic()`` value): ``at_rest``, the first instant of that stretch, and
    ``ended``, when ``check`` last said the move no longer runs (None if not seen); and
    ``error_m``, ``first_m``, ``farthest_m``: the distance to the goal then, at the first
    look and the largest seen [m]; and ``slowest_at_marks``, per point of ``marks``
    the lowest joint speed seen within 5 mm of it [rad/s] (near 0: the arm stopped there)."""
    goal = np.asarray(goal, dtype=float)
    since: float | None = None
    slowest = [float("inf")] * len(marks or [])
    deadline = start + WATCH_TIMEOUT
    ended: float | None = None
    first: float | None = None
    farthest = 0.0
    seen_running = False  # franky reports a move just started as not running for a moment
    while True:
        running = check() if check is not None else True
        dq, p = read()
        now = time.monotonic()
        if running:
            seen_running, ended = True, None
        elif ended is None and seen_running:
            ended = now - start
        speed = float(np.abs(dq).max())
        distance = float(np.linalg.norm(p - goal))
        first = distance if first is None else first
        farthest = max(farthest, distance)
        for i, m in enumerate(marks or []):
            if float(np.linalg.norm(p - m)) < 5e-3:
                slowest[i] = min(slowest[i], speed)
        if speed < REST_SPEED and distance < rest_distance:
            if since is None:
                since = now
            elif now - since >= REST_HOLD:
                return {
                    "ended": ended,
                    "at_rest": since - start,
                    "error_m": distance,
                    "first_m": first,
                    "farthest_m": farthest,
                    "slowest_at_marks": slowest,
                }
        else:
            since = None
        if now > deadline:
            raise TimeoutError(
                f"not at rest at the goal within {WATCH_TIMEOUT} s: "
                f"{distance * 1e3:.1f} mm away, joint speed {speed:.4f} rad/s"
            )
        time.sleep(POLL)


def main() -> None:
    from franky import (
        Affine,
        CartesianMotion,
        CartesianWaypoint,
        CartesianWaypointMotion,
        JointMotion,
        RealtimeConfig,
        Robot,
    )

    host, spec = sys.argv[1], json.loads(sys.argv[2])
    factor = float(spec["factor"])
    rest = float(spec["rest_distance"])
    robot = Robot(host, realtime_config=RealtimeConfig.Ignore)
    q_start = np.array(robot.state.q)
    pose = robot.current_pose.end_effector_pose
    p0, quat = np.array(pose.translation), np.array(pose.quaternion)

    def read() -> tuple[np.ndarray, np.ndarray]:
        s = robot.state
        return np.array(s.dq), np.array(s.O_T_EE.translation)

    def running() -> bool:
        # poll_motion() raises what aborted the motion; its result is True once the motion
        # has finished (not "still in motion" as its docstring says), so is_in_control tells
        robot.poll_motion()
        return bool(robot.is_in_control)

    def target(offset: list[float]) -> Affine:
        return Affine(p0 + np.array(offset), quat)

    out: dict[str, Any] = {
        "limits": {
            "translation_velocity": factor * robot.translation_velocity_limit.get(),
            "translation_acceleration": factor * robot.translation_acceleration_limit.get(),
            "translation_jerk": factor * robot.translation_jerk_limit.get(),
        }
    }

    def path() -> dict[str, Any]:
        points = [p0 + np.array(o) for o in spec["waypoints"]]
        motion = CartesianWaypointMotion(
            [CartesianWaypoint(target(o)) for o in spec["waypoints"]],
            relative_dynamics_factor=factor,
        )
        t0 = time.monotonic()
        robot.move(motion, asynchronous=True)
        r = watch_rest(read, points[-1], t0, points[:-1], running, rest)
        robot.join_motion()
        return r

    def preempt() -> dict[str, Any]:
        robot.move(CartesianMotion(target(spec["goal_a"]), relative_dynamics_factor=factor),
                   asynchronous=True)  # fmt: skip
        time.sleep(spec["preempt_ms"] * 1e-3)
        t0 = time.monotonic()
        robot.move(CartesianMotion(target(spec["goal_b"]), relative_dynamics_factor=factor),
                   asynchronous=True)  # fmt: skip
        state = robot.current_cartesian_state  # the arm just after the call
        goal = p0 + np.array(spec["goal_b"])
        r = watch_rest(read, goal, t0, None, running, rest)
        robot.join_motion()
        position = np.ravel(state.pose.end_effector_pose.translation)
        velocity = np.ravel(state.velocity.end_effector_twist.linear)
        r["call"] = [(position - goal).tolist(), velocity.tolist()]  # for the report's bound
        return r

    for name, case in (("path", path), ("preempt", preempt)):
        try:
            out[name] = case()
        except Exception as exc:  # report it; the other case still runs
            out[name] = {"error": f"{type(exc).__name__}: {exc}"}
            try:
                robot.join_motion()
            except Exception:
                pass
            robot.recover_from_errors()
        # back to the start for the next case; a joint motion begun while the arm still
        # settles from the Cartesian one (its first command q_d, the measured q a
        # millimetre-radian off) is refused, as a robot refuses it: wait, recover, retry
        for _ in range(3):
            time.sleep(0.5)
            try:
                robot.move(JointMotion(q_start.tolist(), relative_dynamics_factor=0.2))
                break
            except Exception as exc:  # (reported; the results are kept)
                out.setdefault("return_errors", []).append(f"{type(exc).__name__}: {exc}")
                robot.recover_from_errors()
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
