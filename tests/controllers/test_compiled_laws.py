"""The compiled Cartesian impedance law equals panda-py's law written in NumPy (the
reference in ``controllers.laws``), and ``CartesianImpedance.step`` gives the same torques
with and without the compiled kernels, on states made here (no simulator)."""

from __future__ import annotations

import math
import os
import types

import numpy as np
import pytest

from panda_py import controllers, kinematics
from panda_py.controllers import laws
from panda_py.jit import LOADED
from panda_py.motion.online import OnlineLimits
from panda_py.robots.params import START_POSE, get_robot

KIN = kinematics.get_kinematics("fr3")
# (numba comes with the package: these compare its kernels, which PANDA_PY_NO_JIT turns off)
pytestmark = pytest.mark.skipif(
    os.environ.get("PANDA_PY_NO_JIT", "") not in ("", "0"), reason="PANDA_PY_NO_JIT is set"
)


def _reference(O_T_EE, J, q, dq, p_d, quat_d, K, Kd, q_n, k_n):  # type: ignore[no-untyped-def]
    err = laws.cartesian_error(O_T_EE, p_d, quat_d)
    tau = J.T @ (-(K @ err) - Kd @ (J @ dq))
    return tau + laws.nullspace_projector(J) @ (k_n * (q_n - q) - 2.0 * math.sqrt(k_n) * dq)


def test_the_kernel_equals_the_numpy_law() -> None:
    kernels = laws.compiled()
    assert kernels is not None  # numba comes with the package here
    rng = np.random.default_rng(3)
    for _ in range(200):
        q, dq = rng.uniform(-1.5, 1.5, 7), rng.normal(size=7)
        O_T_EE = KIN.fk(q).reshape(16, order="F").copy()
        J = KIN.zero_jacobian(q)
        p_d = O_T_EE[12:15] + rng.normal(size=3) * 0.02
        quat_d = laws.quat_from_matrix(O_T_EE) + rng.normal(size=4) * 0.1
        quat_d = quat_d / np.linalg.norm(quat_d) * rng.choice([-1.0, 1.0])  # either sign
        A = rng.normal(size=(6, 6))
        K = A @ A.T + np.diag([600.0, 600.0, 600.0, 30.0, 30.0, 30.0])
        Kd = 2.0 * np.sqrt(np.diag(np.diag(K)))
        q_n, k_n = rng.uniform(-1, 1, 7), float(rng.uniform(0.0, 20.0))
        out = np.empty(7)
        kernels.cartesian_impedance_torque(O_T_EE, J, q, dq, p_d, quat_d, K, Kd, q_n, k_n, out)
        ref = _reference(O_T_EE, J, q, dq, p_d, quat_d, K, Kd, q_n, k_n)
        np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("alpha", [0.0, 0.03, 0.5, 1.0])
def test_the_compiled_input_filter_equals_ema_and_slerp(alpha: float) -> None:
    kernels = laws.compiled()
    assert kernels is not None
    rng = np.random.default_rng(int(alpha * 100))
    for case in range(100):
        K, K_t, Kd, Kd_t = (rng.normal(size=(6, 6)) for _ in range(4))
        p, p_t, q_n, q_n_t = rng.normal(size=3), rng.normal(size=3), *rng.normal(size=(2, 7))
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        if case % 3 == 0:  # nearly the same orientation (the linear branch), either sign
            quat_t = (quat + rng.normal(size=4) * 1e-11) * rng.choice([-1.0, 1.0])
        else:
            quat_t = rng.normal(size=4)
        quat_t /= np.linalg.norm(quat_t)
        want = [K.copy(), Kd.copy(), p.copy(), q_n.copy()]
        for w, t in zip(want, (K_t, Kd_t, p_t, q_n_t), strict=True):
            laws.ema(w, t, alpha)
        want_quat = laws.slerp(quat, quat_t, alpha)
        kernels.pose_filter(alpha, K, K_t, Kd, Kd_t, p, p_t, q_n, q_n_t, quat, quat_t)
        for got, w in zip((K, Kd, p, q_n, quat), (*want, want_quat), strict=True):
            np.testing.assert_allclose(got, w, rtol=1e-12, atol=1e-12)


class _Model:
    def ee_jacobian(self, state):  # type: ignore[no-untyped-def]
        return KIN.zero_jacobian(state.q)

    def coriolis_of(self, state):  # type: ignore[no-untyped-def]
        return np.full(7, 0.1)


def _state(q, dq):  # type: ignore[no-untyped-def]
    return types.SimpleNamespace(q=q, dq=dq, O_T_EE=KIN.fk(q).reshape(16, order="F").copy())


