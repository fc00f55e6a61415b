"""fk / ik / Jacobians: against an independent DH product, finite differences, MuJoCo, and
themselves (round trips, batched against looped)."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import panda_py
from panda_py import kinematics as kin_mod
from panda_py.jit import LOADED
from panda_py.kinematics import IKStatus, Kinematics, _backend
from panda_py.robots.params import DH_FRANKA, FER, FR3, FRANKA_HAND, START_POSE

FER_LO, FER_HI = np.array(FER.joints.q_min), np.array(FER.joints.q_max)
FR3_LO, FR3_HI = np.array(FR3.joints.q_min), np.array(FR3.joints.q_max)


# --- backends: every test runs on the pure-NumPy paths and on the numba kernels ----------


def _numba_backend():
    """The numba backend module, or a pytest.skip reason."""
    if os.environ.get("PANDA_PY_NO_JIT", "") not in ("", "0"):
        return None, "PANDA_PY_NO_JIT is set"
    try:
        import numba  # noqa: F401
    except ImportError:
        return None, "numba is not installed (no wheels for this platform)"
    from panda_py.kinematics import _numba

    return _numba, ""


@pytest.fixture(params=["pure", "numba"], autouse=True)
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    if request.param == "pure":
        monkeypatch.setitem(LOADED, _backend.NAME, None)
    else:
        mod, reason = _numba_backend()
        if mod is None:
            pytest.skip(reason)
        monkeypatch.setitem(LOADED, _backend.NAME, mod)
    return request.param


# --- an independent reference: the DH product with NumPy 4x4 matrices ---------------------


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def ref_frames(q: np.ndarray, F_T_EE: np.ndarray | None = None) -> list[np.ndarray]:
    """O_T_J1..O_T_J7, O_T_F, O_T_EE by multiplying the modified-DH transforms."""
    dh = DH_FRANKA
    T = np.eye(4)
    out = []
    for i in range(7):
        T = T @ _rx(dh.alpha[i]) @ _trans(dh.a[i], 0, 0) @ _rz(q[i]) @ _trans(0, 0, dh.d[i])
        out.append(T)
    T = T @ _trans(0, 0, dh.flange_d)
    out.append(T)
    if F_T_EE is None:
        F_T_EE = _trans(0, 0, FRANKA_HAND.tcp_offset) @ _rz(FRANKA_HAND.tcp_rotz)
    out.append(T @ F_T_EE)
    return out


def random_q(rng: np.random.Generator, n: int, lo=FER_LO, hi=FER_HI) -> np.ndarray:
    return rng.uniform(lo, hi, size=(n, 7))


def random_F_T_EE(rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(3, 3))
    Q, R = np.linalg.qr(A)
    Q = Q * np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    T = np.eye(4)
    T[:3, :3] = Q
    T[:3, 3] = rng.uniform(-0.1, 0.2, 3)
    return T


# --- fk ---------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_fk_matches_dh_product(robot: str) -> None:
    rng = np.random.default_rng(1)
    lo, hi = (FER_LO, FER_HI) if robot == "fer" else (FR3_LO, FR3_HI)
    for q in random_q(rng, 200, lo, hi):
        np.testing.assert_allclose(
            kin_mod.fk(q, robot=robot), ref_frames(q)[-1], rtol=0, atol=1e-14
        )


def test_fk_start_pose_is_the_hand_tcp() -> None:
    T = panda_py.fk(np.array(START_POSE))
    # at the start pose the TCP points straight down, 0.1034 m below the flange
    np.testing.assert_allclose(T[:3, 2], [0, 0, -1], atol=1e-12)
    flange = kin_mod.fk_frames(np.array(START_POSE))[7]
    np.testing.assert_allclose(flange[:3, 3] - T[:3, 3], [0, 0, FRANKA_HAND.tcp_offset], atol=1e-12)
    assert T.shape == (4, 4) and T.dtype == np.float64 and T.flags.writeable


def test_fk_accepts_lists_and_column_vectors() -> None:
    q = np.array(START_POSE)
    np.testing.assert_array_equal(kin_mod.fk(list(START_POSE)), kin_mod.fk(q))
    np.testing.assert_array_equal(kin_mod.fk(q.reshape(7, 1)), kin_mod.fk(q))


def test_fk_with_any_flange_to_ee_transform() -> None:
    rng = np.random.default_rng(2)
    F_T_EE = random_F_T_EE(rng)
    kin = Kinematics("fer", F_T_EE=F_T_EE)
    for q in random_q(rng, 50):
        np.testing.assert_allclose(kin.fk(q), ref_frames(q, F_T_EE)[-1], atol=1e-14)
        np.testing.assert_allclose(
            kin_mod.fk(q, F_T_EE=F_T_EE), ref_frames(q, F_T_EE)[-1], atol=1e-14
        )
    # a pure z offset (folded into joint 7 by the code generator) as well
    Tz = _trans(0, 0, 0.2) @ _rz(0.3)
    q = random_q(rng, 1)[0]
    np.testing.assert_allclose(kin_mod.fk(q, F_T_EE=Tz), ref_frames(q, Tz)[-1], atol=1e-14)


def test_frames_of_every_joint_flange_and_ee() -> None:
    rng = np.random.default_rng(3)
    for q in random_q(rng, 50):
        np.testing.assert_allclose(kin_mod.fk_frames(q), np.array(ref_frames(q)), atol=1e-14)


# --- Jacobians --------------------------------------------------------------------------


def _fd_jacobian(q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences: linear from the position, angular from R(q+h) R(q-h)^T."""
    J = np.zeros((6, 7))
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = h
        Tp, Tm = ref_frames(q + dq)[-1], ref_frames(q - dq)[-1]
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        W = Tp[:3, :3] @ Tm[:3, :3].T  # ~ I + [w]x 2h
        J[3:, i] = np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / (4 * h)
    return J


