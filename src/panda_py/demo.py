"""The demo: a simulated Panda picks up the cube, planned and driven from pure Python.

    panda-py-demo            # lockstep simulator (robust on a loaded machine)
    panda-py-demo --realtime # the simulator keeps 1 kHz wall-clock time like a robot

It starts the embedded simulator, plans joint trajectories with our analytical IK and
time-optimal planner, streams them over the real FCI protocol at 1 kHz, grasps the cube
with the gripper protocol and lifts it, printing what happens.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import numpy as np

from panda_py import fci
from panda_py.kinematics import fk, ik_full
from panda_py.motion import JointTrajectory
from panda_py.robots.mjcf import CUBE_POSITION, CUBE_SIZE
from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.probe import GripperProbe, RawClient, follow_joint_positions


def _q_at(position: np.ndarray, q_near: np.ndarray) -> np.ndarray:
    """Joint positions putting the TCP at ``position`` [m], pointing down, nearest ``q_near``."""
    T = fk(np.asarray(START_POSE))
    T[:3, 3] = position
    solutions = ik_full(T, q_init=q_near, q_7=float(q_near[6]))
    finite = solutions[np.all(np.isfinite(solutions), axis=1)]
    if not len(finite):
        raise RuntimeError(f"no IK solution for a TCP at {list(position)}")
    return finite[np.argmin(np.linalg.norm(finite - q_near, axis=1))]


def _move(client: RawClient, sim: Simulator, waypoints: list[np.ndarray], label: str) -> None:
    """Follow a time-optimal path from where the arm is now through ``waypoints``."""
    q_now = np.asarray(client.state()["q"], dtype=float)
    traj = JointTrajectory([q_now, *waypoints], speed_factor=0.2)
    t0 = time.monotonic()
    status, state = follow_joint_positions(client, traj.get_joint_positions, traj.get_duration())
    tcp = np.asarray(state["O_T_EE"], dtype=float).reshape(4, 4).T[:3, 3]
    print(
        f"  {label}: {status.name.lower()} after {traj.get_duration():.2f} s of robot time "
        f"({time.monotonic() - t0:.2f} s wall); TCP at {np.round(tcp, 3).tolist()} m"
    )
    if status != fci.MoveStatus.SUCCESS:
        errors = fci.dialect(client.server_version).active_errors(state["errors"])
        lost = sim.stats()["commands_lost"]
        raise RuntimeError(f"{label} failed: {status.name} {list(errors)}, {lost} commands lost")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="panda-py-demo", description=__doc__.splitlines()[0])
    parser.add_argument("--realtime", action="store_true", help="run the simulator in realtime")
    parser.add_argument("--robot", default="fer", choices=["fer", "fr3"])
    args = parser.parse_args(argv)
    host = free_loopback_host()
    mode = "realtime" if args.realtime else "lockstep"
    print(f"Starting a simulated {args.robot.upper()} on {host} ({mode})")
    with Simulator(host, robot=args.robot, lockstep=not args.realtime) as sim:
        robot = RawClient(host, fci.NEWEST_VERSION)
        hand = GripperProbe(host)
        print(f"Connected: FCI protocol v{robot.server_version}, gripper v{hand.server_version}")
        s = robot.state()
        q0 = np.asarray(s["q"], dtype=float)
        print(
            f"  q = {np.round(q0, 3).tolist()} rad, mode {fci.RobotMode(int(s['robot_mode'])).name}"
        )
        cube = np.asarray(CUBE_POSITION)
        above = _q_at(cube + np.array([0.0, 0.0, 0.15]), q0)
        grasp = _q_at(cube + np.array([0.0, 0.0, CUBE_SIZE / 2]), above)
        print(
            f"Cube at {cube.tolist()} m; planning with analytical IK and time-optimal trajectories"
        )
        _move(robot, sim, [above, grasp], "reach down to the cube")
        ok = hand.request(fci.GripperCommand.GRASP, width=CUBE_SIZE, epsilon_inner=0.005,
                          epsilon_outer=0.005, speed=0.05, force=30.0)  # fmt: skip
        width = float(hand.state()["width"])
        print(f"  grasp: {ok.name.lower()}, fingers at {width * 1000:.1f} mm")
        _move(robot, sim, [above], "lift")
        lifted = sim.state()["cube_position"]
        rise = (lifted[2] - cube[2]) * 100
        print(f"Cube now at {np.round(lifted, 3).tolist()} m ({rise:.1f} cm up)")
        stats = sim.stats()
        print(f"Simulator: {stats['ticks']} ticks, {stats['commands_lost']} commands lost")
        robot.close()
        hand.close()
        return 0 if lifted[2] - cube[2] > 0.05 and ok == fci.GripperStatus.SUCCESS else 1


if __name__ == "__main__":
    sys.exit(main())
