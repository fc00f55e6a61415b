"""Every control law's ``step`` on states made here (no simulator, no control process):
panda-py's six controllers and the two move trackers give the torques their laws say,
driven through the one interface the loop uses (:class:`ControlLaw`), with their inputs
read through a signal slot as the loop hands it to them."""

from __future__ import annotations

import math
import os
from typing import Any, ClassVar

import numpy as np
import pytest

from panda_py import controllers, fci, kinematics
from panda_py.controllers.law import ControlLaw
from panda_py.controllers.model import ControlModel
from panda_py.controllers.moves import (
    MOVE_ERROR_RATE,
    MOVE_FRICTION_SPEED,
    JointMove,
    PoseMove,
    tracker_for,
)
from panda_py.controllers.plans import JointPlan, PosePlan
from panda_py.libfranka import RobotState
from panda_py.motion.online import OnlineLimits
from panda_py.robots.params import START_POSE, get_robot
from panda_py.rt.shm import SharedBlock

VERSION = 5  # a FER's states (float64 fields: exact comparisons)
KIN = kinematics.get_kinematics("fer")
MODEL = ControlModel("fer")
RNG = np.random.default_rng(11)


ZERO = np.zeros(7)


def make_state(q: Any, dq: Any = ZERO, tau_ext: Any = ZERO, tau_J: Any = ZERO) -> RobotState:
    """A robot's state datagram as the robot would send it at ``q``, ``dq``."""
    dialect = fci.dialect(VERSION)
    rec = np.zeros((), dialect.state_dtype)
    q = np.asarray(q, dtype=np.float64)
    rec["q"] = rec["q_d"] = q
    rec["dq"] = dq
    rec["tau_ext_hat_filtered"] = tau_ext
    rec["tau_J"] = tau_J
    rec["O_T_EE"] = KIN.fk(q).reshape(16, order="F")
    rec["F_T_EE"] = np.eye(4).reshape(16)
    rec["EE_T_K"] = np.eye(4).reshape(16)
    return RobotState(dialect, rec.tobytes())


Q0 = np.array(START_POSE)
STATE0 = make_state(Q0)


def run(law: ControlLaw, states: list[RobotState]) -> list[np.ndarray]:
    """Drive ``law`` as the loop does; the torques of each tick."""
    law.start(states[0], MODEL)
    out = []
    for i, state in enumerate(states):
        law.tick(0.0 if i == 0 else 1e-3)
        out.append(np.asarray(law.step(state, MODEL), dtype=np.float64))
        law.published()
    law.stop(states[-1], MODEL)
    return out


def started(
    ctrl: controllers.TorqueController, state: RobotState = STATE0
) -> tuple[SharedBlock, np.ndarray]:
    """``ctrl`` started as the control process starts it, bound to a fresh slot; the
    user's handle writes into the same slot (as ``Panda.start_controller`` binds it)."""
    block, fd = SharedBlock.create()
    os.close(fd)
    ctrl.start(state, MODEL)
    values = ctrl.open_slot(block)
    return block, values


def test_joint_position_pulls_toward_its_target_with_its_gains() -> None:
    ctrl = controllers.JointPosition()
    user = controllers.JointPosition()
    block, values = started(ctrl)
    user.attach(block, values)
    np.testing.assert_allclose(run_once(ctrl, STATE0), 0.0, atol=1e-12)  # target = start
    target = Q0 + 0.01
    user.set_control(target)
    tau = run_once(ctrl, STATE0)
    K = np.array(controllers._builtin.JOINT_STIFFNESS)
    np.testing.assert_allclose(tau, K * 0.01, rtol=1e-9)
    moving = make_state(Q0, dq=np.full(7, 0.1))
    D = np.array(controllers._builtin.JOINT_DAMPING)
    np.testing.assert_allclose(run_once(ctrl, moving), K * 0.01 - D * 0.1, rtol=1e-9)


def run_once(law: ControlLaw, state: RobotState) -> np.ndarray:
    law.tick(1e-3)
    tau = np.asarray(law.step(state, MODEL), dtype=np.float64)
    law.published()
    return tau