def test_jacobians_match_finite_differences() -> None:
    rng = np.random.default_rng(4)
    for q in random_q(rng, 30):
        J0 = kin_mod.zero_jacobian(q)
        np.testing.assert_allclose(J0, _fd_jacobian(q), atol=1e-8)
        R = ref_frames(q)[-1][:3, :3]
        Jb = kin_mod.body_jacobian(q)
        np.testing.assert_allclose(Jb[:3], R.T @ J0[:3], atol=1e-14)
        np.testing.assert_allclose(Jb[3:], R.T @ J0[3:], atol=1e-14)


# --- ik ---------------------------------------------------------------------------------


def test_ik_start_pose_round_trip() -> None:
    q = np.array(START_POSE)
    np.testing.assert_allclose(panda_py.ik(panda_py.fk(q)), q, atol=1e-12)
    full = panda_py.ik_full(panda_py.fk(q))
    assert full.shape == (4, 7)
    np.testing.assert_allclose(full[3], q, atol=1e-12)  # panda-py's row for this case


def test_fk_of_ik_reproduces_the_pose() -> None:
    rng = np.random.default_rng(5)
    n_finite = 0
    for q in random_q(rng, 400):
        T = kin_mod.fk(q)
        q7 = rng.uniform(FER_LO[6], FER_HI[6])
        for sol in [kin_mod.ik(T, q, q7), *kin_mod.ik_full(T, q_init=q, q_7=q7)]:
            if np.all(np.isfinite(sol)):
                n_finite += 1
                np.testing.assert_allclose(kin_mod.fk(sol), T, rtol=0, atol=1e-9)
                assert np.all(sol >= FER_LO) and np.all(sol <= FER_HI)
                assert sol[6] == q7
            else:
                assert np.all(np.isnan(sol))
    assert n_finite > 400  # not vacuous


def test_ik_recovers_the_generating_configuration() -> None:
    rng = np.random.default_rng(6)
    Q = random_q(rng, 2000)
    hits = sum(
        bool(np.all(np.abs(kin_mod.ik(kin_mod.fk(q), q_init=q, q_7=q[6]) - q) < 1e-9)) for q in Q
    )
    # the solver's four branches cover the elbow below the flip angle (~87 % of the range)
    assert hits / len(Q) > 0.85


