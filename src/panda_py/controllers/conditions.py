"""Conditions on the robot's state for guarded moves, evaluated every tick in the control
process::

    from panda_py.conditions import Distance, Elapsed, Errors, Force, Torque

    panda.move_to_pose(below, until=(Force.z < -10.0) | (Elapsed > 5.0))

A condition is built in the user's process, where its arguments are checked (an unknown
state field, an index out of range, a threshold that is not a finite number: a clear
error, nothing sent), travels to the control process with the move and is evaluated on
each tick's state; when it holds, the move stops gently (or goes on with ``then=``) and
its result names the condition and when it held.

Quantities, compared with ``<``, ``<=``, ``>``, ``>=`` against a finite number:

- ``Force.x/.y/.z/.norm`` [N], ``Moment.x/.y/.z/.norm`` [Nm]: the external wrench in the
  base frame, ``O_F_ext_hat_K``, with libfranka's sign: the wrench the robot applies to
  its environment (pressing down on a table: ``Force.z`` < 0). ``ForceEE``, ``MomentEE``:
  the same in the stiffness frame K (``K_F_ext_hat_K``; the hand's z points down, into it).
- ``Torque[j]`` (joint j, 0-based like NumPy: 0-6) and ``Torque.norm`` [Nm]: the external
  joint torques ``tau_ext_hat_filtered``.
- ``Elapsed``: time since the move started [s]; ``Distance``: to its goal ([m] for a
  Cartesian move, the largest joint's [rad] for a joint move). Both read the move's
  :class:`Progress`.
- ``Field("name")[i]`` or ``Field("name", i)``, ``Field("name").norm``: any float field of
  the robot state, in its units (``Field("dq").norm > 1.0``, ``Field("m_ee") > 1.0``).

``Errors`` holds when the robot reports an error. ``when(function)`` (or
``Condition.of(function)``) wraps a function of the state (``f(state) -> bool``), sent by
value like a user's controller; what it raises ends the move with that error.

Conditions combine with ``&``, ``|`` and ``~`` (parenthesize the comparisons: ``<`` binds
looser than ``|``); all are immutable and picklable, and print as Python that builds them.
"""

from __future__ import annotations

import math
import numbers
import operator
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from panda_py.controllers.plans import Progress
from panda_py.controllers.state import StateView
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
    "Progress",
    "Quantity",
    "Torque",
    "when",
]

_OPS: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,
}  # fmt: skip
# the robot state's float fields -> number of values (the newest protocol's: older ones
# lack some fields, which their states read as libfranka documents, and reorder none)
_SIZES = state_float_fields()
_PROGRESS = ("elapsed", "distance")  # the fields of Progress a Quantity can read
_ERRORS = ("errors",)
_NOT_A_CONDITION = (
    "compare it with a number first, and parenthesize the comparisons: "
    "(Force.z < -10.0) | (Elapsed > 5.0)"
)


class Condition:
    """Something that holds, or not, on a tick's state and the move's :class:`Progress`.
    Combine with ``&``, ``|``, ``~``; ``describe()`` (or ``repr``) prints it."""

    def holds(self, state: StateView, progress: Progress) -> bool:
        """Whether the condition holds on ``state`` (a RobotState) and ``progress``."""
        raise NotImplementedError

    def which(self, state: StateView, progress: Progress) -> Condition | None:
        """The part of this condition that holds (of an ``|``, the first alternative that
        does; otherwise the whole), or None if it does not hold."""
        return self if self.holds(state, progress) else None

    def describe(self) -> str:
        """The condition as an expression (``(Force.z < -10.0) | (Elapsed > 5.0)``)."""
        return repr(self)

    @staticmethod
    def of(function: Callable[[Any], Any]) -> Condition:
        """The same as :func:`when`."""
        return when(function)

    def __and__(self, other: Condition) -> Condition:
        return All(_parts(All, "&", self, other))

    def __rand__(self, other: Any) -> Condition:
        return All(_parts(All, "&", other, self))

    def __or__(self, other: Condition) -> Condition:
        return Any_(_parts(Any_, "|", self, other))

    def __ror__(self, other: Any) -> Condition:
        return Any_(_parts(Any_, "|", other, self))

    def __invert__(self) -> Condition:
        return Not(self)

    def __bool__(self) -> bool:
        raise TypeError(
            "a condition has no truth value here: combine conditions with &, | and ~ "
            "(not and, or, not), and write a < x < b as (a < x) & (x < b)"
        )