def test_integrated_velocity_integrates_its_target_and_publishes_it() -> None:
    ctrl, user = controllers.IntegratedVelocity(), controllers.IntegratedVelocity()
    block, values = started(ctrl)
    user.attach(block, values)
    user.set_control(np.full(7, 0.5))
    for _ in range(10):
        run_once(ctrl, STATE0)
    q_d = user.get_qd()
    np.testing.assert_allclose(q_d - Q0, 0.5 * 10e-3, rtol=1e-6)
    assert user.get_time() == pytest.approx(10e-3)


def test_applied_torque_and_force_give_the_set_torque_and_j_transpose_f() -> None:
    torque, user = controllers.AppliedTorque(), controllers.AppliedTorque()
    block, values = started(torque)
    user.attach(block, values)
    tau_d = RNG.normal(size=7)
    user.set_control(tau_d)
    np.testing.assert_allclose(run_once(torque, STATE0), tau_d, rtol=1e-12)

    force, user_f = controllers.AppliedForce(), controllers.AppliedForce()
    block, values = started(force)
    user_f.attach(block, values)
    f = np.array([0.0, 0.0, -5.0, 0.0, 0.1, 0.0])
    user_f.set_control(f)
    J = KIN.zero_jacobian(Q0)
    np.testing.assert_allclose(run_once(force, STATE0), J.T @ f, rtol=1e-6, atol=1e-9)


def test_force_adds_its_pi_correction_of_the_measured_wrench() -> None:
    gravity = MODEL.gravity_of(STATE0)
    resting = make_state(Q0, tau_J=gravity)  # the sensors read gravity alone: no bias
    ctrl, user = controllers.Force(filter_coeff=1.0), controllers.Force()
    block, values = started(ctrl, resting)
    user.attach(block, values)
    user.set_control([0.0, 0.0, -5.0])
    tau_d = KIN.zero_jacobian(Q0)[:3].T @ np.array([0.0, 0.0, -5.0])
    # the robot already applies what is asked for: no correction
    applying = make_state(Q0, tau_J=gravity + tau_d)
    np.testing.assert_allclose(run_once(ctrl, applying), tau_d, rtol=1e-9, atol=1e-9)
    # it applies nothing: the proportional term (k_p = 1) doubles the feed-forward, and the
    # integral (k_i = 2) adds 2 dt tau_d
    tau = run_once(ctrl, resting)
    np.testing.assert_allclose(tau, tau_d * (2.0 + 2.0 * 1e-3), rtol=1e-9, atol=1e-9)


def test_cartesian_impedance_holds_its_start_pose_and_pulls_toward_a_target() -> None:
    ctrl, user = controllers.CartesianImpedance(filter_coeff=1.0), controllers.CartesianImpedance()
    block, values = started(ctrl)
    user.attach(block, values)
    coriolis = MODEL.coriolis_of(STATE0)
    np.testing.assert_allclose(run_once(ctrl, STATE0), coriolis, atol=1e-9)
    T = KIN.fk(Q0)
    user.set_control(T[:3, 3] + [0.0, 0.0, 0.01], ctrl_quat(T), Q0)
    tau = run_once(ctrl, STATE0)
    J = KIN.zero_jacobian(Q0)
    # the pull is upward: the wrench J^+ T tau points along +z
    wrench = np.linalg.pinv(J.T) @ (tau - coriolis)
    assert wrench[2] == pytest.approx(600.0 * 0.01, rel=0.05)
    assert np.abs(wrench[:2]).max() < 0.5


def ctrl_quat(T: np.ndarray) -> np.ndarray:
    from panda_py.controllers import laws

    return laws.quat_from_matrix(T.reshape(16, order="F"))


def _joint_plan(n: int = 50) -> JointPlan:
    s = np.linspace(0.0, 1.0, n)[:, None]
    q = Q0 + 0.05 * s
    dq = np.gradient(q, 1e-3, axis=0)
    ddq = np.gradient(dq, 1e-3, axis=0)
    K, D = np.full(7, 600.0), np.full(7, 50.0)
    return JointPlan(q, dq, ddq, K, D, 1e-3, 1e-2, OnlineLimits.joints(get_robot("fer"), 1.0))


