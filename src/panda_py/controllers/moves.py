"""The laws that track a planned motion in the control process: a joint trajectory under
joint impedance, a Cartesian trajectory under Cartesian impedance (panda-py's
``move_to_joint_position`` and ``move_to_pose``).

The user's process plans the time-optimal trajectory and samples it at the robot's 1 ms
period; the loop only indexes the samples (no planning or sampling inside a tick). A move
ends when the trajectory is over and the arm has settled at the goal (at rest within
``dq_threshold`` and within the settle tolerance), or 1 s after the trajectory's end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers import laws
from panda_py.controllers.law import ControlLaw
from panda_py.controllers.model import FRICTION_SPEED
from panda_py.fci import PERIOD

__all__ = ["JointMove", "JointPlan", "MoveResult", "PoseMove", "PosePlan", "tracker_for"]

FloatArray = NDArray[np.float64]

SETTLE_JOINT = 5e-5  # [rad] at goal: every joint within this
# [1/s] integral gain per unit stiffness once the trajectory ended: fast enough that a
# joint at panda-py's wrist stiffness (50 Nm/rad) breaks free of the wrist's dry friction
# within the settle time; a pose's lower, as its Cartesian damping is lighter.
SETTLE_INTEGRAL = 10.0
SETTLE_INTEGRAL_POSE = 2.0
SETTLE_POSITION = 2e-3  # [m]
SETTLE_ORIENTATION = 2e-3  # [rad]
SETTLE_TIMEOUT = 1.0  # [s] after the trajectory's end the move ends regardless


@dataclass
class MoveResult:
    """How a move ended: ``success`` as panda-py judges it and why not."""

    success: bool
    reason: str  # "" on success
    joint_error: float = math.nan  # [rad] largest joint distance to the goal
    position_error: float = math.nan  # [m]
    orientation_error: float = math.nan  # [rad]
    duration: float = 0.0  # [s] the trajectory's
    elapsed: float = 0.0  # [s] until the move ended
    error: BaseException | None = None  # what aborted it


@dataclass(frozen=True)
class JointPlan:
    """A joint move as the user's process planned it: the trajectory sampled at the
    robot's 1 ms period and how to track and judge it (``Panda.move_to_joint_position``)."""

    q: FloatArray  # (N, 7) [rad]
    dq: FloatArray  # (N, 7) [rad/s]
    ddq: FloatArray  # (N, 7) [rad/s^2]
    stiffness: FloatArray  # (7,) [Nm/rad]
    damping: FloatArray  # (7,) [Nm s/rad]
    dq_threshold: float  # [rad/s] at rest below this
    success_threshold: float  # [rad] success within this of the goal


@dataclass(frozen=True)
class PosePlan:
    """A Cartesian move as the user's process planned it: positions, orientations, twists
    and their derivatives sampled at 1 ms, and how to track and judge it
    (``Panda.move_to_pose``)."""

    position: FloatArray  # (N, 3) [m]
    orientation: FloatArray  # (N, 4) unit quaternions (x, y, z, w)
    twist: FloatArray  # (N, 6) [m/s, rad/s]
    accel: FloatArray  # (N, 6) [m/s^2, rad/s^2]
    q_nullspace: FloatArray  # (7,) [rad] the nullspace's rest configuration
    impedance: FloatArray  # (6, 6) [N/m, Nm/rad]
    damping_ratio: float
    nullspace_stiffness: float  # [Nm/rad]
    dq_threshold: float  # [rad/s]
    success_threshold: float  # [m]
    orientation_threshold: float  # [rad]


def tracker_for(plan: JointPlan | PosePlan) -> JointMove | PoseMove:
    """The law that tracks ``plan`` in the control loop."""
    if isinstance(plan, JointPlan):
        return JointMove(plan)
    if isinstance(plan, PosePlan):
        return PoseMove(plan)
    raise TypeError(f"plan: expected a JointPlan or a PosePlan, got {type(plan).__name__}")


def rotation_angle(q0: FloatArray, q1: FloatArray) -> float:
    """Angle of the rotation between two unit quaternions [rad] (q and -q are equal)."""
    d = min(1.0, abs(float(q0 @ q1)) / math.sqrt(float(q0 @ q0) * float(q1 @ q1)))
    return 2.0 * math.acos(d)


class JointMove(ControlLaw):
    """``tau = M ddq_d + K (q_d - q) + D (dq_d - dq) + coriolis`` along sampled ``q_d``,
    ``dq_d``, ``ddq_d`` (the inertial and friction feed-forward keep the arm on the planned
    path instead of lagging behind it). Once the trajectory has ended, an integral of the error
    to the goal removes what friction and model errors leave (panda-py stops there)."""

    def __init__(self, plan: JointPlan) -> None:
        super().__init__()
        self.q, self.dq, self.ddq = plan.q, plan.dq, plan.ddq
        self.K, self.D = plan.stiffness, plan.damping
        self.dq_threshold = plan.dq_threshold
        self.success_threshold = plan.success_threshold
        self.duration = (len(plan.q) - 1) * PERIOD
        self.goal = plan.q[-1]
        self.integral = np.zeros(7)

    def step(self, state: Any, model: Any) -> FloatArray:
        k = min(round(self.t / PERIOD), len(self.q) - 1)
        tau = self.K * (self.q[k] - state.q) + self.D * (self.dq[k] - state.dq)
        if self.t > self.duration:
            self.integral += self.dt * (self.goal - state.q)
            tau += SETTLE_INTEGRAL * self.K * self.integral
        tau += model.driven_mass_of(state) @ self.ddq[k] + model.friction_for(self.dq[k])
        return tau + model.coriolis_of(state)

    def finished(self, state: Any) -> bool:
        over = self.t - self.duration
        if over <= 0.0:
            return False
        at_rest = float(np.abs(state.dq).max()) <= self.dq_threshold
        at_goal = float(np.abs(self.goal - state.q).max()) <= SETTLE_JOINT
        return (at_rest and at_goal) or over >= SETTLE_TIMEOUT

    def result(self, state: Any) -> MoveResult:
        err = float(np.abs(self.goal - state.q).max())
        ok = err <= self.success_threshold
        reason = (
            ""
            if ok
            else (
                f"finished {err:.4f} rad from the goal, above the success threshold of "
                f"{self.success_threshold:.4f} rad; consider a higher stiffness or a lower "
                "speed_factor"
            )
        )
        return MoveResult(ok, reason, joint_error=err, duration=self.duration, elapsed=self.t)


