import math

import mujoco
import numpy as np
import pytest

from panda_py import dynamics, jit
from panda_py.jit import LOADED
from panda_py.robots.params import FER, FR3, RobotSpec

TOL_MUJOCO = 1e-8  # [Nm] / [kg m^2] agreement with MuJoCo
TOL_EXACT = 1e-11  # two exact algorithms on the same model


def _f(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _mujoco_xml(spec: RobotSpec, m_load: float, F_x_C, I_load) -> str:
    """An independent MuJoCo model of the same chain: bodies at the DH frames."""
    dh = spec.dh
    bodies, closing = "", ""
    for i in range(7):
        al, link = dh.alpha[i], spec.links[i + 1]
        pos = (dh.a[i], -math.sin(al) * dh.d[i], math.cos(al) * dh.d[i])
        quat = (math.cos(al / 2), math.sin(al / 2), 0.0, 0.0)
        bodies += (
            f'<body name="link{i + 1}" pos="{_f(pos)}" quat="{_f(quat)}">'
            f'<joint name="joint{i + 1}" axis="0 0 1" armature="0" damping="0"/>'
            f'<inertial pos="{_f(link.com)}" mass="{link.mass!r}" '
            f'fullinertia="{_f(link.inertia)}"/>'
        )
        closing += "</body>"
    I = np.asarray(I_load)
    full = (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])
    bodies += (
        f'<body name="load" pos="0 0 {dh.flange_d!r}">'
        f'<inertial pos="{_f(F_x_C)}" mass="{m_load!r}" fullinertia="{_f(full)}"/></body>'
    )
    return (
        '<mujoco><compiler angle="radian"/><option gravity="0 0 -9.81"/>'
        f"<worldbody>{bodies}{closing}</worldbody></mujoco>"
    )


def _random_load(rng):
    m = float(rng.uniform(0.2, 2.0))
    c = rng.uniform(-0.05, 0.05, 3) + np.array([0.0, 0.0, 0.05])
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    I = R @ np.diag(rng.uniform(0.002, 0.004, 3)) @ R.T  # satisfies the triangle inequality
    return m, c, I


def _mujoco_terms(model, data, q, dq):
    data.qpos[:] = q
    data.qvel[:] = 0
    mujoco.mj_forward(model, data)
    M = np.zeros((7, 7))
    mujoco.mj_fullM(model, data, M)
    g = data.qfrc_bias.copy()
    data.qvel[:] = dq
    mujoco.mj_forward(model, data)
    return M, g, data.qfrc_bias - g


@pytest.mark.parametrize("spec", [FER, FR3], ids=lambda s: s.name)
def test_matches_mujoco_with_random_load(spec):
    rng = np.random.default_rng(7)
    m, c, I = _random_load(rng)
    model = mujoco.MjModel.from_xml_string(_mujoco_xml(spec, m, c, I))
    data = mujoco.MjData(model)
    load = {"m_load": m, "F_x_Cload": c, "robot": spec}
    for _ in range(5):
        q = rng.uniform(spec.joints.q_min, spec.joints.q_max)
        dq = rng.uniform(-2.0, 2.0, 7)
        M_ref, g_ref, c_ref = _mujoco_terms(model, data, q, dq)
        np.testing.assert_allclose(
            dynamics.mass_matrix(q, I_load=I, **load), M_ref, rtol=0, atol=TOL_MUJOCO
        )
        np.testing.assert_allclose(dynamics.gravity(q, **load), g_ref, rtol=0, atol=TOL_MUJOCO)
        np.testing.assert_allclose(
            dynamics.coriolis(q, dq, I_load=I, **load), c_ref, rtol=0, atol=TOL_MUJOCO
        )


def test_gravity_sign_holds_the_arm():
    # Arm stretched out horizontally along +x: joint 2 must push up, i.e. a negative
    # torque about its z axis (which points along -y at q = 0).
    q = [0.0, math.pi / 2, 0.0, -0.07, 0.0, 0.0, 0.0]
    tau = dynamics.gravity(q)
    assert tau[1] < -10.0
    assert np.allclose(dynamics.gravity(q, gravity=(0, 0, 0)), 0.0)
    np.testing.assert_allclose(dynamics.gravity(q, gravity=(0, 0, -19.62)), 2 * tau, rtol=1e-12)


