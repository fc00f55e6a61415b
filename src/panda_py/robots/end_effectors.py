"""What can be mounted on the flange: the Franka Hand or Franka's Cobot Pump.

A robot reports its configured end effector in every state (``F_T_NE``, ``m_ee``,
``F_x_Cee``, ``I_ee``) and compensates its weight; the simulator builds the matching
MuJoCo body and serves the matching device (the hand on TCP 1338, the pump on 1339).
The hand's parameters are :data:`~panda_py.robots.params.FRANKA_HAND`; the pump's are here.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py.robots.params import FRANKA_HAND, Inertial


class EndEffector(enum.Enum):
    """The device on the flange."""

    HAND = "hand"
    COBOT_PUMP = "cobot_pump"


@dataclass(frozen=True)
class CobotPumpSpec:
    """Franka's Cobot Pump (a Schmalz electric vacuum generator with one suction cup):
    its TCP (the cup's face), its inertial parameters and the cup's geometry."""

    tcp_offset: float  # [m] flange -> the cup's face along z (F_T_NE translation)
    inertial: Inertial  # the pump as a whole, in the flange frame
    cup_radius: float  # [m] the suction cup's sealing lip
    cup_height: float  # [m] the cup, from its face up to the stem
    housing_half: tuple[float, float, float]  # [m] the pump's body (collision box)
    housing_z: float  # [m] the housing's centre above the flange
    max_vacuum: float  # [mbar] the most the pump builds on a sealed cup


# Franka's own description of the Cobot Pump (franka_description, ``end_effectors/
# cobot_pump``): mass 1.01 kg, centre of mass 0.063 m above the flange, inertia
# diag(0.001) kg m^2 (``inertials.yaml``), TCP 0.105 m along the flange's z, not rotated
# (``cobot_pump_arguments.xacro``: tcp_xyz "0 0 0.105", tcp_rpy "0 0 0"), and collision
# capsules of 4 cm radius at z = 0.04 m and 2 cm at z = 0.10 m (``ee_with_one_link.xacro``),
# from which the housing box and the cup below are sized. The cup's diameter (30 mm, it
# fits the scene's 4 cm cube) and the largest vacuum (750 mbar below ambient, the 75 %
# a Schmalz ECBPi is rated for, as we know the data sheet; not checked against it here)
# are our choices: Franka publishes neither in a form we could cite.
COBOT_PUMP = CobotPumpSpec(
    tcp_offset=0.105,
    inertial=Inertial(1.01, (0.0, 0.0, 0.063), (0.001, 0.001, 0.001, 0.0, 0.0, 0.0)),
    cup_radius=0.015,
    cup_height=0.012,
    housing_half=(0.04, 0.07, 0.04),
    housing_z=0.04,
    max_vacuum=750.0,
)

_NAMES = {
    "hand": EndEffector.HAND,
    "franka_hand": EndEffector.HAND,
    "cobot_pump": EndEffector.COBOT_PUMP,
    "cobot-pump": EndEffector.COBOT_PUMP,
    "pump": EndEffector.COBOT_PUMP,
}
#: The spellings :func:`get_end_effector` takes (``panda-sim --end-effector`` uses these).
END_EFFECTOR_CHOICES = ("hand", "cobot_pump", "cobot-pump")


def get_end_effector(value: Any) -> EndEffector:
    """An :class:`EndEffector` from its name (``"hand"``, ``"cobot_pump"`` or
    ``"cobot-pump"``, any case) or itself; anything else raises ValueError."""
    if isinstance(value, EndEffector):
        return value
    ee = _NAMES.get(value.lower()) if isinstance(value, str) else None
    if ee is None:
        raise ValueError(
            f"end_effector: expected one of {', '.join(map(repr, END_EFFECTOR_CHOICES))}, "
            f"got {value!r}"
        )
    return ee


def end_effector_F_T_NE(ee: EndEffector) -> np.ndarray:
    """The flange-to-nominal-EE transform a robot with ``ee`` reports (``F_T_NE``)."""
    T = np.eye(4)
    if ee is EndEffector.HAND:
        c, s = math.cos(FRANKA_HAND.tcp_rotz), math.sin(FRANKA_HAND.tcp_rotz)
        T[:2, :2] = [[c, -s], [s, c]]
        T[2, 3] = FRANKA_HAND.tcp_offset
    else:
        T[2, 3] = COBOT_PUMP.tcp_offset
    return T


def end_effector_load(ee: EndEffector) -> Inertial:
    """The end effector's inertial parameters (``m_ee``, ``F_x_Cee``, ``I_ee``)."""
    return FRANKA_HAND.inertial if ee is EndEffector.HAND else COBOT_PUMP.inertial


__all__ = [
    "COBOT_PUMP",
    "END_EFFECTOR_CHOICES",
    "CobotPumpSpec",
    "EndEffector",
    "end_effector_F_T_NE",
    "end_effector_load",
    "get_end_effector",
]
