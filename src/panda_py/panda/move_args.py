"""``Panda``'s move arguments bound and checked: panda-py's overloads of
``move_to_joint_position`` and ``move_to_pose`` (:data:`JOINT_FORMS`, :data:`POSE_FORMS`,
bound by :func:`panda_py.overloads.bind`, as ``ik``'s), their targets as waypoints, and
their options with panda-py's defaults. Everything here runs before anything is sent: a
bad target or option is an error naming the argument.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import checks
from panda_py.motion.cartesian import parse_poses, stack_rows
from panda_py.overloads import Form, bind

__all__ = [
    "JOINT_FORMS",
    "JOINT_MOVE_DEFAULTS",
    "POSE_FORMS",
    "POSE_MOVE_DEFAULTS",
    "JointMoveOptions",
    "PoseMoveOptions",
    "joint_options",
    "joint_waypoints",
    "parse_joint_targets",
    "parse_pose_targets",
    "pose_options",
    "pose_waypoints",
    "position_waypoints",
]

FloatArray = NDArray[np.float64]

# panda-python 1.1.1's defaults
JOINT_MOVE_DEFAULTS: dict[str, Any] = {
    "speed_factor": 0.2,
    "stiffness": (600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0),
    "damping": (50.0, 50.0, 50.0, 20.0, 20.0, 20.0, 10.0),
    "dq_threshold": 0.001,
    "success_threshold": 0.01,
    "max_deviation": 0.0,  # ours (keyword only): panda-py stops at every waypoint
}
POSE_MOVE_DEFAULTS: dict[str, Any] = {
    "speed_factor": 0.2,
    "impedance": np.diag([800.0, 800.0, 800.0, 40.0, 40.0, 40.0]),
    "damping_ratio": 1.0,
    "nullspace_stiffness": 15.0,
    "dq_threshold": 0.001,
    "success_threshold": 0.02,
    "orientation_threshold": 0.1,
    "max_deviation": 0.0,  # ours (keyword only), as above
}
_JOINT_DEFAULT_STIFFNESS = JOINT_MOVE_DEFAULTS["stiffness"]
_JOINT_DEFAULT_DAMPING = JOINT_MOVE_DEFAULTS["damping"]
_POSE_DEFAULT_IMPEDANCE = POSE_MOVE_DEFAULTS["impedance"]

# panda-py before 1.0 tracked move_to_pose's Cartesian path in joint space, with joint
# ``stiffness`` and ``damping``; the paper's code block 5 passes them. Given, they select
# that mode (the path is the same straight line, solved by IK at every 1 ms sample).
POSE_MOVE_JOINT_OPTIONS = ("stiffness", "damping")


@dataclass(frozen=True)
class JointMoveOptions:
    """``move_to_joint_position``'s checked keywords."""

    speed_factor: float
    stiffness: FloatArray  # (7,) [Nm/rad]
    damping: FloatArray  # (7,) [Nm s/rad]
    dq_threshold: float  # [rad/s]
    success_threshold: float  # [rad]
    max_deviation: float = 0.0  # [rad] how far the path may cut a waypoint's corner


@dataclass(frozen=True)
class PoseMoveOptions:
    """``move_to_pose``'s checked keywords; ``joint_space`` (joint stiffness, damping)
    when panda-py < 1.0's joint-space tracking was asked for."""

    speed_factor: float
    impedance: FloatArray  # (6, 6) [N/m, Nm/rad]
    damping_ratio: float
    nullspace_stiffness: float  # [Nm/rad]
    dq_threshold: float  # [rad/s]
    success_threshold: float  # [m]
    orientation_threshold: float  # [rad]
    joint_space: tuple[FloatArray, FloatArray] | None = None
    max_deviation: float = 0.0  # [m] how far the path may cut a waypoint's corner


# --- panda-py's overloads ---------------------------------------------------------------

_JOINT_OPTIONS = ("speed_factor", "stiffness", "damping", "dq_threshold", "success_threshold")
_POSE_OPTIONS = (
    "speed_factor", "impedance", "damping_ratio", "nullspace_stiffness", "dq_threshold",
    "success_threshold", "orientation_threshold",
)  # fmt: skip
_POSE_KEYWORDS = ("max_deviation", *POSE_MOVE_JOINT_OPTIONS)


def _shape(value: Any) -> tuple[int, ...]:
    """The shape of ``value`` as an array, () where it is none (ragged, not numbers)."""
    if type(value) is np.ndarray:
        return value.shape
    try:
        return np.shape(np.asarray(value, dtype=np.float64))
    except (TypeError, ValueError):
        return ()


def _is_pose(args: Sequence[Any]) -> bool:
    shape = _shape(args[0])
    return len(shape) >= 2 and shape[-2:] == (4, 4)