def test_mass_matrix_equals_rnea_columns_and_is_positive_definite():
    rng = np.random.default_rng(1)
    m, c, I = _random_load(rng)
    for _ in range(5):
        q = rng.uniform(-2.5, 2.5, 7)
        M = dynamics.mass_matrix(q, m_load=m, F_x_Cload=c, I_load=I)
        cols = [
            dynamics.inverse_dynamics(
                q, np.zeros(7), e, m_load=m, F_x_Cload=c, I_load=I, gravity=(0, 0, 0)
            )
            for e in np.eye(7)
        ]
        np.testing.assert_allclose(M, np.array(cols).T, rtol=0, atol=TOL_EXACT)
        np.testing.assert_array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0


def test_inverse_dynamics_is_the_sum_of_the_terms():
    rng = np.random.default_rng(2)
    m, c, I = _random_load(rng)
    q, dq, ddq = rng.uniform(-2, 2, (3, 7))
    load = {"m_load": m, "F_x_Cload": c}
    tau = dynamics.inverse_dynamics(q, dq, ddq, I_load=I, **load)
    expected = (
        dynamics.mass_matrix(q, I_load=I, **load) @ ddq
        + dynamics.coriolis(q, dq, I_load=I, **load)
        + dynamics.gravity(q, **load)
    )
    np.testing.assert_allclose(tau, expected, rtol=0, atol=TOL_EXACT)


def test_coriolis_is_quadratic_and_load_changes_the_terms():
    rng = np.random.default_rng(3)
    q, dq = rng.uniform(-2, 2, (2, 7))
    np.testing.assert_allclose(
        dynamics.coriolis(q, 2 * dq), 4 * dynamics.coriolis(q, dq), rtol=1e-12, atol=1e-12
    )
    # 1 kg hanging 0.1 m below the flange adds to the holding torques
    assert not np.allclose(
        dynamics.gravity(q, m_load=1.0, F_x_Cload=(0, 0, 0.1)), dynamics.gravity(q)
    )
    # inertia-only load: gravity unchanged, mass matrix changed (joint 7 sees I_zz)
    I = np.diag([0.0, 0.0, 0.01])
    M0, M1 = dynamics.mass_matrix(q), dynamics.mass_matrix(q, I_load=I)
    assert M1[6, 6] - M0[6, 6] == pytest.approx(0.01, abs=1e-12)


def test_I_load_accepts_libfranka_column_major_array():
    rng = np.random.default_rng(4)
    q = rng.uniform(-2, 2, 7)
    I = np.array([[0.01, 0.001, 0.002], [0.003, 0.02, 0.004], [0.005, 0.006, 0.03]])
    np.testing.assert_array_equal(
        dynamics.mass_matrix(q, I_load=I), dynamics.mass_matrix(q, I_load=I.ravel(order="F"))
    )


