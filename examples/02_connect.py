"""Connect to the robot and its gripper, and read their state (the paper's code block 2)."""

import numpy as np
from _robot import connect, robot_host

from panda_py import libfranka

if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)  # panda_py.Panda(hostname), exits clearly if no robot
        gripper = libfranka.Gripper(hostname)

        state = panda.get_state()  # a libfranka RobotState, as the robot sent it
        print("joint positions q [rad]:", np.round(panda.q, 3) + 0.0)  # + 0.0: no "-0."
        print("end effector position [m]:", np.round(panda.get_position(), 3) + 0.0)
        print("orientation (quaternion x, y, z, w):", np.round(panda.get_orientation(), 3) + 0.0)
        print("robot mode:", state.robot_mode)
        print(f"gripper width: {gripper.read_once().width * 1000:.1f} mm")
        panda.close()
