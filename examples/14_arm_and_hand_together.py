"""The arm and the hand at once: moves and gripper commands with ``asynchronous=True``
return at once (a ``MotionHandle`` and a future), so the hand opens while the arm
approaches and closes as soon as it arrives; ``await`` both from asyncio. The cube is
picked, lifted and put back; the script prints how long the pick took together and how
long the same steps take one after the other.

On a real robot, put a 4 cm cube at x = 0.5 m, y = 0 on the table first."""

import asyncio

from _cube import ABOVE, CUBE, GRIP, WIDTH, tcp_at
from _robot import connect, robot_host

from panda_py import libfranka


async def pick(panda, gripper):
    """Open the hand on the way down, grasp on arrival, lift: arm and hand together."""
    arm = panda.move_to_pose([tcp_at(CUBE + ABOVE), tcp_at(CUBE + GRIP)], asynchronous=True)
    hand = gripper.move(0.06, 0.1, asynchronous=True)
    reached, opened = await asyncio.gather(arm, hand)
    grasped = await gripper.grasp(WIDTH, speed=0.05, force=20.0, asynchronous=True)
    lifted = await panda.move_to_pose(tcp_at(CUBE + ABOVE), asynchronous=True)
    return reached and opened and grasped and lifted


def pick_one_after_the_other(panda, gripper):
    ok = gripper.move(0.06, 0.1)
    ok &= panda.move_to_pose([tcp_at(CUBE + ABOVE), tcp_at(CUBE + GRIP)])
    ok &= gripper.grasp(WIDTH, speed=0.05, force=20.0)
    return ok & panda.move_to_pose(tcp_at(CUBE + ABOVE))


def robot_time(panda):
    """The robot's clock [s] (a simulator in lockstep keeps its own pace)."""
    return panda.get_state().time.to_sec()


def put_back(panda, gripper):
    panda.move_to_pose(tcp_at(CUBE + GRIP + [0.0, 0.0, 0.003]))  # just above the table
    gripper.move(0.08, 0.1)
    panda.move_to_start()


if __name__ == "__main__":
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        gripper = libfranka.Gripper(hostname)
        # homing the hand while the arm goes to the start pose
        homed = gripper.homing(asynchronous=True)
        panda.move_to_start()
        print(f"homed while the arm moved: {homed.result()}")

        t0 = robot_time(panda)
        together = asyncio.run(pick(panda, gripper))
        t_together = robot_time(panda) - t0
        width = gripper.read_once().width
        put_back(panda, gripper)

        t0 = robot_time(panda)
        alone = pick_one_after_the_other(panda, gripper)
        t_alone = robot_time(panda) - t0
        put_back(panda, gripper)
        print(f"picked together: {together}, holding {width * 1000:.1f} mm, "
              f"in {t_together:.2f} s (one after the other: {alone}, {t_alone:.2f} s)")  # fmt: skip
        gripper.close()
        panda.close()
