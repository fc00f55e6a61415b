"""Follow a target streamed at 20 Hz, as a learned policy or a teleoperation device sends
it: ``CartesianTarget`` runs an online, jerk-limited generator toward the newest target at
1 kHz within the robot's limits (times ``speed_factor``), so the arm moves smoothly between
targets that arrive 50 ms apart. Here the targets go round a 10 cm circle, then jump 30 cm
aside and stop arriving, as from a policy that died: after ``timeout`` the arm comes to
rest where it is, short of the last target."""

import time

import numpy as np
from _robot import connect, robot_host

from panda_py import controllers
from panda_py.robots.params import get_robot

RADIUS = 0.1  # [m]
LAP = 4.0  # [s] once round (0.16 m/s)


def wait_until(panda, ms):
    """Wait until the robot's clock reads ``ms``."""
    while panda.get_state().time.to_msec() < ms:
        time.sleep(0.0005)


def options(parser):
    parser.add_argument("--runtime", type=float, default=6.0, help="[s] of streaming")


if __name__ == "__main__":
    with robot_host(__doc__, options=options) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        center, quat = panda.get_position(), panda.get_orientation()
        panda.enable_logging(30_000)
        ctrl = controllers.CartesianTarget(speed_factor=0.2, timeout=0.5)
        panda.start_controller(ctrl)  # runs in panda_py's control process, at 1 kHz

        lags = []
        # the policy: a new target every 50 ms of the robot's clock (the wall clock on a
        # robot; a simulator in lockstep runs at its own pace), round the circle...
        start = panda.get_state().time.to_msec()
        count = round(args.runtime * 20)
        for k in range(count):
            wait_until(panda, start + 50 * k)
            a = 2.0 * np.pi * (k * 0.05) / LAP
            offset = RADIUS * np.array([0.0, np.sin(a), 1.0 - np.cos(a)])
            ctrl.set_target(center + offset, quat)
            lags.append(ctrl.lag)  # how far the reference is behind the newest target
        print(f"followed {count} targets sent at 20 Hz; lag at most {max(lags) * 1000:.0f} mm")

        # ...then 30 cm aside, and it dies 0.1 s later: no more targets
        aside = center + np.array([0.0, -0.3, 0.0])
        for k in (1, 2, 3):
            wait_until(panda, start + 50 * (count + k))
            ctrl.set_target(aside, quat)
        last = ctrl.get_time()
        deadline = time.monotonic() + 30.0
        while not (ctrl.stale and np.abs(panda.get_state().dq).max() < 0.01):
            if time.monotonic() > deadline:
                raise SystemExit("the arm did not come to rest")
            time.sleep(0.005)
        short = np.linalg.norm(panda.get_position() - aside)
        print(f"targets stopped: at rest {ctrl.get_time() - last:.2f} s later (timeout 0.5 s), "
              f"{short * 1000:.0f} mm short of the last one")  # fmt: skip
        panda.stop_controller()

        log = panda.get_log()
        dq = np.array(log["dq"])
        t = np.array(log["time"]).ravel() * 1e-3
        ddq = np.abs(np.diff(dq, axis=0) / np.diff(t)[:, None]).max(axis=0)  # [rad/s^2]
        joints = get_robot(args.robot).joints  # --robot: fer or fr3
        print(f"largest joint velocity: {(np.abs(dq).max(axis=0) / joints.dq_max).max() * 100:.0f}"
              f" %, acceleration: {(ddq / joints.ddq_max).max() * 100:.0f} % of the "
              f"{args.robot.upper()}'s limits")  # fmt: skip
        panda.move_to_start()
        panda.close()