def test_robot_names_resolve():
    q = [0.1] * 7
    np.testing.assert_array_equal(dynamics.gravity(q, robot="panda"), dynamics.gravity(q))
    np.testing.assert_array_equal(dynamics.gravity(q, robot="fr3"), dynamics.gravity(q, robot=FR3))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: dynamics.gravity([0.0] * 6), r"q: expected shape \(7,\)"),
        (lambda: dynamics.gravity([0.0] * 6 + [math.nan]), "q: expected finite"),
        (lambda: dynamics.gravity([0.0] * 7, m_load=-1.0), "m_load"),
        (lambda: dynamics.gravity([0.0] * 7, m_load="heavy"), "m_load"),
        (lambda: dynamics.gravity([0.0] * 7, F_x_Cload=(0, 0)), "F_x_Cload"),
        (lambda: dynamics.gravity([0.0] * 7, gravity=(0, 0)), "gravity"),
        (lambda: dynamics.mass_matrix([0.0] * 7, I_load=np.eye(2)), "I_load"),
        (lambda: dynamics.mass_matrix([0.0] * 7, I_load=[math.inf] * 9), "I_load"),
        (lambda: dynamics.coriolis([0.0] * 7, [0.0] * 8), "dq"),
        (lambda: dynamics.inverse_dynamics([0.0] * 7, [0.0] * 7, "x"), "ddq"),
        (lambda: dynamics.gravity([0.0] * 7, robot="ur5"), "robot"),
    ],
)
def test_invalid_input_is_rejected(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_loaded_arm_equals_the_checked_functions() -> None:
    from panda_py.dynamics import LoadedArm, coriolis, gravity, mass_matrix

    rng = np.random.default_rng(7)
    load = {"m_load": 0.9, "F_x_Cload": [0.01, -0.02, 0.05], "I_load": np.eye(3) * 2e-3}
    for robot in ("fer", "fr3"):
        arm = LoadedArm(robot, **load)
        for _ in range(5):
            q, dq = rng.uniform(-1, 1, 7), rng.normal(size=7)
            np.testing.assert_allclose(
                arm.coriolis(q.tolist(), dq.tolist()),
                coriolis(q, dq, robot=robot, **load),
                atol=1e-12,
            )
            np.testing.assert_allclose(
                arm.gravity(q.tolist()),
                gravity(q, m_load=0.9, F_x_Cload=load["F_x_Cload"], robot=robot),
                atol=1e-12,
            )
            np.testing.assert_allclose(
                arm.mass_matrix(q.tolist()), mass_matrix(q, robot=robot, **load), atol=1e-12
            )


def test_motion_torques_along_a_trajectory_are_the_mass_and_coriolis_terms() -> None:
    """LoadedArm.motion_torques: ``M(q) ddq + C(q, dq) dq`` at every row (no gravity), on
    the compiled kernels and on the plain recursion; rows of different counts refused."""
    from panda_py import dynamics

    rng = np.random.default_rng(46)
    load = {"m_load": 0.73, "F_x_Cload": [-0.01, 0.0, 0.03], "I_load": np.eye(3) * 2e-3}
    Q, dQ, ddQ = rng.uniform(-1.5, 1.5, (3, 6, 7))
    for robot in ("fer", "fr3"):
        arm = dynamics.LoadedArm(robot, **load)
        expected = np.array([arm.mass_matrix(q) @ a + arm.coriolis(q, v)
                             for q, v, a in zip(Q, dQ, ddQ, strict=True)])  # fmt: skip
        np.testing.assert_allclose(arm.motion_torques(Q, dQ, ddQ), expected, atol=1e-12)
        plain = dynamics.LoadedArm(robot, **load)
        plain._kernels = None  # the plain recursion
        np.testing.assert_allclose(plain.motion_torques(Q, dQ, ddQ), expected, atol=1e-12)
        with pytest.raises(ValueError, match="as many rows each, got 6, 5, 6"):
            arm.motion_torques(Q, dQ[:5], ddQ)
        with pytest.raises(
            ValueError, match=r"dq: expected rows of 7 joints \(N, 7\), got shape \(6, 6\)"
        ):
            arm.motion_torques(Q, dQ[:, :6], ddQ)


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_the_loaded_arm_compiled_equals_the_plain_recursion(robot, monkeypatch) -> None:
    """LoadedArm (the control loop's model terms) on numba's kernels gives the plain
    recursion's numbers, loaded or not; with the JIT off it runs the plain recursion."""
    from panda_py import dynamics

    rng = np.random.default_rng(7)
    load = {
        "m_load": 0.73,
        "F_x_Cload": [-0.01, 0.0, 0.03],
        "I_load": np.diag([1e-3, 2.5e-3, 1.7e-3]),
    }
    for kwargs in ({}, load):
        arm = dynamics.LoadedArm(robot, **kwargs)
        assert arm._kernels is not None  # numba is installed with the package here
        monkeypatch.setitem(LOADED, "panda_py.dynamics._compiled", None)
        plain = dynamics.LoadedArm(robot, **kwargs)
        monkeypatch.undo()
        assert plain._kernels is None
        for _ in range(20):
            q, dq = rng.uniform(-2.0, 2.0, 7), rng.uniform(-2.0, 2.0, 7)
            np.testing.assert_allclose(arm.coriolis(q, dq), plain.coriolis(q, dq), atol=1e-12)
            np.testing.assert_allclose(arm.gravity(q), plain.gravity(q), atol=1e-12)
            np.testing.assert_allclose(arm.mass_matrix(q), plain.mass_matrix(q), atol=1e-12)
            np.testing.assert_allclose(
                arm.coriolis(q, dq), dynamics.coriolis(q, dq, robot=robot, **kwargs), atol=1e-12
            )
