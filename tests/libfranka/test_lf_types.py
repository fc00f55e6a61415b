"""libfranka value types: Errors, Duration, commands and their validation (no robot)."""

from __future__ import annotations

import datetime

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.fci import ERROR_NAMES


def test_errors_has_the_41_named_flags_in_wire_order():
    flags = np.zeros(41, dtype=bool)
    for i, name in enumerate(ERROR_NAMES):
        flags[:] = False
        flags[i] = True
        e = lf.Errors(flags)
        assert getattr(e, name) is True
        assert e.active == (name,)
        assert sum(bool(getattr(e, n)) for n in ERROR_NAMES) == 1
    assert len(ERROR_NAMES) == 41


def test_errors_str_is_libfrankas_list_and_bool_any():
    e = lf.Errors(np.eye(41, dtype=bool)[6] | np.eye(41, dtype=bool)[31])
    assert str(e) == '["joint_reflex", "cartesian_position_motion_generator_invalid_frame_flag"]'
    assert bool(e) and not bool(lf.Errors(np.zeros(41)))
    assert e.tau_j_range_violation is False and e.tau_J_range_violation is False
    assert list(e) == ["joint_reflex", "cartesian_position_motion_generator_invalid_frame"]


def test_errors_of_protocol_v4_pad_the_four_newer_flags():
    e = lf.Errors(np.ones(37))
    assert e.joint_p2p_insufficient_torque_for_planning and e.joint_move_in_wrong_direction
    assert not e.cartesian_spline_motion_generator_violation
    assert not e.base_acceleration_invalid_reading
    with pytest.raises(ValueError, match="at most 41"):
        lf.Errors(np.ones(42))


def test_duration_arithmetic_and_conversions():
    d = lf.Duration(1500)
    assert d.to_msec() == 1500 and d.to_sec() == 1.5
    assert lf.Duration(datetime.timedelta(seconds=0.25)) == lf.Duration(250)
    assert (d - lf.Duration(500)).to_msec() == 1000 and (d + d).to_msec() == 3000
    assert lf.Duration(1) < d
    with pytest.raises(ValueError, match="milliseconds"):
        lf.Duration(1.5)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "make",
    [
        lambda v: lf.Torques(v),
        lambda v: lf.JointPositions(v),
        lambda v: lf.JointVelocities(v),
        lambda v: lf.CartesianVelocities(v[:6]),
    ],
)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_commands_reject_non_finite_values(make, bad):
    v = np.zeros(7)
    v[3] = bad
    with pytest.raises(ValueError, match="infinite or NaN"):
        make(v)


def test_commands_reject_wrong_shapes_naming_the_argument():
    with pytest.raises(ValueError, match=r"tau_J: expected shape \(7,\)"):
        lf.Torques(np.zeros(6))
    with pytest.raises(ValueError, match="q: expected 7 numbers"):
        lf.JointPositions("abc")


def test_cartesian_pose_checks_the_transform_and_elbow():
    T = np.eye(4)
    T[:3, 3] = (0.3, 0.1, 0.5)
    pose = lf.CartesianPose(T)  # a 4x4 matrix becomes libfranka's column-major 16
    np.testing.assert_array_equal(pose.O_T_EE[12:15], (0.3, 0.1, 0.5))
    assert not pose.has_elbow()
    bad = T.copy()
    bad[0, 0] = 1.001  # not orthonormal
    with pytest.raises(ValueError, match="Has to be column major"):
        lf.CartesianPose(bad)
    row_major = T.reshape(16)  # translation in the last row: not a transform
    with pytest.raises(ValueError, match="Has to be column major"):
        lf.CartesianPose(row_major)
    assert lf.CartesianPose(T, [0.1, -1.0]).has_elbow()
    with pytest.raises(ValueError, match=r"elbow\[1\]"):
        lf.CartesianPose(T, [0.1, 0.5])
    with pytest.raises(ValueError, match=r"elbow\[1\]"):
        lf.CartesianVelocities(np.zeros(6), [0.1, 0.0])


def test_is_homogeneous_transformation_tolerance():
    T = np.eye(4).reshape(16)
    assert lf.is_homogeneous_transformation(T)
    T2 = T.copy()
    T2[0] = 1.0 + 5e-6  # inside libfranka's 1e-5
    assert lf.is_homogeneous_transformation(T2)
    T2[0] = 1.0 + 2e-5
    assert not lf.is_homogeneous_transformation(T2)
    assert lf.is_valid_elbow([0.0, 1.0]) and not lf.is_valid_elbow([0.0, 0.9])


def test_motion_finished_marks_and_returns_the_command():
    t = lf.Torques(np.zeros(7))
    assert lf.motion_finished(t) is t and t.motion_finished
    with pytest.raises(ValueError, match="command"):
        lf.motion_finished("stop")  # type: ignore[type-var]


def test_enums_keep_libfrankas_names_and_numbers():
    assert lf.RobotMode.kReflex == 4 and lf.RobotMode.kUserStopped == 5
    assert lf.ControllerMode.kCartesianImpedance == 1
    assert lf.RealtimeConfig.kIgnore == 1
    assert [f.name for f in lf.Frame][-3:] == ["kFlange", "kEndEffector", "kStiffness"]


def test_all_is_honest():
    for name in lf.__all__:
        assert hasattr(lf, name), name
    exceptions = [getattr(lf, n) for n in lf.__all__ if n.endswith("Exception")]
    assert len(exceptions) == 9
    assert all(issubclass(e, lf.FrankaException) for e in exceptions)
    assert issubclass(lf.FrankaException, RuntimeError)
