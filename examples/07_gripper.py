"""Grasp the cube with the gripper and lift it (libfranka's Gripper: homing, move, grasp;
homing while the arm moves, with ``asynchronous=True``).

On a real robot, put a 4 cm cube at x = 0.5 m, y = 0 on the table first."""

from _cube import ABOVE as UP
from _cube import CUBE, GRIP, WIDTH, tcp_at
from _robot import connect, robot_host

from panda_py import libfranka

ABOVE = CUBE + UP  # [m] TCP positions: 10 cm above the cube,
AT_CUBE = CUBE + GRIP  # and with the fingers around it


if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        gripper = libfranka.Gripper(hostname)
        # homing calibrates the fingers (opens them fully); asynchronous=True returns a
        # future at once, so the arm moves to the start pose meanwhile
        homing = gripper.homing(asynchronous=True)
        panda.move_to_start()
        print(f"homed: {homing.result()}, open: {gripper.read_once().width * 1000:.1f} mm")

        panda.move_to_pose(tcp_at(ABOVE))
        panda.move_to_pose(tcp_at(AT_CUBE))
        # True if the fingers stop within [width - 5 mm, width + 5 mm], squeezing with 20 N
        grasped = gripper.grasp(WIDTH, speed=0.05, force=20.0, epsilon_inner=0.005,
                                epsilon_outer=0.005)  # fmt: skip
        print(f"grasped: {grasped}")
        lifted = panda.move_to_pose(tcp_at(ABOVE))
        print(f"lifted: {lifted}")

        panda.move_to_pose(tcp_at(AT_CUBE))  # put it back
        gripper.move(0.08, 0.1)
        panda.move_to_start()
        panda.close()
