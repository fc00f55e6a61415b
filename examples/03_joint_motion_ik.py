"""Move in joint space to a pose found by inverse kinematics (the paper's code block 3)."""

import numpy as np
from _robot import connect, robot_host

import panda_py

if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        pose = panda.get_pose()  # the end effector's 4x4 pose in the base frame
        pose[2, 3] -= 0.1  # 10 cm lower
        q = panda_py.ik(pose)  # analytical IK, the solution nearest the current q
        panda.move_to_joint_position(q)  # a time-optimal joint trajectory

        error = np.linalg.norm(panda.get_pose()[:3, 3] - pose[:3, 3])
        print(f"end effector {error * 1000:.2f} mm from the goal")
        panda.close()
