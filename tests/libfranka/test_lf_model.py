"""Model: frames against the URDF the simulator serves, Jacobians against finite
differences, dynamics against panda_py.dynamics with libfranka's combined load."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from panda_py import dynamics
from panda_py import libfranka as lf
from panda_py.libfranka.state import combine_load
from panda_py.robots import FER, FR3
from panda_py.robots.urdf import robot_urdf

F = lf.Frame


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _urdf_link_poses(robot: str, q: np.ndarray) -> dict[str, np.ndarray]:
    """Poses of link1..link8 by walking the served URDF (an independent reading)."""
    root = ET.fromstring(robot_urdf(robot))
    poses = {"link0": np.eye(4)}
    for joint in root.iter("joint"):
        origin = joint.find("origin")
        assert origin is not None
        xyz = [float(v) for v in origin.get("xyz", "0 0 0").split()]
        rpy = [float(v) for v in origin.get("rpy", "0 0 0").split()]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = _rpy(*rpy), xyz
        if joint.get("type") == "revolute":
            i = int(joint.get("name", "")[-1]) - 1
            c, s = math.cos(q[i]), math.sin(q[i])
            Rz = np.eye(4)
            Rz[:2, :2] = [[c, -s], [s, c]]
            T = T @ Rz
        parent = joint.find("parent").get("link")  # type: ignore[union-attr]
        child = joint.find("child").get("link")  # type: ignore[union-attr]
        poses[child] = poses[parent] @ T
    return poses


def _T(flat: np.ndarray) -> np.ndarray:
    return np.asarray(flat).reshape(4, 4, order="F")


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_frames_equal_the_served_urdf(robot):
    rng = np.random.default_rng(10)
    model = lf.Model(robot)
    spec = FER if robot == "fer" else FR3
    for _ in range(10):
        q = rng.uniform(spec.joints.q_min, spec.joints.q_max)
        links = _urdf_link_poses(robot, q)
        for i in range(7):
            np.testing.assert_allclose(_T(model.pose(F(i), q)), links[f"link{i + 1}"], atol=1e-12)
        np.testing.assert_allclose(_T(model.pose(F.kFlange, q)), links["link8"], atol=1e-12)


def test_end_effector_and_stiffness_frames_compose_F_T_EE_and_EE_T_K():
    rng = np.random.default_rng(11)
    model = lf.Model("fer")
    q = rng.uniform(FER.joints.q_min, FER.joints.q_max)
    F_T_EE = np.eye(4)
    F_T_EE[:3, :3] = _rpy(0, 0, -math.pi / 4)
    F_T_EE[2, 3] = 0.1034
    EE_T_K = np.eye(4)
    EE_T_K[:3, 3] = (0.01, 0.02, 0.03)
    flange = _T(model.pose(F.kFlange, q))
    ee = _T(model.pose(F.kEndEffector, q, F_T_EE.reshape(16, order="F"), EE_T_K))
    k = _T(model.pose(F.kStiffness, q, F_T_EE, EE_T_K))
    np.testing.assert_allclose(ee, flange @ F_T_EE, atol=1e-12)
    np.testing.assert_allclose(k, flange @ F_T_EE @ EE_T_K, atol=1e-12)


def _rotvec(R: np.ndarray) -> np.ndarray:
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2)))
    if angle < 1e-12:
        return np.zeros(3)
    return (
        angle
        / (2 * math.sin(angle))
        * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    )


@pytest.mark.parametrize("frame", list(F))
def test_jacobians_match_finite_differences(frame):
    rng = np.random.default_rng(12)
    model = lf.Model("fr3")
    q = rng.uniform(FR3.joints.q_min, FR3.joints.q_max)
    F_T_EE = np.eye(4)
    F_T_EE[:3, 3] = (0.0, 0.05, 0.1)
    EE_T_K = np.eye(4)
    EE_T_K[:3, 3] = (0.02, 0.0, 0.0)
    args = (F_T_EE, EE_T_K)
    J = model.zero_jacobian(frame, q, *args).reshape(6, 7, order="F")
    T0 = _T(model.pose(frame, q, *args))
    h = 1e-7
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = h
        T1 = _T(model.pose(frame, q + dq, *args))
        np.testing.assert_allclose(J[:3, i], (T1[:3, 3] - T0[:3, 3]) / h, atol=2e-6)
        np.testing.assert_allclose(J[3:, i], _rotvec(T1[:3, :3] @ T0[:3, :3].T) / h, atol=2e-6)
    Jb = model.body_jacobian(frame, q, *args).reshape(6, 7, order="F")
    R = T0[:3, :3]
    np.testing.assert_allclose(Jb, np.vstack((R.T @ J[:3], R.T @ J[3:])), atol=1e-12)


def test_combined_load_is_what_the_dynamics_of_two_loads_add_up_to():
    """Inertial parameters enter the dynamics linearly, so end effector and payload as one
    body (libfranka's m_total, F_x_Ctotal, I_total) must equal their sum."""
    rng = np.random.default_rng(13)
    model = lf.Model("fer")
    q = rng.uniform(FER.joints.q_min, FER.joints.q_max)
    dq = rng.normal(0, 1, 7)
    A = rng.normal(size=(3, 3))
    I_ee, I_load = np.diag([0.001, 0.0025, 0.0017]), 0.002 * np.eye(3) + 1e-4 * (A + A.T)
    ee = (0.73, np.array([-0.01, 0.0, 0.03]), I_ee)
    load = (0.5, np.array([0.02, -0.01, 0.08]), I_load)
    m, c, inertia = combine_load(ee[0], ee[1], I_ee.reshape(9), load[0], load[1], I_load)

    def dyn(fn, *a, with_inertia=True):
        def one(mass, com, I):
            kw = {"m_load": mass, "F_x_Cload": com, "robot": "fer"}
            if with_inertia:
                kw["I_load"] = I
            return fn(*a, **kw)

        return one(*ee) + one(*load) - one(0.0, np.zeros(3), np.zeros((3, 3)))

    np.testing.assert_allclose(
        model.mass(q, inertia, m, c).reshape(7, 7), dyn(dynamics.mass_matrix, q), atol=1e-12
    )
    np.testing.assert_allclose(
        model.coriolis(q, dq, inertia, m, c), dyn(dynamics.coriolis, q, dq), atol=1e-12
    )
    np.testing.assert_allclose(
        model.gravity(q, m, c), dyn(dynamics.gravity, q, with_inertia=False), atol=1e-12
    )
    g = model.gravity(q, m, c, [0.0, 0.0, -9.81 * 2])
    np.testing.assert_allclose(g, 2 * model.gravity(q, m, c), atol=1e-12)


def test_model_validates_its_inputs():
    model = lf.Model("fer")
    with pytest.raises(ValueError, match="frame"):
        model.pose(12, np.zeros(7))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"q: expected shape \(7,\)"):
        model.pose(F.kFlange, np.zeros(6))
    with pytest.raises(ValueError, match="m_total"):
        model.gravity(np.zeros(7), -1.0, np.zeros(3))
    with pytest.raises(ValueError, match="F_x_Ctotal"):
        model.mass(np.zeros(7), np.zeros(9), 1.0, [0, 0, np.nan])
