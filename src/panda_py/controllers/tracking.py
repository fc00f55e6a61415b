"""How a moving reference becomes joint torques: joint impedance or Cartesian impedance
around the reference, plus the inertial and friction feed-forward of its motion, so that
the arm follows the reference instead of lagging behind it.

Shared by the laws that track a reference in the control process: the planned moves
(:mod:`panda_py.controllers.moves`) and the streamed targets
(:mod:`panda_py.controllers.streaming`). Neither adds the Coriolis torques here: the
callers add them last (after what else they add).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers import laws
from panda_py.controllers.model import FRICTION_SPEED

__all__ = ["PoseImpedance", "joint_impedance_torque"]

FloatArray = NDArray[np.float64]


def joint_impedance_torque(
    K: FloatArray, D: FloatArray, q_d: FloatArray, dq_d: FloatArray, ddq_d: FloatArray,
    state: Any, model: Any,
) -> FloatArray:  # fmt: skip
    """``K (q_d - q) + D (dq_d - dq) + M ddq_d + friction(dq_d)`` [Nm]: joint impedance
    (stiffness ``K`` [Nm/rad], damping ``D`` [Nm s/rad]) around the reference ``q_d``,
    ``dq_d`` with the inertial (links and rotors) and dry-friction feed-forward of its
    motion."""
    tau = K * (q_d - state.q) + D * (dq_d - state.dq)
    tau += model.driven_mass_of(state) @ ddq_d + model.friction_for(dq_d)
    return tau


class PoseImpedance:
    """Cartesian impedance around a moving pose reference, with a joint impedance toward
    ``q_nullspace`` in the task's nullspace and the inertial feed-forward of the reference's
    acceleration: ``tau = J^T (-K e - D (J dq - v_d)) + M J^+ (a_d - dJ dq)
    + N (k_n (q_n - q) - 2 sqrt(k_n) dq)`` plus the drives' dry friction along ``J^+ v_d``,
    ``D = 2 damping_ratio sqrt(K)``.

    After :meth:`torque`, ``err`` (6,) is the pose error [m, rad], ``J_prev`` the
    Jacobian of that tick (its rate is taken from the change of the Jacobian) and
    ``J_pinv`` its damped pseudo-inverse."""

    def __init__(self, impedance: FloatArray, damping_ratio: float, q_nullspace: FloatArray,
                 nullspace_stiffness: float) -> None:  # fmt: skip
        self.K = np.array(impedance, dtype=np.float64)
        w, v = np.linalg.eigh(self.K)
        self.D = 2.0 * damping_ratio * (v * np.sqrt(np.maximum(w, 0.0))) @ v.T
        self.qn = np.array(q_nullspace, dtype=np.float64)  # its own: one kernel signature
        self.kn = float(nullspace_stiffness)
        self.err = np.empty(6)
        self.J_prev: FloatArray | None = None
        self.J_pinv = np.empty((7, 6))

    def torque(self, state: Any, model: Any, dt: float, p_d: FloatArray, quat_d: FloatArray,
               v_d: FloatArray, a_d: FloatArray) -> FloatArray:  # fmt: skip
        """The torques [Nm] (without Coriolis) toward the reference position ``p_d`` [m],
        orientation ``quat_d`` (x, y, z, w), twist ``v_d`` [m/s, rad/s] and its rate
        ``a_d`` [m/s^2, rad/s^2], ``dt`` [s] after the previous call."""
        q, dq = state.q, state.dq
        J = model.ee_jacobian(state)
        kn = self.kn
        kernels = laws.compiled()
        if kernels is not None:  # the same terms, compiled in one call
            tau = np.empty(7)
            kernels.pose_tracking_torque(
                state.O_T_EE, J, J if self.J_prev is None else self.J_prev, q, dq, dt, p_d,
                quat_d, v_d, a_d, self.K, self.D, self.qn, kn, model.mass_of(state),
                model.armature, model.coulomb, FRICTION_SPEED, tau, self.err, self.J_pinv,
            )  # fmt: skip
        else:
            err = self.err = laws.cartesian_error(state.O_T_EE, p_d, quat_d)
            tau = J.T @ (-(self.K @ err) - self.D @ (J @ dq - v_d))
            tau += laws.nullspace_projector(J) @ (kn * (self.qn - q) - 2.0 * math.sqrt(kn) * dq)
            J_pinv = self.J_pinv = laws.damped_pinv(J)
            a = a_d
            if self.J_prev is not None and dt > 0.0:
                a = a - ((J - self.J_prev) @ dq) / dt
            tau += model.driven_mass_of(state) @ (J_pinv @ a) + model.friction_for(J_pinv @ v_d)
        self.J_prev = J
        return tau
