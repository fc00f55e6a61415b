"""Change your mind half way: a move started with ``asynchronous=True`` is replaced
mid-motion by a new one, without stopping. The joint move toward one side is replaced,
when it is half way, by a Cartesian move to a pose on the other side; the arm bends over
smoothly (no velocity step: the log shows the largest change of any joint's velocity in
one tick, well under what the robot's acceleration limit allows)."""

import time

import numpy as np
from _robot import connect, robot_host

from panda_py.robots.params import get_robot

SIDE = np.array([0.6, 0.3, 0.0, 0.2, 0.0, 0.2, 0.0])  # [rad] from the start pose
OTHER_SIDE = np.array([0.1, -0.25, -0.05])  # [m] the second goal, from the start position

if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        start = panda.q
        goal = panda.get_pose()
        goal[:3, 3] += OTHER_SIDE
        panda.enable_logging(20_000)

        first = panda.move_to_joint_position(start + SIDE, asynchronous=True)
        while np.abs(panda.q - start).max() < 0.5 * np.abs(SIDE).max():  # half way there
            time.sleep(0.001)
        print(f"half way, joint speed {np.abs(panda.get_state().dq).max():.2f} rad/s")
        second = panda.move_to_pose(goal, asynchronous=True)  # replaces the first

        print(f"first move: {first.wait()} ({first.result.reason})")
        print(f"second move: {second.wait()}, "
              f"{second.result.position_error * 1000:.1f} mm from its goal")  # fmt: skip

        log = panda.get_log()
        ddq = np.abs(np.diff(np.array(log["dq"]), axis=0)).max(axis=0) / 1e-3  # [rad/s^2]
        limit = np.array(get_robot(args.robot).joints.ddq_max)  # --robot: fer or fr3
        print(
            f"largest joint acceleration: {(ddq / limit).max() * 100:.0f} % of the "
            f"{args.robot.upper()}'s limit"
        )
        panda.move_to_start()
        panda.close()
