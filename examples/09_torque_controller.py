"""Your own torque controller in Python, run at 1 kHz in panda_py's control process: a
joint-space spring and damper whose target your script moves along a sine."""

from typing import ClassVar

import numpy as np
from _robot import connect, robot_host

from panda_py import controllers


class JointSpring(controllers.TorqueController):
    """tau = K (target - q) - D dq  [Nm]; the robot adds gravity compensation itself."""

    signals: ClassVar[dict[str, int]] = {"target": 7}  # the inputs your script sets

    def start(self, state, model):  # once, in the control process, before the first step
        self.initial_signals(target=state.q)
        self.K = np.array([600, 600, 600, 600, 250, 150, 50.0])  # [Nm/rad]
        self.D = 2 * np.sqrt(self.K)  # [Nm s/rad]

    def step(self, state, model):  # every millisecond: the newest state -> torques
        return self.K * (self.signal("target") - state.q) - self.D * state.dq


if __name__ == "__main__":
    with robot_host(__doc__, paced=True) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        q0 = panda.q
        ctrl = JointSpring()
        panda.start_controller(ctrl)  # the class is sent to the control process by value
        errors = []
        with panda.create_context(frequency=100, max_runtime=3.0) as ctx:
            while ctx.ok():
                # the sine advances with the script's own 100 Hz updates (on the lockstep
                # simulator the robot's clock runs ahead of a script: a stalled script then
                # holds its target instead of making it jump when it wakes)
                target = q0.copy()
                target[3] += 0.2 * np.sin(np.pi * ctx.num_ticks / 100)  # elbow, 0.5 Hz, 0.2 rad
                ctrl.set_signals(target=target)
                errors.append(abs(panda.q[3] - target[3]))
        panda.stop_controller()
        print(f"{ctx.num_ticks} updates; elbow tracking error: mean "
              f"{np.mean(errors):.3f} rad, max {np.max(errors):.3f} rad")  # fmt: skip
        panda.close()
