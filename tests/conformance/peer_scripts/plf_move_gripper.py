"""pylibfranka 0.21.3's move_gripper example, as its documentation and printed output
describe it (written here from that behaviour, not copied): home the gripper, wait 2 s,
read and print its state, grasp an object of ``width`` (default 5 mm) at 0.1 m/s with
60 N, wait 3 s, then read the state again: "Object lost." (exit -1) unless is_grasped is
still true, else "Grasped object, will release it now." and stop.

Usage: plf_move_gripper.py HOST. Two runs: the example's defaults with nothing between the
fingers (they close fully: 0 mm lies within 5 +- 5 mm), and the scene's 4 cm cube
(``--width 0.04``, the arm placed around it by the test).
"""

from __future__ import annotations

import sys
import time

from peer_io import Scenarios, event
from pylibfranka import Gripper

HOST = sys.argv[1]


def example(width: float, speed: float = 0.1, force: float = 60.0) -> dict:
    """One run of the example's steps; returns what it printed and its exit code."""
    printed: list[str] = []
    gripper = Gripper(HOST)
    gripper.homing()
    time.sleep(2.0)
    state = gripper.read_once()
    printed += [
        f"Gripper width: {state.width}",
        f"Gripper is grasped: {state.is_grasped}",
        f"Gripper temperature: {state.temperature}",
        f"Gripper time: {state.time.to_sec()}",
    ]
    out = {"width_homed": state.width, "max_width": state.max_width}
    if not gripper.grasp(width, speed, force):
        printed.append("Failed to grasp object.")
        return {**out, "printed": printed, "exit": -1}
    time.sleep(3.0)
    state = gripper.read_once()
    out.update(width_held=state.width, is_grasped=state.is_grasped)
    if not state.is_grasped:
        printed.append("Object lost.")
        return {**out, "printed": printed, "exit": -1}
    printed.append("Grasped object, will release it now.")
    out["stop"] = gripper.stop()
    return {**out, "printed": printed, "exit": 0}


def cube() -> dict:
    event("teleport_to_cube")
    try:
        return example(0.04)
    finally:
        Gripper(HOST).move(0.08, 0.1)
        event("teleport_home")


runs = Scenarios()
runs.run("defaults", lambda: example(0.005))
runs.run("cube", cube)
runs.finish()