def _parts(kind: type, op: str, *items: Any) -> tuple[Condition, ...]:
    """The operands of an ``&`` or ``|``, those of the same operator spliced in (a | b | c
    is one alternative of three, not two nested)."""
    parts: list[Condition] = []
    for item in items:
        if isinstance(item, Quantity):
            raise TypeError(f"{op}: {item!r} is a quantity, not a condition: {_NOT_A_CONDITION}")
        if not isinstance(item, Condition):
            raise TypeError(
                f"{op}: expected a condition (e.g. Force.z < -10.0), got {type(item).__name__}"
            )
        parts.extend(item.parts if type(item) is kind else (item,))  # type: ignore[attr-defined]
    return tuple(parts)


@dataclass(frozen=True, eq=True)
class All(Condition):
    """Holds when all its parts hold (``a & b``); evaluates them in order, up to the first
    that does not."""

    parts: tuple[Condition, ...]

    def holds(self, state: StateView, progress: Progress) -> bool:
        for part in self.parts:
            if not part.holds(state, progress):
                return False
        return True

    def __repr__(self) -> str:
        return " & ".join(_paren(p) for p in self.parts)


@dataclass(frozen=True, eq=True)
class Any_(Condition):  # noqa: N801 (``Any`` is typing's)
    """Holds when one of its parts holds (``a | b``); evaluates them in order, up to the
    first that does."""

    parts: tuple[Condition, ...]

    def holds(self, state: StateView, progress: Progress) -> bool:
        for part in self.parts:
            if part.holds(state, progress):
                return True
        return False

    def which(self, state: StateView, progress: Progress) -> Condition | None:
        for part in self.parts:
            held = part.which(state, progress)
            if held is not None:
                return held
        return None

    def __repr__(self) -> str:
        return " | ".join(_paren(p) for p in self.parts)


@dataclass(frozen=True, eq=True)
class Not(Condition):
    """Holds when its part does not (``~a``)."""

    part: Condition

    def holds(self, state: StateView, progress: Progress) -> bool:
        return not self.part.holds(state, progress)

    def __invert__(self) -> Condition:
        return self.part

    def __repr__(self) -> str:
        return f"~{_paren(self.part)}"


def _paren(c: Condition) -> str:
    return f"({c!r})" if isinstance(c, (All, Any_, Compare)) else repr(c)


class _Comparable:
    """``<``, ``<=``, ``>``, ``>=`` against a number make a condition (``_compare``)."""

    def _compare(self, op: str, threshold: Any) -> Compare:
        raise NotImplementedError

    def __lt__(self, threshold: Any) -> Compare:
        return self._compare("<", threshold)

    def __le__(self, threshold: Any) -> Compare:
        return self._compare("<=", threshold)

    def __gt__(self, threshold: Any) -> Compare:
        return self._compare(">", threshold)

    def __ge__(self, threshold: Any) -> Compare:
        return self._compare(">=", threshold)


@dataclass(frozen=True, eq=True)
class Quantity(_Comparable):
    """A number read each tick: one value of a state field (``source``, ``index``), the
    Euclidean norm of its values ``start:stop``, a one-value field (``m_ee``; neither
    given), or ``"elapsed"``/``"distance"`` of the move's progress. Compare it with a
    number to get a condition: ``Force.z < -10.0``. ``name`` is how it prints."""

    name: str
    source: str
    index: int | None = None
    start: int = 0
    stop: int = 0

    def __post_init__(self) -> None:
        size = 1 if self.source in _PROGRESS else _SIZES.get(self.source, 0)
        if not size:
            raise ValueError(
                f"source: expected one of {sorted(_SIZES)} or {list(_PROGRESS)}, "
                f"got {self.source!r}"
            )
        if size == 1:
            if self.index is None and self.stop == 0:
                return
            raise ValueError(
                f"index, start, stop: {self.source} is one value, expected none, "
                f"got {self.index}, {self.start}, {self.stop}"
            )
        if self.index is not None:
            if not 0 <= self.index < size:
                raise ValueError(f"index: expected 0-{size - 1}, got {self.index}")
        elif not 0 <= self.start < self.stop <= size:
            raise ValueError(
                f"start, stop: expected 0 <= start < stop <= {size}, got {self.start}, {self.stop}"
            )

    def value(self, state: StateView, progress: Progress) -> float:
        """The quantity on ``state`` and ``progress`` (in the field's units)."""
        if self.index is not None:
            return float(getattr(state, self.source)[self.index])
        if self.stop:
            # hypot of Python floats: a third of np.dot's cost on a few values
            return math.hypot(*getattr(state, self.source)[self.start : self.stop].tolist())
        if self.source in _PROGRESS:
            return float(getattr(progress, self.source))
        return float(getattr(state, self.source))  # a one-value field (m_ee [kg])

    def _compare(self, op: str, threshold: Any) -> Compare:
        return Compare(self, op, _threshold(f"{self.name} {op}", threshold))

    def _not_a_condition(self, other: Any) -> Any:
        raise TypeError(f"{self.name} is a quantity, not a condition: {_NOT_A_CONDITION}")

    __and__ = __rand__ = __or__ = __ror__ = _not_a_condition

    def __invert__(self) -> Any:
        return self._not_a_condition(None)

    def __repr__(self) -> str:
        return self.name


