import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

from panda_py import dynamics
from panda_py.robots.params import FER, FR3, FR3_PRE_5_9, RobotSpec
from panda_py.robots.urdf import robot_urdf

SPECS = [FER, FR3, FR3_PRE_5_9]
TOL_FK = 1e-12  # [m] / rotation-matrix entries


def _rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _trans(x, y, z):
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _dh_frames(spec: RobotSpec, q):
    """O_T_J1..O_T_J7 and the flange by the modified-DH product."""
    dh, T, out = spec.dh, np.eye(4), []
    for i in range(7):
        T = T @ _rot_x(dh.alpha[i]) @ _trans(dh.a[i], 0, 0) @ _rot_z(q[i]) @ _trans(0, 0, dh.d[i])
        out.append(T)
    out.append(T @ _trans(0, 0, dh.flange_d))
    return out


def _floats(text):
    return [float(v) for v in text.split()]


def _urdf_origin(joint):
    origin = joint.find("origin")
    x, y, z = _floats(origin.get("xyz"))
    r, p, yw = _floats(origin.get("rpy"))
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(yw),
        math.sin(yw),
    )
    T = _trans(x, y, z)
    # URDF: R = Rz(yaw) Ry(pitch) Rx(roll)
    T[:3, :3] = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    return T


def _urdf_frames(root, q):
    """Poses of link1..link8 by walking the URDF's joints from link0."""
    joints = {j.find("parent").get("link"): j for j in root.findall("joint")}
    T, link, poses = np.eye(4), "link0", {}
    while link in joints:
        j = joints[link]
        T = T @ _urdf_origin(j)
        if j.get("type") == "revolute":
            assert _floats(j.find("axis").get("xyz")) == [0.0, 0.0, 1.0]
            T = T @ _rot_z(q[int(j.get("name")[-1]) - 1])
        link = j.find("child").get("link")
        poses[link] = T
    return [poses[f"link{i}"] for i in range(1, 9)]


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: s.name)
def test_urdf_frames_equal_dh_frames(spec):
    root = ET.fromstring(robot_urdf(spec))
    rng = np.random.default_rng(11)
    for _ in range(20):
        q = rng.uniform(-math.pi, math.pi, 7)
        for T_urdf, T_dh in zip(_urdf_frames(root, q), _dh_frames(spec, q), strict=True):
            np.testing.assert_allclose(T_urdf, T_dh, rtol=0, atol=TOL_FK)


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: s.name)
def test_libfranka_requirements_present(spec):
    root = ET.fromstring(robot_urdf(spec))
    assert root.tag == "robot"
    assert root.get("name") == ("fer" if spec is FER else "fr3")
    links = {link.get("name") for link in root.findall("link")}
    assert links == {f"link{i}" for i in range(9)}
    joints = {j.get("name"): j for j in root.findall("joint")}
    lim = spec.joints
    for i in range(7):
        j = joints[f"joint{i + 1}"]
        assert j.get("type") == "revolute"
        limit = j.find("limit")
        assert float(limit.get("lower")) == lim.q_min[i]
        assert float(limit.get("upper")) == lim.q_max[i]
        assert float(limit.get("velocity")) == lim.dq_max[i]
        assert float(limit.get("effort")) == lim.tau_max[i]
        pbvl = j.find("position_based_velocity_limits")
        assert float(pbvl.get("velocity_offset")) == lim.dq_offset[i]
        assert float(pbvl.get("deceleration_limit")) == lim.ddq_decel[i]
    flange = joints["joint8"]
    assert flange.get("type") == "fixed"
    assert (flange.find("parent").get("link"), flange.find("child").get("link")) == (
        "link7",
        "link8",
    )


def test_inertials_equal_params():
    root = ET.fromstring(robot_urdf("fer"))
    links = {link.get("name"): link for link in root.findall("link")}
    for i, expected in enumerate(FER.links):
        inertial = links[f"link{i}"].find("inertial")
        assert float(inertial.find("mass").get("value")) == expected.mass
        assert _floats(inertial.find("origin").get("xyz")) == list(expected.com)
        assert _floats(inertial.find("origin").get("rpy")) == [0.0, 0.0, 0.0]
        el = inertial.find("inertia")
        got = tuple(float(el.get(k)) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz"))
        assert got == expected.inertia
    assert links["link8"].find("inertial") is None


def test_mujoco_loads_the_urdf_and_agrees_with_dynamics():
    # An independent URDF consumer: MuJoCo's importer builds the same rigid-body model.
    model = mujoco.MjModel.from_xml_string(robot_urdf("fr3"))
    data = mujoco.MjData(model)
    assert model.nq == 7
    rng = np.random.default_rng(12)
    for _ in range(3):
        q = rng.uniform(-2.0, 2.0, 7)
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        M = np.zeros((7, 7))
        mujoco.mj_fullM(model, data, M)
        np.testing.assert_allclose(M, dynamics.mass_matrix(q, robot="fr3"), rtol=0, atol=1e-10)
        np.testing.assert_allclose(
            data.qfrc_bias, dynamics.gravity(q, robot="fr3"), rtol=0, atol=1e-10
        )


def test_rejects_unknown_robot():
    with pytest.raises(ValueError, match="robot"):
        robot_urdf("kuka")
