"""One accept/refuse table for the quaternions every entry point takes: ``ik``,
``CartesianTrajectory``, ``move_to_pose``'s binder and ``CartesianImpedance.set_control``
accept and refuse the same ones (one tolerance, ``checks.QUATERNION_NORM_TOL``); one for
the 4x4 poses and frames (``ik``, ``CartesianTrajectory``, ``move_to_pose``,
``get_robot().set_K``: one test, ``checks.rigid_errors`` within ``checks.RIGID_TOL``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import panda_py
from panda_py import controllers
from panda_py.motion import CartesianTrajectory
from panda_py.panda import move_args

POSITION = [0.30689057, 0.0, 0.48688205]  # the start pose's, reachable with q7 = pi/4
H = math.sqrt(0.5)

ACCEPTED = [
    [1.0, 0.0, 0.0, 0.0],
    [0.7071, 0.7071, 0.0, 0.0],  # typed with four decimals: 3e-5 off
    [1.0005, 0.0, 0.0, 0.0],  # 5e-4 off
    [H, -H, 0.0, 0.0],
]
REFUSED = [
    [1.002, 0.0, 0.0, 0.0],  # 2e-3 off
    [0.9, 0.0, 0.0, 0.0],
    [1.0, 1.0, 0.0, 0.0],  # not normalised
    [0.0, 0.0, 0.0, 0.0],
    [math.nan, 0.0, 0.0, 1.0],
]


def _ik(quat: list[float]) -> Any:
    return panda_py.ik(POSITION, quat)


def _trajectory(quat: list[float]) -> Any:
    return CartesianTrajectory([POSITION, [POSITION[0], 0.05, POSITION[2]]], [quat, quat])


def _move_to_pose(quat: list[float]) -> Any:
    return move_args.parse_pose_targets((POSITION, quat), {})


def _set_control(quat: list[float]) -> Any:
    ctrl = controllers.CartesianImpedance()
    ctrl.set_control(POSITION, quat)
    return ctrl


ENTRY_POINTS: list[Callable[[list[float]], Any]] = [_ik, _trajectory, _move_to_pose, _set_control]


@pytest.mark.parametrize("entry", ENTRY_POINTS, ids=lambda f: f.__name__.lstrip("_"))
@pytest.mark.parametrize("quat", ACCEPTED)
def test_accepted_everywhere(entry: Callable[[list[float]], Any], quat: list[float]) -> None:
    entry(quat)


@pytest.mark.parametrize("entry", ENTRY_POINTS, ids=lambda f: f.__name__.lstrip("_"))
@pytest.mark.parametrize("quat", REFUSED)
def test_refused_everywhere(entry: Callable[[list[float]], Any], quat: list[float]) -> None:
    with pytest.raises(ValueError, match=r"quaternion|orientation"):
        entry(quat)


def test_accepted_quaternions_are_normalised_alike() -> None:
    quat = [1.0005, 0.0, 0.0, 0.0]
    _, quats, _ = move_args.parse_pose_targets((POSITION, quat), {})
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-15)
    T = panda_py.fk(_ik(quat))
    np.testing.assert_allclose(T[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-9)


# --- one rigid-transform test ------------------------------------------------------------


START = np.diag([1.0, -1.0, -1.0])  # the start pose's orientation


def _pose(R: Any = START, last: Any = (0.0, 0.0, 0.0, 1.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = POSITION
    T[3] = last
    return T


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


RIGID = [
    _pose(),
    _pose(START @ _rot_x(0.3)),
    _pose(START * (1.0 + 4e-7)),  # within RIGID_TOL
    _pose(last=(0.0, 0.0, 0.0, 1.0 + 5e-7)),
]
NOT_RIGID = [
    _pose(START * 1.01),  # scaled 1 %
    _pose(np.diag([1.0, 1.0, -1.0])),  # a reflection: det -1
    _pose(last=(0.0, 0.0, 0.0, 1.0 + 5e-6)),  # last row off beyond the tolerance
    _pose(last=(0.0, 0.01, 0.0, 1.0)),
    _pose(START + 1e-5),
]


def _ik_pose(T: np.ndarray) -> Any:
    return panda_py.ik(T)


def _trajectory_poses(T: np.ndarray) -> Any:
    T2 = T.copy()
    T2[1, 3] += 0.05
    return CartesianTrajectory([T, T2])


def _move_to_pose_pose(T: np.ndarray) -> Any:
    return move_args.parse_pose_targets((T,), {})


def _set_k(T: np.ndarray) -> Any:
    from panda_py.panda import RobotProxy

    frame = T.copy()
    frame[:3, 3] = 0.0
    return RobotProxy._transform(None, "EE_T_K", frame)  # type: ignore[arg-type]


POSE_ENTRY_POINTS: list[Callable[[np.ndarray], Any]] = [
    _ik_pose,
    _trajectory_poses,
    _move_to_pose_pose,
    _set_k,
]


@pytest.mark.parametrize("entry", POSE_ENTRY_POINTS, ids=lambda f: f.__name__.lstrip("_"))
@pytest.mark.parametrize("T", RIGID, ids=range(len(RIGID)))
def test_rigid_poses_accepted_everywhere(entry: Callable[[np.ndarray], Any], T: Any) -> None:
    entry(T)


@pytest.mark.parametrize("entry", POSE_ENTRY_POINTS, ids=lambda f: f.__name__.lstrip("_"))
@pytest.mark.parametrize("T", NOT_RIGID, ids=range(len(NOT_RIGID)))
def test_non_rigid_poses_refused_everywhere(entry: Callable[[np.ndarray], Any], T: Any) -> None:
    with pytest.raises(ValueError, match="expected a rigid transform"):
        entry(T)


def test_the_compiled_and_the_numpy_rigid_tests_are_one() -> None:
    from panda_py import checks
    from panda_py.kinematics import _ik

    assert _ik.ROTATION_TOL == checks.RIGID_TOL
    rng = np.random.default_rng(5)
    for _ in range(500):
        T = _pose(START @ _rot_x(rng.uniform(-3, 3)))
        T += rng.normal(scale=10 ** rng.uniform(-9, -4), size=(4, 4))
        assert float(checks.rigid_errors(T)) == pytest.approx(
            _ik.rigid_error(*T.ravel().tolist()), rel=1e-9, abs=1e-15
        )


def test_rigid_errors_of_a_few_matrices_equal_the_vectorised_ones() -> None:
    """Up to 8 matrices are checked in scalars (a move's targets), more vectorised: the
    same deviation either way, for rigid transforms, perturbed ones and non-rotations."""
    from panda_py import checks
    from panda_py.motion import rotation

    rng = np.random.default_rng(11)
    T = np.tile(np.eye(4), (20, 1, 1))
    for i in range(20):
        q = rng.normal(size=4)
        T[i, :3, :3] = rotation.to_matrix(q / np.linalg.norm(q))
        T[i, :3, 3] = rng.normal(size=3)
    T[3] += rng.normal(scale=1e-3, size=(4, 4))  # off by a little everywhere
    T[7, :3, :3] *= -1.0  # a reflection: det -1
    T[12, 3, :] = [0.1, 0.0, 0.0, 0.9]  # a projective last row
    batch = checks.rigid_errors(T)  # 20: vectorised
    assert batch.shape == (20,)
    singles = [float(checks.rigid_errors(T[i])) for i in range(20)]  # scalars
    np.testing.assert_allclose(singles, batch, rtol=1e-12, atol=1e-15)
    fours = np.concatenate([checks.rigid_errors(T[i : i + 4]) for i in range(0, 20, 4)])
    np.testing.assert_allclose(fours, batch, rtol=1e-12, atol=1e-15)
    assert batch[3] > checks.RIGID_TOL and batch[7] > 1.0 and batch[12] >= 0.1
    assert max(batch[i] for i in range(20) if i not in (3, 7, 12)) < 1e-12


def test_a_single_pose_is_parsed_in_scalars_to_its_position_and_quaternion() -> None:
    """One 4x4 float64 target (``move_to_pose``'s, a policy's) is parsed in scalars: the
    quaternion is the rotation's in each of Shepperd's four branches and at their ties
    (half turns), the same as the general path's (a list); what it cannot take goes the
    general way and is refused with its words."""
    from panda_py.motion import rotation
    from panda_py.motion.cartesian import parse_poses

    rng = np.random.default_rng(2)
    rotations = [np.eye(3), START, np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0]),
                 _rot_x(math.pi), _rot_x(2.0), START @ _rot_x(-2.5)]  # fmt: skip
    for q in rng.normal(size=(50, 4)):
        rotations.append(rotation.to_matrix(q / np.linalg.norm(q)))
    for R in rotations:
        T = _pose(R)
        T[:3, 3] = rng.normal(size=3)
        positions, quats = parse_poses(T.reshape(1, 4, 4))
        assert positions.shape == (1, 3) and quats.shape == (1, 4)
        np.testing.assert_array_equal(positions[0], T[:3, 3])
        np.testing.assert_allclose(rotation.to_matrix(quats[0]), R, atol=2e-15)
        assert abs(np.linalg.norm(quats[0]) - 1.0) < 1e-15
        general = parse_poses(T.reshape(1, 4, 4).tolist())
        np.testing.assert_array_equal(positions, general[0])
        np.testing.assert_allclose(quats, general[1], atol=1e-15)
    for bad, words in ((np.nan, r"poses\[0\]\[1\]\[3\]: expected a finite number"),
                       (np.inf, r"poses\[0\]\[1\]\[3\]: expected a finite number")):  # fmt: skip
        T = _pose()
        T[1, 3] = bad
        for given in (T.reshape(1, 4, 4), T.reshape(1, 4, 4).tolist()):
            with pytest.raises(ValueError, match=words):
                parse_poses(given)


def test_all_finite_is_exact_where_the_sum_overflows() -> None:
    from panda_py import checks

    assert checks.all_finite([0.5, -2.0, 3.0])
    assert checks.all_finite([1e308, 1e308, 1e308])  # the sum overflows, each is finite
    assert not checks.all_finite([1e308, 1e308, math.inf])
    assert not checks.all_finite([0.0, math.nan])
    assert not checks.all_finite([math.inf, -math.inf])