def _is_position(args: Sequence[Any]) -> bool:
    return _shape(args[0]) in ((3,), (3, 1))


JOINT_FORMS = (
    Form(("positions",), _JOINT_OPTIONS, ("max_deviation",)),
    Form(("waypoints",), _JOINT_OPTIONS, ("max_deviation",)),
)
POSE_FORMS = (
    Form(("pose",), _POSE_OPTIONS, _POSE_KEYWORDS, fits=_is_pose),
    Form(("position", "orientation"), _POSE_OPTIONS, _POSE_KEYWORDS, fits=_is_position),
    Form(("positions", "orientations"), _POSE_OPTIONS, _POSE_KEYWORDS),
)


def parse_joint_targets(
    args: Sequence[Any], kwargs: dict[str, Any]
) -> tuple[FloatArray, JointMoveOptions]:
    """``(waypoints (N, 7), options)`` from ``move_to_joint_position``'s overloads:
    ``(positions, ...)`` one 7-vector or ``(waypoints, ...)`` a sequence of them."""
    given = bind("move_to_joint_position", JOINT_FORMS, args, kwargs).arguments
    target = given.pop("positions", None)
    if target is None:
        target = given.pop("waypoints")
    return joint_waypoints(target), joint_options(given)


def parse_pose_targets(
    args: Sequence[Any], kwargs: dict[str, Any]
) -> tuple[FloatArray, FloatArray, PoseMoveOptions]:
    """``(positions (N, 3), unit quaternions (N, 4), options)`` from ``move_to_pose``'s
    overloads: ``(positions, orientations)``, ``(position, orientation)``, ``(poses)`` or
    ``(pose)`` (4x4 homogeneous transforms)."""
    bound = bind("move_to_pose", POSE_FORMS, args, kwargs)
    given = bound.arguments
    if bound.index == 0:
        positions, quats = pose_waypoints(given.pop("pose"))
    else:
        names = POSE_FORMS[bound.index].target
        positions, quats = position_waypoints(given.pop(names[0]), given.pop(names[1]))
    return positions, quats, pose_options(given)


# --- the targets and the options, checked -----------------------------------------------


def joint_waypoints(target: Any) -> FloatArray:
    """Joint positions (7,) or a sequence of them, checked, as waypoints (N, 7)."""
    # the common target, a finite float64 (7,), in two calls (the general path's eight
    # NumPy calls cost 0.15 ms on the cold caches of a caller that slept in between, as a
    # policy does between targets)
    if type(target) is np.ndarray and target.dtype == np.float64 and target.shape == (7,):
        values = target.tolist()
        if checks.all_finite(values):
            return np.array([values])
    try:
        arr = np.array(target, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"waypoints: expected 7 joint positions [rad] or a sequence of "
                         f"them, got {target!r}") from exc  # fmt: skip
    if arr.shape in ((7,), (7, 1)):
        arr = arr.reshape(1, 7)
    return stack_rows("waypoints", arr, 7, "[rad]")


def pose_waypoints(pose: Any) -> tuple[FloatArray, FloatArray]:
    """A pose (4, 4) or poses (N, 4, 4), checked, as (positions (N, 3), quaternions (N, 4))."""
    numeric = type(pose) is np.ndarray and pose.dtype == np.float64
    arr = pose if numeric else (np.array(pose, dtype=np.float64) if _numeric(pose) else pose)
    if isinstance(arr, np.ndarray) and arr.shape == (4, 4):
        arr = arr.reshape(1, 4, 4)
    return parse_poses(arr)  # (it copies)


def position_waypoints(position: Any, orientation: Any) -> tuple[FloatArray, FloatArray]:
    """A position (3,) and a quaternion (4,) (x, y, z, w), or sequences of them, checked."""
    p = np.array(position, dtype=np.float64) if _numeric(position) else position
    o = np.array(orientation, dtype=np.float64) if _numeric(orientation) else orientation
    if isinstance(p, np.ndarray) and p.shape in ((3,), (3, 1)):
        p = p.reshape(1, 3)
    if isinstance(o, np.ndarray) and o.shape in ((4,), (4, 1)):
        o = o.reshape(1, 4)
    positions = stack_rows("positions", p, 3, "[m]")
    quats = stack_rows("orientations", o, 4, "(unit quaternions x, y, z, w)")
    if len(positions) != len(quats):
        raise ValueError(f"orientations: expected one per position ({len(positions)}), "
                         f"got {len(quats)}")  # fmt: skip
    for i, qv in enumerate(quats):
        quats[i] = checks.quaternion(f"orientations[{i}]", qv)
    return positions, quats


def _numeric(value: Any) -> bool:
    try:
        np.array(value, dtype=np.float64)
        return True
    except (TypeError, ValueError):
        return False


