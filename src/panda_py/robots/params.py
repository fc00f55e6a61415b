"""The one source of truth for the robots' kinematic, inertial and limit parameters.

Everything else (the MuJoCo model, the URDF served on GetRobotModel, the C model library
served on LoadModelLibrary, kinematics, dynamics, trajectory limits, the simulator's safety
checks) is computed or generated from the tables in this module. Never hand-edit a
generated model: change the numbers here.

Frames follow Craig's (modified) Denavit-Hartenberg convention, which is also the frame
convention of Franka's ``franka_description`` and of libfranka's ``Frame`` enum:
``O_T_Ji = O_T_J(i-1) * RotX(alpha_i) * TransX(a_i) * RotZ(q_i) * TransZ(d_i)``.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

Vec7 = tuple[float, float, float, float, float, float, float]


class RobotKind(enum.Enum):
    """Which arm. ``FR3_PRE_5_9`` is an FR3 running a robot system older than 5.9."""

    FER = "fer"
    FR3 = "fr3"
    FR3_PRE_5_9 = "fr3-pre-5.9"


@dataclass(frozen=True)
class DH:
    """Modified (Craig) DH parameters of the seven joints plus the flange offset."""

    a: Vec7  # [m]
    d: Vec7  # [m]
    alpha: Vec7  # [rad]
    flange_d: float  # [m] joint7 -> flange (link8) along z


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits. ``dq_offset``/``ddq_decel`` describe the FR3's position-based
    velocity limit (see :func:`position_based_velocity_limits`)."""

    q_min: Vec7  # [rad]
    q_max: Vec7  # [rad]
    dq_max: Vec7  # [rad/s]
    ddq_max: Vec7  # [rad/s^2]
    dddq_max: Vec7  # [rad/s^3]
    tau_max: Vec7  # [Nm]
    dtau_max: Vec7  # [Nm/s]
    dq_offset: Vec7  # [rad/s]
    ddq_decel: Vec7  # [rad/s^2]


@dataclass(frozen=True)
class CartesianLimits:
    """Limits of the end effector's motion (translation, rotation) and of the elbow."""

    translation_velocity: float  # [m/s]
    translation_acceleration: float  # [m/s^2]
    translation_jerk: float  # [m/s^3]
    rotation_velocity: float  # [rad/s]
    rotation_acceleration: float  # [rad/s^2]
    rotation_jerk: float  # [rad/s^3]
    elbow_velocity: float  # [rad/s]
    elbow_acceleration: float  # [rad/s^2]
    elbow_jerk: float  # [rad/s^3]


@dataclass(frozen=True)
class Inertial:
    """Rigid-body inertial parameters in the body's own (DH link) frame.

    ``inertia`` is ``(ixx, iyy, izz, ixy, ixz, iyz)`` about the centre of mass [kg m^2].
    """

    mass: float  # [kg]
    com: tuple[float, float, float]  # [m]
    inertia: tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class HandSpec:
    """The Franka Hand: its TCP, inertial parameters as configured in Desk, and its stroke."""

    tcp_offset: float  # [m] flange -> TCP along z (F_T_NE translation)
    tcp_rotz: float  # [rad] rotation about z of the TCP frame relative to the flange
    inertial: Inertial  # the hand as a whole, in the flange frame (Desk's end-effector data)
    finger_mass: float  # [kg] each finger
    max_width: float  # [m] fully open
    max_speed: float  # [m/s]
    max_force: float  # [N] continuous grasp force
    peak_force: float  # [N] the most a grasp may command
    # the fingertips' rubber pads: sliding friction coefficient, torsional friction about
    # the pad's normal [m] and rolling friction [m] (MuJoCo's three friction values)
    pad_friction: tuple[float, float, float]


