"""Torque controllers (panda-py's ``panda_py.controllers``).

Instantiate one and hand it to :meth:`panda_py.Panda.start_controller`; it runs at 1 kHz in
the control process while this process feeds it with ``set_control`` and its setters, all
changeable while it runs. Subclass :class:`TorqueController` (declare ``signals``,
implement ``step(state, model) -> tau``) to run a control law of your own at 1 kHz.
Beyond panda-py, :class:`JointTarget` and :class:`CartesianTarget` follow targets streamed
at any rate (a policy, teleoperation) smoothly within the robot's limits
(:mod:`panda_py.controllers.streaming`), and :class:`HybridJointImpedance` follows joint
setpoints at once with DROID's soft gains, as polymetis does
(:mod:`panda_py.controllers.setpoints`).
"""

from __future__ import annotations

from panda_py.controllers._base import TorqueController
from panda_py.controllers._builtin import (
    AppliedForce,
    AppliedTorque,
    CartesianImpedance,
    Force,
    IntegratedVelocity,
    JointPosition,
)
from panda_py.controllers.setpoints import HybridJointImpedance
from panda_py.controllers.streaming import CartesianTarget, JointTarget

__all__ = [
    "AppliedForce",
    "AppliedTorque",
    "CartesianImpedance",
    "CartesianTarget",
    "Force",
    "HybridJointImpedance",
    "IntegratedVelocity",
    "JointPosition",
    "JointTarget",
    "TorqueController",
]
