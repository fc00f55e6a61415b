"""ik with an unknown q7: ``q7_search`` over joint 7's range (``_ik.search_q7``), single and
batched, compiled and plain."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from panda_py import kinematics as kin_mod
from panda_py.jit import LOADED
from panda_py.kinematics import Q7_SEARCH_STEP, IKStatus, Kinematics, _backend
from panda_py.robots.params import FER, FR3, START_POSE

# fk(ik(T)) matches T within this [m, -] in every entry (as in test_kinematics.py)
FK_TOL = 1e-9
FER_LO, FER_HI = np.array(FER.joints.q_min), np.array(FER.joints.q_max)


def _numba():
    if os.environ.get("PANDA_PY_NO_JIT", "") not in ("", "0"):
        pytest.skip("PANDA_PY_NO_JIT is set")
    pytest.importorskip("numba")
    from panda_py.kinematics import _numba

    return _numba


@pytest.fixture
def jit(monkeypatch: pytest.MonkeyPatch):
    """The compiled backend (skips where numba is missing)."""
    mod = _numba()
    monkeypatch.setitem(LOADED, _backend.NAME, mod)
    return mod


def reachable_poses(n: int, seed: int, lo=FER_LO, hi=FER_HI, robot: str = "fer"):
    """fk of n configurations drawn uniformly within the joint limits: reachable poses."""
    Q = np.random.default_rng(seed).uniform(lo, hi, size=(n, 7))
    return Q, kin_mod.fk(Q, robot=robot)


def solved(Q: np.ndarray, T: np.ndarray, lo=FER_LO, hi=FER_HI, robot: str = "fer") -> np.ndarray:
    """Which rows of Q are real solutions of T: finite, within the joint limits, fk
    matching."""
    ok = np.isfinite(Q).all(axis=1)
    Qf = np.where(ok[:, None], Q, 0.0)
    ok &= ((Qf >= lo) & (Qf <= hi)).all(axis=1)
    ok &= np.abs(kin_mod.fk(Qf, robot=robot) - T).max(axis=(1, 2)) <= FK_TOL
    return ok


def test_the_whole_range_finds_at_least_450_of_500_reachable_poses(jit) -> None:
    _, T = reachable_poses(500, seed=0)
    S = kin_mod.ik(T, q7_search=math.inf)
    finite = np.isfinite(S).all(axis=1)
    ok = solved(S, T)
    assert ok.sum() >= 450  # 463 at this writing; q_7 alone (no search): 122
    np.testing.assert_array_equal(ok, finite)  # every answer given is a real solution
    assert np.isnan(S[~finite]).all()  # and the others are NaN rows, as panda-py's
    # in q_init's (START_POSE's) case: q2 < 0, cos(q5) >= 0
    assert (S[finite, 1] < 0).all() and (np.cos(S[finite, 4]) >= 0).all()


def test_batched_equals_single_bit_for_bit(jit) -> None:
    Q, T = reachable_poses(200, seed=1)
    T[::11, :3, 3] *= 3.0  # some unreachable
    rng = np.random.default_rng(2)
    Qi = rng.uniform(FER_LO, FER_HI, size=Q.shape)
    q7 = rng.uniform(-3.2, 3.2, Q.shape[0])
    for radius in (0.3, math.inf):
        S = kin_mod.ik(T, Qi, q7, q7_search=radius)
        L = np.array([kin_mod.ik(T[i], Qi[i], q7[i], q7_search=radius) for i in range(200)])
        np.testing.assert_array_equal(S, L)  # NaN where NaN
        F = kin_mod.ik_full(T, Qi, q7, q7_search=radius)
        FL = np.array([kin_mod.ik_full(T[i], Qi[i], q7[i], q7_search=radius) for i in range(200)])
        np.testing.assert_array_equal(F, FL)
        r = kin_mod.ik_result(T, Qi, q7, q7_search=radius)
        np.testing.assert_array_equal(r.q, S)
        np.testing.assert_array_equal(r.solutions, F)
        for i in range(0, 200, 17):
            ri = kin_mod.ik_result(T[i], Qi[i], q7[i], q7_search=radius)
            assert ri.q_7 == r.q_7[i] and ri.status == r.status[i]
        ok = solved(S, T)
        np.testing.assert_array_equal(ok, np.isfinite(S).all(axis=1))
        assert ok.sum() > 50  # not vacuous


def test_the_q7_found_is_the_nearest_candidate_with_a_solution(jit) -> None:
    # the reference: plain ik at each candidate q_7 +- k step, nearest first, + before -
    _, T = reachable_poses(40, seed=3)
    qi = np.array(START_POSE)
    radius = 1.5
    r = kin_mod.ik_result(T, q7_search=radius)
    for i in range(40):
        expected = math.nan
        for k in range(round(radius / Q7_SEARCH_STEP) + 1):
            d = k * Q7_SEARCH_STEP
            hits = [c for c in (math.pi / 4 + d, math.pi / 4 - d)[: 2 if k else 1]
                    if np.isfinite(kin_mod.ik(T[i], qi, c)).all()]  # fmt: skip
            if hits:
                expected = hits[0]
                break
        if math.isnan(expected):
            assert not r.ok[i] and r.q_7[i] == math.pi / 4 and np.isnan(r.q[i]).all()
        else:
            assert r.ok[i] and r.q_7[i] == expected
            np.testing.assert_array_equal(r.q[i], kin_mod.ik(T[i], qi, expected))
            np.testing.assert_array_equal(r.solutions[i], kin_mod.ik_full(T[i], qi, expected))
    assert 5 < r.ok.sum() < 40  # not vacuous: found near and far, and not everywhere


def test_the_search_stays_within_its_radius_and_joint_7s_limits(jit) -> None:
    Q, T = reachable_poses(300, seed=4)
    q7 = np.full(300, 2.5)
    for radius in (0.05, 0.8):
        r = kin_mod.ik_result(T, Q, q7, q7_search=radius)
        assert r.ok.any()
        assert np.all(np.abs(r.q_7 - q7) <= radius + 1e-9)
        assert np.all(r.q_7[r.ok] <= FER_HI[6])
        np.testing.assert_array_equal(r.q[r.ok, 6], r.q_7[r.ok])
    # math.inf and any radius covering joint 7's range give the same answers
    np.testing.assert_array_equal(
        kin_mod.ik(T, Q, q7, q7_search=math.inf), kin_mod.ik(T, Q, q7, q7_search=6.0)
    )


def test_the_parallel_kernel_gives_the_serial_answers(jit, monkeypatch: pytest.MonkeyPatch) -> None:
    Q, T = reachable_poses(300, seed=8)
    T[::13, :3, 3] *= 3.0
    monkeypatch.setattr(_backend, "PARALLEL_MIN_ROWS", 10**9)
    serial = kin_mod.ik(T, q7_search=math.inf), kin_mod.ik_full(T, Q, 0.0, q7_search=1.0)
    # a search counts as SEARCH_ROW_COST rows: 300 poses go parallel from a threshold below
    monkeypatch.setattr(_backend, "PARALLEL_MIN_ROWS", 300 * _backend.SEARCH_ROW_COST)
    calls = []
    original = _backend._run

    def spy(serial_kernel, parallel_kernel, n, *args):
        calls.append(n)
        original(serial_kernel, parallel_kernel, n, *args)

    monkeypatch.setattr(_backend, "_run", spy)
    parallel = kin_mod.ik(T, q7_search=math.inf), kin_mod.ik_full(T, Q, 0.0, q7_search=1.0)
    assert calls == [300 * _backend.SEARCH_ROW_COST] * 2
    for a, b in zip(serial, parallel, strict=True):
        np.testing.assert_array_equal(a, b)


def test_every_way_of_calling_takes_the_search(jit) -> None:
    q = np.array([0.3, 0.2, -0.4, -1.9, 0.5, 1.8, 2.85])
    T = kin_mod.fk(q)
    R = T[:3, :3]
    w = math.sqrt(1 + np.trace(R)) / 2
    quat = np.array([(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
                     (R[1, 0] - R[0, 1]) / (4 * w), w])  # fmt: skip
    a = kin_mod.ik(T, q, 2.95, q7_search=math.inf)
    assert np.isfinite(a).all() and a[6] == pytest.approx(2.89)
    for b in (
        kin_mod.ik(T, q_init=q, q_7=2.95, q7_search=math.inf),
        kin_mod.ik(O_T_EE=T, q_init=q, q_7=2.95, q7_search=math.inf),
        kin_mod.ik(T, q, 2.95, q7_search=10),  # an int radius: the general path
        kin_mod.ik(T.tolist(), q.tolist(), 2.95, q7_search=math.inf),
        Kinematics().ik(T, q, 2.95, q7_search=math.inf),
        kin_mod.ik_result(T, q, 2.95, q7_search=math.inf).q,
    ):
        np.testing.assert_array_equal(b, a)
    for b in (
        kin_mod.ik(T[:3, 3], quat, q, 2.95, q7_search=math.inf),
        kin_mod.ik(position=T[:3, 3], orientation=quat, q_init=q, q_7=2.95, q7_search=math.inf),
    ):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(
        kin_mod.ik_full(T, q, 2.95, q7_search=math.inf), kin_mod.ik_full(T, q, a[6])
    )


def test_unreachable_poses_are_nan_with_the_reason_at_q_7(jit) -> None:
    far = np.eye(4)
    far[:3, 3] = (2.0, 0.0, 0.3)
    assert np.isnan(kin_mod.ik(far, q7_search=math.inf)).all()
    assert np.isnan(kin_mod.ik_full(far, q7_search=math.inf)).all()
    r = kin_mod.ik_result(far, q7_search=math.inf)
    assert r.status is IKStatus.UNREACHABLE and r.q_7 == math.pi / 4 and not r.ok
    B = kin_mod.ik(np.stack([far, kin_mod.fk(np.array(START_POSE))]), q7_search=math.inf)
    assert np.isnan(B[0]).all() and np.isfinite(B[1]).all()


def test_other_arms_and_end_effectors(jit) -> None:
    lo, hi = np.array(FR3.joints.q_min), np.array(FR3.joints.q_max)
    _, T = reachable_poses(100, seed=5, lo=lo, hi=hi, robot="fr3")
    fr3 = Kinematics("fr3")
    S = fr3.ik(T, q7_search=math.inf)
    ok = solved(S, T, lo, hi, robot="fr3")
    assert ok.sum() > 60
    np.testing.assert_array_equal(ok, np.isfinite(S).all(axis=1))
    np.testing.assert_array_equal(S[:5], [fr3.ik(Ti, q7_search=math.inf) for Ti in T[:5]])
    np.testing.assert_array_equal(S, kin_mod.ik(T, q7_search=math.inf, robot="fr3"))
    # an end effector off the flange's axis: the general path, the same search
    F_T_EE = np.eye(4)
    F_T_EE[:3, 3] = (0.05, 0.0, 0.1)
    tool = Kinematics("fer", F_T_EE=F_T_EE)
    Q, _ = reachable_poses(50, seed=6)
    T = tool.fk(Q)
    S = tool.ik(T, q7_search=math.inf)
    ok = np.isfinite(S).all(axis=1)
    assert ok.sum() > 30
    np.testing.assert_allclose(tool.fk(S[ok]), T[ok], rtol=0, atol=FK_TOL)


@pytest.mark.parametrize(
    ("radius", "match"),
    [
        (-1.0, r"q7_search: expected a finite number in \[0, inf\) \[rad\] \(or math.inf"),
        (math.nan, r"q7_search: expected a finite number in \[0, inf\)"),
        (-math.inf, r"q7_search: expected a finite number in \[0, inf\)"),
        ("wide", r"q7_search: expected a number \[rad\] \(or math.inf.*got 'wide'"),
        (True, r"q7_search: expected a number \[rad\]"),
        (None, r"q7_search: expected a number \[rad\]"),
    ],
)
@pytest.mark.parametrize("fn", ["ik", "ik_full", "ik_result"])
def test_a_bad_radius_is_a_clear_value_error(radius, match: str, fn: str) -> None:
    T = kin_mod.fk(np.array(START_POSE))
    with pytest.raises(ValueError, match=match):
        getattr(kin_mod, fn)(T, q7_search=radius)
    with pytest.raises(ValueError, match=match):
        getattr(kin_mod, fn)(T[None].repeat(3, 0), q7_search=radius)


def test_bad_poses_are_named_with_the_search_too() -> None:
    T = kin_mod.fk(np.zeros((3, 7)))
    T[1, 0, 0] = math.nan
    with pytest.raises(ValueError, match=r"O_T_EE: expected finite.*batch index 1"):
        kin_mod.ik(T, q7_search=math.inf)
    with pytest.raises(ValueError, match="O_T_EE: expected a rigid transform"):
        kin_mod.ik(np.eye(4) * 2, q7_search=math.inf)
    with pytest.raises(ValueError, match="q_7: expected finite"):
        kin_mod.ik(np.eye(4), np.zeros(7), math.nan, q7_search=1.0)


def test_the_plain_backend_gives_the_same_answers(monkeypatch: pytest.MonkeyPatch) -> None:
    jit = _numba()
    Q, T = reachable_poses(12, seed=7)
    T[3, :3, 3] *= 3.0  # one unreachable: a whole walk

    def answers():
        return (
            kin_mod.ik(T, q7_search=math.inf),
            np.array([kin_mod.ik(Ti, q7_search=math.inf) for Ti in T]),
            kin_mod.ik_full(T[:4], Q[:4], 2.0, q7_search=0.5),
            kin_mod.ik_result(T, q7_search=math.inf).q_7,
        )

    monkeypatch.setitem(LOADED, _backend.NAME, None)
    plain = answers()
    monkeypatch.setitem(LOADED, _backend.NAME, jit)
    fast = answers()
    for a, b in zip(plain, fast, strict=True):
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    assert np.isfinite(plain[0]).all(axis=1).sum() >= 8  # not vacuous


def test_without_the_jit_in_a_fresh_process() -> None:
    q = np.array([0.3, 0.2, -0.4, -1.9, 0.5, 1.8, 2.85])
    code = (
        "import json, math, numpy as np, panda_py.kinematics as k\n"
        f"q = np.array({q.tolist()})\n"
        "print(json.dumps(k.ik(k.fk(q), q, 2.95, q7_search=math.inf).tolist()))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
        env={**os.environ, "PANDA_PY_NO_JIT": "1"},
    )
    got = np.array(json.loads(out.stdout))
    np.testing.assert_allclose(kin_mod.fk(got), kin_mod.fk(q), rtol=0, atol=FK_TOL)
    assert got[6] == pytest.approx(2.95 - 6 * Q7_SEARCH_STEP)


def test_warmup_compiles_the_search_kernels(jit) -> None:
    assert kin_mod.warmup() is True
    for name in ("ik_one", "ik_full_one", "ik_batch", "ik_batch_par"):
        assert getattr(jit, name).signatures, name
