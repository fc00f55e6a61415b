"""Teaching mode: the arm floats under gravity compensation so you can guide it by hand;
the script records where you took it. (In the simulator nobody pushes: it stays put.)"""

import numpy as np
from _robot import connect, robot_host


def options(parser):
    parser.add_argument("--duration", type=float, default=10.0, help="[s] to record")


if __name__ == "__main__":
    with robot_host(__doc__, options=options, paced=True) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        start = panda.get_position()
        panda.enable_logging(int(args.duration * 1000))
        panda.teaching_mode(True, damping=[1.0] * 7)  # a little joint damping [Nm s/rad]
        print(f"Guide the arm by hand for {args.duration:.0f} s ...")
        with panda.create_context(frequency=10, max_runtime=args.duration) as ctx:
            while ctx.ok():  # raises if the robot stops with an error (a reflex)
                pass
        panda.teaching_mode(False)
        panda.disable_logging()
        path = np.array(panda.get_log()["O_T_EE"])[:, 12:15]
        farthest = np.linalg.norm(path - start, axis=1).max()
        print(f"recorded {len(path)} poses; the end effector went up to "
              f"{farthest * 1000:.1f} mm from where it started")  # fmt: skip
        panda.close()
