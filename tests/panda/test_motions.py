"""The typed motions (panda_py.JointMotion, panda_py.PoseMotion): their typed
constructors make the same motion as panda-py's arguments do, check what they are given
(a clear error, nothing made), and ``Panda.move`` runs them as ``move_to_*`` does."""

from __future__ import annotations

import numpy as np
import pytest

import panda_py
from panda_py import constants
from panda_py.panda import MotionHandle

pytestmark = pytest.mark.timeout(300)

Q = np.array(constants.JOINT_POSITION_START)
T = panda_py.fk(Q)


def _same_joint(a: panda_py.JointMotion, b: panda_py.JointMotion) -> None:
    np.testing.assert_array_equal(a.waypoints, b.waypoints)
    for name in ("speed_factor", "dq_threshold", "success_threshold", "max_deviation"):
        assert getattr(a.options, name) == getattr(b.options, name), name
    np.testing.assert_array_equal(a.options.stiffness, b.options.stiffness)
    np.testing.assert_array_equal(a.options.damping, b.options.damping)


def _same_pose(a: panda_py.PoseMotion, b: panda_py.PoseMotion) -> None:
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-15)
    np.testing.assert_allclose(np.abs(a.orientations), np.abs(b.orientations), atol=1e-15)
    for name in ("speed_factor", "damping_ratio", "nullspace_stiffness", "dq_threshold",
                 "success_threshold", "orientation_threshold", "max_deviation"):  # fmt: skip
        assert getattr(a.options, name) == getattr(b.options, name), name
    np.testing.assert_array_equal(a.options.impedance, b.options.impedance)


def test_typed_joint_motions_are_panda_pys_arguments() -> None:
    _same_joint(panda_py.JointMotion.to(Q), panda_py.JointMotion(Q))
    _same_joint(panda_py.JointMotion.to(Q.tolist(), speed_factor=0.3, dq_threshold=0.002),
                panda_py.JointMotion(Q, 0.3, dq_threshold=0.002))  # fmt: skip
    path = [Q, Q + 0.1, Q - 0.1]
    _same_joint(panda_py.JointMotion.through(path, max_deviation=0.05),
                panda_py.JointMotion(waypoints=path, max_deviation=0.05))  # fmt: skip
    assert panda_py.JointMotion.to(Q).options is panda_py.JointMotion(Q).options  # defaults


def test_typed_pose_motions_are_panda_pys_arguments() -> None:
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    p = T[:3, 3]
    _same_pose(panda_py.PoseMotion.to(T), panda_py.PoseMotion(T))
    _same_pose(panda_py.PoseMotion.to(T, speed_factor=0.1, damping_ratio=0.8),
               panda_py.PoseMotion(pose=T, speed_factor=0.1, damping_ratio=0.8))  # fmt: skip
    _same_pose(panda_py.PoseMotion.to_position(p, quat), panda_py.PoseMotion(p, quat))
    poses = np.stack([T, T])
    poses[1, 2, 3] -= 0.1
    _same_pose(panda_py.PoseMotion.through(poses, max_deviation=0.01),
               panda_py.PoseMotion(poses, max_deviation=0.01))  # fmt: skip
    ps = poses[:, :3, 3]
    _same_pose(panda_py.PoseMotion.through_positions(ps, [quat, quat]),
               panda_py.PoseMotion(positions=ps, orientations=[quat, quat]))  # fmt: skip


@pytest.mark.parametrize(
    ("make", "error", "match"),
    [
        (lambda: panda_py.JointMotion.to([Q, Q]), ValueError, "positions: expected 7 joint"),
        (lambda: panda_py.JointMotion.to(Q[:6]), ValueError, r"waypoints: expected shape"),
        (lambda: panda_py.JointMotion.to(Q, speed_factor=2.0), ValueError,
         r"speed_factor: expected a number in \(0, 1\]"),
        (lambda: panda_py.JointMotion.through([Q, Q * np.nan]), ValueError,
         r"waypoints\[1\]\[0\]: expected a finite number"),
        (lambda: panda_py.JointMotion(Q, 0.2, sped=1), TypeError,
         "move_to_joint_position\\(\\) got an unexpected keyword argument 'sped'"),
        (lambda: panda_py.JointMotion(Q, speed_factor=0.1, positions=Q), TypeError,
         "multiple values for argument 'positions'"),
        (lambda: panda_py.PoseMotion.to(np.stack([T, T])), ValueError, "pose: expected one"),
        (lambda: panda_py.PoseMotion.to(T, impedance=-np.eye(6)), ValueError, "impedance"),
        (lambda: panda_py.PoseMotion(T[:3, 3]), TypeError,
         "move_to_pose\\(\\) missing a required argument: 'orientation'"),
        (lambda: panda_py.PoseMotion.to_position(T[:3, 3], [0.0, 0.0, 0.0, 2.0]), ValueError,
         "orientations\\[0\\]"),
    ],
)  # fmt: skip
def test_bad_motions_are_clear_errors(make, error, match) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(error, match=match):
        make()


@pytest.fixture
def panda(reset_panda: panda_py.Panda) -> panda_py.Panda:
    return reset_panda


def test_move_runs_typed_motions_blocking_and_asynchronously(panda: panda_py.Panda) -> None:
    goal = Q + np.array([0.1, -0.1, 0.1, 0.1, -0.1, 0.1, 0.2])
    assert panda.move(panda_py.JointMotion.to(goal)) is True
    np.testing.assert_allclose(panda.q, goal, atol=0.01)
    target = panda_py.fk(Q)
    target[2, 3] -= 0.05
    handle = panda.move(panda_py.PoseMotion.to(target), asynchronous=True)
    assert isinstance(handle, MotionHandle)
    assert handle.wait(30.0) is True
    np.testing.assert_allclose(panda.get_pose()[:3, 3], target[:3, 3], atol=0.02)
    assert panda.move_to_start() is True  # the wrappers: the same path
    np.testing.assert_allclose(panda.q, Q, atol=0.01)


def test_move_refuses_what_is_not_a_motion_before_anything_moves(panda: panda_py.Panda) -> None:
    q = panda.q
    with pytest.raises(ValueError, match="motion: expected a JointMotion or a PoseMotion, got"):
        panda.move(Q)  # type: ignore[call-overload]
    with pytest.raises(ValueError, match="asynchronous: expected True or False"):
        panda.move(panda_py.JointMotion.to(Q + 0.1), asynchronous="yes")  # type: ignore[call-overload]
    from panda_py.conditions import Elapsed

    joint_space = panda_py.PoseMotion(T, stiffness=[600.0] * 7)
    with pytest.raises(ValueError, match="then: expected a PoseMotion with impedance"):
        panda.move(panda_py.JointMotion.to(Q + 0.1), until=Elapsed > 0.1, then=joint_space)
    with pytest.raises(ValueError, match="joint-space form of move_to_pose blocks"):
        panda.move(joint_space, asynchronous=True)
    np.testing.assert_allclose(panda.q, q, atol=1e-6)  # (at rest: nanometres of drift)
    assert not panda.is_moving()