@pytest.mark.parametrize("compiled", [True, False])
def test_cartesian_impedance_step_is_the_same_either_way(compiled: bool, monkeypatch) -> None:
    rng = np.random.default_rng(4)
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    start = _state(q0, np.zeros(7))
    if not compiled:
        monkeypatch.setitem(LOADED, laws.KERNELS, None)
    ctrl = controllers.CartesianImpedance(filter_coeff=0.5)
    ctrl.start(start, _Model())
    x = start.O_T_EE[12:15] + np.array([0.02, -0.01, 0.03])
    ctrl._p_t[:] = x  # the target as set_control would write it
    taus = []
    for _ in range(5):
        s = _state(q0 + rng.normal(size=7) * 0.01, rng.normal(size=7) * 0.1)
        taus.append(ctrl.step(s, _Model()))
    # the plain law on the same filtered inputs, step by step
    monkeypatch.setitem(LOADED, laws.KERNELS, None)
    rng = np.random.default_rng(4)
    ref_ctrl = controllers.CartesianImpedance(filter_coeff=0.5)
    ref_ctrl.start(start, _Model())
    ref_ctrl._p_t[:] = x
    for tau in taus:
        s = _state(q0 + rng.normal(size=7) * 0.01, rng.normal(size=7) * 0.1)
        np.testing.assert_allclose(tau, ref_ctrl.step(s, _Model()), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("gain", [1.0, 0.47])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_compiled_finalize_equals_walls_saturation_and_limits_in_numpy(
    seed: int, gain: float
) -> None:
    """Over a run that starts inside a wall zone, crosses zones and saturates, the one
    compiled call gives what the reference (walls, then rate saturation, then limits)
    gives, tick by tick, with the walls' state evolving the same."""
    rng = np.random.default_rng(seed)
    lower, upper = np.full(7, -2.0), np.full(7, 2.0)
    fast, ref = laws.JointWalls(lower, upper), laws.JointWalls(lower, upper)
    tau_max = np.array([87.0] * 4 + [12.0] * 3)
    q = rng.uniform(-2.0, 2.0, 7)
    q[0] = -1.95  # starts inside the lower zone: the zone shrinks
    tau_J_d = np.zeros(7)
    out = np.empty(7)
    for _ in range(400):
        dq = rng.normal(scale=0.5, size=7)
        q = np.clip(q + 0.01 * dq, -2.05, 2.05)
        tau = rng.normal(scale=20.0, size=7)
        assert fast.finalize(tau, q, dq, tau_J_d, tau_max, out, gain)
        walls = np.array(ref.torques(q, dq))
        expected = laws.clip_torques(laws.saturate_torque_rate(tau + walls, tau_J_d), tau_max)
        expected = tau_J_d + gain * (expected - tau_J_d)  # libfranka's low-pass
        np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-12)
        tau_J_d = out.copy()


