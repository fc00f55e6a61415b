"""Move the end effector on a straight line to a pose (the paper's code block 4)."""

import numpy as np
from _robot import connect, robot_host

if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        pose = panda.get_pose()
        pose[2, 3] -= 0.1
        ok = panda.move_to_pose(pose)  # straight, time-optimal, tracked by Cartesian impedance

        error = np.linalg.norm(panda.get_pose()[:3, 3] - pose[:3, 3])
        print(f"move_to_pose returned {ok}; end effector {error * 1000:.2f} mm from the goal")
        panda.close()
