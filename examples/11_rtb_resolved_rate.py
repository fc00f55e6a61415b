"""The Robotics Toolbox drives the robot: a resolved-rate controller that solves a QP each
step (reach the goal, keep away from joint limits, maximise manipulability) and feeds the
joint velocities to IntegratedVelocity at 20 Hz (the paper's Robotics Toolbox block, after
Haviland and Corke's MMC). Needs ``pip install ".[examples]"``."""

import numpy as np
import qpsolvers
import roboticstoolbox as rtb
import spatialmath as sm
from _robot import connect, robot_host

from panda_py import controllers

N = 7  # joints
SLACK = 6  # one slack variable per task-space direction, so the QP stays feasible


def resolved_rate(model, q, goal):
    """Joint velocities [rad/s] toward ``goal`` (an SE3), and whether it is reached."""
    v, arrived = rtb.p_servo(model.fkine(q), goal, gain=1.0, threshold=0.005)
    Q = np.eye(N + SLACK)
    Q[:N, :N] *= 0.01  # small joint velocities ...
    Q[N:, N:] *= 100.0  # ... and far smaller slack: follow v as closely as possible
    A_eq = np.c_[model.jacobe(q), np.eye(SLACK)]  # J qd + slack = v
    A_in = np.zeros((N + SLACK, N + SLACK))
    b_in = np.zeros(N + SLACK)
    # slow down near joint limits (start 0.9 rad away, stop 0.05 rad away)
    A_in[:N, :N], b_in[:N] = model.joint_velocity_damper(q, ps=0.05, pi=0.9, n=N)
    # climb the manipulability gradient (of the arm's links, not the fingers)
    J_m = model.jacobm(q, start=model.links[0], end=model.links[8])
    c = np.r_[-J_m.reshape(N), np.zeros(SLACK)]
    limit = np.r_[model.qdlim[:N], 10 * np.ones(SLACK)]
    x = qpsolvers.solve_qp(Q, c, A_in, b_in, A_eq, v, lb=-limit, ub=limit, solver="daqp")
    if x is None:
        raise RuntimeError("the QP has no solution")
    return x[:N], arrived


if __name__ == "__main__":
    with robot_host(__doc__, paced=True) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        model = rtb.models.Panda()
        start = panda.get_position()
        # 20 cm forward, 20 cm left and 10 cm down, turned 30 degrees about the vertical
        goal = sm.SE3.Trans(0.2, 0.2, -0.1) * model.fkine(panda.q) * sm.SE3.Rz(np.pi / 6)

        ctrl = controllers.IntegratedVelocity()
        panda.start_controller(ctrl)  # integrates the velocities into a joint target at 1 kHz
        arrived = False
        with panda.create_context(frequency=20, max_runtime=20) as ctx:
            while ctx.ok() and not arrived:
                qd, arrived = resolved_rate(model, panda.q, goal)
                ctrl.set_control(qd)
        ctrl.set_control(np.zeros(N))
        panda.stop_controller()

        error = model.fkine(panda.q).inv() * goal
        print(f"arrived: {arrived} after {ctx.num_ticks} steps ({ctx.num_ticks / 20:.1f} s); "
              f"{np.linalg.norm(error.t) * 1000:.1f} mm and "
              f"{np.degrees(np.linalg.norm(error.rpy())):.1f} deg from the goal")  # fmt: skip
        moved = panda.get_position() - start  # measured by the robot, in its base frame
        print(f"the end effector moved {np.round(moved, 3)} m")
        panda.close()
