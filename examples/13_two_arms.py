"""Two arms from one PC: one Panda per robot, each with its own control process, so each
arm keeps its own 1 kHz loop. Both move to the start pose at once (blocking moves, one
thread each), then trace mirrored sines along y under Cartesian impedance, fed from one
1 kHz loop of this script."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from _robot import connect, robot_hosts

from panda_py import controllers


def options(parser):
    parser.add_argument("--runtime", type=float, default=2 * np.pi, help="[s] of the sines")
    parser.add_argument("--amplitude", type=float, default=0.05, help="[m] along y")


if __name__ == "__main__":
    with robot_hosts(__doc__, 2, options=options, paced=True) as (hosts, args):
        arms = [connect(host) for host in hosts]
        with ThreadPoolExecutor(len(arms)) as pool:  # a blocking move per thread: together
            reached = list(pool.map(lambda arm: arm.move_to_start(), arms))
        print(f"both at the start pose: {all(reached)}")
        ctrls = [controllers.CartesianImpedance(filter_coeff=1.0) for _ in arms]
        x0 = [arm.get_position() for arm in arms]
        q0 = [arm.get_orientation() for arm in arms]
        for arm, ctrl in zip(arms, ctrls, strict=True):
            arm.start_controller(ctrl)
        y = [[], []]
        with arms[0].create_context(frequency=1e3, max_runtime=args.runtime) as ctx:
            while ctx.ok():
                s = args.amplitude * np.sin(ctrls[0].get_time())
                for i, (arm, ctrl) in enumerate(zip(arms, ctrls, strict=True)):
                    x_d = x0[i].copy()
                    x_d[1] += s if i == 0 else -s  # mirrored
                    ctrl.set_control(x_d, q0[i])
                    y[i].append(arm.get_position()[1] - x0[i][1])
                arms[1].raise_error()  # the context raises the first arm's errors
        for arm in arms:
            arm.stop_controller()
        a, b = np.array(y[0]), np.array(y[1])
        mirror = np.abs(a + b) * 1000  # [mm]
        print(
            f"{ctx.num_ticks} ticks; left y {a.min() * 100:.1f} to {a.max() * 100:.1f} cm, "
            f"right y {b.min() * 100:.1f} to {b.max() * 100:.1f} cm; "
            f"mirror error {np.median(mirror):.1f} mm (median), at most {mirror.max():.1f} mm, "
            f"within {np.percentile(mirror, 99):.1f} mm in 99 % of the ticks"
        )
        for arm in arms:
            arm.close()
