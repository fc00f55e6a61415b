"""Log the end effector's path and plot the paper's figure: move_to_pose draws a straight
line, move_to_joint_position a curve (the paper's code block 5), with matplotlib (installed
with the package)."""

import numpy as np
from _robot import connect, robot_host

import panda_py
from panda_py import constants


def options(parser):
    parser.add_argument("--figure", default="paths.png", help="the PNG to write")
    parser.add_argument(
        "--speed-factor", type=float, default=0.05, help="of the logged Cartesian move "
        "(the paper: 0.01, about 30 s)"
    )  # fmt: skip


def deviation_from_line(log):
    """The largest distance [m] of the logged path in the xy plane (the figure's) from the
    line between its ends."""
    p = np.array(log["O_T_EE"])[:, 12:14]  # O_T_EE is column-major: [12:15] is the position
    (ax, ay), (bx, by) = p[0], p[-1]
    cross = (bx - ax) * (p[:, 1] - ay) - (by - ay) * (p[:, 0] - ax)
    return np.max(np.abs(cross)) / np.hypot(bx - ax, by - ay)


if __name__ == "__main__":
    import matplotlib

    matplotlib.use("Agg")  # write a file, no window
    import matplotlib.pyplot as plt

    with robot_host(__doc__, options=options) as (hostname, args):
        panda = connect(hostname)
        T_0 = panda_py.fk(constants.JOINT_POSITION_START)
        T_0[1, 3] = 0.25
        T_1 = T_0.copy()
        T_1[1, 3] = -0.25

        panda.move_to_pose(T_0)
        panda.enable_logging(40000)  # keep up to 40 s of states (1 kHz)
        panda.move_to_pose(T_1, speed_factor=args.speed_factor)
        panda.disable_logging()
        log = panda.get_log()

        panda.move_to_pose(T_0)
        panda.enable_logging(10000)
        panda.move_to_joint_position(panda_py.ik(T_1))
        panda.disable_logging()
        joint_log = panda.get_log()
        panda.close()

    fig, axes = plt.subplots(1, 2, figsize=(8, 4), sharey=True)
    titles = ("move_to_pose", "move_to_joint_position")
    for ax, data, title in zip(axes, (log, joint_log), titles, strict=True):
        O_T_EE = np.array(data["O_T_EE"])
        ax.plot(O_T_EE[:, 13], O_T_EE[:, 12])  # y across, x up: the robot seen from above
        ax.set_title(title)
        ax.set_xlabel("y [m]")
    axes[0].set_ylabel("x [m]")
    fig.tight_layout()
    fig.savefig(args.figure)
    print(f"move_to_pose: {deviation_from_line(log) * 1000:.1f} mm from a straight line")
    print(f"move_to_joint_position: {deviation_from_line(joint_log) * 1000:.1f} mm from it")
    print(f"figure: {args.figure}")
