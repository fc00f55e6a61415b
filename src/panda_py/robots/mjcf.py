"""Generate the simulator's MuJoCo model (MJCF) from the parameter tables.

Bodies follow the modified-DH link frames of :mod:`panda_py.robots.params`, so a body's
pose in MuJoCo equals ``O_T_Ji`` and link inertials go in unchanged. Gravity is
compensated on every robot body (``gravcomp``), as the real robot compensates the arm's
and the configured end effector's weight; a grasped object or contact forces are not.

Collision geometry is a coarse capsule approximation of each link (no meshes ship with
the package): enough for contact with the table and the cube, not for visual fidelity.
Arm bodies do not collide with each other.

Names (stable, used by the simulator and tests): joints ``joint1..joint7``,
``finger_joint1``/``finger_joint2``; bodies ``link0..link7``, ``hand``, ``left_finger``,
``right_finger``, ``cube``; sites ``flange`` and ``tcp``; geoms ``table``, ``left_pad``,
``right_pad``, ``cube_geom``; the fingers' tendon ``finger_width`` (their opening) and its
actuator ``finger_motor`` (the force the fingers squeeze with, positive opens).

With the Cobot Pump instead of the hand (``end_effector="cobot_pump"``): the body
``cobot_pump`` with the geoms ``pump_housing``, ``pump_stem`` and ``cup_geom`` (the suction
cup, its face at the TCP), and for every free body of the scene (the cube, and the named
free bodies of ``extra``) an inactive weld ``hold_<body>`` between the pump and that body,
which the simulated pump activates while its vacuum holds the body.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

from panda_py.robots.end_effectors import COBOT_PUMP, EndEffector, get_end_effector
from panda_py.robots.params import FRANKA_HAND, RobotSpec, get_robot

if TYPE_CHECKING:
    import mujoco

# Contact filtering bits: the world (table) has type 1, the robot type 2; the arm never
# collides with itself but does with the table and free objects.
_WORLD = 'contype="1" conaffinity="2"'
_ROBOT = 'contype="2" conaffinity="1"'
_OBJECT = 'contype="1" conaffinity="3"'

# Coarse collision capsules per link, in the link's DH frame: (from, to, radius) [m].
_Capsule = tuple[tuple[float, float, float], tuple[float, float, float], float]
_LINK_CAPSULES: dict[int, list[_Capsule]] = {
    1: [((0, 0, -0.19), (0, 0, -0.02), 0.06)],
    2: [((0, 0, -0.05), (0, 0, 0.05), 0.06), ((0, -0.03, 0), (0, -0.2, 0), 0.06)],
    3: [((0, 0, -0.12), (0, 0, -0.02), 0.06), ((0.0, 0, 0), (0.0825, 0, 0), 0.055)],
    4: [((0, 0, -0.05), (0, 0, 0.05), 0.055), ((0, 0.03, 0), (-0.0825, 0.12, 0), 0.055)],
    5: [((0, 0, -0.26), (0, 0, -0.1), 0.05), ((0, 0.07, -0.08), (0, 0.07, -0.02), 0.035)],
    6: [((0, 0, -0.04), (0, 0, 0.02), 0.05), ((0.02, 0, 0), (0.088, 0, 0), 0.045)],
    7: [((0, 0, -0.01), (0, 0, 0.08), 0.04)],
}  # fmt: skip

# The cube the default scene offers to grasp: 4 cm edge, 100 g, on the table in reach.
CUBE_SIZE = 0.04  # [m] edge length
CUBE_MASS = 0.1  # [kg]
CUBE_POSITION = (0.5, 0.0, CUBE_SIZE / 2)  # [m] resting on the table top (z = 0)
TABLE_TOP_Z = 0.0  # [m] the robot stands on the table top

# Finger pad geometry in the hand frame (TCP frame orientation): half sizes [m].
_PAD_HALF = (0.009, 0.006, 0.018)
_PAD_CENTER_Z = FRANKA_HAND.tcp_offset - 0.012  # pads reach 6 mm past the TCP


def _f(x: float) -> str:
    return repr(float(x))


def _vec(v: tuple[float, ...] | list[float]) -> str:
    return " ".join(_f(x) for x in v)


def _inertial(mass: float, com: tuple[float, ...], inertia: tuple[float, ...]) -> str:
    return f'<inertial pos="{_vec(com)}" mass="{_f(mass)}" fullinertia="{_vec(inertia)}"/>'


# The fingers' closed and open stops are hard: the stiffest constraint MuJoCo keeps stable
# at 1 ms (time constant 2 steps, MuJoCo's "refsafe" floor; impedance 0.9999 once 0.1 mm
# in), so 140 N on closed fingers pushes them 0.04 mm each past their stop, where the
# default (0.02 s, 0.95) let 60 N push them 5 mm through each other. The coupling of the two
# fingers (one motor, a rack) is as stiff.
_HARD = 'solref="0.002 1" solimp="0.99 0.9999 0.0001"'
_STOP = 'solreflimit="0.002 1" solimplimit="0.99 0.9999 0.0001"'
# The joints' dry friction as MuJoCo's friction constraint, as stiff as it keeps stable at
# 1 ms (time constant 2 steps): a joint held at 80 % of its Coulomb level creeps 14 urad
# in 0.6 s (MuJoCo's default softness let it creep 1.4 mrad).
_DRY_FRICTION = 'solreffriction="0.002 1" solimpfriction="0.99 0.9999 0.001"'
# The pads' contacts: rubber on a stiff object, as hard as the stops (a soft contact let
# the pads sink 1.6 mm each into the cube, and MuJoCo's friction is soft by the same
# impedance: its creep speed falls with 1 - d, so a held cube slid out within seconds).
# priority: the pad's friction and contact dimensions decide its contacts, whatever the
# object's; condim 4 adds torsional friction about the pad's normal (a patch, not a
# point), so an object held by one contact point cannot spin in the fingers. Measured
# with the scene's cube (lift, move_to_start, 10 cm moves, 30 s): it stays within 1 mm of
# the hand at 2-140 N, slides 14 mm at 0.6 N and drops at 0.3 N (friction 2 x 0.3 N <
# its weight); condim 6 holds no better and costs more.
_PAD = f'priority="1" condim="4" {_HARD}'
# The table's contacts, with whatever touches it (the fingertips, the hand, the links, a
# held or a free object): the higher priority, so its parameters decide them. An arm
# stopped by a surface is stopped through a chain of compliances a rigid-joint plant lacks:
# the joints' harmonic drives and torque sensors (between the rotors' reflected inertia, a
# quarter to a third of the arm's effective mass at the hand, and the links), the
# fingertips, the table top. On a Panda they spread an impact over tens of milliseconds
# into a damped oscillation (I. Aouaj, V. Padois, A. Saccon, "Predicting the Post-Impact
# Velocity of a Robotic Arm via Rigid Multibody Models: an Experimental Study", arXiv:2010.08220),
# and a viscoelastic (spring-damper) contact model fits its measured impact forces best (Y.
# Wang, N. Dehio, A. Kheddar, "On Inverse Inertia Matrix and Contact-Force Model for
# Robotic Manipulators at Normal Impacts", IEEE RA-L 7(2), 2022). The table stands for that
# chain with MuJoCo's default time constant: a critically damped spring-damper of 20 ms
# (about 33 kN/m for the hand's 13 kg effective mass, its fingertips sticking, 4 cm above
# the table at x = 0.45 m, y = 0.25 m), impedance 0.99 at once so that a steady push finds
# the surface firm. Franka publishes no such figure: a judgement, and the reason the pads'
# 2 ms (made for holding objects) no longer decide their contacts with the table. Its
# friction and contact dimensions keep those that decided the cube's contacts with it
# before (MuJoCo's maximum of the two geoms').
_TABLE = (
    'priority="2" condim="4" friction="1.5 0.01 0.001" solref="0.02 1" solimp="0.99 0.99 0.001"'
)


def _hand_xml() -> str:
    h = FRANKA_HAND
    half = h.max_width / 2
    rot = h.tcp_rotz
    quat = (math.cos(rot / 2), 0.0, 0.0, math.sin(rot / 2))
    pad = _vec(_PAD_HALF)
    friction = _vec(h.pad_friction)
    finger_inertia = _vec((1e-6, 1e-6, 1e-6, 0, 0, 0))
    return f"""
        <body name="hand" pos="0 0 0" gravcomp="1">
          {_inertial(h.inertial.mass, h.inertial.com, h.inertial.inertia)}
          <body name="hand_frame" quat="{_vec(quat)}">
            <geom name="hand_geom" type="box" size="0.025 0.1 0.03" pos="0 0 0.035"
                  {_ROBOT} rgba="0.9 0.9 0.9 1"/>
            <site name="tcp" pos="0 0 {_f(h.tcp_offset)}" size="0.005"/>
            <body name="left_finger" gravcomp="1">
              <inertial pos="0 0.01 {_f(_PAD_CENTER_Z)}" mass="{_f(h.finger_mass)}"
                        fullinertia="{finger_inertia}"/>
              <joint name="finger_joint1" type="slide" axis="0 1 0" range="0 {_f(half)}"
                     damping="2" armature="0.1" {_STOP}/>
              <geom name="left_pad" type="box" size="{pad}" {_ROBOT}
                    pos="0 {_f(_PAD_HALF[1])} {_f(_PAD_CENTER_Z)}" friction="{friction}"
                    {_PAD} rgba="0.2 0.2 0.2 1"/>
            </body>
            <body name="right_finger" gravcomp="1">
              <inertial pos="0 -0.01 {_f(_PAD_CENTER_Z)}" mass="{_f(h.finger_mass)}"
                        fullinertia="{finger_inertia}"/>
              <joint name="finger_joint2" type="slide" axis="0 -1 0" range="0 {_f(half)}"
                     damping="2" armature="0.1" {_STOP}/>
              <geom name="right_pad" type="box" size="{pad}" {_ROBOT}
                    pos="0 {_f(-_PAD_HALF[1])} {_f(_PAD_CENTER_Z)}" friction="{friction}"
                    {_PAD} rgba="0.2 0.2 0.2 1"/>
            </body>
          </body>
        </body>"""


def _hand_actuation() -> str:
    """The fingers' coupling and motor: one motor drives both fingers (a rack), pushing
    each with the motor's force, so the force on the ``finger_width`` tendon (the width,
    q1 + q2) is the force the fingers squeeze an object with (positive opens)."""
    return f"""
  <tendon>
    <fixed name="finger_width">
      <joint joint="finger_joint1" coef="1"/>
      <joint joint="finger_joint2" coef="1"/>
    </fixed>
  </tendon>
  <equality><joint joint1="finger_joint1" joint2="finger_joint2" {_HARD}/></equality>
  <actuator><motor name="finger_motor" tendon="finger_width"/></actuator>"""


def _arm_xml(spec: RobotSpec, tool: str) -> str:
    dh = spec.dh
    lim = spec.joints
    drv = spec.drives
    # Open the nested bodies link1..link7; each body frame is the DH frame J_i, so the
    # fixed part of the DH step (RotX(alpha) TransX(a) TransZ(d)) is the body's pose in
    # its parent and RotZ(q) is the hinge about the body's own z axis.
    parts: list[str] = []
    for i in range(7):
        alpha, a, d = dh.alpha[i], dh.a[i], dh.d[i]
        pos = (a, -math.sin(alpha) * d, math.cos(alpha) * d)
        quat = (math.cos(alpha / 2), math.sin(alpha / 2), 0.0, 0.0)
        link = spec.links[i + 1]
        geoms = "".join(
            f'<geom type="capsule" fromto="{_vec(p0 + p1)}" size="{_f(r)}" {_ROBOT}'
            f' rgba="0.95 0.95 0.95 1"/>'
            for p0, p1, r in _LINK_CAPSULES[i + 1]
        )
        parts.append(
            f'<body name="link{i + 1}" pos="{_vec(pos)}" quat="{_vec(quat)}" gravcomp="1">'
            f"{_inertial(link.mass, link.com, link.inertia)}"
            f'<joint name="joint{i + 1}" axis="0 0 1"'
            f' range="{_f(lim.q_min[i])} {_f(lim.q_max[i])}"'
            f' armature="{_f(drv.armature[i])}" damping="{_f(drv.viscous[i])}"'
            f' frictionloss="{_f(drv.coulomb[i])}" {_DRY_FRICTION}/>'
            f"{geoms}"
        )
    inner = f'<site name="flange" pos="0 0 {_f(dh.flange_d)}" size="0.005"/>'
    if tool:
        inner += f'<body name="flange_body" pos="0 0 {_f(dh.flange_d)}">{tool}</body>'
    base = spec.links[0]
    return (
        f'<body name="link0">{_inertial(base.mass, base.com, base.inertia)}'
        f'<geom type="cylinder" size="0.07 0.07" pos="0 0 0.07" {_ROBOT}/>'
        + "".join(parts)
        + inner
        + "</body>" * 7
        + "</body>"
    )


# The weld that holds a sucked part: as stiff as MuJoCo keeps stable at 1 ms (a part of
# 100 g sags 0.1 mm under its weight; the default 20 ms time constant let it sag 1 mm).
_WELD = 'solref="0.004 1" solimp="0.95 0.99 0.001"'


def _pump_xml() -> str:
    """The Cobot Pump: its housing, a stem and the suction cup, whose face is the TCP."""
    p = COBOT_PUMP
    stem_top = p.housing_z + p.housing_half[2]
    cup_top = p.tcp_offset - p.cup_height
    stem_half = (cup_top - stem_top) / 2
    return f"""
        <body name="cobot_pump" pos="0 0 0" gravcomp="1">
          {_inertial(p.inertial.mass, p.inertial.com, p.inertial.inertia)}
          <geom name="pump_housing" type="box" size="{_vec(p.housing_half)}"
                pos="0 0 {_f(p.housing_z)}" {_ROBOT} rgba="0.2 0.3 0.6 1"/>
          <geom name="pump_stem" type="cylinder" size="0.008 {_f(stem_half)}"
                pos="0 0 {_f(stem_top + stem_half)}" {_ROBOT} rgba="0.7 0.7 0.7 1"/>
          <geom name="cup_geom" type="cylinder" size="{_f(p.cup_radius)} {_f(p.cup_height / 2)}"
                pos="0 0 {_f(p.tcp_offset - p.cup_height / 2)}" {_ROBOT} friction="1 0.005 0.0001"
                rgba="0.1 0.1 0.1 1"/>
          <site name="tcp" pos="0 0 {_f(p.tcp_offset)}" size="0.005"/>
        </body>"""


def _pump_welds(bodies: list[str]) -> str:
    """Inactive welds between the pump and each body it may hold."""
    welds = "".join(
        f'<weld name="hold_{b}" body1="cobot_pump" body2="{b}" active="false" {_WELD}/>'
        for b in bodies
    )
    return f"<equality>{welds}</equality>" if welds else ""


def _scene_xml(cube: bool = True) -> str:
    c = CUBE_SIZE / 2
    inertia = CUBE_MASS * CUBE_SIZE**2 / 6  # [kg m^2] solid cube
    table = f"""
    <geom name="table" type="box" size="0.8 0.8 0.02" pos="0.4 0 {_f(TABLE_TOP_Z - 0.02)}"
          {_WORLD} rgba="0.6 0.45 0.3 1" {_TABLE}/>"""
    if not cube:
        return table
    return f"""{table}
    <body name="cube" pos="{_vec(CUBE_POSITION)}">
      <freejoint name="cube_joint"/>
      <inertial pos="0 0 0" mass="{_f(CUBE_MASS)}" diaginertia="{_vec([inertia] * 3)}"/>
      <geom name="cube_geom" type="box" size="{_f(c)} {_f(c)} {_f(c)}"
            {_OBJECT} rgba="0.8 0.1 0.1 1" friction="1.5 0.01 0.001" condim="4"/>
    </body>"""


def _extra_worldbody(extra: str | Path) -> tuple[str, str, list[str]]:
    """Children of ``<worldbody>`` and ``<asset>`` from a user MJCF file, as XML text, and
    the names of its free bodies (top-level bodies with a free joint)."""
    path = Path(extra)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ValueError(f"extra: expected a readable MJCF file, got {str(path)!r}: {exc}") from exc
    if root.tag != "mujoco":
        raise ValueError(f"extra: expected an MJCF file with a <mujoco> root, got <{root.tag}>")
    bodies = "".join(
        ET.tostring(el, encoding="unicode") for wb in root.iter("worldbody") for el in wb
    )
    assets = "".join(ET.tostring(el, encoding="unicode") for a in root.iter("asset") for el in a)
    free = [
        str(el.get("name"))
        for wb in root.iter("worldbody")
        for el in wb
        if el.tag == "body"
        and el.get("name")
        and any(j.tag == "freejoint" or (j.tag == "joint" and j.get("type") == "free") for j in el)
    ]
    return bodies, assets, free


def model_xml(
    robot: str | RobotSpec = "fer",
    *,
    hand: bool = True,
    scene: bool = True,
    extra: str | Path | None = None,
    end_effector: EndEffector | str = EndEffector.HAND,
    cube: bool = True,
) -> str:
    """The MJCF text of the robot (and, with ``scene``, a table and, with ``cube``, a
    graspable cube on it).

    ``extra`` names an MJCF file whose ``<worldbody>`` children (and ``<asset>`` entries)
    are added to the scene. ``end_effector`` is what the flange carries (``hand=False``:
    nothing).
    """
    spec = get_robot(robot)
    ee = get_end_effector(end_effector)
    world = _scene_xml(cube) if scene else ""
    assets = ""
    free = ["cube"] if scene and cube else []
    if extra is not None:
        extra_bodies, assets, extra_free = _extra_worldbody(extra)
        world += extra_bodies
        free += extra_free
    tool, tool_parts = "", ""
    if hand and ee is EndEffector.HAND:
        tool, tool_parts = _hand_xml(), _hand_actuation()
    elif hand:
        tool, tool_parts = _pump_xml(), _pump_welds(free)
    return f"""<mujoco model="{spec.name}">
  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>
  <option timestep="0.001" integrator="implicitfast" gravity="0 0 -9.81"/>
  <asset>{assets}</asset>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1" directional="true"/>
    {_arm_xml(spec, tool)}
    {world}
  </worldbody>
  {tool_parts}
</mujoco>
"""


def build_model(
    robot: str | RobotSpec = "fer",
    *,
    hand: bool = True,
    scene: bool = False,
    extra: str | Path | None = None,
    end_effector: EndEffector | str = EndEffector.HAND,
    cube: bool = True,
) -> mujoco.MjModel:
    """Compile :func:`model_xml` into a ``mujoco.MjModel`` (imports MuJoCo on first use)."""
    import mujoco

    return mujoco.MjModel.from_xml_string(
        model_xml(robot, hand=hand, scene=scene, extra=extra, end_effector=end_effector,
                  cube=cube)
    )  # fmt: skip
