"""``Kinematics.follow``: configurations that follow a path of poses as the arm moves
along it (damped least-squares steps from the configuration before), on both backends."""

from __future__ import annotations

import os

import numpy as np
import pytest

from panda_py.jit import LOADED
from panda_py.kinematics import Kinematics, _backend
from panda_py.robots.params import START_POSE

START = np.array(START_POSE)


@pytest.fixture(params=["pure", "numba"], autouse=True)
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    if request.param == "pure":
        monkeypatch.setitem(LOADED, _backend.NAME, None)
    else:
        if os.environ.get("PANDA_PY_NO_JIT", "") not in ("", "0"):
            pytest.skip("PANDA_PY_NO_JIT is set")
        pytest.importorskip("numba")
        from panda_py.kinematics import _numba

        monkeypatch.setitem(LOADED, _backend.NAME, _numba)
    return request.param


def straight_down(kin: Kinematics, n: int) -> np.ndarray:
    """n poses, the start pose's orientation, from the start pose's position straight to
    0.5 m in front of the robot and 17 cm up (the demo's approach to its cube)."""
    T = kin.fk(START)
    poses = np.tile(T, (n, 1, 1))
    poses[:, :3, 3] = np.linspace(T[:3, 3], (0.5, 0.0, 0.17), n)
    return poses


def test_the_configurations_reach_every_pose_of_a_path_through_q2_0() -> None:
    kin = Kinematics("fer")
    poses = straight_down(kin, 300)
    q = kin.follow(poses, START, damping=0.01)
    reached = kin.fk(q)
    assert np.abs(reached[:, :3, 3] - poses[:, :3, 3]).max() < 1e-5
    assert np.abs(reached[:, :3, :3] - poses[:, :3, :3]).max() < 1e-5
    assert np.abs(np.diff(q, axis=0)).max() < 0.02  # continuous: a joint step per pose
    assert q[0, 1] < 0.0 < q[-1, 1]  # q2 crossed 0 ...
    # ... where the start's case of the inverse kinematics ends
    assert np.isnan(kin.ik(poses[-1], START, START[6])).all()


def test_a_random_smooth_joint_path_is_followed_pose_for_pose() -> None:
    rng = np.random.default_rng(5)
    kin = Kinematics("fr3")
    t = np.linspace(0.0, 1.0, 500)[:, None]
    q_path = START + 0.4 * np.sin(2.0 * t * rng.uniform(0.5, 1.5, 7) + rng.uniform(0, 1, 7))
    poses = kin.fk(q_path)
    q = kin.follow(poses, q_path[0])
    np.testing.assert_allclose(kin.fk(q), poses, atol=1e-6)
    # the redundancy is the arm's own (J^+: q7 moves), not the path's
    assert np.abs(q[:, 6] - q_path[:, 6]).max() > 1e-3


def test_from_the_stretched_out_arm_without_damping_the_steps_stay_finite() -> None:
    kin = Kinematics("fer")
    q0 = np.zeros(7)  # singular: joints 1, 3, 5 and 7 aligned
    poses = np.tile(kin.fk(q0), (20, 1, 1))
    poses[:, 0, 3] -= np.linspace(0.0, 0.05, 20)  # 5 cm back toward the base
    q = kin.follow(poses, q0)
    assert np.isfinite(q).all()
    np.testing.assert_allclose(kin.fk(q)[:, :3, 3], poses[:, :3, 3], atol=1e-6)


def test_the_backends_agree(backend: str) -> None:
    if backend == "pure":
        pytest.skip("compares both backends itself")
    kin = Kinematics("fer")
    poses = straight_down(kin, 50)
    compiled = kin.follow(poses, START, damping=0.01, iterations=3)
    jit = LOADED[_backend.NAME]
    try:
        LOADED[_backend.NAME] = None
        plain = kin.follow(poses, START, damping=0.01, iterations=3)
    finally:
        LOADED[_backend.NAME] = jit
    np.testing.assert_allclose(compiled, plain, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"poses": np.eye(4)}, "expected a batch of poses"),
        ({"q_start": np.zeros((2, 7))}, "one configuration"),
        ({"q_start": np.full(7, np.nan)}, "q_start"),
        ({"damping": -1.0}, "damping"),
        ({"iterations": 0}, "iterations"),
        ({"iterations": 1.5}, "iterations"),
    ],
)
def test_bad_input_is_refused_by_name(kwargs: dict, message: str) -> None:
    kin = Kinematics("fer")
    args = {"poses": np.tile(kin.fk(START), (3, 1, 1)), "q_start": START, **kwargs}
    poses, q_start = args.pop("poses"), args.pop("q_start")
    with pytest.raises(ValueError, match=message):
        kin.follow(poses, q_start, **args)
