"""The robot's own limits on its settings (stiffness, collision thresholds, load, frames).

A robot answers a setter with values outside these ranges "rejected: invalid argument"
and changes nothing. Each check returns None for acceptable values, else the reason (the
simulator logs it; the wire has no room for it). Where Franka publishes no range the
bound is ours, chosen far above any sensible use and below what breaks the simulation,
and marked "unpublished" here.
"""

from __future__ import annotations

import numpy as np

from panda_py.sim.safety import is_valid_transform

__all__ = [
    "JOINT_STIFFNESS",
    "LOAD_MASS",
    "MAX_FRAME_OFFSET",
    "MAX_LOAD_INERTIA",
    "ROTATIONAL_STIFFNESS",
    "TRANSLATIONAL_STIFFNESS",
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
