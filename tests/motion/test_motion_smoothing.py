"""The moving average a move's samples get (panda_py.motion.smoothing): it keeps the
ends, the limits and the derivatives' relations, bounds the jerk, and a sampled Cartesian
plan comes out of it with its acceleration steps ramped."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py.motion import smoothing
from panda_py.motion.rotation import exp, multiply


def test_the_moving_average_keeps_the_ends_and_the_bounds() -> None:
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.uniform(-1.0, 1.0, (200, 3)), axis=0)
    y = smoothing.box_filter(x, 30)
    assert y.shape == (229, 3)
    np.testing.assert_allclose(y[0], x[0])
    np.testing.assert_allclose(y[-1], x[-1])
    a = rng.uniform(-2.0, 2.0, (300, 2))  # a bounded signal (each coordinate, the norm)
    b = smoothing.box_filter(a, 25)
    assert np.abs(b).max() <= np.abs(a).max() + 1e-12
    norms = np.linalg.norm(a, axis=1)
    assert np.linalg.norm(b, axis=1).max() <= norms.max() + 1e-12
    np.testing.assert_array_equal(smoothing.box_filter(x, 1), x)


def test_bad_widths_and_quaternions_are_refused_by_name() -> None:
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="width: expected a whole number of samples >= 1"):
            smoothing.box_filter(np.zeros((5, 3)), bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"quats: expected finite quaternions of shape \(N, 4\)"):
        smoothing.smooth_quaternions(np.zeros((5, 3)), 3)
    with pytest.raises(ValueError, match="quats: expected finite quaternions"):
        smoothing.smooth_quaternions(np.full((5, 4), np.nan), 3)


def test_a_step_becomes_a_ramp_and_the_derivatives_stay_consistent() -> None:
    dt, m = 1e-3, 30
    a = np.concatenate([np.zeros(50), np.full(300, 1.8), np.full(300, -1.8), np.zeros(50)])
    v = np.concatenate([[0.0], np.cumsum(a[:-1]) * dt])
    p = np.concatenate([[0.0], np.cumsum(v[:-1]) * dt])
    af, vf, pf = (smoothing.box_filter(s, m) for s in (a, v, p))
    jerk = np.abs(np.diff(af)) / dt
    assert jerk.max() <= 2 * 1.8 / (m * dt) + 1e-9  # a reversal ramps over the width
    assert np.abs(np.diff(a)).max() / dt == pytest.approx(3600.0)  # it was a step
    # the box filter commutes with differences: still each other's rates
    np.testing.assert_allclose(np.diff(vf) / dt, af[:-1], atol=1e-9)
    np.testing.assert_allclose(np.diff(pf) / dt, vf[:-1], atol=1e-9)


def test_quaternions_are_averaged_across_a_sign_flip() -> None:
    q0 = np.array([0.0, 0.0, 0.0, 1.0])
    quats = np.array([multiply(q0, exp(np.array([0.0, 0.0, 1e-3 * k]))) for k in range(100)])
    quats[40:] *= -1.0  # the same rotations, the other sign
    out = smoothing.smooth_quaternions(quats, 10)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
    dots = np.abs(np.einsum("ij,ij->i", out[1:], out[:-1]))
    assert dots.min() > np.cos(1e-3)  # no jump where the sign flipped
    assert abs(out[-1] @ quats[-1]) == pytest.approx(1.0)


def test_a_move_to_a_pose_is_planned_with_bounded_jerk() -> None:
    from panda_py import fk
    from panda_py.controllers import laws
    from panda_py.panda import move_args, planning
    from panda_py.robots.params import get_robot

    q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
    T = fk(q0)
    p0, quat = T[:3, 3].copy(), laws.quat_from_matrix(T.reshape(16, order="F"))
    offsets = np.array([[0.12, 0, 0], [0.12, 0.12, 0], [0, 0.12, 0.05]])
    points = p0 + offsets
    positions, quats, opts = move_args.parse_pose_targets(
        (points, np.tile(quat, (3, 1))), {"speed_factor": 0.2, "max_deviation": 0.02}
    )
    plan = planning.pose_move(p0, quat, positions, quats, opts, q0, get_robot("fr3"))
    assert plan is not None
    jerk = np.linalg.norm(np.diff(plan.accel[:, :3], axis=0), axis=1) / 1e-3
    # the time-optimal profile's steps (3600 m/s^3 a tick) ramped over the width
    assert jerk.max() <= 2 * 1.8 / smoothing.SMOOTHING_TIME + 1e-6
    np.testing.assert_allclose(plan.position[-1], points[-1], atol=1e-9)
    np.testing.assert_allclose(plan.twist[[0, -1]], 0.0, atol=1e-12)


def _planned_joint_accelerations(plan: object, q0: np.ndarray) -> np.ndarray:
    """The plan's joint accelerations [rad/s^2] (N-1, 7) as the Cartesian law moves the
    joints (``J^+`` of the planned twist, planning.ArmJoints)."""
    from panda_py.motion.rotation import transforms
    from panda_py.panda import planning
    from panda_py.robots.params import get_robot

    poses = transforms(plan.position, plan.orientation)  # type: ignore[attr-defined]
    dq = planning.ArmJoints(get_robot("fer"), q0).rates(poses, plan.twist)  # type: ignore[attr-defined]
    assert np.isfinite(dq).all()
    return np.diff(dq, axis=0) / 1e-3


def test_a_move_to_a_pose_runs_slower_where_its_joints_need_it() -> None:
    """Near the start pose the Cartesian limits (2.6 m/s^2 at speed factor 0.2) ask joint
    2 for all of its acceleration (1.08 of it planned before): the plan keeps every joint
    within PLAN_JOINT_SHARE of its limits, and a move the joints can follow keeps its
    time."""
    from panda_py import fk
    from panda_py.controllers import laws
    from panda_py.motion import CartesianTrajectory
    from panda_py.panda import move_args, planning
    from panda_py.robots.params import get_robot

    fer = get_robot("fer")
    q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
    T = fk(q0)
    p0, quat = T[:3, 3].copy(), laws.quat_from_matrix(T.reshape(16, order="F"))
    limit = planning.PLAN_JOINT_SHARE * np.array(fer.joints.ddq_max)
    slowed = 0
    for offset in ([0.065, -0.09, -0.11], [0.1, 0.0, 0.0], [0.0, 0.0, 0.03], [-0.1, 0.05, 0.1]):
        target = T.copy()
        target[:3, 3] += offset
        positions, quats, opts = move_args.parse_pose_targets((target,), {})
        plan = planning.pose_move(p0, quat, positions, quats, opts, q0, fer)
        assert plan is not None
        ddq = _planned_joint_accelerations(plan, q0)
        assert (np.abs(ddq) / limit).max() <= 1.0 + 1e-3, offset
        free = CartesianTrajectory(np.stack([T, target]), 0.2).get_duration()
        duration = (len(plan.position) - 1) * 1e-3 - smoothing.SMOOTHING_TIME  # (its ramps)
        assert duration >= free - 2e-3
        slowed += duration > free + 0.01
        np.testing.assert_allclose(plan.position[-1], target[:3, 3], atol=1e-9)
    assert 0 < slowed < 4  # only the moves that needed it


def test_a_move_from_the_start_pose_keeps_its_time_whatever_the_arms_noise() -> None:
    """From the start pose down to above the demo's cube, the path crosses q2 = 0, where
    joints 1 and 3 align and the inverse kinematics splits their angle anew at every
    sample: judged between neighbouring samples' configurations, 0.1 mrad of noise on
    the arm's joints once slowed the move 5x (12 s instead of 1.5 in the demo). Judged
    on the configurations the arm passes through, the plan keeps its time, and an arm that
    follows it (integrating the Cartesian law's J^+ v) stays within its joints' limits all
    the way, past q2 = 0 too (where the start pose's case of the inverse kinematics ends)."""
    from panda_py import fk
    from panda_py.controllers import laws
    from panda_py.panda import move_args, planning
    from panda_py.robots.params import START_POSE, get_robot

    fer = get_robot("fer")
    start = np.array(START_POSE)
    target = fk(start)
    target[:3, 3] = (0.5, 0.0, 0.17)
    positions, quats, opts = move_args.parse_pose_targets((target,), {})
    rng = np.random.default_rng(7)
    durations = []
    for noise in [np.zeros(7), *(rng.normal(scale=1e-4, size=7) for _ in range(4))]:
        q0 = start + noise
        T = fk(q0)
        p0, quat = T[:3, 3].copy(), laws.quat_from_matrix(T.reshape(16, order="F"))
        plan = planning.pose_move(p0, quat, positions, quats, opts, q0, fer)
        assert plan is not None
        durations.append(len(plan.position) * 1e-3)
        # an arm following the plan from q0, as the law's feed-forward moves it
        joints = planning.ArmJoints(fer, q0)
        q, dq = q0.copy(), np.zeros(7)
        peak_v, peak_a = np.zeros(7), np.zeros(7)
        for twist in plan.twist:
            rate = joints.rates_at(q[None], twist[None])[0]
            peak_v = np.maximum(peak_v, np.abs(rate))
            peak_a = np.maximum(peak_a, np.abs(rate - dq) / 1e-3)
            q, dq = q + rate * 1e-3, rate
        assert (peak_v <= np.array(fer.joints.dq_max)).all()
        assert (peak_a <= np.array(fer.joints.ddq_max)).all(), peak_a / fer.joints.ddq_max
        reached = fk(q)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 2e-3
    assert max(durations) <= 1.01 * min(durations), durations
    assert max(durations) < 1.4


def _joint_space_plan(q0: np.ndarray, goal: tuple[float, float, float]) -> object:
    """panda-py < 1.0's form of move_to_pose (joint stiffness and damping given): the
    straight path to ``goal`` (the start orientation kept) from ``q0``, as joint samples."""
    from panda_py import fk
    from panda_py.controllers import laws
    from panda_py.kinematics import Kinematics
    from panda_py.panda import move_args, planning
    from panda_py.robots.params import START_POSE, get_robot

    fer = get_robot("fer")
    target = fk(np.array(START_POSE))
    target[:3, 3] = goal
    T = fk(q0)
    p0, quat = T[:3, 3].copy(), laws.quat_from_matrix(T.reshape(16, order="F"))
    kwargs = {"stiffness": [600.0] * 7, "damping": [50.0] * 7}
    positions, quats, opts = move_args.parse_pose_targets((target,), kwargs)
    plan = planning.pose_move(p0, quat, positions, quats, opts, q0, fer)
    hand = Kinematics("fer").F_T_EE  # the robot's default end effector
    return planning.pose_move_in_joint_space(plan, opts, q0, fer, hand)


def test_the_joint_space_form_keeps_q7_where_its_inverse_kinematics_can() -> None:
    from panda_py.robots.params import START_POSE

    start = np.array(START_POSE)
    plan = _joint_space_plan(start, (0.35, 0.1, 0.55))
    q = plan.q  # type: ignore[attr-defined]
    np.testing.assert_allclose(q[:, 6], start[6])  # panda-py's: the current q7 held


def test_the_joint_space_form_crosses_q2_0_continuously() -> None:
    """Where the inverse kinematics' case ends (q2 = 0, down in front of the robot) the
    plan takes the configurations the arm passes through: once refused as out of reach."""
    from panda_py import fk
    from panda_py.robots.params import START_POSE, get_robot

    fer = get_robot("fer")
    q0 = np.array(START_POSE) + np.random.default_rng(3).normal(scale=1e-4, size=7)
    plan = _joint_space_plan(q0, (0.5, 0.0, 0.17))
    q = plan.q  # type: ignore[attr-defined]
    assert q[0, 1] < 0.0 < q[-1, 1]
    assert (np.abs(np.diff(q, axis=0)) / 1e-3 <= np.array(fer.joints.dq_max)).all()
    np.testing.assert_allclose(fk(q[-1])[:3, 3], (0.5, 0.0, 0.17), atol=1e-4)


def test_the_joint_space_form_refuses_a_path_out_of_reach() -> None:
    from panda_py.robots.params import START_POSE

    with pytest.raises(ValueError, match=r"leaves the fer's reach [\d.]+ s into the motion"):
        _joint_space_plan(np.array(START_POSE), (1.2, 0.0, 0.5))