def _speed(value: Any) -> float:
    v = checks.scalar("speed_factor", value)
    if not 0.0 < v <= 1.0:
        raise ValueError(f"speed_factor: expected a number in (0, 1], got {v}")
    return v


def _nonnegative(name: str, value: Any, unit: str) -> float:
    v = checks.scalar(name, value, unit)
    if v < 0.0:
        raise ValueError(f"{name}: expected a number >= 0 {unit}, got {v}")
    return v


def _positive(name: str, value: Any, unit: str) -> float:
    v = checks.scalar(name, value, unit)
    if v <= 0.0:
        raise ValueError(f"{name}: expected a number > 0 {unit}, got {v}")
    return v


def joint_options(given: dict[str, Any]) -> JointMoveOptions:
    """The checked options of a joint move, panda-py's defaults where not ``given``
    (names as :data:`JOINT_MOVE_DEFAULTS`')."""
    if not given:  # panda-py's defaults, checked once
        return _default_joint_options()
    unknown = sorted(set(given) - set(JOINT_MOVE_DEFAULTS))
    if unknown:
        raise TypeError(f"move_to_joint_position() got unexpected keyword arguments {unknown}")
    opts = {**JOINT_MOVE_DEFAULTS, **given}
    return JointMoveOptions(
        speed_factor=_speed(opts["speed_factor"]),
        stiffness=np.array(checks.nonnegative("stiffness", opts["stiffness"], 7, "[Nm/rad]")),
        damping=np.array(checks.nonnegative("damping", opts["damping"], 7, "[Nm s/rad]")),
        dq_threshold=_positive("dq_threshold", opts["dq_threshold"], "[rad/s]"),
        success_threshold=_positive("success_threshold", opts["success_threshold"], "[rad]"),
        max_deviation=_nonnegative("max_deviation", opts["max_deviation"], "[rad]"),
    )


@functools.cache
def _default_joint_options() -> JointMoveOptions:
    """The defaults' options, shared by every move that gives none (read-only arrays)."""
    options = joint_options(dict(JOINT_MOVE_DEFAULTS))
    options.stiffness.setflags(write=False)
    options.damping.setflags(write=False)
    return options


def pose_options(given: dict[str, Any]) -> PoseMoveOptions:
    """The checked options of a Cartesian move, panda-py's defaults where not ``given``
    (names as :data:`POSE_MOVE_DEFAULTS`', or ``stiffness``/``damping``: panda-py < 1.0's
    joint-space tracking)."""
    if not given:  # panda-py's defaults, checked once
        return _default_pose_options()
    given = dict(given)
    joint = {k: given.pop(k) for k in POSE_MOVE_JOINT_OPTIONS if k in given}
    unknown = sorted(set(given) - set(POSE_MOVE_DEFAULTS))
    if unknown:
        raise TypeError(f"move_to_pose() got unexpected keyword arguments {unknown}")
    opts = {**POSE_MOVE_DEFAULTS, **given}
    joint_space = None
    if joint:
        stiffness = joint.get("stiffness", _JOINT_DEFAULT_STIFFNESS)
        damping = joint.get("damping", _JOINT_DEFAULT_DAMPING)
        joint_space = (
            np.array(checks.nonnegative("stiffness", stiffness, 7, "[Nm/rad]")),
            np.array(checks.nonnegative("damping", damping, 7, "[Nm s/rad]")),
        )
    impedance = opts["impedance"]
    return PoseMoveOptions(
        speed_factor=_speed(opts["speed_factor"]),
        impedance=(
            _default_impedance()  # checked once (its PSD test costs)
            if impedance is _POSE_DEFAULT_IMPEDANCE
            else np.array(checks.matrix6("impedance", impedance)).reshape(6, 6)
        ),
        damping_ratio=checks.nonnegative_scalar("damping_ratio", opts["damping_ratio"]),
        nullspace_stiffness=checks.nonnegative_scalar(
            "nullspace_stiffness", opts["nullspace_stiffness"]
        ),
        dq_threshold=_positive("dq_threshold", opts["dq_threshold"], "[rad/s]"),
        success_threshold=_positive("success_threshold", opts["success_threshold"], "[m]"),
        orientation_threshold=_positive(
            "orientation_threshold", opts["orientation_threshold"], "[rad]"
        ),
        joint_space=joint_space,
        max_deviation=_nonnegative("max_deviation", opts["max_deviation"], "[m]"),
    )


@functools.cache
def _default_impedance() -> FloatArray:
    impedance = np.array(checks.matrix6("impedance", _POSE_DEFAULT_IMPEDANCE)).reshape(6, 6)
    impedance.setflags(write=False)
    return impedance


@functools.cache
def _default_pose_options() -> PoseMoveOptions:
    """The defaults' options, shared by every move that gives none (read-only arrays)."""
    return pose_options(dict(POSE_MOVE_DEFAULTS))
