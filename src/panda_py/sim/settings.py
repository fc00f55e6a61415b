"""The robot's settings: its setters (:class:`RobotSettings`, a part of ``RobotCore``),
the collision thresholds and the robot's own limits on every setting (stiffness,
collision thresholds, load, frames).

A robot answers a setter with values outside these ranges "rejected: invalid argument"
and changes nothing. Each check returns None for acceptable values, else the reason (the
simulator logs it; the wire has no room for it). Where Franka publishes no range the
bound is ours, chosen far above any sensible use and below what breaks the simulation,
and marked "unpublished" here.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from panda_py import fci
from panda_py.fci import GetterSetterStatus, RobotMode
from panda_py.sim.safety import all_finite, from_col_major, is_valid_transform

log = logging.getLogger("panda_py.sim")

__all__ = [
    "JOINT_STIFFNESS",
    "LOAD_MASS",
    "MAX_FRAME_OFFSET",
    "MAX_LOAD_INERTIA",
    "ROTATIONAL_STIFFNESS",
    "TRANSLATIONAL_STIFFNESS",
    "CollisionThresholds",
    "RobotSettings",
    "check_cartesian_stiffness",
    "check_collision_thresholds",
    "check_frame",
    "check_joint_stiffness",
    "check_load",
]

# [Nm/rad] per joint. Unpublished: the robot's defaults are 2000-3000 (libfranka's
# examples_common setDefaultBehavior); the internal controller's bandwidth grows with the
# square root of the stiffness, and at 1e9 the simulated arm leaves its joint limits.
JOINT_STIFFNESS = (0.0, 10000.0)
# [N/m] and [Nm/rad]: the ranges documented beside libfranka's Cartesian impedance
# (pantor/frankx include/frankx/motion_impedance.hpp: "in [10, 3000] N/m", "in [1, 300]
# Nm/rad", which the robot enforces).
TRANSLATIONAL_STIFFNESS = (10.0, 3000.0)
ROTATIONAL_STIFFNESS = (1.0, 300.0)
# [kg] FER and FR3 data sheets: payload 3 kg.
LOAD_MASS = (0.0, 3.0)
# [kg m^2] largest principal moment of a load: unpublished; a 3 kg point mass 1 m away.
MAX_LOAD_INERTIA = 3.0
# [m] largest translation of the EE and K frames and of a load's center of mass from
# the flange: unpublished (a tool a metre long already exceeds the arm's payload moment).
MAX_FRAME_OFFSET = 1.0
# Symmetry and the triangle inequality of an inertia hold up to this [kg m^2].
_INERTIA_TOLERANCE = 1e-9


def _outside(values: np.ndarray, low: float, high: float) -> bool:
    return bool(np.any(~np.isfinite(values)) or np.any(values < low) or np.any(values > high))


def check_joint_stiffness(K_theta: np.ndarray) -> str | None:
    low, high = JOINT_STIFFNESS
    if K_theta.shape != (7,) or _outside(K_theta, low, high):
        return f"K_theta must be 7 values in [{low:g}, {high:g}] Nm/rad, got {K_theta.tolist()}"
    return None


def check_cartesian_stiffness(K_x: np.ndarray) -> str | None:
    (tl, th), (rl, rh) = TRANSLATIONAL_STIFFNESS, ROTATIONAL_STIFFNESS
    if K_x.shape != (6,) or _outside(K_x[:3], tl, th) or _outside(K_x[3:], rl, rh):
        return (
            f"K_x must be 3 values in [{tl:g}, {th:g}] N/m and 3 in [{rl:g}, {rh:g}] Nm/rad, "
            f"got {K_x.tolist()}"
        )
    return None


def check_collision_thresholds(pairs: list[tuple[np.ndarray, np.ndarray]]) -> str | None:
    """``pairs``: (lower, upper) threshold arrays. Each must be finite and >= 0 with lower
    <= upper (contacts below collisions). No upper bound is published, and none is
    needed: a threshold only decides when a reflex fires."""
    for lower, upper in pairs:
        if _outside(lower, 0.0, np.inf) or _outside(upper, 0.0, np.inf):
            return f"thresholds must be finite and >= 0, got {lower.tolist()}, {upper.tolist()}"
        if np.any(lower > upper):
            return f"a lower threshold exceeds its upper one: {lower.tolist()} > {upper.tolist()}"
    return None


def check_load(m: float, F_x_C: np.ndarray, I: np.ndarray) -> str | None:
    """A load's mass [kg], center of mass from the flange [m] and inertia (3x3) [kg m^2]:
    a physical inertia is symmetric, positive semi-definite and obeys the triangle
    inequality of its principal moments."""
    low, high = LOAD_MASS
    if not (np.isfinite(m) and low <= m <= high):
        return f"load mass must be in [{low:g}, {high:g}] kg, got {m!r}"
    if _outside(F_x_C, -MAX_FRAME_OFFSET, MAX_FRAME_OFFSET) or not (
        np.linalg.norm(F_x_C) <= MAX_FRAME_OFFSET
    ):
        return f"F_x_Cload must lie within {MAX_FRAME_OFFSET:g} m of the flange, got {F_x_C}"
    if not np.all(np.isfinite(I)) or not np.allclose(I, I.T, rtol=0.0, atol=_INERTIA_TOLERANCE):
        return f"load inertia must be a finite symmetric matrix, got {I.tolist()}"
    moments = np.linalg.eigvalsh(I)  # ascending
    if moments[0] < -_INERTIA_TOLERANCE or moments[2] > MAX_LOAD_INERTIA:
        return (
            f"load inertia's principal moments must be in [0, {MAX_LOAD_INERTIA:g}] kg m^2, "
            f"got {moments.tolist()}"
        )
    if moments[0] + moments[1] < moments[2] - _INERTIA_TOLERANCE:
        return f"load inertia violates the triangle inequality: {moments.tolist()}"
    return None


def check_frame(name: str, T: np.ndarray) -> str | None:
    """A transform as libfranka checks it (:func:`is_valid_transform`) whose translation
    stays within :data:`MAX_FRAME_OFFSET`."""
    if T.shape != (4, 4) or not is_valid_transform(T):
        return f"{name} must be a rigid 4x4 transform (unit rotation, last row 0 0 0 1)"
    if not np.linalg.norm(T[:3, 3]) <= MAX_FRAME_OFFSET:
        return f"{name}'s translation must be within {MAX_FRAME_OFFSET:g} m, got {T[:3, 3]}"
    return None


# Power-up collision thresholds. Source: libfranka examples_common.cpp
# setDefaultBehavior (the values Franka's examples and franka_ros start with).
_DEFAULT_TORQUE_THRESHOLDS = (20.0, 20.0, 18.0, 18.0, 16.0, 14.0, 12.0)  # [Nm]
_DEFAULT_FORCE_THRESHOLDS = (20.0, 20.0, 20.0, 25.0, 25.0, 25.0)  # [N, Nm]


@dataclass
class CollisionThresholds:
    lower_torque_acc: np.ndarray = field(
        default_factory=lambda: np.array(_DEFAULT_TORQUE_THRESHOLDS)
    )
    upper_torque_acc: np.ndarray = field(
        default_factory=lambda: np.array(_DEFAULT_TORQUE_THRESHOLDS)
    )
    lower_torque_nom: np.ndarray = field(
        default_factory=lambda: np.array(_DEFAULT_TORQUE_THRESHOLDS)
    )
    upper_torque_nom: np.ndarray = field(
        default_factory=lambda: np.array(_DEFAULT_TORQUE_THRESHOLDS)
    )
    lower_force_acc: np.ndarray = field(default_factory=lambda: np.array(_DEFAULT_FORCE_THRESHOLDS))
    upper_force_acc: np.ndarray = field(default_factory=lambda: np.array(_DEFAULT_FORCE_THRESHOLDS))
    lower_force_nom: np.ndarray = field(default_factory=lambda: np.array(_DEFAULT_FORCE_THRESHOLDS))
    upper_force_nom: np.ndarray = field(default_factory=lambda: np.array(_DEFAULT_FORCE_THRESHOLDS))


class RobotSettings:
    """The robot's setters (a part of :class:`~panda_py.sim.robot.RobotCore`): each checks
    the mode and the value's range, then changes the setting, or answers rejected and
    changes nothing."""

    robot_mode: RobotMode
    thresholds: CollisionThresholds
    K_theta: np.ndarray
    K_x: np.ndarray
    guiding_axes: np.ndarray
    guiding_elbow: bool
    F_T_NE: np.ndarray
    NE_T_EE: np.ndarray
    EE_T_K: np.ndarray
    m_load: float
    F_x_Cload: np.ndarray
    I_load: np.ndarray
    filters: np.ndarray

    if TYPE_CHECKING:

        def _fill_static(self) -> None: ...  # the state's setter-owned fields (StateAssembly)

    def _setter_check(self, *arrays: np.ndarray) -> GetterSetterStatus | None:
        if self.robot_mode not in (RobotMode.IDLE, RobotMode.REFLEX):
            return GetterSetterStatus.COMMAND_NOT_POSSIBLE_REJECTED
        if not all_finite(*arrays):
            return GetterSetterStatus.INVALID_ARGUMENT_REJECTED
        return None

    @staticmethod
    def _refuse(command: str, reason: str | None) -> GetterSetterStatus | None:
        """INVALID_ARGUMENT_REJECTED (logged with ``reason``) if there is a reason."""
        if reason is None:
            return None
        log.warning("%s rejected: %s", command, reason)
        return GetterSetterStatus.INVALID_ARGUMENT_REJECTED

    def set_collision_behavior(self, f: dict[str, np.ndarray]) -> GetterSetterStatus:
        arrays = [np.asarray(f[n], dtype=float) for n in fci.COLLISION_THRESHOLD_FIELDS]
        bad = self._setter_check(*arrays) or self._refuse(
            "SetCollisionBehavior",
            check_collision_thresholds([(arrays[i], arrays[i + 1]) for i in (0, 2, 4, 6)]),
        )
        if bad is not None:
            return bad
        self.thresholds = CollisionThresholds(*arrays)
        return GetterSetterStatus.SUCCESS

    def set_joint_impedance(self, K_theta: np.ndarray) -> GetterSetterStatus:
        K = np.array(K_theta, dtype=float)
        bad = self._setter_check(K) or self._refuse("SetJointImpedance", check_joint_stiffness(K))
        if bad is not None:
            return bad
        self.K_theta = K
        return GetterSetterStatus.SUCCESS

    def set_cartesian_impedance(self, K_x: np.ndarray) -> GetterSetterStatus:
        K = np.array(K_x, dtype=float)
        bad = self._setter_check(K) or self._refuse(
            "SetCartesianImpedance", check_cartesian_stiffness(K)
        )
        if bad is not None:
            return bad
        self.K_x = K
        return GetterSetterStatus.SUCCESS

    def set_guiding_mode(self, axes: np.ndarray, elbow: bool) -> GetterSetterStatus:
        bad = self._setter_check()
        if bad is not None:
            return bad
        self.guiding_axes = np.asarray(axes, dtype=bool)
        self.guiding_elbow = bool(elbow)
        return GetterSetterStatus.SUCCESS

    def _set_transform(
        self, flat: np.ndarray, attr: str, *, relative_to_ne: bool = False
    ) -> GetterSetterStatus:
        """Set the column-major transform ``flat`` as ``attr``; ``relative_to_ne``: it is
        given from the flange and stored from the nominal EE."""
        T = from_col_major(flat)
        bad = self._setter_check(T) or self._refuse(attr, check_frame(attr, T))
        if bad is not None:
            return bad
        setattr(self, attr, np.linalg.inv(self.F_T_NE) @ T if relative_to_ne else T)
        self._fill_static()
        return GetterSetterStatus.SUCCESS

    def set_ee_to_k(self, EE_T_K: np.ndarray) -> GetterSetterStatus:
        return self._set_transform(EE_T_K, "EE_T_K")

    def set_ne_to_ee(self, NE_T_EE: np.ndarray) -> GetterSetterStatus:
        return self._set_transform(NE_T_EE, "NE_T_EE")

    def set_f_to_ee(self, F_T_EE: np.ndarray) -> GetterSetterStatus:
        """Protocol v3's SetFToEE: the whole flange-to-EE transform (NE_T_EE follows)."""
        return self._set_transform(F_T_EE, "NE_T_EE", relative_to_ne=True)

    def set_load(self, m: float, F_x_C: np.ndarray, I: np.ndarray) -> GetterSetterStatus:
        F_x_C = np.asarray(F_x_C, dtype=float)
        I_m = np.asarray(I, dtype=float).reshape(3, 3)
        bad = self._setter_check(np.array([m]), F_x_C, I_m) or self._refuse(
            "SetLoad", check_load(float(m), F_x_C, I_m)
        )
        if bad is not None:
            return bad
        self.m_load, self.F_x_Cload, self.I_load = float(m), F_x_C, I_m
        self._fill_static()
        return GetterSetterStatus.SUCCESS

    def set_filters(self, frequencies: np.ndarray) -> GetterSetterStatus:
        f = np.asarray(frequencies, dtype=float)
        bad = self._setter_check(f)
        if bad is not None:
            return bad
        if np.any(f <= 0) or np.any(f > 1000):
            return GetterSetterStatus.INVALID_ARGUMENT_REJECTED
        self.filters = f
        return GetterSetterStatus.SUCCESS
