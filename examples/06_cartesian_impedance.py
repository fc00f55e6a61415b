"""Cartesian impedance control with a 1 kHz loop in your script: the end effector follows a
sine along y (the paper's code block 6, panda-py's examples/cartesian_impedance.py)."""

import numpy as np
from _robot import connect, robot_host

from panda_py import controllers


def options(parser):
    parser.add_argument(
        "--runtime", type=float, default=np.pi * 4, help="[s] of the loop, on the wall clock"
    )


if __name__ == "__main__":
    with robot_host(__doc__, options=options, paced=True) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        ctrl = controllers.CartesianImpedance(filter_coeff=1.0)
        x0 = panda.get_position()
        q0 = panda.get_orientation()
        panda.start_controller(ctrl)  # runs in panda_py's control process, at 1 kHz
        y = []
        # the context keeps this loop at 1 kHz and raises the robot's errors in ok()
        with panda.create_context(frequency=1e3, max_runtime=args.runtime) as ctx:
            while ctx.ok():
                x_d = x0.copy()
                x_d[1] += 0.1 * np.sin(ctrl.get_time())
                ctrl.set_control(x_d, q0)
                y.append(panda.get_position()[1] - x0[1])
        panda.stop_controller()
        print(f"{ctx.num_ticks} ticks; y swung from {min(y) * 100:.1f} to {max(y) * 100:.1f} cm")
        panda.close()