@dataclass(frozen=True)
class JointDrives:
    """What the joints' drives add to the links' rigid-body dynamics: the reflected rotor
    inertia (``armature``) and the joint friction, viscous and Coulomb. The simulated plant
    has them; the robot's own model does not (libfranka's ``Model.mass``, the URDF and
    the model library hold the links' inertias only, as on a real robot), so our
    ``dynamics`` and ``libfranka.Model`` leave them out too."""

    armature: Vec7  # [kg m^2] reflected rotor inertia, added to the mass matrix's diagonal
    viscous: Vec7  # [Nm s/rad]
    # [Nm] dry friction as a torque-controlling client feels it: a robot compensates its
    # joints' friction in its own controllers and, in part, under torque commands
    # ("torques without gravity and friction", libfranka's Torques); the identification
    # below was made through FCI torque commands, so this is what is left of it there.
    coulomb: Vec7


@dataclass(frozen=True)
class RobotSpec:
    """Everything the library knows about one kind of arm."""

    kind: RobotKind
    name: str
    dh: DH
    joints: JointLimits
    cartesian: CartesianLimits
    links: tuple[Inertial, ...]  # link0 (base) .. link7
    elbow_flip_q: float  # [rad] q_elbow-flip of the control parameters page
    default_K_theta: Vec7  # [Nm/rad] joint impedance after power-up
    default_K_x: tuple[float, float, float, float, float, float]  # [N/m, Nm/rad]
    drives: JointDrives  # the simulated plant's armature and friction
    # The FCI protocol versions its robot systems speak (a robot speaks one; a simulated
    # robot accepts any of these). Source: libfranka's compatibility matrix.
    protocol_versions: tuple[int, ...]


def _t7(*values: float) -> Vec7:
    if len(values) != 7:
        raise ValueError(f"expected 7 values, got {len(values)}")
    return (values[0], values[1], values[2], values[3], values[4], values[5], values[6])


# DH parameters, identical on FER and FR3. Source: Franka FCI documentation, "Robot and
# interface specifications" / control parameters page (Craig convention).
DH_FRANKA = DH(
    a=_t7(0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088),
    d=_t7(0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0),
    alpha=_t7(0.0, -math.pi / 2, math.pi / 2, math.pi / 2, -math.pi / 2, math.pi / 2, math.pi / 2),
    flange_d=0.107,
)

# Link inertial parameters, link0..link7, in the DH link frames. Source: C. Gaz,
# M. Cognetti, A. Oliva, P. Robuffo Giordano, A. De Luca, "Dynamic Identification of the
# Franka Emika Panda Robot With Retrieval of Feasible Parameters Using Penalty-Based
# Optimization", IEEE RA-L 4(4), 2019, as published in Franka's franka_description
# (the link0 values are franka_description's own). Link 7 excludes the hand.
LINKS_FRANKA: tuple[Inertial, ...] = (
    Inertial(0.629769, (-0.041018, -0.00014, 0.049974), (0.00315, 0.00388, 0.004285, 8.2904e-7, 0.00015, 8.2299e-6)),  # noqa: E501
    Inertial(4.970684, (0.003875, 0.002081, -0.04762), (0.70337, 0.70661, 0.009117, -0.000139, 0.006772, 0.019169)),  # noqa: E501
    Inertial(0.646926, (-0.003141, -0.02872, 0.003495), (0.007962, 0.02811, 0.025995, -0.003925, 0.010254, 0.000704)),  # noqa: E501
    Inertial(3.228604, (0.027518, 0.039252, -0.066502), (0.037242, 0.036155, 0.01083, -0.004761, -0.011396, -0.012805)),  # noqa: E501
    Inertial(3.587895, (-0.05317, 0.104419, 0.027454), (0.025853, 0.019552, 0.028323, 0.007796, -0.001332, 0.008641)),  # noqa: E501
    Inertial(1.225946, (-0.011953, 0.041065, -0.038437), (0.035549, 0.029474, 0.008627, -0.002117, -0.004037, 0.000229)),  # noqa: E501
    Inertial(1.666555, (0.060149, -0.014117, -0.010517), (0.001964, 0.004354, 0.005433, 0.000109, -0.001158, 0.000341)),  # noqa: E501
    Inertial(0.735522, (0.010517, -0.004252, 0.061597), (0.012516, 0.010027, 0.004815, -0.000428, -0.001196, -0.000741)),  # noqa: E501
)  # fmt: skip