def test_finalize_filters_alike_compiled_or_not(monkeypatch) -> None:
    rng = np.random.default_rng(7)  # (joints far from the walls: no wall torque)
    q, dq, tau_J_d = rng.uniform(-1, 1, 7), rng.normal(size=7), rng.uniform(-5, 5, 7)
    tau = tau_J_d + rng.uniform(-0.9, 0.9, 7)  # within a tick's rate bound
    tau_max, compiled, plain = np.full(7, 87.0), np.empty(7), np.empty(7)
    assert laws.JointWalls(np.full(7, -9.0), np.full(7, 9.0)).finalize(
        tau, q, dq, tau_J_d, tau_max, compiled, 0.3
    )
    monkeypatch.setitem(LOADED, laws.KERNELS, None)
    assert laws.JointWalls(np.full(7, -9.0), np.full(7, 9.0)).finalize(
        tau, q, dq, tau_J_d, tau_max, plain, 0.3
    )
    np.testing.assert_allclose(compiled, plain, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(compiled, tau_J_d + 0.3 * (tau - tau_J_d), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_finalize_refuses_a_non_finite_torque_even_one_it_could_saturate(
    bad: float, compiled: bool, monkeypatch
) -> None:
    if not compiled:
        monkeypatch.setitem(LOADED, laws.KERNELS, None)
    walls = laws.JointWalls(np.full(7, -2.0), np.full(7, 2.0))
    tau = np.zeros(7)
    tau[3] = bad
    z = np.zeros(7)
    assert not walls.finalize(tau, z, z, z, np.full(7, 87.0), np.empty(7))


@pytest.mark.parametrize("seed", [0, 1])
def test_the_pose_trackers_compiled_feedforward_equals_its_numpy_branch(
    seed: int, monkeypatch
) -> None:
    """PoseMove.step compiled (impedance and feed-forward in one call: (M + rotors) J^+ (a
    - dJ dq) + friction along J^+ (v - r e) + viscous J^+ v; the damping from the arm's
    inertia) gives the NumPy branch's torques, tick after tick (dJ from the previous tick;
    the damping updated on the first tick and the 21st)."""
    from panda_py.controllers.model import ControlModel
    from panda_py.controllers.moves import PoseMove
    from panda_py.controllers.plans import PosePlan

    rng = np.random.default_rng(seed)
    model = ControlModel("fr3")
    n = 30
    q0 = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8])
    T0 = KIN.fk(q0).reshape(16, order="F")
    p = T0[12:15] + rng.normal(scale=0.01, size=(n, 3))
    quat = np.tile(laws.quat_from_matrix(T0), (n, 1))
    twist, accel = rng.normal(scale=0.1, size=(n, 6)), rng.normal(scale=1.0, size=(n, 6))
    plan = PosePlan(p, quat, twist, accel, q0, np.diag([800.0] * 3 + [40.0] * 3), 1.0, 15.0,
                    1e-3, 2e-2, 0.1, OnlineLimits.cartesian(get_robot('fer'), 1.0))  # fmt: skip
    states = []
    for _ in range(n):
        q = q0 + rng.normal(scale=0.01, size=7)
        s = types.SimpleNamespace(q=q, dq=rng.normal(scale=0.2, size=7),
                                  O_T_EE=KIN.fk(q).reshape(16, order="F").copy(),
                                  F_T_EE=np.eye(4).reshape(16), m_ee=0.0)  # fmt: skip
        states.append(s)

    class Model:  # the model terms the move reads, on namespaces for states
        coulomb, armature, viscous = model.coulomb, model.armature, model.viscous

        def ee_jacobian(self, s):  # type: ignore[no-untyped-def]
            return KIN.zero_jacobian(s.q)

        def mass_of(self, s):  # type: ignore[no-untyped-def]  (the links')
            return np.eye(7) * 0.5 + 0.01 + 0.02 * s.q[:, None] * s.q[None, :]

        def driven_mass_of(self, s):  # type: ignore[no-untyped-def]  (and the rotors')
            return self.mass_of(s) + np.diag(self.armature)

        def friction_for(self, v):  # type: ignore[no-untyped-def]
            return model.friction_for(v)

        def coriolis_of(self, s):  # type: ignore[no-untyped-def]
            return np.zeros(7)

    def run(compiled: bool) -> list[np.ndarray]:
        if not compiled:
            monkeypatch.setitem(LOADED, laws.KERNELS, None)
        else:
            monkeypatch.undo()
        law, out = PoseMove(plan), []
        for k, s in enumerate(states):
            law.tick(0.0 if k == 0 else 1e-3)
            out.append(np.array(law.step(s, Model())))
        return out

    fast, slow = run(True), run(False)
    assert laws.compiled() is None  # the second run was the NumPy branch
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_damping_from_the_arms_inertia_has_the_ratio_asked_for(seed: int) -> None:
    """tracking.mass_damping (and its kernel, equal): with S = Lambda^(1/2), the end
    effector's inertia's root, (S^-1 D S^-1 / 2 zeta)^2 = S^-1 K S^-1 (for one axis D =
    2 zeta sqrt(K Lambda)); D is symmetric positive semi-definite; and on a diagonal
    inertia and stiffness it is the per-axis formula."""
    from panda_py.controllers import _kernels
    from panda_py.controllers.tracking import MIN_INVERSE_INERTIA, mass_damping

    rng = np.random.default_rng(seed)
    q = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8]) + rng.normal(scale=0.2, size=7)
    J = KIN.zero_jacobian(q)
    B = rng.normal(size=(7, 7))
    M = 0.05 * B @ B.T + 0.1 * np.eye(7)  # an arm's sizes [kg m^2]
    assert np.linalg.eigvalsh(J @ np.linalg.solve(M, J.T)).min() > MIN_INVERSE_INERTIA
    C = rng.normal(size=(6, 6))
    K = C @ C.T * 100.0
    zeta = 0.8
    D = mass_damping(K, zeta, M, J)
    out = np.empty((6, 6))
    _kernels.mass_damping(K, zeta, M, np.zeros(7), J, MIN_INVERSE_INERTIA, out)
    np.testing.assert_allclose(out, D, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(D, D.T, atol=1e-9)
    assert np.linalg.eigvalsh(D).min() > -1e-9
    Lam = np.linalg.inv(J @ np.linalg.solve(M, J.T))
    w, V = np.linalg.eigh(Lam)
    S_inv = (V / np.sqrt(w)) @ V.T
    R = S_inv @ D @ S_inv / (2.0 * zeta)
    np.testing.assert_allclose(R @ R, S_inv @ K @ S_inv, rtol=1e-6, atol=1e-6 * np.abs(K).max())
    # one axis at a time: J picks six joints whose inertias are the diagonal's
    J6 = np.hstack([np.eye(6), np.zeros((6, 1))])
    m = rng.uniform(0.5, 5.0, 7)
    k = rng.uniform(10.0, 1000.0, 6)
    D6 = mass_damping(np.diag(k), zeta, np.diag(m), J6)
    np.testing.assert_allclose(D6, np.diag(2.0 * zeta * np.sqrt(k * m[:6])), atol=1e-9)


def test_the_damping_stays_bounded_at_a_singular_configuration() -> None:
    """The arm stretched straight up (q = 0) has lost directions of motion, along which its
    inertia is unbounded: the damping is bounded by the kept inverse inertia instead."""
    from panda_py.controllers.model import ControlModel
    from panda_py.controllers.tracking import MIN_INVERSE_INERTIA, mass_damping

    model = ControlModel("fer")
    q = np.zeros(7)
    J = KIN.zero_jacobian(q)
    assert np.linalg.svd(J, compute_uv=False).min() < 1e-9  # singular indeed
    M = np.asarray(model.mass(q, np.zeros(9), 0.0, np.zeros(3))).reshape(7, 7, order="F")
    M += np.diag(model.armature)
    K = np.diag([800.0] * 3 + [40.0] * 3)
    D = mass_damping(K, 1.0, M, J)
    assert np.isfinite(D).all()
    assert np.linalg.eigvalsh(D).max() <= 2.0 * np.sqrt(800.0 / MIN_INVERSE_INERTIA) + 1e-6
    out = np.empty((6, 6))  # and the kernel's the same
    laws.compiled().mass_damping(K, 1.0, M - np.diag(model.armature), model.armature, J,
                                 MIN_INVERSE_INERTIA, out)  # fmt: skip
    np.testing.assert_allclose(out, D, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("case", ["random", "repeated", "diagonal", "rank one", "zero"])
def test_jacobis_eigenvalues_agree_with_lapacks(case: str) -> None:
    """The damping's eigen-decomposition in loops (_kernels._symmetric_eigen): the same
    eigenvalues as LAPACK's, orthonormal eigenvectors that rebuild the matrix, also where
    eigenvalues repeat (eigenvectors not unique) or the matrix is already diagonal."""
    from panda_py.controllers import _kernels

    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    values = {
        "random": rng.normal(size=6) * 100.0,
        "repeated": np.array([2.0, 2.0, 2.0, 5.0, 5.0, -1.0]),
        "diagonal": rng.uniform(0.01, 10.0, 6),
        "rank one": np.array([0.0] * 5 + [3.0]),
        "zero": np.zeros(6),
    }[case]
    A = np.diag(values) if case == "diagonal" else Q @ np.diag(values) @ Q.T
    A = 0.5 * (A + A.T)
    w, V = np.empty(6), np.empty((6, 6))
    _kernels._symmetric_eigen(A.copy(), w, V)
    scale = max(1.0, np.abs(values).max())
    np.testing.assert_allclose(np.sort(w), np.linalg.eigvalsh(A), atol=1e-12 * scale)
    np.testing.assert_allclose(V.T @ V, np.eye(6), atol=1e-12)
    np.testing.assert_allclose(V @ np.diag(w) @ V.T, A, atol=1e-12 * scale)


def test_the_compiled_joint_cap_equals_the_numpy_one(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from panda_py.controllers.moves import joint_capped
    from panda_py.motion.online import _frame

    assert laws.compiled() is not None
    spec = get_robot("fr3")
    rng = np.random.default_rng(7)
    capped = 0
    for _ in range(300):
        q = rng.uniform(-2.0, 2.0, 7)
        q[3] = rng.uniform(-2.8, -0.2)
        J = KIN.zero_jacobian(q)
        frames = (_frame(rng.normal(size=3), np.zeros(3)), _frame(rng.normal(size=3), np.zeros(3)))
        limits = OnlineLimits.cartesian(spec, rng.uniform(0.05, 1.0))
        fast = joint_capped(limits, J, spec, frames)
        with monkeypatch.context() as m:
            m.setattr(laws, "compiled", lambda: None)
            slow = joint_capped(limits, J, spec, frames)
        capped += fast is not limits
        assert (fast is limits) == (slow is limits)
        for name in ("velocity", "acceleration", "jerk"):
            np.testing.assert_allclose(getattr(fast, name), getattr(slow, name), rtol=1e-9)
    assert 0 < capped < 300  # both branches seen


def _robot_state(q, dq, F_T_EE, m_load, F_x_Cload, pose_q=None, tau_J=None):  # type: ignore[no-untyped-def]
    """A TickState (read-only fields, as the loop hands them) of a FER with a load (its
    pose that of ``pose_q``, by default ``q``; its measured torques ``tau_J``, or 0)."""
    from panda_py import fci
    from panda_py.libfranka.state import TickState

    kin = kinematics.get_kinematics("fer", F_T_EE)
    dialect = fci.dialect(5)
    rec = np.zeros((), dialect.state_dtype)
    rec["q"] = rec["q_d"] = q
    rec["dq"] = dq
    rec["O_T_EE"] = kin.fk(q if pose_q is None else pose_q).reshape(16, order="F")
    rec["F_T_EE"] = F_T_EE.reshape(16, order="F")
    rec["EE_T_K"] = np.eye(4).reshape(16)
    rec["m_ee"] = 0.73
    rec["F_x_Cee"] = (-0.01, 0.0, 0.03)
    rec["I_ee"] = np.diag([0.001, 0.0025, 0.0017]).reshape(9)
    rec["m_load"] = m_load
    rec["F_x_Cload"] = F_x_Cload
    rec["I_load"] = np.diag([0.002, 0.002, 0.001]).reshape(9)
    if tau_J is not None:
        rec["tau_J"] = tau_J
    return TickState(dialect, rec.tobytes())


@pytest.mark.parametrize("path", ["separate kernels", "numpy"])
def test_the_fused_step_equals_the_separate_calls_and_the_numpy_law(path: str, monkeypatch):  # type: ignore[no-untyped-def]
    """CartesianImpedance's one-call step (filter, Jacobian, law, Coriolis: _fused) on a
    real ControlModel, with a load and another end effector, while the target, the
    stiffness and the load change, gives the torques of the separate calls and of the
    plain law."""
    from panda_py.controllers.model import ControlModel

    assert laws.fused() is not None
    rng = np.random.default_rng(7)
    F_T_EE = np.eye(4)
    F_T_EE[:3, 3] = (0.0, 0.02, 0.15)
    F_T_EE[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]
    q0 = np.array([0.1, -0.6, 0.2, -2.2, 0.1, 1.7, 0.6])
    states = []
    for k in range(12):
        load = (0.0, (0.0, 0.0, 0.0)) if k < 6 else (0.8, (0.01, -0.02, 0.05))  # picked up
        states.append(_robot_state(q0 + rng.normal(size=7) * 0.02, rng.normal(size=7) * 0.2,
                                   F_T_EE, *load))  # fmt: skip
    A = rng.normal(size=(6, 6))
    K = A @ A.T + np.diag([900.0] * 3 + [40.0] * 3)

    def run() -> list[np.ndarray]:
        model = ControlModel("fer")
        ctrl = controllers.CartesianImpedance(filter_coeff=0.3, nullspace_stiffness=4.0)
        ctrl.start(states[0], model)
        out = []
        for k, s in enumerate(states):
            if k == 3:  # a new target, as set_control writes it
                ctrl._p_t[:] = s.O_T_EE[12:15] + np.array([0.03, -0.02, 0.01])
                ctrl._quat_t[:] = laws.quat_from_matrix(states[0].O_T_EE)[[1, 0, 2, 3]] * (
                    1.0, -1.0, 1.0, 1.0)  # fmt: skip
                ctrl._quat_t /= np.linalg.norm(ctrl._quat_t)
            if k == 8:  # a stiffer, coupled impedance
                ctrl._K_t[:] = K
            ctrl.inputs_changed = k in (0, 3, 8)
            ctrl.tick(1e-3)
            out.append(np.array(ctrl.step(s, model)))
        return out

    fused = run()
    monkeypatch.setitem(LOADED, laws.FUSED, None)
    for got, want in zip(fused, run(), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    assert np.abs(fused[-1]).max() > 1.0  # the target and the load made it work


def _force_law(kind: str):  # type: ignore[no-untyped-def]
    if kind == "AppliedForce":
        return controllers.AppliedForce(damping=np.full(7, 3.0), filter_coeff=0.3)
    return controllers.Force(k_p=0.7, k_i=4.0, threshold=0.5, filter_coeff=0.3)


def _drive_force_law(kind: str, states: list) -> tuple[list, dict]:  # type: ignore[type-arg]
    """``kind`` stepped through ``states`` on a fresh ControlModel as the loop steps it,
    its inputs changed on the way (as the user's setters write them); per tick its
    torques, or the error that ended it, and its filtered inputs (and Force's integral)
    at the end."""
    from panda_py.controllers.model import ControlModel
    from panda_py.libfranka import ControlException

    model = ControlModel("fer")
    ctrl = _force_law(kind)
    ctrl.start(states[0], model)
    out: list = []  # type: ignore[type-arg]
    for k, s in enumerate(states):
        if k == 3:
            if kind == "AppliedForce":
                ctrl.set_control([3.0, -2.0, 8.0, 0.4, -0.2, 0.5])
            else:
                ctrl.set_control([2.0, -3.0, -8.0])
        if k == 12:
            ctrl.set_damping(np.full(7, 1.5))
            if kind == "Force":  # new gains, and a threshold the arm soon passes
                ctrl.set_proportional_gain(1.4)
                ctrl.set_integral_gain(0.8)
                ctrl.set_threshold(0.0)
        ctrl.tick(0.0 if k == 0 else 1e-3)
        try:
            out.append(np.array(ctrl.step(s, model)))
        except ControlException as exc:
            out.append(str(exc))
            break
    names = ("_law",) if kind == "Force" else ("_in", "_D")
    return out, {name: getattr(ctrl, name).copy() for name in names}


@pytest.mark.parametrize("kind", ["AppliedForce", "Force"])
def test_the_force_laws_fused_steps_equal_their_numpy_laws(kind: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """AppliedForce's and Force's one-call steps (_fused.applied_force_step,
    _fused.force_step: the filter, the Jacobian to another end effector, for Force the
    gravity torques of the loaded arm, its PI law on the measured torques and its
    distance check) on a real ControlModel, while the inputs change and a load is picked
    up, give the NumPy law's torques tick by tick (to 1e-9) and the same filtered inputs
    and integral; Force passes its threshold at the same tick with the same error."""
    assert laws.fused() is not None
    rng = np.random.default_rng(13)
    F_T_EE = np.eye(4)
    F_T_EE[:3, 3] = (0.01, -0.02, 0.14)
    F_T_EE[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]
    q0 = np.array([0.1, -0.6, 0.2, -2.2, 0.1, 1.7, 0.6])
    drift = rng.normal(scale=2e-3, size=7)  # the arm drifts off: some mm a tick
    states = []
    for k in range(60):
        load = (0.0, (0.0, 0.0, 0.0)) if k < 8 else (0.7, (0.0, 0.01, 0.05))
        q = q0 + k * drift + rng.normal(scale=1e-3, size=7)
        states.append(_robot_state(q, rng.normal(scale=0.2, size=7), F_T_EE, *load,
                                   tau_J=rng.normal(scale=4.0, size=7)))  # fmt: skip
    kernels, calls = laws.fused(), []
    name = "applied_force_step" if kind == "AppliedForce" else "force_step"
    step = getattr(kernels, name)

    def counted(*args):  # type: ignore[no-untyped-def]
        calls.append(1)
        return step(*args)

    monkeypatch.setattr(kernels, name, counted)
    fused, fused_buffers = _drive_force_law(kind, states)
    assert len(calls) == len(fused)  # every tick was the fused step's
    monkeypatch.setitem(LOADED, laws.FUSED, None)
    plain, plain_buffers = _drive_force_law(kind, states)
    assert len(fused) == len(plain)
    for got, want in zip(fused, plain, strict=True):
        if isinstance(want, str):
            assert got == want
        else:
            np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-9)
    for key, want in plain_buffers.items():
        np.testing.assert_allclose(fused_buffers[key], want, rtol=0.0, atol=1e-9)
    torques = [t for t in fused if not isinstance(t, str)]
    assert np.abs(torques[-1]).max() > 1.0  # the force and the sensors made it work
    if kind == "Force":  # it aborted past its threshold, well after its start
        assert isinstance(fused[-1], str) and "distance threshold exceeded" in fused[-1]
        assert 14 < len(fused) < len(states)
    else:
        assert len(fused) == len(states)


@pytest.mark.parametrize("kind", ["AppliedForce", "Force"])
def test_the_force_laws_fused_steps_give_nan_torques_for_a_non_finite_state(kind: str) -> None:
    from panda_py.controllers.model import ControlModel

    q = np.array(START_POSE)
    good = _robot_state(q, np.zeros(7), np.eye(4), 0.0, (0.0, 0.0, 0.0))
    q_bad = q.copy()
    q_bad[3] = np.nan
    bad = _robot_state(q_bad, np.zeros(7), np.eye(4), 0.0, (0.0, 0.0, 0.0), pose_q=q)
    model = ControlModel("fer")
    ctrl = _force_law(kind)
    ctrl.start(good, model)
    ctrl.tick(0.0)
    assert np.isfinite(ctrl.step(good, model)).all()
    ctrl.tick(1e-3)
    assert np.isnan(ctrl.step(bad, model)).all()  # which the loop's finalize refuses


def test_the_fused_step_gives_nan_torques_for_a_non_finite_state() -> None:
    from panda_py.controllers.model import ControlModel

    q = np.array(START_POSE)
    good = _robot_state(q, np.zeros(7), np.eye(4), 0.0, (0.0, 0.0, 0.0))
    q_bad = q.copy()
    q_bad[3] = np.nan
    bad = _robot_state(q_bad, np.zeros(7), np.eye(4), 0.0, (0.0, 0.0, 0.0), pose_q=q)
    model = ControlModel("fer")
    ctrl = controllers.CartesianImpedance()
    ctrl.start(good, model)
    assert np.isfinite(ctrl.step(good, model)).all()
    assert np.isnan(ctrl.step(bad, model)).all()  # which the loop's finalize refuses


def _loaded_states(rng, q0, F_T_EE):  # type: ignore[no-untyped-def]
    """32 states near ``q0``, moving, a load picked up from the 11th."""
    states = []
    for k in range(32):
        load = (0.0, (0.0, 0.0, 0.0)) if k < 10 else (0.6, (0.0, 0.01, 0.04))
        q = q0 + rng.normal(scale=0.005, size=7)
        states.append(_robot_state(q, rng.normal(scale=0.1, size=7), F_T_EE, *load))
    return states


def _target_away(target, name, offset):  # type: ignore[no-untyped-def]
    """A streamed target moved by ``offset`` from where it started, as set_target writes
    it (the signal, then its count)."""
    layout = target._sig_layout
    start, size = layout[name]
    target._values[start : start + size] += offset
    target._values[layout["count"][0]] += 1.0


def _drive(move, target, name, offset, states):  # type: ignore[no-untyped-def]
    """A move and a streamed target (moved by ``offset`` after its start) stepped
    through ``states`` on a fresh ControlModel; per tick the move's torques, the target's
    and a copy of the target's outputs."""
    from panda_py.controllers.model import ControlModel

    model, out = ControlModel("fer"), []
    target.dt = 1e-3
    target.start(states[0], model)
    _target_away(target, name, offset)
    for k, s in enumerate(states):
        move.tick(0.0 if k == 0 else 1e-3)
        target.tick(1e-3)
        out.append((move.step(s, model), target.step(s, model), target._out.copy()))
    return out


@pytest.mark.parametrize("path", ["separate kernels", "numpy"])
def test_the_fused_pose_tracking_equals_the_separate_calls_and_the_numpy_law(
    path: str, monkeypatch
) -> None:
    """PoseMove and CartesianTarget on a real ControlModel (a load picked up mid-way,
    another end effector): the tracking in one call (_fused.pose_tracking_step: Jacobian,
    mass matrix, damping from the arm's inertia on the first tick and the 21st, tracking
    torque with its feed-forward, Coriolis; for the target with its generator's sampling
    and its outputs, _fused.pose_target_step) gives the torques and outputs of the
    separate calls and of the plain law, through the plan, its end and the settle phase
    after it."""
    from panda_py.controllers.moves import PoseMove
    from panda_py.controllers.plans import PosePlan

    assert laws.fused() is not None
    rng = np.random.default_rng(5)
    F_T_EE = np.eye(4)
    F_T_EE[:3, 3] = (0.01, 0.0, 0.12)
    kin = kinematics.get_kinematics("fer", F_T_EE)
    q0 = np.array([0.1, -0.5, 0.1, -2.1, 0.0, 1.6, 0.7])
    T0 = kin.fk(q0).reshape(16, order="F")
    n = 20
    p = T0[12:15] + np.linspace(0.0, 0.01, n)[:, None] * np.array([1.0, -0.5, 0.3])
    quat = np.tile(laws.quat_from_matrix(T0), (n, 1))
    twist, accel = rng.normal(scale=0.05, size=(n, 6)), rng.normal(scale=0.5, size=(n, 6))
    plan = PosePlan(p, quat, twist, accel, q0, np.diag([800.0] * 3 + [40.0] * 3), 0.9, 10.0,
                    1e-3, 2e-2, 0.1, OnlineLimits.cartesian(get_robot("fer"), 1.0))  # fmt: skip
    states = _loaded_states(rng, q0, F_T_EE)

    def run() -> list[np.ndarray]:
        move, target = PoseMove(plan), controllers.CartesianTarget()
        ticks = _drive(move, target, "position", np.array([0.02, 0.0, -0.01]), states)
        out = [np.concatenate(tick) for tick in ticks]  # and the target's outputs
        assert move.t > move.t_end  # into the settle phase
        assert np.abs(out[-1][7:14]).max() > 0.5  # the target pulls
        assert out[-1][14 + target._out_layout["lag"][0]] > 0.01  # and lags
        return out

    kernels, calls = laws.fused(), []
    target_step = kernels.pose_target_step  # the target's tick in one call: counted

    def counted(*args):  # type: ignore[no-untyped-def]
        calls.append(args[0][0])  # whether it sampled the generator's trajectory
        return target_step(*args)

    monkeypatch.setattr(kernels, "pose_target_step", counted)
    fused = run()
    assert len(calls) == len(states) and 0.0 in calls and 1.0 in calls
    monkeypatch.setitem(LOADED, laws.FUSED, None)
    if path == "numpy":
        monkeypatch.setitem(LOADED, laws.KERNELS, None)
    for got, want in zip(fused, run(), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-8)


def test_the_fused_joint_tracking_equals_the_numpy_law(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """JointMove and JointTarget on a real ControlModel (a load picked up mid-way): the
    joint tracking in one call (_fused.joint_tracking_step: mass matrix, impedance,
    inertial and friction feed-forward, Coriolis) gives the torques of the NumPy law on
    the model's terms, through the plan, its end and the settle phase."""
    from panda_py.controllers.moves import JointMove
    from panda_py.controllers.plans import JointPlan

    assert laws.fused() is not None
    rng = np.random.default_rng(9)
    q0 = np.array([0.1, -0.5, 0.1, -2.1, 0.0, 1.6, 0.7])
    n = 20
    q = q0 + np.linspace(0.0, 0.02, n)[:, None] * rng.normal(size=7)
    dq, ddq = rng.normal(scale=0.1, size=(n, 7)), rng.normal(scale=1.0, size=(n, 7))
    plan = JointPlan(q, dq, ddq, np.full(7, 600.0), np.full(7, 40.0), 1e-3, 1e-2,
                     OnlineLimits.joints(get_robot("fer"), 1.0))  # fmt: skip
    states = _loaded_states(rng, q0, np.eye(4))

    def run() -> list[np.ndarray]:
        move, target = JointMove(plan), controllers.JointTarget()
        ticks = _drive(move, target, "q", np.full(7, 0.05), states)
        out = [np.concatenate(tick[:2]) for tick in ticks]
        assert move.t > move.t_end  # into the settle phase
        assert np.abs(out[-1][7:]).max() > 1.0  # the target pulls
        return out

    fused = run()
    monkeypatch.setitem(LOADED, laws.FUSED, None)
    for got, want in zip(fused, run(), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_the_fused_kernels_never_compile_in_the_loop() -> None:
    """Each fused kernel has one signature, compiled at import, taking read-only and
    writable inputs alike; an input of another layout is refused with a TypeError, not
    compiled for (which would stop the loop for seconds)."""
    fused = laws.fused()
    assert fused is not None
    kernels = (fused.cartesian_impedance_step, fused.pose_tracking_step,
               fused.joint_tracking_step, fused.pose_target_step, fused.applied_force_step,
               fused.force_exceeded, fused.force_step)  # fmt: skip
    fused.warmup()  # read-only state fields and writable buffers
    assert [len(k.signatures) for k in kernels] == [1] * 7
    from panda_py import dynamics

    arm = dynamics.LoadedArm("fer").arrays
    z7 = np.zeros(7)
    strided = np.zeros(14)[::2]  # not C-contiguous
    with pytest.raises(TypeError, match="No matching definition"):
        fused.joint_tracking_step(strided, z7, *arm, z7, z7, z7, z7, z7, z7, z7, 0.01, 10.0,
                                  np.empty(7))  # fmt: skip
    assert [len(k.signatures) for k in kernels] == [1] * 7


_NO_ALLOCATION = """
import numba
import numpy as np
from numba.core.runtime import rtsys
from panda_py import dynamics, kinematics
from panda_py.controllers import _builtin, _fused, tracking

def ro(a):
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a

rng = np.random.default_rng(3)
q, dq = ro(rng.normal(size=7)), ro(rng.normal(size=7))
T = ro(kinematics.get_kinematics("fer").fk(q).reshape(16, order="F"))
arm = dynamics.LoadedArm("fer").arrays
chain = kinematics.get_kinematics("fer").chain_constants
ctrl = _builtin.CartesianImpedance()
at = np.array([ctrl._sig_layout[n][0] for n in _builtin._FUSED_SIGNALS], dtype=np.int64)
at.flags.writeable = False
values = ro(ctrl._values)
filtered = np.zeros(_builtin._FILTERED_SIZE)
filtered[78] = 1.0
J, tau, z7, z6 = np.empty((1, 6, 7)), np.empty(7), ro(np.zeros(7)), ro(np.zeros(6))
law = tracking.PoseImpedance(np.eye(6) * 100.0, 1.0, np.zeros(7), 1.0).compiled_inputs(1e-3)
quat = ro([0.0, 0.0, 0.0, 1.0])
traj, I3 = ro(np.zeros((6, _fused._ONLINE.ROW))), ro(np.eye(3))
tick = ro([1.0, 0.0, 0.0, 0.0, 0.0])
p, v, a, pos, ori = np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(3), np.array(quat)
tw, acc, out = np.zeros(6), np.zeros(6), np.zeros(20)
applied, force = _builtin.AppliedForce(), _builtin.Force()
af_at, f_at = (np.array([c._sig_layout[n][0] for n in names], dtype=np.int64)
               for c, names in ((applied, _builtin._APPLIED_SIGNALS),
                                (force, _builtin._FORCE_SIGNALS)))
af_at.flags.writeable = f_at.flags.writeable = False
wrench, D, f_law = np.zeros(6), np.zeros(7), np.zeros(_builtin._FORCE_SIZE)
f_law[12] = 10.0  # a threshold the arm is within [m]

@numba.njit
def run(n, values, at, filtered, Kd_t, T, q, dq, chain, o, ca, sa, m, h, I, J, tau, z7, z6, p_d,
        quat, law, tick, traj, p, v, a, I3, pos, ori, tw, acc, target, out, af_values, af_at,
        wrench, D, f_values, f_at, f_law):
    for _ in range(n):
        _fused.applied_force_step(af_values, af_at, wrench, D, q, dq, chain, J, tau)
        _fused.force_step(f_values, f_at, f_law, 1e-3, 1e-3, T, q, dq, dq, chain, o, ca, sa, m,
                          h, I, J, tau)
        _fused.cartesian_impedance_step(values, at, filtered, Kd_t, T, q, dq, chain, o, ca, sa,
                                        m, h, I, J, tau)
        _fused.joint_tracking_step(q, dq, o, ca, sa, m, h, I, z7, z7, z7, z7, q, dq, dq, 0.01,
                                   10.0, tau)
        for update in (0.0, 1.0):  # the mass matrix and the damping too (every 20 ticks)
            law[6], law[7] = update, 1.0
            _fused.pose_tracking_step(T, q, dq, chain, o, ca, sa, m, h, I, z7, z7, p_d, quat,
                                      z6, z6, law, tau)
        _fused.pose_target_step(tick, traj, p, v, a, I3, I3, I3, quat, pos, ori, tw, acc, T, q,
                                dq, chain, o, ca, sa, m, h, I, z7, z7, law, target, out, tau)

args = (values, at, filtered, ro(np.eye(6)), T, q, dq, chain, *arm, J, tau, z7, z6,
        ro(T[12:15]), quat, law, tick, traj, p, v, a, I3, pos, ori, tw, acc, ro(np.zeros(7)), out,
        ro(applied._values), af_at, wrench, D, ro(force._values), f_at, f_law)
counts = []
for n in (1, 51):  # (numba's runtime counts the arguments' unboxing too: once a call)
    before = rtsys.get_allocation_stats().alloc
    run(n, *args)
    counts.append(rtsys.get_allocation_stats().alloc - before)
print((counts[1] - counts[0]) / 50)
"""


def test_the_fused_steps_allocate_nothing_per_tick() -> None:
    """The fused steps' temporaries live on the stack (jit.stack): running every one of
    them from a compiled loop (the Cartesian impedance, the force laws, the pose and joint
    tracking with and without the mass matrix's update, a streamed target with its
    generator's sample) allocates nothing in numba's runtime (counted by its statistics,
    on in a fresh process: before the stack arrays, 220 allocations a round)."""
    import subprocess
    import sys

    assert laws.fused() is not None
    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    out = subprocess.run([sys.executable, "-c", _NO_ALLOCATION], capture_output=True,
                         text=True, env=env, timeout=600, check=True)  # fmt: skip
    assert float(out.stdout.split()[-1]) == 0.0, out.stdout
