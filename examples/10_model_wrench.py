"""Read the robot's model: gravity torques, the Jacobian, and from them the wrench the end
effector feels (libfranka's Model, computed locally from the robot's parameters)."""

import numpy as np
from _robot import connect, robot_host

from panda_py import libfranka

if __name__ == "__main__":
    np.set_printoptions(precision=3, suppress=True)
    with robot_host(__doc__) as (hostname, args):
        panda = connect(hostname)
        panda.move_to_start()
        model = panda.get_model()
        state = panda.get_state()

        print("gravity torques [Nm]:", model.gravity(state))
        J = model.zero_jacobian(libfranka.Frame.kEndEffector, state).reshape(6, 7, order="F")
        print("Jacobian (6x7, base frame):\n", J)
        # external joint torques -> the wrench at the end effector: tau = J^T F
        F = np.linalg.pinv(J.T) @ state.tau_ext_hat_filtered
        print("external wrench from the model [N, Nm]:", F)
        print("the robot's own estimate O_F_ext_hat_K: ", np.asarray(state.O_F_ext_hat_K))
        panda.close()
