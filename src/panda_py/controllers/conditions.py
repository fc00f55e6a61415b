"""Conditions on the robot's state for guarded moves, evaluated every tick in the control
process::

    from panda_py.conditions import Distance, Elapsed, Errors, Force, Torque

    panda.move_to_pose(below, until=(Force.z < -10.0) | (Elapsed > 5.0))

A condition is built in the user's process, where its arguments are checked (an unknown
state field, an index out of range, a threshold that is not a finite number: a clear
error, nothing sent), travels to the control process with the move and is evaluated on
each tick's state; when it holds, the move stops gently (or goes on with ``then=``) and
its result names the condition and when it held.

Quantities, compared with ``<``, ``<=``, ``>``, ``>=`` against a number:

- ``Force.x/.y/.z/.norm``, ``Moment.x/.y/.z/.norm``: the external wrench in the base
  frame, ``O_F_ext_hat_K``, with libfranka's sign: the wrench the robot applies to its
  environment (pressing down on a table: ``Force.z`` < 0). ``ForceEE``, ``MomentEE``: the
  same in the stiffness frame K (``K_F_ext_hat_K``; the hand's z points down, into it).
- ``Torque[j]`` (joint j, 0-6) and ``Torque.norm``: ``tau_ext_hat_filtered`` [Nm].
- ``Elapsed``: time since the move started [s]; ``Distance``: to its goal ([m] for a
  Cartesian move, the largest joint's [rad] for a joint move).
- ``Field("name")[i]`` / ``Field("name").norm``: any numeric field of the robot state.

``Errors`` holds when the robot reports an error. ``when(function)`` wraps a function of
the state (``f(state) -> bool``), sent by value like a user's controller. Conditions
combine with ``&``, ``|`` and ``~``; all are immutable and picklable.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py.fci import state_float_fields

__all__ = [
    "Condition",
    "Distance",
    "Elapsed",
    "Errors",
    "Field",
    "Force",
    "ForceEE",
    "Moment",
    "MomentEE",
    "Quantity",
    "Torque",
    "when",
]

_OPS: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,
}  # fmt: skip


class Condition:
    """Something that holds, or not, on a tick's state and the move's progress (an object
    with ``elapsed`` [s] and ``distance`` to the goal). Combine with ``&``, ``|``, ``~``."""

    def holds(self, state: Any, progress: Any) -> bool:
        raise NotImplementedError

    def which(self, state: Any, progress: Any) -> Condition | None:
        """The part of this condition that holds (of an ``|``, the first alternative that
        does; otherwise the whole), or None if it does not hold."""
        return self if self.holds(state, progress) else None

    def __and__(self, other: Condition) -> Condition:
        return All(_conditions("&", self, other))

    def __or__(self, other: Condition) -> Condition:
        return Any_(_conditions("|", self, other))

    def __invert__(self) -> Condition:
        return Not(self)

    def __bool__(self) -> bool:
        raise TypeError(
            "a condition has no truth value here: combine conditions with &, | and ~ "
            "(not and, or, not), and write a < x < b as (a < x) & (x < b)"
        )


def _conditions(op: str, *items: Any) -> tuple[Condition, ...]:
    for item in items:
        if not isinstance(item, Condition):
            raise TypeError(
                f"{op}: expected a condition (e.g. Force.z < -10.0), got {type(item).__name__}"
            )
    return tuple(items)


@dataclass(frozen=True, eq=True)
class All(Condition):
    parts: tuple[Condition, ...]

    def holds(self, state: Any, progress: Any) -> bool:
        return all(p.holds(state, progress) for p in self.parts)

    def __repr__(self) -> str:
        return " & ".join(_paren(p) for p in self.parts)


@dataclass(frozen=True, eq=True)
class Any_(Condition):  # noqa: N801 (``Any`` is typing's)
    parts: tuple[Condition, ...]

    def holds(self, state: Any, progress: Any) -> bool:
        return any(p.holds(state, progress) for p in self.parts)

    def which(self, state: Any, progress: Any) -> Condition | None:
        for part in self.parts:
            held = part.which(state, progress)
            if held is not None:
                return held
        return None

    def __repr__(self) -> str:
        return " | ".join(_paren(p) for p in self.parts)


@dataclass(frozen=True, eq=True)
class Not(Condition):
    part: Condition

    def holds(self, state: Any, progress: Any) -> bool:
        return not self.part.holds(state, progress)

    def __repr__(self) -> str:
        return f"~{_paren(self.part)}"


def _paren(c: Condition) -> str:
    return f"({c!r})" if isinstance(c, (All, Any_, Compare)) else repr(c)


@dataclass(frozen=True, eq=True)
class Quantity:
    """A number read from the state or the progress each tick: ``source`` a state field
    (or ``"elapsed"``/``"distance"`` of the progress), one value (``index``) or the norm
    of a slice (``start:stop``)."""

    name: str
    source: str
    index: int | None = None
    start: int = 0
    stop: int = 0

    def value(self, state: Any, progress: Any) -> float:
        if self.source == "elapsed":
            return float(progress.elapsed)
        if self.source == "distance":
            return float(progress.distance)
        data = getattr(state, self.source)
        if self.index is not None:
            return float(data[self.index])
        return math.sqrt(float(np.dot(data[self.start : self.stop], data[self.start : self.stop])))

    def _compare(self, op: str, threshold: Any) -> Compare:
        if isinstance(threshold, (bool, np.bool_)) or not isinstance(
            threshold, (int, float, np.integer, np.floating)
        ):
            raise ValueError(f"{self.name} {op}: expected a finite number, got {threshold!r}")
        value = float(threshold)
        if not math.isfinite(value):
            raise ValueError(f"{self.name} {op}: expected a finite number, got {value}")
        return Compare(self, op, value)

    def __lt__(self, threshold: Any) -> Compare:
        return self._compare("<", threshold)

    def __le__(self, threshold: Any) -> Compare:
        return self._compare("<=", threshold)

    def __gt__(self, threshold: Any) -> Compare:
        return self._compare(">", threshold)

    def __ge__(self, threshold: Any) -> Compare:
        return self._compare(">=", threshold)

    def __repr__(self) -> str:
        return self.name


@dataclass(frozen=True, eq=True)
class Compare(Condition):
    quantity: Quantity
    op: str
    threshold: float

    def holds(self, state: Any, progress: Any) -> bool:
        return _OPS[self.op](self.quantity.value(state, progress), self.threshold)

    def __repr__(self) -> str:
        return f"{self.quantity!r} {self.op} {self.threshold!r}"


class Field:
    """Any numeric field of the robot state: ``Field("tau_J")[3]``, ``Field("dq").norm``
    (the fields' names and sizes are libfranka's ``RobotState``'s)."""

    def __init__(self, name: str, label: str | None = None, start: int = 0,
                 stop: int | None = None) -> None:  # fmt: skip
        sizes = state_float_fields()
        if name not in sizes:
            raise ValueError(f"field: expected one of {sorted(sizes)}, got {name!r}")
        self.field = name
        self.start = start
        self.stop = sizes[name] if stop is None else stop
        self.label = label or f'Field("{name}")'

    def __getitem__(self, index: Any) -> Quantity:
        n = self.stop - self.start
        if isinstance(index, (bool, np.bool_)) or not isinstance(index, (int, np.integer)):
            raise ValueError(f"{self.label}[]: expected an index 0-{n - 1}, got {index!r}")
        if not 0 <= int(index) < n:
            raise ValueError(f"{self.label}[]: expected an index 0-{n - 1}, got {index}")
        return Quantity(f"{self.label}[{int(index)}]", self.field, self.start + int(index))

    @property
    def norm(self) -> Quantity:
        """The Euclidean norm of the field's values."""
        return Quantity(f"{self.label}.norm", self.field, None, self.start, self.stop)


class _Vector3(Field):
    """Three values of a field with named axes: ``.x``, ``.y``, ``.z``, ``.norm``."""

    @property
    def x(self) -> Quantity:
        return self._axis(0, "x")

    @property
    def y(self) -> Quantity:
        return self._axis(1, "y")

    @property
    def z(self) -> Quantity:
        return self._axis(2, "z")

    def _axis(self, i: int, name: str) -> Quantity:
        return Quantity(f"{self.label}.{name}", self.field, self.start + i)


class _ErrorsHold(Condition):
    """Holds when the robot reports any error (``current_errors``)."""

    def holds(self, state: Any, progress: Any) -> bool:
        return bool(state.current_errors)

    def __repr__(self) -> str:
        return "Errors"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _ErrorsHold)

    def __hash__(self) -> int:
        return hash("Errors")

    def __reduce__(self) -> str:
        return "Errors"  # the module's one instance


@dataclass(frozen=True, eq=True)
class _When(Condition):
    function: Callable[[Any], Any]

    def holds(self, state: Any, progress: Any) -> bool:
        return bool(self.function(state))

    def __repr__(self) -> str:
        return f"when({getattr(self.function, '__qualname__', repr(self.function))})"


def when(function: Callable[[Any], Any]) -> Condition:
    """A condition from a function of the state (``f(state) -> bool``), evaluated in the
    control process every tick; an exception it raises aborts the move with that error."""
    if not callable(function):
        raise ValueError(f"when: expected a function of the state, got {function!r}")
    return _When(function)


Force = _Vector3("O_F_ext_hat_K", "Force", 0, 3)
Moment = _Vector3("O_F_ext_hat_K", "Moment", 3, 6)
ForceEE = _Vector3("K_F_ext_hat_K", "ForceEE", 0, 3)
MomentEE = _Vector3("K_F_ext_hat_K", "MomentEE", 3, 6)
Torque = Field("tau_ext_hat_filtered", "Torque")
Elapsed = Quantity("Elapsed", "elapsed")
Distance = Quantity("Distance", "distance")
Errors = _ErrorsHold()