def test_joint_move_tracks_its_samples_with_the_model_feed_forward() -> None:
    plan = _joint_plan()
    law = tracker_for(plan)
    assert isinstance(law, JointMove)
    law.start(STATE0, MODEL)
    law.tick(0.0)
    for k in (0, 10, 20):
        law.t = k * 1e-3
        tau = law.step(STATE0, MODEL)
        e = plan.q[k] - Q0
        expected = (
            plan.stiffness * e
            + plan.damping * plan.dq[k]
            + MODEL.viscous * plan.dq[k]  # the drives' viscous friction, fed forward
            + MODEL.driven_mass_of(STATE0) @ plan.ddq[k]
            + MODEL.coulomb * np.tanh((plan.dq[k] + MOVE_ERROR_RATE * e) / MOVE_FRICTION_SPEED)
            + MODEL.coriolis_of(STATE0)
        )
        np.testing.assert_allclose(tau, expected, rtol=1e-9, atol=1e-9)
    assert not law.finished(STATE0)  # the trajectory is not over


def test_a_move_ends_at_rest_at_its_goal_and_judges_the_result() -> None:
    plan = _joint_plan()
    law = tracker_for(plan)
    goal = make_state(plan.q[-1])
    law.t = law.duration + 0.01
    assert law.finished(goal)
    result = law.result(goal)
    assert result.success and result.joint_error == pytest.approx(0.0, abs=1e-6)
    far = make_state(plan.q[-1] + 0.1)
    result = law.result(far)
    assert not result.success and "success threshold" in result.reason
    law.t = law.duration + 1.5  # past the settle timeout it ends wherever it is
    assert law.finished(far)


def test_pose_move_at_its_goal_and_at_rest_commands_only_the_model_terms() -> None:
    T = STATE0.O_T_EE
    n = 20
    p = np.tile(T[12:15], (n, 1))
    quat = np.tile(ctrl_quat(KIN.fk(Q0)), (n, 1))
    z = np.zeros((n, 6))
    plan = PosePlan(p, quat, z, z, Q0, np.diag([800.0] * 3 + [40.0] * 3), 1.0, 15.0,
                    1e-3, 2e-2, 0.1, OnlineLimits.cartesian(get_robot('fer'), 1.0))  # fmt: skip
    law = tracker_for(plan)
    assert isinstance(law, PoseMove)
    taus = run(law, [STATE0] * 5)
    np.testing.assert_allclose(taus[-1], MODEL.coriolis_of(STATE0), atol=1e-6)
    law.t = law.duration + 0.01
    assert law.finished(STATE0) and law.result(STATE0).success


def test_a_plan_of_another_kind_is_refused_by_name() -> None:
    with pytest.raises(TypeError, match="plan: expected a JointPlan or a PosePlan, got dict"):
        tracker_for({"q": Q0})  # type: ignore[arg-type]


def test_a_users_controller_runs_through_the_same_interface() -> None:
    class Spring(controllers.TorqueController):
        signals: ClassVar[dict[str, int]] = {"k": 1}

        def step(self, state: Any, model: Any) -> np.ndarray:
            return -self.signal("k")[0] * (state.q - Q0) + self.t

    ctrl, user = Spring(), Spring()
    block, values = started(ctrl)
    user.attach(block, values)
    user.set_signals(k=100.0)
    moved = make_state(Q0 + 0.01)
    tau = run_once(ctrl, moved)
    np.testing.assert_allclose(tau, -100.0 * 0.01 + 1e-3, rtol=1e-5)
    assert user.get_time() == pytest.approx(1e-3)
    user.detach()
    assert user.get_time() == pytest.approx(1e-3)  # kept after the controller stopped
    np.testing.assert_allclose(user.get_signal("k"), [100.0])
    assert not ctrl.finished(moved) and ctrl.result(moved) is None
    assert math.isfinite(ctrl.t)