# Franka Hand. TCP 0.1034 m below the flange, rotated -45 deg about z (Franka Hand data
# sheet; libfranka's F_T_NE with the hand configured in Desk). The inertial parameters
# are Desk's defaults for the hand as reported in RobotState (m_ee, F_x_Cee, I_ee).
FRANKA_HAND = HandSpec(
    tcp_offset=0.1034,
    tcp_rotz=-math.pi / 4,
    inertial=Inertial(0.73, (-0.01, 0.0, 0.03), (0.001, 0.0025, 0.0017, 0.0, 0.0, 0.0)),
    finger_mass=0.015,
    max_width=0.08,  # [m] Franka Hand data sheet: 80 mm stroke
    max_speed=0.1,  # [m/s] libfranka Gripper::move documentation (max 0.1 m/s)
    max_force=70.0,  # [N] Franka Hand data sheet: 70 N continuous, 140 N peak
    peak_force=140.0,  # [N] Franka Hand data sheet
    # Rubber pads on the fingertips: sliding friction ~1 (rubber on dry wood, plastic or
    # metal: 0.6-1.2, engineering tables), torsional friction of a ~2 cm patch under
    # uniform pressure (2/3 of its radius times the coefficient: 2/3 * 0.01 m * 1), rolling
    # friction MuJoCo's default (the pads' contacts do not use it). A judgement: Franka
    # publishes no friction values for the pads.
    pad_friction=(1.0, 0.0067, 0.0001),
)
"""The Franka Hand: its TCP, inertial parameters, stroke, speed and force limits and finger
friction (sources beside each value)."""

_TAU_MAX = _t7(87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)  # [Nm] FCI docs, both robots
_DTAU_MAX = _t7(*([1000.0] * 7))  # [Nm/s] FCI docs, both robots

