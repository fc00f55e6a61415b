"""Every built-in law run once, as the control loop runs them, so that nothing compiles or
loads mid-loop: the control process calls :func:`warm_up` after connecting, and the server
control processes are forked from (:mod:`panda_py.rt.warm`) calls it before forking."""

from __future__ import annotations

import numpy as np

from panda_py import kinematics
from panda_py.controllers import laws
from panda_py.controllers._builtin import (
    AppliedForce,
    AppliedTorque,
    CartesianImpedance,
    Force,
    IntegratedVelocity,
    JointPosition,
)
from panda_py.controllers.finalize import Finalize
from panda_py.controllers.model import ControlModel
from panda_py.controllers.moves import tracker_for
from panda_py.controllers.plans import JointPlan, PosePlan
from panda_py.controllers.streaming import CartesianTarget, JointTarget
from panda_py.fci import PERIOD
from panda_py.libfranka.state import RobotState
from panda_py.motion import online
from panda_py.motion.online import OnlineLimits
from panda_py.robots.params import RobotSpec

__all__ = ["BUILTIN", "example_plans", "warm_up"]

#: the built-in torque controllers, each warmed by :func:`warm_up`
BUILTIN = (
    CartesianImpedance,
    JointPosition,
    IntegratedVelocity,
    AppliedTorque,
    AppliedForce,
    Force,
    CartesianTarget,
    JointTarget,
)


def warm_up(state: RobotState, model: ControlModel, limits: RobotSpec, finalize: Finalize) -> None:
    """Run every built-in law once on ``state`` (results discarded) as the loop runs them:
    the controllers, both moves, their lead-ins from each other and their stops."""
    kinematics.warmup()
    online.warmup()  # the online generators' compiled steps (lead-ins, stops, streams)
    for cls in BUILTIN:
        ctrl = cls()
        ctrl.dt = PERIOD
        ctrl.start(state, model)
        for _ in range(2):  # (the streamed targets' feed-forward starts on the second)
            ctrl.tick(PERIOD)
            finalize(ctrl.step(state, model), state)
    finalize.reset()
    model.gravity_of(state)
    joint, pose = example_plans(state, limits)
    for plan in (joint, pose):  # and their lead-ins and stops
        law = tracker_for(plan)
        law.step(state, model)
        other = tracker_for(pose if plan is joint else joint)
        other.handover(law, state, model)
        other.step(state, model)
        other.cancel("warm-up")
        other.step(state, model)


def example_plans(state: RobotState, limits: RobotSpec) -> tuple[JointPlan, PosePlan]:
    """A joint and a Cartesian plan of two samples that hold the arm where ``state`` has
    it (what the warm-ups run the moves on)."""
    q = state.q
    z = np.zeros((2, 7))
    joint = JointPlan(np.array([q, q]), z, z, np.ones(7), np.ones(7), 1e-3, 1e-2,
                      OnlineLimits.joints(limits, 1.0))  # fmt: skip
    p = np.array([state.O_T_EE[12:15]] * 2)
    quat = np.array([laws.quat_from_matrix(state.O_T_EE)] * 2)
    six = np.zeros((2, 6))
    pose = PosePlan(p, quat, six, six, q, np.eye(6), 1.0, 1.0, 1e-3, 1e-2, 1e-1,
                    OnlineLimits.cartesian(limits, 1.0))  # fmt: skip
    return joint, pose