class PoseMove(ControlLaw):
    """Cartesian impedance along sampled positions, orientations, twists and their
    derivatives, with a joint impedance toward the start configuration in the task's
    nullspace and an inertial feed-forward of the planned acceleration:
    ``tau = J^T (-K e - D (J dq - v_d)) + M J^+ (a_d - dJ dq)
    + N (k_n (q_0 - q) - 2 sqrt(k_n) dq) + coriolis``, plus the drives' dry friction along
    the planned joint velocity ``J^+ v_d`` and, once the trajectory has ended, an integral
    of the error to the goal (as :class:`JointMove`)."""

    def __init__(self, plan: PosePlan) -> None:
        super().__init__()
        self.p, self.quat, self.v, self.a = plan.position, plan.orientation, plan.twist, plan.accel
        self._J_prev: FloatArray | None = None
        self.qn = plan.q_nullspace
        self.K = plan.impedance
        w, v = np.linalg.eigh(plan.impedance)
        self.D = 2.0 * plan.damping_ratio * (v * np.sqrt(np.maximum(w, 0.0))) @ v.T
        self.kn = plan.nullspace_stiffness
        self.dq_threshold = plan.dq_threshold
        self.success_threshold = plan.success_threshold
        self.orientation_threshold = plan.orientation_threshold
        self.duration = (len(plan.position) - 1) * PERIOD
        self.integral = np.zeros(6)
        self._err, self._J_pinv = np.empty(6), np.empty((7, 6))

    def step(self, state: Any, model: Any) -> FloatArray:
        k = min(round(self.t / PERIOD), len(self.p) - 1)
        q, dq = state.q, state.dq
        J = model.ee_jacobian(state)
        kn = self.kn
        kernels = laws.compiled()
        if kernels is not None:  # the same terms, compiled
            tau, err, J_pinv = np.empty(7), self._err, self._J_pinv
            kernels.impedance_torque(
                state.O_T_EE, J, q, dq, self.p[k], self.quat[k], self.v[k], self.K, self.D,
                self.qn, kn, tau, err, J_pinv,
            )  # fmt: skip
        else:
            err = laws.cartesian_error(state.O_T_EE, self.p[k], self.quat[k])
            tau = J.T @ (-(self.K @ err) - self.D @ (J @ dq - self.v[k]))
            tau += laws.nullspace_projector(J) @ (kn * (self.qn - q) - 2.0 * math.sqrt(kn) * dq)
            J_pinv = laws.damped_pinv(J)
        if kernels is not None:
            J_prev = J if self._J_prev is None else self._J_prev
            kernels.pose_feedforward(J, J_prev, dq, self.dt, self.a[k], self.v[k], J_pinv,
                                     model.driven_mass_of(state), model.coulomb,
                                     FRICTION_SPEED, tau)  # fmt: skip
        else:
            a = self.a[k]
            if self._J_prev is not None and self.dt > 0.0:
                a = a - ((J - self._J_prev) @ dq) / self.dt
            tau += model.driven_mass_of(state) @ (J_pinv @ a) + model.friction_for(
                J_pinv @ self.v[k]
            )
        self._J_prev = J
        if self.t > self.duration:  # remove what friction and model errors leave
            self.integral += self.dt * err
            tau -= J.T @ (SETTLE_INTEGRAL_POSE * (self.K @ self.integral))
        return tau + model.coriolis_of(state)

    def _errors(self, state: Any) -> tuple[float, float]:
        T = state.O_T_EE
        pos = float(np.linalg.norm(T[12:15] - self.p[-1]))
        return pos, rotation_angle(laws.quat_from_matrix(T), self.quat[-1])

    def finished(self, state: Any) -> bool:
        over = self.t - self.duration
        if over <= 0.0:
            return False
        at_rest = float(np.abs(state.dq).max()) <= self.dq_threshold
        pos, rot = self._errors(state)
        at_goal = pos <= SETTLE_POSITION and rot <= SETTLE_ORIENTATION
        return (at_rest and at_goal) or over >= SETTLE_TIMEOUT

    def result(self, state: Any) -> MoveResult:
        pos, rot = self._errors(state)
        ok = pos <= self.success_threshold and rot <= self.orientation_threshold
        reason = (
            ""
            if ok
            else (
                f"finished {pos:.4f} m and {math.degrees(rot):.2f} deg from the goal, above the "
                f"success threshold of {self.success_threshold:.4f} m and "
                f"{math.degrees(self.orientation_threshold):.2f} deg; consider a higher "
                "impedance or a lower speed_factor"
            )
        )
        return MoveResult(
            ok, reason, position_error=pos, orientation_error=rot,
            duration=self.duration, elapsed=self.t,
        )  # fmt: skip
