"""Joint setpoints followed as polymetis follows them: DROID's controller.

DROID's robots run polymetis's ``HybridJointImpedanceControl`` (started by
``RobotInterface.start_cartesian_impedance``, fed by ``update_desired_joint_positions``:
droid-dataset/droid ``droid/franka/robot.py`` lines 86-99). Each new setpoint replaces the
last at once, with no reference trajectory between them, and the arm follows it through a
joint impedance whose stiffness and damping add the end effector's Cartesian impedance seen
from the joints (facebookresearch/fairo, polymetis ``torchcontrol/modules/feedback.py``,
``HybridJointSpacePD``)::

    tau = (Kq + J^T Kx J) (q_d - q) - (Kqd + J^T Kxd J) dq + C(q, dq) dq

``J`` the zero Jacobian of ``panda_link8`` (the flange: DROID's
``config/panda/franka_panda.yaml``, ``ee_link_name``), gravity compensated by the robot.
The gains are DROID's (``config/panda/franka_hardware.yaml`` and ``config/fr3/...``, lines
10-13): soft, so a policy's 15 Hz steps are followed as the policy saw them followed while
its data was recorded.

Where it differs from polymetis, to stay within the robot's limits with no reflex: a new
setpoint is approached at no more than 0.4 of each joint's speed limit
(:data:`SETPOINT_SPEED_SHARE`; polymetis jumps to it): a policy's usual step at 15 Hz
(0.02-0.1 rad) within a period, DROID's largest (0.2 rad) in about three. Measured on the
simulator: DROID's gains following a full-scale reversal of every joint, jumped, drive the
wrist (joint 6, 12 Nm into little inertia) from +1.7 to -2.8 rad/s in 20 ms, past its
limit, and the robot's ``joint_velocity_violation`` reflex stops it; ramped, full-scale
actions reversed, alternated or random on every joint peak at 1.3 rad/s.
polymetis's own safety controller (``franka_hardware.yaml``, ``safety_controller``: a
joint faster than its limit less a margin pushed back in proportion) is kept too. The
loop's joint walls keep the joints off their position limits, and its torque-rate and
torque limits and its low-pass filter follow, as for every controller.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from panda_py import checks, kinematics
from panda_py.controllers._base import FloatArray, TorqueController
from panda_py.controllers.law import StateView
from panda_py.controllers.model import ControlModel

__all__ = [
    "DROID_KQ",
    "DROID_KQD",
    "DROID_KX",
    "DROID_KXD",
    "HybridJointImpedance",
]

# DROID's gains (droid config/panda/franka_hardware.yaml lines 10-13, the same for fr3)
DROID_KQ = (40.0, 30.0, 50.0, 25.0, 35.0, 25.0, 10.0)  # [Nm/rad]
DROID_KQD = (4.0, 6.0, 5.0, 5.0, 3.0, 2.0, 1.0)  # [Nm s/rad]
DROID_KX = (400.0, 400.0, 400.0, 15.0, 15.0, 15.0)  # [N/m, Nm/rad]
DROID_KXD = (37.0, 37.0, 37.0, 2.0, 2.0, 2.0)  # [N s/m, Nm s/rad]
# a new setpoint is approached at no more than this share of each joint's speed limit
# (measured on the simulator, full-scale actions reversed, alternated and random on every
# joint: 0.5 peaks at 1.0 rad/s, 0.6 of the limit less VELOCITY_MARGIN at 1.3, the full
# limit less it at 2.3, past joint 2's 2.175, the coupled Cartesian stiffness driving it)
SETPOINT_SPEED_SHARE = 0.4
# [rad/s] polymetis's velocity guard starts this far inside each joint's limit
# (franka_hardware.yaml: limits.joint_vel 0.1 rad/s inside the robot's, and
# safety_controller.margins.joint_vel 0.5 inside those) ...
VELOCITY_MARGIN = 0.6
# ... and pushes a joint faster than that back with this much [Nm s/rad] each rad/s faster
# (safety_controller.stiffness.joint_vel)
VELOCITY_GAIN = 20.0


class HybridJointImpedance(TorqueController):
    """Follow joint setpoints ``set_target(q)`` [rad] at once, as polymetis's
    ``HybridJointImpedanceControl`` does: ``tau = (Kq + J^T Kx J)(q_d - q) - (Kqd + J^T Kxd
    J) dq + C dq``, ``J`` the flange's zero Jacobian; gains default to DROID's
    (:data:`DROID_KQ`, :data:`DROID_KQD` per joint; :data:`DROID_KX`, :data:`DROID_KXD`
    per Cartesian axis). Unlike polymetis, ``q_d`` moves toward a new setpoint at no more
    than 0.4 of each joint's speed limit (the module says why); a joint faster than its limit
    less :data:`VELOCITY_MARGIN` is pushed back (:data:`VELOCITY_GAIN` per rad/s), as
    polymetis's safety controller does.

    The setpoint starts where the arm is and stays where it was last set (a policy that
    stops sending leaves the arm holding its last setpoint). Outputs: ``target`` (the
    newest setpoint), ``q_d`` (where the law pulls this tick), ``q_min``, ``q_max`` (the
    joint limits setpoints are checked against)."""

    signals: ClassVar[dict[str, int]] = {"q": 7}
    outputs: ClassVar[dict[str, int]] = {"target": 7, "q_d": 7, "q_min": 7, "q_max": 7}

    def __init__(
        self,
        Kq: Any = DROID_KQ,
        Kqd: Any = DROID_KQD,
        Kx: Any = DROID_KX,
        Kxd: Any = DROID_KXD,
    ) -> None:
        super().__init__()
        self.Kq = np.array(checks.nonnegative("Kq", Kq, 7, "[Nm/rad]"))
        self.Kqd = np.array(checks.nonnegative("Kqd", Kqd, 7, "[Nm s/rad]"))
        self.Kx = np.array(checks.nonnegative("Kx", Kx, 6, "[N/m, Nm/rad]"))
        self.Kxd = np.array(checks.nonnegative("Kxd", Kxd, 6, "[N s/m, Nm s/rad]"))

    def set_target(self, q: Any) -> None:
        """Follow the joint positions ``q`` [rad] from now on (within the joint limits)."""
        values = self._joint_target(q)
        self._send(0, values)

    @property
    def target(self) -> FloatArray:
        """The newest setpoint the loop has seen [rad]."""
        return self.get_output("target")

    # --- control process ------------------------------------------------------------

    def start(self, state: StateView, model: ControlModel) -> None:
        joints = model.spec.joints
        self._flange = kinematics.get_kinematics(model.spec, np.eye(4))
        self._speed = SETPOINT_SPEED_SHARE * np.asarray(joints.dq_max)  # [rad/s]
        self._guard = np.asarray(joints.dq_max) - VELOCITY_MARGIN  # [rad/s]
        self._q_d = np.array(state.q, dtype=np.float64)
        self.initial_signals(q=state.q)
        self.set_output("q_min", joints.q_min)
        self.set_output("q_max", joints.q_max)
        self.set_output("target", state.q)
        self.set_output("q_d", state.q)

    def step(self, state: StateView, model: ControlModel) -> FloatArray:
        target = self.signal("q")
        reach = self._speed * self.dt
        q_d = self._q_d
        q_d += np.clip(target - q_d, -reach, reach)
        q, dq = state.q, state.dq
        J = self._flange.zero_jacobian(q)  # (6, 7), panda_link8's
        stiffness = J.T @ (self.Kx[:, None] * J)
        damping = J.T @ (self.Kxd[:, None] * J)
        stiffness[np.diag_indices(7)] += self.Kq
        damping[np.diag_indices(7)] += self.Kqd
        tau = stiffness @ (q_d - q) - damping @ dq + model.coriolis_of(state)
        over = np.abs(dq) - self._guard
        if (over > 0.0).any():
            tau -= VELOCITY_GAIN * np.maximum(over, 0.0) * np.sign(dq)
        self.set_output("target", target)
        self.set_output("q_d", q_d)
        return tau