# FER joint limits. Source: FCI docs control-parameters-joint-panda.csv.
# The FER publishes no position-based velocity limit; for the URDF element libfranka
# requires, the offset is 0 and the deceleration is the joint's acceleration limit
# (our choice: a limit that stops the joint at its position limit with ddq_max).
_FER_JOINTS = JointLimits(
    q_min=_t7(-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973),
    q_max=_t7(2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973),
    dq_max=_t7(2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100),
    ddq_max=_t7(15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
    dddq_max=_t7(7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0),
    tau_max=_TAU_MAX,
    dtau_max=_DTAU_MAX,
    dq_offset=_t7(*([0.0] * 7)),
    ddq_decel=_t7(15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
)

# FR3 (robot system >= 5.9, data sheet). Source: FCI docs control-parameters-joint-fr3.csv,
# including the position-based velocity limit's offset and deceleration.
_FR3_JOINTS = JointLimits(
    q_min=_t7(-2.9007, -1.8361, -2.9007, -3.0770, -2.8763, 0.4398, -3.0508),
    q_max=_t7(2.9007, 1.8361, 2.9007, -0.1169, 2.8763, 4.6216, 3.0508),
    dq_max=_t7(2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26),
    ddq_max=_t7(*([10.0] * 7)),
    dddq_max=_t7(*([5000.0] * 7)),
    tau_max=_TAU_MAX,
    dtau_max=_DTAU_MAX,
    dq_offset=_t7(0.6599, 0.2517, 0.2000, 0.3533, 0.5757, 0.4878, 0.4628),
    ddq_decel=_t7(6.0, 2.585, 3.5, 4.0, 17.0, 5.5, 17.0),
)

# FR3 before robot system 5.9 (panda-py's JOINT_LIMITS_*_FR3). Source: FCI docs, FR3
# joint limits as published before system 5.9; velocity/acceleration/jerk as above.
_FR3_PRE_5_9_JOINTS = JointLimits(
    q_min=_t7(-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159),
    q_max=_t7(2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159),
    dq_max=_FR3_JOINTS.dq_max,
    ddq_max=_FR3_JOINTS.ddq_max,
    dddq_max=_FR3_JOINTS.dddq_max,
    tau_max=_TAU_MAX,
    dtau_max=_DTAU_MAX,
    dq_offset=_FR3_JOINTS.dq_offset,
    ddq_decel=_FR3_JOINTS.ddq_decel,
)

# Cartesian limits. Source: frankarobotics docs source/control_parameters.rst.
_FER_CARTESIAN = CartesianLimits(1.7, 13.0, 6500.0, 2.5, 25.0, 12500.0, 2.175, 10.0, 5000.0)
_FR3_CARTESIAN = CartesianLimits(3.0, 9.0, 4500.0, 2.5, 17.0, 8500.0, 2.62, 10.0, 5000.0)

# q_elbow-flip, both robots. Source: control_parameters.rst.
_ELBOW_FLIP_Q = -0.467002423653011

# Power-up impedances: libfranka's examples set these values and Desk reports them as the
# defaults (K_theta [Nm/rad], K_x translational [N/m] and rotational [Nm/rad]).
_DEFAULT_K_THETA = _t7(3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0)
_DEFAULT_K_X = (3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0)

# The FR3's drives, identified in torque control: MuJoCo Menagerie's franka_fr3/fr3.xml
# (google-deepmind/mujoco_menagerie, "update armature, damping, friction parameters,
# identified in torque control", 2025-04-25): armature 0.195 kg m^2 on joints 1-4 and
# 0.074 on 5-7, viscous 0.21 Nm s/rad, Coulomb 1.137 Nm on joints 1-4, then 0.763, 0.44,
# 0.248 Nm. Without them joint 7's inertia at the start pose is 0.0067 kg m^2, and
# pylibfranka's joint impedance example (damping 2 sqrt(k) at 1 ms) diverges on the wrist.
_FR3_DRIVES = JointDrives(
    armature=_t7(0.195, 0.195, 0.195, 0.195, 0.074, 0.074, 0.074),
    viscous=_t7(0.21, 0.21, 0.21, 0.21, 0.21, 0.21, 0.21),
    coulomb=_t7(1.137, 1.137, 1.137, 1.137, 0.763, 0.44, 0.248),
)
# The FER's Coulomb friction from the same identification as its link parameters above
# (Gaz et al., RA-L 2019): their sigmoid model phi1 / (1 + exp(-phi2 (dq + phi3))) - const
# saturates at about phi1 / 2 either way, phi1 = 0.54615, 0.87224, 0.64068, 1.2794,
# 0.83904, 0.30301, 0.56489 Nm. Its rotor inertia and viscous friction are not published:
# the FR3's identified values stand in for them (the same family of drives).
_FER_DRIVES = JointDrives(
    armature=_FR3_DRIVES.armature,
    viscous=_FR3_DRIVES.viscous,
    coulomb=_t7(0.273, 0.436, 0.320, 0.640, 0.420, 0.152, 0.282),
)

# Which FCI protocol each robot system speaks. Source: libfranka docs/compatibility_matrix.rst
# (robot/gripper server versions): FER systems 3.0-4.1 speak 3 and 4, 4.2.x speaks 5 (the
# FER's last); FR3 systems 5.2-5.7 speak 6-9; 5.9 and later speak 10 (with the wider joint
# limits above).
_FER_PROTOCOLS = (3, 4, 5)
_FR3_PRE_5_9_PROTOCOLS = (6, 7, 8, 9)
_FR3_PROTOCOLS = (10,)

FER = RobotSpec(
    kind=RobotKind.FER,
    name="fer",
    dh=DH_FRANKA,
    joints=_FER_JOINTS,
    cartesian=_FER_CARTESIAN,
    links=LINKS_FRANKA,
    elbow_flip_q=_ELBOW_FLIP_Q,
    default_K_theta=_DEFAULT_K_THETA,
    default_K_x=_DEFAULT_K_X,
    drives=_FER_DRIVES,
    protocol_versions=_FER_PROTOCOLS,
)
"""The Franka Emika Robot (FER, "Panda"), robot systems 3.0-4.2.x, protocol versions 3-5."""

# The FR3 carries the same published link inertial parameters: Franka publishes no
# separate identified set for it, and its kinematics are identical (DH above).
FR3 = RobotSpec(
    kind=RobotKind.FR3,
    name="fr3",
    dh=DH_FRANKA,
    joints=_FR3_JOINTS,
    cartesian=_FR3_CARTESIAN,
    links=LINKS_FRANKA,
    elbow_flip_q=_ELBOW_FLIP_Q,
    default_K_theta=_DEFAULT_K_THETA,
    default_K_x=_DEFAULT_K_X,
    drives=_FR3_DRIVES,
    protocol_versions=_FR3_PROTOCOLS,
)
"""The Franka Research 3 with robot system 5.9 or later (the data sheet's wider joint limits),
protocol version 10."""

FR3_PRE_5_9 = RobotSpec(
    kind=RobotKind.FR3_PRE_5_9,
    name="fr3-pre-5.9",
    dh=DH_FRANKA,
    joints=_FR3_PRE_5_9_JOINTS,
    cartesian=_FR3_CARTESIAN,
    links=LINKS_FRANKA,
    elbow_flip_q=_ELBOW_FLIP_Q,
    default_K_theta=_DEFAULT_K_THETA,
    default_K_x=_DEFAULT_K_X,
    drives=_FR3_DRIVES,
    protocol_versions=_FR3_PRE_5_9_PROTOCOLS,
)
"""The Franka Research 3 with a robot system from 5.2 to 5.7.x (narrower joint limits), protocol
versions 6-9."""

ROBOTS: dict[str, RobotSpec] = {
    "fer": FER,
    "panda": FER,
    "fr3": FR3,
    "fr3-pre-5.9": FR3_PRE_5_9,
}
"""The robots by name (``"fer"`` and its alias ``"panda"``, ``"fr3"``, ``"fr3-pre-5.9"``);
:func:`get_robot` looks names up here."""

START_POSE: Vec7 = _t7(0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)
"""panda-py's start pose (``Panda.move_to_start``) [rad]."""

GRAVITY = (0.0, 0.0, -9.81)
"""Standard gravity as libfranka reports it in ``O_ddP_O`` [m/s^2]."""


def get_robot(robot: str | RobotKind | RobotSpec = "fer") -> RobotSpec:
    """Look a robot up by name (``"fer"``/``"panda"``, ``"fr3"``, ``"fr3-pre-5.9"``)."""
    if isinstance(robot, RobotSpec):
        return robot
    if isinstance(robot, RobotKind):
        robot = robot.value
    if not isinstance(robot, str):
        raise ValueError(f"robot: expected a name in {sorted(ROBOTS)}, got {robot!r}")
    spec = ROBOTS.get(robot.lower())
    if spec is None:
        raise ValueError(f"robot: expected one of {sorted(ROBOTS)}, got {robot!r}")
    return spec


def robot_for_protocol(version: int) -> RobotSpec:
    """The robot whose systems speak FCI protocol ``version`` (as panda-py picks its joint
    limits): 3-5 the FER, 6-9 an FR3 before system 5.9, 10 an FR3 on 5.9 or later."""
    for spec in (FER, FR3_PRE_5_9, FR3):
        if version in spec.protocol_versions:
            return spec
    known = sorted({v for spec in ROBOTS.values() for v in spec.protocol_versions})
    raise ValueError(f"version: expected an FCI protocol version in {known}, got {version!r}")


def position_based_velocity_limits(spec: RobotSpec, q: object) -> tuple[list[float], list[float]]:
    """The joint velocity limits at position ``q`` as libfranka >= 0.18 computes them
    (``Robot::getUpper/LowerJointVelocityLimits``) [rad/s]:
    ``upper = min(dq_max, max(0, -offset + sqrt(max(0, 2 decel (q_max - q)))))`` and the
    mirror image for the lower limit."""
    j = spec.joints
    qs = [float(v) for v in q]  # type: ignore[attr-defined]
    if len(qs) != 7:
        raise ValueError(f"q: expected 7 joint positions, got {len(qs)}")
    upper, lower = [], []
    for i, qi in enumerate(qs):
        up = -j.dq_offset[i] + math.sqrt(max(0.0, 2.0 * j.ddq_decel[i] * (j.q_max[i] - qi)))
        lo = -j.dq_offset[i] + math.sqrt(max(0.0, 2.0 * j.ddq_decel[i] * (qi - j.q_min[i])))
        upper.append(min(j.dq_max[i], max(0.0, up)))
        lower.append(-min(j.dq_max[i], max(0.0, lo)))
    return upper, lower