def _threshold(what: str, threshold: Any) -> float:
    if isinstance(threshold, (bool, np.bool_)) or not isinstance(threshold, numbers.Real):
        raise ValueError(f"{what}: expected a finite number, got {threshold!r}")
    value = float(threshold)
    if not math.isfinite(value):
        raise ValueError(f"{what}: expected a finite number, got {value}")
    return value


@dataclass(frozen=True, eq=True)
class Compare(Condition):
    """Holds when ``quantity op threshold`` (op one of ``<``, ``<=``, ``>``, ``>=``)."""

    quantity: Quantity
    op: str
    threshold: float

    def holds(self, state: StateView, progress: Progress) -> bool:
        return _OPS[self.op](self.quantity.value(state, progress), self.threshold)

    def __repr__(self) -> str:
        return f"{self.quantity!r} {self.op} {self.threshold!r}"


class Field(_Comparable):
    """A float field of the robot state (libfranka's ``RobotState`` names and sizes, e.g.
    ``"tau_J"`` (7,) [Nm], ``"O_T_EE"`` (16,) column-major): ``Field("tau_J")[3]`` or
    ``Field("tau_J", 3)`` is one value (0-based), ``Field("dq").norm`` the Euclidean norm of
    them all; a one-value field (``"m_ee"``, ``"m_load"`` [kg]) compares as it is."""

    field: str  # the state's attribute
    label: str  # how it prints
    start: int  # the values it stands for: field[start:stop]
    stop: int
    _one: Quantity | None  # what it compares as: its one value (or given index), if any
    _single: bool  # one value: no index, no norm

    def __init__(self, name: str, index: int | None = None) -> None:
        if not isinstance(name, str) or name not in _SIZES:
            raise ValueError(
                f"Field(name): expected the name of a float field of the robot state, one of "
                f"{sorted(_SIZES)}, got {name!r}"
            )
        self._setup(name, f'Field("{name}")', 0, _SIZES[name])
        if index is not None:
            one = self[index]
            self._one = Quantity(f'Field("{name}", {one.index})', name, one.index)
            self._single = True

    @classmethod
    def _view(cls, field: str, label: str, start: int, stop: int) -> Any:
        """The values ``start:stop`` of ``field``, printed as ``label``."""
        view = cls.__new__(cls)
        view._setup(field, label, start, stop)
        return view

    def _setup(self, field: str, label: str, start: int, stop: int) -> None:
        self.field, self.label, self.start, self.stop = field, label, start, stop
        self._single = _SIZES[field] == 1
        self._one = Quantity(label, field) if self._single else None

    def __getitem__(self, index: Any) -> Quantity:
        """The value ``index`` (0-based) of the field."""
        n = self.stop - self.start
        if self._single:
            raise ValueError(f"{self._one!r}[]: is one value already, it has no index")
        if isinstance(index, (bool, np.bool_)) or not isinstance(index, numbers.Integral):
            raise ValueError(f"{self.label}[]: expected an index 0-{n - 1}, got {index!r}")
        if not 0 <= int(index) < n:
            raise ValueError(f"{self.label}[]: expected an index 0-{n - 1}, got {index}")
        return Quantity(f"{self.label}[{int(index)}]", self.field, self.start + int(index))

    @property
    def norm(self) -> Quantity:
        """The Euclidean norm of the field's values (in their units)."""
        if self._single:
            raise ValueError(f"{self._one!r}.norm: is one value already, compare it as it is")
        return Quantity(f"{self.label}.norm", self.field, None, self.start, self.stop)

    def _choices(self) -> str:
        return f"{self.label}[i] with i 0-{self.stop - self.start - 1}"

    def _compare(self, op: str, threshold: Any) -> Compare:
        if self._one is None:
            raise ValueError(
                f"{self.label} {op}: expected one value, {self.label} has "
                f"{self.stop - self.start}: compare {self._choices()}, or {self.label}.norm"
            )
        return self._one._compare(op, threshold)

    def __repr__(self) -> str:
        return repr(self._one) if self._single else self.label


