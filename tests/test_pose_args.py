"""One accept/refuse table for the quaternions every entry point takes: ``ik``,
``CartesianTrajectory``, ``move_to_pose``'s binder and ``CartesianImpedance.set_control``
accept and refuse the same ones (one tolerance, ``checks.QUATERNION_NORM_TOL``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import panda_py
from panda_py import controllers
from panda_py.motion import CartesianTrajectory
from panda_py.panda import planning as _moves

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
    return _moves.parse_pose_targets((POSITION, quat), {})


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
    _, quats, _ = _moves.parse_pose_targets((POSITION, quat), {})
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-15)
    T = panda_py.fk(_ik(quat))
    np.testing.assert_allclose(T[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-9)
