"""The commands a control callback returns: :class:`Torques`, :class:`JointPositions`,
:class:`JointVelocities`, :class:`CartesianPose`, :class:`CartesianVelocities`, and
:func:`motion_finished`. Constructors check shapes and finiteness (and, for poses, that the
transform is rigid and column-major) so that a bad value fails where it is made."""

from __future__ import annotations

from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from panda_py.libfranka import _fast

__all__ = [
    "CartesianPose",
    "CartesianVelocities",
    "JointPositions",
    "JointVelocities",
    "Torques",
    "is_homogeneous_transformation",
    "is_valid_elbow",
    "motion_finished",
]

FloatArray = NDArray[np.float64]


def _checked(name: str, value: Any, n: int, unit: str) -> tuple[FloatArray, list[float]]:
    """``value`` as a new float64 array of shape ``(n,)`` and as a list, checked finite."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected {n} numbers {unit}, got {value!r}") from exc
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},) {unit}, got shape {arr.shape}")
    values = arr.tolist()
    s = sum(values)  # a builtin sum of floats: cheaper than a NumPy reduction
    if s - s != 0.0:  # NaN or infinity somewhere
        raise ValueError(f"{name}: Commanding value is infinite or NaN: {values}")
    return arr, values


def _vector(name: str, value: Any, n: int, unit: str) -> FloatArray:
    return _checked(name, value, n, unit)[0]


def is_homogeneous_transformation(transform: Any) -> bool:
    """True if ``transform`` (16 values, column-major) is a rigid transform as libfranka
    checks it: last row exactly (0, 0, 0, 1), rotation rows and columns of unit norm."""
    t = np.asarray(transform, dtype=np.float64).reshape(-1)
    return t.shape == (16,) and _fast.is_pose(t.tolist())


def is_valid_elbow(elbow: Any) -> bool:
    """True if ``elbow[1]`` (the joint-4 flip sign) is exactly +1 or -1."""
    e = np.asarray(elbow, dtype=np.float64).reshape(-1)
    return e.shape == (2,) and (e[1] == 1.0 or e[1] == -1.0)


def _pose(value: Any) -> tuple[FloatArray, list[float]]:
    if getattr(value, "shape", None) == (4, 4):
        value = np.asarray(value, dtype=np.float64).reshape(16, order="F")  # -> column-major
    flat, values = _checked("O_T_EE", value, 16, "(column-major 4x4 transform)")
    if not _fast.is_pose(values):
        raise ValueError(
            "O_T_EE: Attempt to set invalid transformation in motion generator. "
            "Has to be column major!"
        )
    return flat, values


def _elbow(value: Any) -> FloatArray | None:
    if value is None:
        return None
    e = _vector("elbow", value, 2, "([rad], flip sign)")
    if not is_valid_elbow(e):
        raise ValueError(f"elbow: Invalid elbow configuration given: elbow[1] must be +1 or -1, "
                         f"got {e[1]!r}")  # fmt: skip
    return e


def _elbow_attribute() -> Any:
    """The ``elbow`` attribute of Cartesian commands, checked on every assignment so that a
    bad value fails where it is set, not inside the control loop."""

    def get(self: Any) -> FloatArray | None:
        return self._elbow

    def set(self: Any, value: Any) -> None:
        self._elbow = _elbow(value)

    return property(get, set, doc="Elbow (2,): joint-3 value, joint-4 flip sign +-1; or None.")


def _value(name: str, doc: str) -> Any:
    """The public value attribute of a command: its float64 array. The constructor's checked
    list of the same numbers rides along in ``_values`` for the 1 kHz path, which then
    needs no NumPy call and no second check; it is dropped as soon as the array is handed
    out (it may then be changed in place) or replaced, and the path reads the array."""

    def get(self: Any) -> FloatArray:
        self._values = None
        return self._array

    def set(self: Any, value: Any) -> None:
        self._values = None
        self._array = value

    return property(get, set, doc=doc)


class Torques:
    """Joint torques ``tau_J`` (7,) [Nm] for the robot's external-controller mode, without
    gravity (the robot compensates it)."""

    __slots__ = ("_array", "_values", "motion_finished")

    def __init__(self, tau_J: Any) -> None:
        self._array, self._values = _checked("tau_J", tau_J, 7, "[Nm]")
        self.motion_finished = False

    tau_J = _value("tau_J", "Joint torques (7,) [Nm].")


class JointPositions:
    """Joint positions ``q`` (7,) [rad] for the joint position motion generator."""

    __slots__ = ("_array", "_values", "motion_finished")

    def __init__(self, q: Any) -> None:
        self._array, self._values = _checked("q", q, 7, "[rad]")
        self.motion_finished = False

    q = _value("q", "Joint positions (7,) [rad].")


class JointVelocities:
    """Joint velocities ``dq`` (7,) [rad/s] for the joint velocity motion generator."""

    __slots__ = ("_array", "_values", "motion_finished")

    def __init__(self, dq: Any) -> None:
        self._array, self._values = _checked("dq", dq, 7, "[rad/s]")
        self.motion_finished = False

    dq = _value("dq", "Joint velocities (7,) [rad/s].")


class CartesianPose:
    """End-effector pose ``O_T_EE`` (16 values column-major, or a 4x4 matrix) [m], with an
    optional ``elbow`` (joint-3 position [rad], joint-4 flip sign +-1)."""

    __slots__ = ("_array", "_elbow", "_values", "motion_finished")

    def __init__(self, O_T_EE: Any, elbow: Any = None) -> None:
        self._array, self._values = _pose(O_T_EE)
        self._elbow: FloatArray | None = _elbow(elbow)
        self.motion_finished = False

    O_T_EE = _value("O_T_EE", "End-effector pose (16,) column-major [m].")
    elbow = _elbow_attribute()

    def has_elbow(self) -> bool:
        """Whether the command carries an elbow (``elbow`` is not None)."""
        return self.elbow is not None


class CartesianVelocities:
    """End-effector twist ``O_dP_EE`` (6,) [m/s, rad/s] in the base frame, with an
    optional ``elbow`` (joint-3 velocity [rad/s], joint-4 flip sign +-1)."""

    __slots__ = ("_array", "_elbow", "_values", "motion_finished")

    def __init__(self, O_dP_EE: Any, elbow: Any = None) -> None:
        self._array, self._values = _checked("O_dP_EE", O_dP_EE, 6, "[m/s, rad/s]")
        self._elbow: FloatArray | None = _elbow(elbow)
        self.motion_finished = False

    O_dP_EE = _value("O_dP_EE", "End-effector twist (6,) [m/s, rad/s].")
    elbow = _elbow_attribute()

    def has_elbow(self) -> bool:
        """Whether the command carries an elbow (``elbow`` is not None)."""
        return self.elbow is not None


MotionCommand = TypeVar(
    "MotionCommand", Torques, JointPositions, JointVelocities, CartesianPose, CartesianVelocities
)


def motion_finished(command: MotionCommand) -> MotionCommand:
    """Mark ``command`` as the last of its motion and return it (libfranka's
    ``MotionFinished``)."""
    if not isinstance(
        command, (Torques, JointPositions, JointVelocities, CartesianPose, CartesianVelocities)
    ):
        raise ValueError(f"command: expected a libfranka command object, got {command!r}")
    command.motion_finished = True
    return command