class _Vector3(Field):
    """Three values of a field with named axes: ``.x``, ``.y``, ``.z``, ``.norm``."""

    @property
    def x(self) -> Quantity:
        """The value along the frame's x axis."""
        return self._axis(0, "x")

    @property
    def y(self) -> Quantity:
        """The value along the frame's y axis."""
        return self._axis(1, "y")

    @property
    def z(self) -> Quantity:
        """The value along the frame's z axis."""
        return self._axis(2, "z")

    def _axis(self, i: int, name: str) -> Quantity:
        return Quantity(f"{self.label}.{name}", self.field, self.start + i)

    def _choices(self) -> str:
        return f"{self.label}.x, .y, .z"


class _ErrorsHold(Condition):
    """Holds when the robot reports any error (``current_errors``)."""

    def holds(self, state: StateView, progress: Progress) -> bool:
        raw = getattr(state, "raw_fields", None)
        if raw is not None:
            # a RobotState: its error flags' bytes (0 or 1 each), without decoding the
            # whole state as current_errors does (0.4 us instead of 3)
            return raw(_ERRORS).strip(b"\0") != b""
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

    def holds(self, state: StateView, progress: Progress) -> bool:
        return bool(self.function(state))

    def __repr__(self) -> str:
        return f"when({getattr(self.function, '__qualname__', repr(self.function))})"


def when(function: Callable[[Any], Any]) -> Condition:
    """A condition from a function of the state (``f(state) -> bool``), evaluated in the
    control process every tick (keep it to a few microseconds: it runs within the 1 ms
    tick); an exception it raises ends the move with that error."""
    if not callable(function):
        raise ValueError(f"when: expected a function of the state, got {function!r}")
    return _When(function)


Force = _Vector3._view("O_F_ext_hat_K", "Force", 0, 3)
"""The external force on the environment in the base frame [N] (``O_F_ext_hat_K[0:3]``,
libfranka's sign: pressing down reads ``Force.z < 0``): ``Force.x``, ``.y``, ``.z``, ``.norm``."""
Moment = _Vector3._view("O_F_ext_hat_K", "Moment", 3, 6)
"""The external moment in the base frame [Nm] (``O_F_ext_hat_K[3:6]``): ``Moment.x``, ``.y``,
``.z``, ``.norm``."""
ForceEE = _Vector3._view("K_F_ext_hat_K", "ForceEE", 0, 3)
"""The external force in the stiffness frame K [N] (``K_F_ext_hat_K[0:3]``; the hand's z points
down, into it): ``.x``, ``.y``, ``.z``, ``.norm``."""
MomentEE = _Vector3._view("K_F_ext_hat_K", "MomentEE", 3, 6)
"""The external moment in the stiffness frame K [Nm] (``K_F_ext_hat_K[3:6]``): ``.x``, ``.y``,
``.z``, ``.norm``."""
Torque = Field._view("tau_ext_hat_filtered", "Torque", 0, 7)
"""The external joint torques [Nm] (``tau_ext_hat_filtered``): ``Torque[j]`` for joint j (0-6),
``Torque.norm``."""
Elapsed = Quantity("Elapsed", "elapsed")
"""The time since the move started [s]."""
Distance = Quantity("Distance", "distance")
"""The distance to the move's goal: [m] for a Cartesian move, the largest joint's [rad] for a
joint move."""
Errors = _ErrorsHold()
"""Holds when the robot reports an error (any flag of ``current_errors``)."""