def test_ik_position_orientation_overload() -> None:
    rng = np.random.default_rng(7)
    q = random_q(rng, 1)[0]
    T = kin_mod.fk(q)
    R = T[:3, :3]
    w = math.sqrt(1 + np.trace(R)) / 2
    quat = np.array([(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
                     (R[1, 0] - R[0, 1]) / (4 * w), w])  # fmt: skip
    a = kin_mod.ik(T, q, q[6])
    b = kin_mod.ik(T[:3, 3], quat, q, q[6])
    c = kin_mod.ik(position=T[:3, 3], orientation=quat, q_init=q, q_7=q[6])
    np.testing.assert_allclose(b, a, atol=1e-12)
    np.testing.assert_allclose(c, a, atol=1e-12)
    np.testing.assert_allclose(
        kin_mod.ik_full(T[:3, 3], quat, q, q[6]), kin_mod.ik_full(T, q, q[6]), atol=1e-12
    )


def test_ik_reasons() -> None:
    far = np.eye(4)
    far[:3, 3] = (2.0, 0.0, 0.3)
    r = kin_mod.ik_result(far)
    assert r.status is IKStatus.UNREACHABLE and not r.ok and np.all(np.isnan(r.q))
    assert np.all(np.isnan(kin_mod.ik(far)))  # ik keeps panda-py's NaN answer
    T = kin_mod.fk(np.array(START_POSE))
    r = kin_mod.ik_result(T, q_7=3.0)  # beyond joint 7's limit
    assert r.status is IKStatus.JOINT_LIMIT and r.statuses == (IKStatus.JOINT_LIMIT,) * 4
    r = kin_mod.ik_result(T)
    assert r.ok and r.statuses[3] is IKStatus.OK and r.statuses[0] is IKStatus.JOINT_LIMIT
    # The wrist degenerate pose: the shoulder on the joint-6 axis leaves q6 undefined.
    P = kin_mod._DEFAULT._ik_params
    q7 = 0.3
    R6 = np.eye(3)  # frame 6 axes; J7 = J6 RotX(pi/2) TransX(a7) RotZ(q7)
    R_EE = R6 @ _rx(math.pi / 2)[:3, :3] @ _rz(q7 + P.theta_e)[:3, :3]
    p6 = np.array([0.0, 0.0, P.d1 + 0.5])  # straight above the shoulder, on z6
    T = np.eye(4)
    T[:3, :3] = R_EE
    T[:3, 3] = p6 + P.a7 * R6[:, 0] + P.d_e * R_EE[:, 2]
    assert kin_mod.ik_result(T, q_7=q7).status is IKStatus.SINGULAR


def test_q7_search_finds_the_nearest_feasible_q7() -> None:
    q = np.array([0.3, 0.2, -0.4, -1.9, 0.5, 1.8, 2.85])
    T = kin_mod.fk(q)
    assert np.all(np.isnan(kin_mod.ik(T, q, 2.95)))  # beyond the limit 2.8973
    r = kin_mod.ik_result(T, q, 2.95, q7_search=0.2)
    assert r.ok
    assert r.q_7 == pytest.approx(2.95 - 0.06)  # nearest step inside the limit
    np.testing.assert_allclose(kin_mod.fk(r.q), T, atol=1e-9)
    np.testing.assert_allclose(kin_mod.ik(T, q, 2.95, q7_search=0.2), r.q)
    # the search never widens past its radius
    assert np.all(np.isnan(kin_mod.ik(T, q, 2.95, q7_search=0.03)))


def test_robot_selects_the_joint_limits() -> None:
    q = np.array([0.0, 0.3, 0.0, -1.5, 0.0, 4.0, 0.5])  # q6 inside FR3's, beyond FER's limit
    T = kin_mod.fk(q, robot="fr3")
    np.testing.assert_allclose(kin_mod.ik(T, q, q[6], robot="fr3"), q, atol=1e-9)
    np.testing.assert_allclose(Kinematics("fr3").ik(T, q, q[6]), q, atol=1e-9)
    assert np.all(np.isnan(kin_mod.ik(T, q, q[6])))  # default: FER limits
    assert kin_mod.ik_result(T, q, q[6]).status is IKStatus.JOINT_LIMIT


# --- batches ----------------------------------------------------------------------------


def test_batched_equals_looped() -> None:
    rng = np.random.default_rng(8)
    Q = random_q(rng, 300)
    T = kin_mod.fk(Q)
    assert T.shape == (300, 4, 4)
    np.testing.assert_allclose(T, np.array([kin_mod.fk(q) for q in Q]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        kin_mod.fk_frames(Q), np.array([kin_mod.fk_frames(q) for q in Q]), rtol=0, atol=1e-15
    )
    for f in (kin_mod.zero_jacobian, kin_mod.body_jacobian):
        np.testing.assert_allclose(f(Q), np.array([f(q) for q in Q]), rtol=0, atol=1e-14)
    q7 = rng.uniform(-2.5, 2.5, 300)
    S = kin_mod.ik(T, Q, q7)
    L = np.array([kin_mod.ik(T[i], Q[i], q7[i]) for i in range(300)])
    np.testing.assert_array_equal(np.isnan(S), np.isnan(L))
    np.testing.assert_allclose(S, L, rtol=0, atol=1e-12)
    F = kin_mod.ik_full(T, Q, q7)
    FL = np.array([kin_mod.ik_full(T[i], Q[i], q7[i]) for i in range(300)])
    np.testing.assert_array_equal(np.isnan(F), np.isnan(FL))
    np.testing.assert_allclose(F, FL, rtol=0, atol=1e-12)
    r = kin_mod.ik_result(T, Q, q7)
    assert r.status.shape == (300,) and r.statuses.shape == (300, 4)
    np.testing.assert_array_equal(r.q, S)
    # a batch with the q7 search: a superset of solutions, each reproducing its pose
    W = kin_mod.ik(T, Q, q7, q7_search=0.3)
    found = np.isfinite(W).all(axis=1)
    assert found.sum() > np.isfinite(S).all(axis=1).sum()
    np.testing.assert_allclose(kin_mod.fk(W[found]), T[found], atol=1e-9)
    assert np.all(np.abs(W[found, 6] - q7[found]) <= 0.3 + 1e-9)
    assert np.isfinite(S).all(axis=1).sum() > 50  # not vacuous


# --- MuJoCo -----------------------------------------------------------------------------


def test_agrees_with_the_simulators_mujoco_model() -> None:
    mujoco = pytest.importorskip("mujoco")
    from panda_py.robots.mjcf import build_model

    rng = np.random.default_rng(9)
    for robot, lo, hi in (("fer", FER_LO, FER_HI), ("fr3", FR3_LO, FR3_HI)):
        model = build_model(robot)
        data = mujoco.MjData(model)
        adr = [model.jnt_qposadr[model.joint(f"joint{i}").id] for i in range(1, 8)]
        for q in random_q(rng, 20, lo, hi):
            data.qpos[adr] = q
            mujoco.mj_kinematics(model, data)
            frames = kin_mod.fk_frames(q, robot=robot)
            for i in range(7):
                body = data.body(f"link{i + 1}")
                np.testing.assert_allclose(frames[i][:3, 3], body.xpos, atol=1e-12)
                np.testing.assert_allclose(frames[i][:3, :3], body.xmat.reshape(3, 3), atol=1e-12)
            for site, T in (("flange", frames[7]), ("tcp", kin_mod.fk(q, robot=robot))):
                s = data.site(site)
                np.testing.assert_allclose(T[:3, 3], s.xpos, atol=1e-12)
                np.testing.assert_allclose(T[:3, :3], s.xmat.reshape(3, 3), atol=1e-12)


# --- bad input --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: kin_mod.fk(np.zeros(6)), "q: expected 7 joint positions"),
        (lambda: kin_mod.fk(np.zeros((3, 6))), "q: expected 7"),
        (lambda: kin_mod.fk(np.zeros((2, 2, 7))), "q: expected 7"),
        (lambda: kin_mod.fk([0, 0, 0, math.nan, 0, 0, 0]), "q: expected finite"),
        (lambda: kin_mod.fk(np.array([0, 0, 0, math.inf, 0, 0, 0])), "q: expected finite"),
        (lambda: kin_mod.fk("abcdefg"), "q: expected an array of real numbers"),
        (lambda: kin_mod.fk(np.zeros(7), robot="ur5"), "robot: expected one of"),
        (lambda: kin_mod.ik(np.eye(4), robot="ur5"), "robot: expected one of"),
        (lambda: kin_mod.ik(np.eye(3)), "O_T_EE: expected a 4x4"),
        (lambda: kin_mod.ik(np.eye(4) * 2), "O_T_EE: expected a rigid transform"),
        (lambda: kin_mod.ik(np.diag([1.0, 1.0, -1.0, 1.0])), "O_T_EE: expected a rigid transform"),
        (lambda: kin_mod.ik(np.full((4, 4), math.nan)), "O_T_EE: expected finite"),
        (lambda: kin_mod.ik(np.eye(4), np.zeros(6)), "q_init: expected 7"),
        (lambda: kin_mod.ik(np.eye(4), np.zeros(7), math.nan), "q_7: expected finite"),
        (lambda: kin_mod.ik(np.eye(4), np.zeros(7), [1.0, 2.0]), "q_7: expected a number"),
        (lambda: kin_mod.ik(np.zeros(3), np.array([0, 0, 0, 2.0])), "orientation: expected a unit"),
        (lambda: kin_mod.ik(np.zeros(3), np.zeros(3)), "orientation: expected a quaternion"),
        (lambda: kin_mod.ik(np.eye(4), q7_search=-1.0), "q7_search: expected a finite number"),
        (
            lambda: kin_mod.ik(np.eye(4), np.zeros(7), q_init=np.zeros(7)),
            "values for argument 'q_init'",
        ),
        (lambda: kin_mod.ik_full(np.eye(4), None, 0.5, q_7=0.5), "values for argument 'q_7'"),
        (
            lambda: kin_mod.ik_full(np.eye(4)[None].repeat(3, 0), np.zeros((2, 7))),
            "q_init: expected",
        ),
        (lambda: Kinematics("fer", F_T_EE=np.ones((4, 4))), "F_T_EE: expected a rigid"),
        (lambda: kin_mod.zero_jacobian(np.zeros(8)), "q: expected 7"),
    ],
)
def test_bad_input_is_a_clear_value_error(call, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("n", [5, 3000])  # 3000: the parallel kernels (numba: prange)
@pytest.mark.parametrize("fn", ["ik", "ik_full"])
def test_a_bad_pose_in_a_batch_is_named_by_its_index(
    n: int, fn: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_backend, "PARALLEL_MIN_ROWS", 2048)
    rng = np.random.default_rng(13)
    Q = random_q(rng, n)
    T = kin_mod.fk(Q)
    q7 = Q[:, 6].copy()
    call = getattr(kin_mod, fn)
    k = n - 2
    bad = T.copy()
    bad[k, :3, :3] *= 1.001  # not orthonormal
    with pytest.raises(ValueError, match=rf"O_T_EE: expected a rigid transform.*batch index {k}\b"):
        call(bad, Q, q7)
    bad = T.copy()
    bad[k, 3, 0] = 1e-3  # last row not 0 0 0 1
    with pytest.raises(ValueError, match=rf"O_T_EE: expected a rigid.*batch index {k}\b"):
        call(bad, Q, q7)
    bad = T.copy()
    bad[k, 1, 3] = math.inf
    with pytest.raises(ValueError, match=rf"O_T_EE: expected finite values.*batch index {k}\b"):
        call(bad, Q, q7)
    Qb = Q.copy()
    Qb[k, 3] = math.nan
    with pytest.raises(ValueError, match=rf"q_init: expected finite values.*batch index {k}\b"):
        call(T, Qb, q7)
    q7b = q7.copy()
    q7b[k] = math.nan
    with pytest.raises(ValueError, match=rf"q_7: expected finite values.*batch index {k}\b"):
        call(T, Q, q7b)
    # the first bad one is named, and a single bad pose says no index
    bad = T.copy()
    bad[[1, k], 0, 0] = 2.0
    with pytest.raises(ValueError, match=r"batch index 1\b"):
        call(bad, Q, q7)
    with pytest.raises(ValueError, match=r"rigid transform \(orthonormal[^(]*\); largest"):
        call(bad[1], Q[1], float(q7[1]))
    # within the tolerance (1e-6) a pose is accepted, on both backends alike
    ok = T.copy()
    ok[k, :3, :3] *= 1.0 + 2e-7
    assert np.all(np.isfinite(call(ok, Q, q7)[k]) == np.isfinite(call(T, Q, q7)[k]))


def test_public_names_exist() -> None:
    for name in kin_mod.__all__:
        assert hasattr(kin_mod, name), name
    for name in ("fk", "ik", "ik_full"):
        assert getattr(panda_py, name) is getattr(kin_mod, name)


# --- the numba backend against the pure one ------------------------------------------------


def _both(monkeypatch: pytest.MonkeyPatch, fn):
    """fn() on the pure paths, then on the numba kernels."""
    mod, reason = _numba_backend()
    if mod is None:
        pytest.skip(reason)
    monkeypatch.setitem(LOADED, _backend.NAME, None)
    pure = fn()
    monkeypatch.setitem(LOADED, _backend.NAME, mod)
    return pure, fn()


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_numba_equals_pure(robot: str, backend: str, monkeypatch: pytest.MonkeyPatch) -> None:
    if backend == "pure":
        pytest.skip("compares both backends itself")
    rng = np.random.default_rng(11)
    lo, hi = (FER_LO, FER_HI) if robot == "fer" else (FR3_LO, FR3_HI)
    Q = random_q(rng, 400, lo, hi)
    kins = [Kinematics(robot), Kinematics(robot, F_T_EE=random_F_T_EE(rng))]
    for kin in kins:
        for f in (kin.fk, kin.fk_frames, kin.zero_jacobian, kin.body_jacobian):
            pure, fast = _both(monkeypatch, lambda f=f: (f(Q), f(Q[0]), f(Q[1].tolist())))
            for a, b in zip(pure, fast, strict=True):
                np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
        T = kin.fk(Q)
        # q7 partly out of range, poses partly unreachable: NaN rows of every kind
        q7 = rng.uniform(-3.2, 3.2, Q.shape[0])
        T[::7, :3, 3] *= 3.0
        Qi = random_q(rng, Q.shape[0], lo, hi)
        pure, fast = _both(
            monkeypatch,
            lambda kin=kin, T=T, q7=q7, Qi=Qi: (
                kin.ik(T, Qi, q7),
                kin.ik_full(T, Qi, q7),
                kin.ik_result(T, Qi, q7).statuses,
                kin.ik(T, Qi[0], q7),
                [kin.ik(T[i], Qi[i], float(q7[i])) for i in range(40)],
                [kin.ik_full(T[i], Qi[i], float(q7[i])) for i in range(40)],
                [kin.ik(T[i]) for i in range(40)],
            ),
        )
        for a, b in zip(pure, fast, strict=True):
            a, b = np.asarray(a), np.asarray(b)
            np.testing.assert_array_equal(np.isnan(b), np.isnan(a))
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
        statuses = pure[2]
        for s in IKStatus:  # not vacuous: every outcome occurs
            if s is not IKStatus.SINGULAR:
                assert np.any(statuses == s), s


def test_numba_atan2_and_sincos_are_within_3_ulp_of_libm(backend: str) -> None:
    if backend == "pure":
        pytest.skip("numba only")
    import numba

    from panda_py.kinematics import _scalar

    @numba.njit
    def run(y, x, out):  # atan2(y, x), sin(x), cos(x): _nbmath's, as the kernels run them
        for i in range(y.shape[0]):
            out[i, 0] = _scalar.atan2(y[i], x[i])
            out[i, 1], out[i, 2] = _scalar.sincos(x[i])

    rng = np.random.default_rng(14)
    n = 200_000
    for scale in (1e-200, 1e-8, 1.0, 1e3, 1e200):
        y = rng.normal(size=n) * scale * np.exp(rng.uniform(-4, 4, n))
        x = rng.normal(size=n) * scale * np.exp(rng.uniform(-4, 4, n))
        out = np.empty((n, 3))
        run(y, x, out)
        ref = np.array([math.atan2(a, b) for a, b in zip(y, x, strict=True)])
        assert np.all(np.abs(out[:, 0] - ref) <= 3 * np.spacing(np.abs(ref)))
    x = np.concatenate([rng.uniform(-7, 7, n), rng.uniform(-9e4, 9e4, 1000)])
    out = np.empty((x.size, 3))
    run(x, x, out)
    for col, f in ((1, math.sin), (2, math.cos)):
        ref = np.array([f(v) for v in x])
        assert np.all(np.abs(out[:, col] - ref) <= 3 * np.spacing(np.abs(ref)))
    # special values go to the C library: the same results, signs of zero included
    special = [0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan, 5e-324, -1e308, 1e5]
    ys, xs = np.array(special).repeat(len(special)), np.tile(special, len(special))
    out = np.empty((ys.size, 3))
    run(ys, xs, out)
    for (a, b), got in zip(zip(ys, xs, strict=True), out, strict=True):
        for value, ref in zip(got, (math.atan2(a, b), *_libm_sincos(b)), strict=True):
            same = value == ref and math.copysign(1, value) == math.copysign(1, ref)
            assert (
                same
                or (math.isnan(value) and math.isnan(ref))
                or abs(value - ref) <= 3 * np.spacing(abs(ref))
            ), (a, b)


def _libm_sincos(x: float) -> tuple[float, float]:
    try:
        return math.sin(x), math.cos(x)
    except ValueError:  # math raises for infinity where the C library returns NaN
        return math.nan, math.nan


def test_parallel_kernels_equal_the_serial_ones(
    backend: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    if backend == "pure":
        pytest.skip("numba only")
    rng = np.random.default_rng(15)
    Q = random_q(rng, 2500)
    T = kin_mod.fk(Q)
    q7 = rng.uniform(-3.0, 3.0, Q.shape[0])
    T[::9, :3, 3] *= 2.0  # some unreachable

    def all_of_them():
        return (kin_mod.fk(Q), kin_mod.ik(T, Q, q7), kin_mod.ik_full(T, Q, q7), kin_mod.ik(T))

    monkeypatch.setattr(_backend, "PARALLEL_MIN_ROWS", 10**9)
    serial = all_of_them()
    monkeypatch.setattr(_backend, "PARALLEL_MIN_ROWS", 1)
    calls = []
    original = _backend._run

    def spy(serial_kernel, parallel_kernel, n, *args):
        calls.append(parallel_kernel.__name__)
        original(serial_kernel, parallel_kernel, n, *args)

    monkeypatch.setattr(_backend, "_run", spy)
    parallel = all_of_them()
    assert calls == ["fk_batch_par", "ik_batch_par", "ik_batch_par", "ik_batch_par"]
    for a, b in zip(serial, parallel, strict=True):
        np.testing.assert_array_equal(a, b)  # bit for bit, NaN where NaN
    # not in a forked child (GNU OpenMP is not fork-safe) and not while another thread
    # runs a parallel kernel: the serial kernel then
    monkeypatch.setattr(_backend, "_run", original)
    ran = []
    monkeypatch.setattr(_backend, "_PAR_PID", -1)
    _backend._run(lambda: ran.append("serial"), lambda: ran.append("parallel"), 10**6)
    monkeypatch.setattr(_backend, "_PAR_PID", os.getpid())
    with _backend._PAR_LOCK:
        _backend._run(lambda: ran.append("serial"), lambda: ran.append("parallel"), 10**6)
    _backend._run(lambda: ran.append("serial"), lambda: ran.append("parallel"), 10**6)
    assert ran == ["serial", "serial", "parallel"]


def _python(code: str, **env: str) -> str:
    full_env = {**os.environ, **env}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=full_env, timeout=120
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


@pytest.mark.timeout(240)
def test_jit_is_lazy_optional_and_survives_an_unwritable_cache(backend: str) -> None:
    if backend == "pure":
        pytest.skip("runs once")
    if _numba_backend()[0] is None:
        pytest.skip(_numba_backend()[1])
    probe = (
        "import sys, numpy as np, panda_py, panda_py.kinematics as k\n"
        "from panda_py.kinematics import _backend\n"
        "print('numba' in sys.modules, end=' ')\n"
        "k.fk(np.zeros(7)); print(_backend.jit() is not None)"
    )
    assert _python(probe) == "False True"  # not imported with panda_py; used on first call
    assert _python(probe, PANDA_PY_NO_JIT="1") == "False False"
    # no writable place for the cache (a path below a file): the kernels compile in memory
    no_cache = (
        "import numpy as np\n"
        "from panda_py.kinematics import _numba, _fk, Kinematics\n"
        "K = Kinematics(); out = np.empty((4, 4))\n"
        "ok = _numba.fk_one(np.zeros(7), K._CF, out)\n"
        "print(ok, np.allclose(out[:3].ravel(), _fk.ee_pose(K._chain, [0.0] * 7)), "
        "_numba.fk_one._cache.__class__.__name__)"
    )
    assert _python(no_cache, PANDA_PY_CACHE=__file__) == "True True NullCache"


def test_without_numba_the_plain_backend_runs(backend: str) -> None:
    if backend == "pure":
        pytest.skip("runs once")
    probe = (
        "import sys; sys.modules['numba'] = None  # as if not installed\n"
        "import numpy as np, panda_py.kinematics as k\n"
        "from panda_py.kinematics import _backend\n"
        "q = np.array([0.1, -0.3, 0.2, -2.0, 0.1, 1.6, 0.7])\n"
        "print(_backend.jit(), k.warmup(), np.allclose(k.ik(k.fk(q), q, q[6]), q))"
    )
    assert _python(probe) == "None False True"


@pytest.mark.timeout(400)
def test_the_jit_cache_is_invalidated_by_any_edit_to_what_it_compiles(
    backend: str, tmp_path
) -> None:
    """A scratch copy of the package: an edit to _ik.py's ``rigid_error`` (not the file
    that defines the kernel, which is all numba's own cache would look at) changes the
    result of the next process, which must not load the kernel compiled before the edit.
    (The rigid-transform check's kernel: the smallest that compiles code of _ik.py, a
    third of the solver's compile time.)"""
    if backend == "pure":
        pytest.skip("runs once")
    if _numba_backend()[0] is None:
        pytest.skip(_numba_backend()[1])
    import shutil

    src = tmp_path / "src"
    shutil.copytree(
        os.path.dirname(os.path.dirname(panda_py.__file__)),
        src,
        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"),
    )
    env = {"PYTHONPATH": str(src), "PANDA_PY_CACHE": str(tmp_path / "cache")}
    probe = (
        "import numpy as np\n"
        "from panda_py.kinematics import _backend, _numba\n"
        "T = np.eye(4); T[:3, :3] *= 1.01; T[:3, 3] = (0.5, 0.0, 0.4)\n"  # 1 % off rigid
        "print(round(float(_backend.rigid_errors(T[None])[0]), 4), end=' ')\n"
        "print(_numba.rigid_batch.stats.cache_hits.most_common(1)[0][1] "
        "if _numba.rigid_batch.stats.cache_hits else 0)"
    )
    assert _python(probe, **env) == "0.0201 0"  # compiled and cached
    assert _python(probe, **env) == "0.0201 1"  # loaded from the cache
    ik_py = src / "panda_py" / "kinematics" / "_ik.py"
    text = ik_py.read_text()
    assert "    return e + (s - s)" in text
    ik_py.write_text(text.replace("    return e + (s - s)", "    return 2.0 * e + (s - s)"))
    assert _python(probe, **env) == "0.0402 0"  # the edit took effect: compiled afresh
    assert len(list((tmp_path / "cache" / "numba").iterdir())) == 2


def test_warmup_compiles_every_kernel_and_is_cheap_once_done(backend: str) -> None:
    import time

    if backend == "pure":
        assert kin_mod.warmup() is False
        return
    assert kin_mod.warmup() is True
    t0 = time.perf_counter()
    assert kin_mod.warmup() is True
    assert time.perf_counter() - t0 < 0.01
    jit = _backend.jit()
    for name in ("fk_one", "fk_batch", "fk_batch_par", "ik_batch", "ik_batch_par", "ik_one"):
        assert getattr(jit, name).signatures, name


def test_packed_parameters_unpack_to_the_same_names() -> None:
    from panda_py.kinematics import _fk, _ik

    for kin in (
        Kinematics("fer"),
        Kinematics("fr3", F_T_EE=random_F_T_EE(np.random.default_rng(3))),
    ):
        assert _ik.unpack_ik_params(kin._P) == kin._ik_params
        assert _fk.unpack_chain(kin._CF) == kin._chain


@pytest.mark.parametrize(
    "call",
    [
        lambda: kin_mod.fk(np.array(START_POSE) + 1j),
        lambda: kin_mod.fk([0j] * 7),
        lambda: kin_mod.ik(kin_mod.fk(np.array(START_POSE)) + 0j),
        lambda: kin_mod.ik(kin_mod.fk(np.array(START_POSE)), np.array(START_POSE), 0.5 + 1j),
        lambda: kin_mod.ik_full(kin_mod.fk(np.array(START_POSE)), np.array(START_POSE) + 0j),
        lambda: kin_mod.zero_jacobian(np.zeros(7, dtype=complex)),
    ],
)
def test_complex_input_is_a_value_error(call) -> None:
    with pytest.raises(ValueError, match="expected real numbers, got complex"):
        call()


def test_strided_and_integer_inputs_give_the_same_results() -> None:
    rng = np.random.default_rng(12)
    q = random_q(rng, 1)[0]
    strided = np.empty(14)
    strided[::2] = q
    q_s = strided[::2]
    T = kin_mod.fk(q)
    T_s = np.asfortranarray(T)
    for f in (kin_mod.fk, kin_mod.zero_jacobian, kin_mod.body_jacobian, kin_mod.fk_frames):
        np.testing.assert_allclose(f(q_s), f(q), rtol=0, atol=1e-15)
    np.testing.assert_allclose(kin_mod.ik(T_s, q_s, q[6]), kin_mod.ik(T, q, q[6]), atol=1e-15)
    np.testing.assert_allclose(kin_mod.ik_full(T_s, q_s), kin_mod.ik_full(T, q), atol=1e-15)
    np.testing.assert_allclose(kin_mod.fk(np.zeros(7, dtype=int)), kin_mod.fk(np.zeros(7)))
    # other dtypes and Python sequences: the general path, the same answer
    T32 = T.astype(np.float32).astype(np.float64)
    for f in (kin_mod.ik, kin_mod.ik_full):
        ref = f(T32, q, 1.0)
        np.testing.assert_array_equal(f(T32.astype(np.float32), q.tolist(), 1), ref)
        np.testing.assert_array_equal(f(T32.tolist(), list(q), np.float64(1.0)), ref)
