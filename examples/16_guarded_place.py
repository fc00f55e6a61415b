"""Place the cube by feel: a guarded move lowers the grasped cube toward a point below the
table and stops gently when the table pushes back (``until=Force.z < -5``: libfranka's
wrench is the robot's force on its environment, so pressing down reads negative). No
table height is needed; the result says which condition ended the move and when.

On a real robot, put a 4 cm cube at x = 0.5 m, y = 0 on the table first."""

import numpy as np
from _cube import ABOVE, CUBE, GRIP, WIDTH, tcp_at
from _robot import connect, robot_host

from panda_py import libfranka
from panda_py.conditions import Elapsed, Force

PLACE = np.array([0.45, 0.2, 0.02])  # [m] where to put it (the centre, roughly)


if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        gripper = libfranka.Gripper(hostname)
        gripper.homing()
        panda.move_to_start()
        # touching the table is an impact: raise the reflex thresholds, as for any contact
        panda.get_robot().set_collision_behavior(
            [60.0] * 7, [60.0] * 7, [60.0] * 7, [60.0] * 7,
            [60.0] * 6, [60.0] * 6, [60.0] * 6, [60.0] * 6,
        )  # fmt: skip
        panda.move_to_pose([tcp_at(CUBE + ABOVE), tcp_at(CUBE + GRIP)])
        print(f"grasped: {gripper.grasp(WIDTH, speed=0.05, force=20.0)}")
        panda.move_to_pose([tcp_at(CUBE + ABOVE), tcp_at(PLACE + ABOVE)])

        # down at 5 cm/s toward 3 cm below the table, until it pushes back with 5 N
        below = PLACE + GRIP - np.array([0.0, 0.0, 0.05])
        handle = panda.move_to_pose(
            tcp_at(below), speed_factor=0.03, until=(Force.z < -5.0) | (Elapsed > 10.0),
            asynchronous=True,
        )  # fmt: skip
        handle.wait()
        result = handle.result
        height = panda.get_position()[2]
        print(f"stopped by {result.condition} after {result.condition_time:.2f} s, "
              f"TCP {height * 1000:.1f} mm above the table")  # fmt: skip
        gripper.move(0.08, 0.1)  # let go
        panda.move_to_pose(tcp_at(PLACE + ABOVE))
        print(f"released; the cube rests {(height - GRIP[2]) * 1000:.0f} mm up (its centre)")
        panda.move_to_start()
        panda.close()
