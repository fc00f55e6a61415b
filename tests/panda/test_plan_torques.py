"""A Cartesian plan asks the arm for torques that change no faster than the loop delivers
(panda_py.panda.plan_torques): its smoothing is widened where the default one would ask for
more, and left alone where it does not."""

from __future__ import annotations

import numpy as np
import pytest

import panda_py
from panda_py.controllers import laws
from panda_py.motion.cartesian import CartesianSamples
from panda_py.panda import planning
from panda_py.panda.move_args import pose_options
from panda_py.panda.plan_torques import (
    PLAN_TORQUE_RATE,
    feedforward_torques,
    loaded_arm,
    smoothed,
)
from panda_py.robots.params import get_robot

# the FER's short fast Cartesian move (random seed 46's fourth of tests/panda/
# test_move_ends.py): 3.8 cm from this configuration in 0.29 s at speed factor 0.2
Q_SHORT = np.array([0.0787, -0.6699, 0.0796, -2.2763, 0.0494, 1.6085, 0.9249])
GOAL_SHORT = np.array([0.3665, 0.0913, 0.4867])


def _plan(q0: np.ndarray, goal: np.ndarray, speed_factor: float = 0.2) -> planning.PosePlan:
    spec = get_robot("fer")
    T = panda_py.fk(q0)
    quat = laws.quat_from_matrix(T.reshape(16, order="F"))
    opts = pose_options({"speed_factor": speed_factor})
    return planning.pose_move(T[:3, 3], quat, goal[None], np.array([[1.0, 0.0, 0.0, 0.0]]),
                              opts, q0, spec, at_rest=True)  # fmt: skip


def _peak_rate(plan: planning.PosePlan, q0: np.ndarray) -> float:
    """The largest change a tick of a joint's feed-forward torque along ``plan`` [Nm]."""
    spec = get_robot("fer")
    joints = planning.ArmJoints(spec, q0)
    q = joints.configurations(planning.transforms(plan.position, plan.orientation))
    tau = feedforward_torques(q, joints.rates_at(q, plan.twist), loaded_arm(spec, None),
                              np.asarray(spec.drives.armature))  # fmt: skip
    return float(np.abs(np.diff(tau, axis=0)).max())


def _default_smoothing(plan_fn, monkeypatch) -> planning.PosePlan:  # type: ignore[no-untyped-def]
    from panda_py.panda import plan_torques

    monkeypatch.setattr(plan_torques, "WIDTH_TRIES", 1)  # the default width, unwidened
    return plan_fn()


def test_a_short_fast_move_is_smoothed_until_its_torques_fit_the_loops_rate(monkeypatch) -> None:
    """With the default 30 ms smoothing joint 2's torque turns by up to 0.6 Nm a tick,
    where accelerating becomes braking (the loop delivers 0.386); the plan comes smoothed
    wider, its feed-forward within PLAN_TORQUE_RATE, a few tens of ms longer."""
    narrow = _default_smoothing(lambda: _plan(Q_SHORT, GOAL_SHORT), monkeypatch)
    monkeypatch.undo()
    plan = _plan(Q_SHORT, GOAL_SHORT)
    assert _peak_rate(narrow, Q_SHORT) > 1.5 * PLAN_TORQUE_RATE
    assert _peak_rate(plan, Q_SHORT) <= PLAN_TORQUE_RATE
    longer = len(plan.position) - len(narrow.position)
    assert 10 <= longer <= 60, longer  # [ms]
    # the same path, at rest at both ends, to the same goal
    np.testing.assert_allclose(plan.position[-1], GOAL_SHORT, atol=1e-9)
    np.testing.assert_allclose(plan.twist[[0, -1]], 0.0, atol=1e-12)


def test_a_slow_move_keeps_the_default_smoothing(monkeypatch) -> None:
    """At speed factor 0.05 the torques change slowly: nothing is widened, the plan is the
    default one sample for sample."""
    q0 = np.array(panda_py.constants.JOINT_POSITION_START)
    goal = panda_py.fk(q0)[:3, 3] + [0.1, -0.1, -0.05]
    narrow = _default_smoothing(lambda: _plan(q0, goal, 0.05), monkeypatch)
    monkeypatch.undo()
    plan = _plan(q0, goal, 0.05)
    assert _peak_rate(plan, q0) <= PLAN_TORQUE_RATE
    np.testing.assert_array_equal(plan.position, narrow.position)


def test_smoothed_samples_are_consistent() -> None:
    """smoothed: position, orientation and twist averaged over the width (N + width - 1
    samples), the acceleration the twist's rate, at rest at both ends."""
    n, width = 50, 7
    t = np.linspace(0.0, 1.0, n)[:, None]
    v = np.hstack([np.sin(np.pi * t)] * 6)
    s = CartesianSamples(np.cumsum(v[:, :3], axis=0) * 1e-3, np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
                         v[:, :3], np.zeros((n, 3)), v[:, 3:])  # fmt: skip
    p, quat, twist, accel = smoothed(s, width)
    assert len(p) == len(quat) == len(twist) == len(accel) == n + width - 1
    np.testing.assert_allclose(accel, np.gradient(twist, 1e-3, axis=0))
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0)
    with pytest.raises(ValueError, match="width"):
        smoothed(s, 0)
