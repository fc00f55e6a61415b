"""HybridJointImpedance's step on states made here: polymetis's hybrid joint impedance
(facebookresearch/fairo, polymetis torchcontrol/modules/feedback.py, HybridJointSpacePD:
``(Kq + J^T Kx J)(q_d - q) + (Kqd + J^T Kxd J)(0 - dq)``, J of panda_link8, plus the
Coriolis torques), its setpoint approached at 0.4 of the joints' speed limits, and
polymetis's velocity guard."""

from __future__ import annotations

import numpy as np
import pytest
from test_law_steps import MODEL, Q0, make_state

from panda_py import kinematics
from panda_py.controllers import HybridJointImpedance
from panda_py.controllers.setpoints import (
    SETPOINT_SPEED_SHARE,
    VELOCITY_GAIN,
    VELOCITY_MARGIN,
)

DT = 1e-3
DQ_MAX = np.array(MODEL.spec.joints.dq_max)


def polymetis_torque(law: HybridJointImpedance, q_d: np.ndarray, state: object) -> np.ndarray:
    J = kinematics.zero_jacobian(state.q, F_T_EE=np.eye(4))  # type: ignore[attr-defined]
    Kp = J.T @ np.diag(law.Kx) @ J + np.diag(law.Kq)
    Kd = J.T @ np.diag(law.Kxd) @ J + np.diag(law.Kqd)
    q, dq = state.q, state.dq  # type: ignore[attr-defined]
    return Kp @ (q_d - q) + Kd @ (np.zeros(7) - dq) + MODEL.coriolis_of(state)


def started(law: HybridJointImpedance, target: np.ndarray) -> None:
    state = make_state(Q0)
    law.start(state, MODEL)
    law._values[0:7] = target  # the user's setpoint, as the slot hands it over
    law.tick(0.0)


def test_the_torque_is_polymetis_hybrid_joint_impedance() -> None:
    law = HybridJointImpedance(Kq=[60, 50, 40, 30, 20, 10, 5])
    target = Q0 + 1e-4 * np.arange(1, 8)  # within a tick's approach: followed at once
    started(law, target)
    dq = np.array([0.1, -0.2, 0.05, 0.3, -0.1, 0.2, -0.3])
    for k in range(3):
        state = make_state(Q0 + 0.01 * k, dq=dq)
        law.tick(DT)
        tau = law.step(state, MODEL)
        np.testing.assert_allclose(tau, polymetis_torque(law, target, state), atol=1e-9)
    np.testing.assert_array_equal(law.get_output("q_d"), target)


def test_a_far_setpoint_is_approached_at_a_bounded_speed() -> None:
    law = HybridJointImpedance()
    target = Q0 + np.array([0.2, -0.2, 0.2, 0.2, -0.2, 0.2, 0.2])  # DROID's largest step
    started(law, target)
    state = make_state(Q0)
    for n in range(1, 101):
        law.tick(DT)
        tau = law.step(state, MODEL)
        q_d = law.get_output("q_d")
        expected = Q0 + np.clip(target - Q0, -n * DT * 0.4 * DQ_MAX, n * DT * 0.4 * DQ_MAX)
        np.testing.assert_allclose(q_d, expected, atol=1e-12)
    np.testing.assert_allclose(tau, polymetis_torque(law, q_d, state), atol=1e-9)
    np.testing.assert_array_equal(law.get_output("target"), target)
    assert SETPOINT_SPEED_SHARE == 0.4
    # at 0.87 rad/s (joints 1-4) a 0.2 rad step takes 230 ms: 3.5 periods of 15 Hz
    assert not np.allclose(q_d, target)


def test_a_joint_too_fast_is_pushed_back_as_polymetis_guards() -> None:
    law = HybridJointImpedance()
    started(law, Q0)
    guard = DQ_MAX - VELOCITY_MARGIN
    dq = np.zeros(7)
    dq[1] = -(guard[1] + 0.25)  # 0.25 rad/s too fast, downward
    dq[5] = guard[5] - 0.01  # just under: no push
    state = make_state(Q0, dq=dq)
    law.tick(DT)
    tau = law.step(state, MODEL)
    push = np.zeros(7)
    push[1] = VELOCITY_GAIN * 0.25  # against the motion
    np.testing.assert_allclose(tau, polymetis_torque(law, Q0, state) + push, atol=1e-9)


def test_a_setpoint_before_the_start_is_refused() -> None:
    from panda_py.libfranka import InvalidOperationException

    law = HybridJointImpedance()
    with pytest.raises(InvalidOperationException, match="not running"):
        law.set_target(Q0)  # no limits published yet to check it against
