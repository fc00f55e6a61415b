"""The robot-side checks' geometry: pose errors are the rotation vector and translation
between two poses, and transforms are validated as libfranka does."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panda_py.sim.safety import integrate_twist, is_valid_transform, pose_error


def _rot(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula, written out independently of the code under test."""
    angle = float(np.linalg.norm(w))
    if angle == 0.0:
        return np.eye(3)
    k = w / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = _rot(rng.normal(size=3))
    T[:3, 3] = rng.normal(size=3)
    return T


def test_pose_error_is_the_translation_and_rotation_vector() -> None:
    rng = np.random.default_rng(1)
    for _ in range(200):
        T_a = _pose(rng)
        w = rng.normal(size=3)
        w *= rng.uniform(0.0, 3.0) / np.linalg.norm(w)  # angles up to 3 rad (< pi)
        d = rng.normal(size=3)
        T_b = np.eye(4)
        T_b[:3, :3] = _rot(w) @ T_a[:3, :3]
        T_b[:3, 3] = T_a[:3, 3] + d
        np.testing.assert_allclose(pose_error(T_a, T_b), np.r_[d, w], atol=1e-9)
    T = _pose(rng)
    np.testing.assert_array_equal(pose_error(T, T), np.zeros(6))


def test_integrating_a_twist_inverts_the_pose_error() -> None:
    rng = np.random.default_rng(2)
    for _ in range(50):
        T = _pose(rng)
        v = rng.normal(size=6)
        np.testing.assert_allclose(pose_error(T, integrate_twist(T, v, 1e-3)) / 1e-3, v, atol=1e-9)


def test_valid_transforms_pass_and_broken_ones_fail() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        assert is_valid_transform(_pose(rng))
    T = _pose(rng)
    broken = []
    for i, j, value in ((3, 0, 1e-9), (3, 3, 0.5), (0, 3, math.nan), (1, 3, math.inf),
                        (0, 0, math.nan), (2, 1, math.inf)):  # fmt: skip
        B = T.copy()
        B[i, j] = value
        broken.append(B)
    scaled = T.copy()
    scaled[:3, :3] *= 1.0 + 2e-5
    skewed = T.copy()
    skewed[:3, 0] += 1e-3 * skewed[:3, 1]
    broken += [scaled, skewed]
    for B in broken:
        assert not is_valid_transform(B), B
    nearly = T.copy()
    nearly[:3, :3] *= 1.0 + 5e-6  # within libfranka's 1e-5
    assert is_valid_transform(nearly)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-8, 3.0])
def test_pose_error_of_tiny_and_large_turns(angle: float) -> None:
    T_a = np.eye(4)
    T_b = np.eye(4)
    T_b[:3, :3] = _rot(np.array([0.0, 0.0, angle]))
    e = pose_error(T_a, T_b)
    assert np.all(np.isfinite(e))
    np.testing.assert_allclose(e[5], angle, atol=1e-6)
