"""Argument checks shared by every package area (client, simulator, math, controllers): each
raises a ``ValueError`` naming the argument, the expected shape or range with its unit, and
what was given, before anything is sent or changed.

Two flavours of vector: :func:`vector` gives a new float64 array (libfranka's setters, the
model); :func:`floats` gives plain Python floats, cheap to pack into shared memory (the
controllers' inputs, checked in the user's process: nothing reaches the control process
unchecked, and a robot is never sent a non-finite value)."""

from __future__ import annotations

import math
import operator
import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "MAX_TIMEOUT",
    "QUATERNION_NORM_TOL",
    "RIGID_TOL",
    "cpu_set",
    "cpus",
    "fast_floats",
    "floats",
    "matrix6",
    "nonnegative",
    "nonnegative_scalar",
    "number",
    "online_cpus",
    "quaternion",
    "rigid_errors",
    "rigid_message",
    "scalar",
    "timeout",
    "unit_interval",
    "vector",
]

#: The longest wait a caller may ask for [s]: finite, and small enough for every socket
#: and ``select`` (which reject, e.g., infinity or 1e300 with an ``OverflowError``).
MAX_TIMEOUT = 86400.0
# One tolerance for a quaternion's norm wherever one is given (move_to_pose,
# CartesianImpedance.set_control, CartesianTrajectory, ik): within it the quaternion is
# normalised, beyond it refused. Hand-typed four-decimal quaternions (0.7071, 0.7071, 0, 0)
# are 3e-5 off; a forgotten normalisation is percents off.
QUATERNION_NORM_TOL = 1e-3  # [-] |norm - 1|
# One test of "a rigid transform" wherever a pose or a frame is given (move_to_pose,
# CartesianTrajectory, ik, get_robot().set_K / set_EE): unit orthogonal x and y columns,
# z = x cross y (so det = +1), last row (0, 0, 0, 1), every deviation within this. The
# compiled kinematics test the same (kinematics/_ik.py's rigid_error and ROTATION_TOL,
# kept in the kernels' sources so that their cache follows an edit; a test holds the two
# equal).
RIGID_TOL = 1e-6  # [-]


def number(
    name: str,
    value: Any,
    unit: str = "",
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a finite float within ``[low, high]`` (``(`` / ``)`` where open)."""
    u = f" {unit}" if unit else ""
    try:
        if isinstance(value, (bool, str, bytes)):  # float() would take "5" and True
            raise TypeError(value)
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a number{u}, got {value!r}") from exc
    too_low = x <= low if low_open else x < low
    too_high = x >= high if high_open else x > high
    if not math.isfinite(x) or too_low or too_high:
        interval = _interval(low, high, low_open, high_open)
        raise ValueError(f"{name}: expected a finite number in {interval}{u}, got {value!r}")
    return x


def cpus(name: str, value: Any) -> tuple[int, ...] | None:
    """The CPUs a process may be pinned to (``os.sched_setaffinity``): ``None`` (no
    pinning), or a non-empty collection of CPU numbers this process may be moved to (an
    isolated one too: tried on the calling thread and switched back), as a sorted tuple.
    Linux only (other systems have no per-process affinity to set)."""
    if value is None:
        return None
    if not hasattr(os, "sched_setaffinity"):
        raise ValueError(f"{name}: pinning to CPUs needs Linux (sched_setaffinity), got {value!r}")
    expected = f"expected None or a non-empty set of CPU numbers from {online_cpus()}"
    if isinstance(value, (str, bytes, int)) or not hasattr(value, "__iter__"):
        raise ValueError(f"{name}: {expected}, got {value!r}")
    try:
        items = list(value)
        if any(isinstance(c, bool) for c in items):
            raise TypeError(value)
        chosen = {operator.index(c) for c in items}  # ints (NumPy's too), not 1.0 or True
    except TypeError:
        chosen = set()
    if not chosen or min(chosen) < 0:
        raise ValueError(f"{name}: {expected}, got {value!r}")
    before = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, chosen)
    except (OSError, OverflowError) as exc:  # offline, absent, or outside this cpuset
        reason = getattr(exc, "strerror", None) or str(exc)
        raise ValueError(f"{name}: {expected}, got {value!r} ({reason})") from None
    finally:
        os.sched_setaffinity(0, before)
    return tuple(sorted(chosen))


def online_cpus() -> list[int]:
    """The CPUs the machine has online (``/sys/devices/system/cpu/online``; where that
    cannot be read, those this process may run on)."""
    try:
        with open("/sys/devices/system/cpu/online") as f:
            return sorted(cpu_set(f.read()))
    except (OSError, ValueError):
        return sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []


def cpu_set(text: str) -> set[int]:
    """A kernel CPU list ("0-3,5", as in /sys/devices/system/cpu/*; "" for none) as a
    set; ValueError for anything else."""
    out: set[int] = set()
    for part in text.strip().split(","):
        if not part:
            continue
        first, _, last = part.partition("-")
        try:
            low, high = int(first), int(last or first)
        except ValueError:
            low, high = -1, -1
        if low < 0 or high < low:
            raise ValueError(f"expected a CPU list such as 0-3,5, got {text!r}")
        out.update(range(low, high + 1))
    return out


def _interval(low: float, high: float, low_open: bool, high_open: bool) -> str:
    lo = "(" if low_open or low == -math.inf else "["
    hi = ")" if high_open or high == math.inf else "]"
    return f"{lo}{low:g}, {high:g}{hi}"


def timeout(name: str, value: Any) -> float:
    """A wait [s]: finite, > 0 and at most :data:`MAX_TIMEOUT`."""
    return number(name, value, "[s]", low=0.0, low_open=True, high=MAX_TIMEOUT)


def vector(name: str, value: Any, n: int, unit: str = "") -> NDArray[np.float64]:
    """``value`` as a new finite float64 array of shape ``(n,)``; a 4x4 (n = 16) or 3x3
    (n = 9) matrix is accepted and flattened column-major, as libfranka stores them."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected {n} numbers {unit}, got {value!r}") from exc
    if (n == 16 and arr.shape == (4, 4)) or (n == 9 and arr.shape == (3, 3)):
        arr = arr.reshape(n, order="F")
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},) {unit}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected finite values {unit}, got {arr.tolist()}")
    return arr


_F64 = np.dtype(np.float64)


def all_finite(values: list[float]) -> bool:
    """Whether every one of a few floats is finite, in scalars (a NumPy call costs 20-30
    us on the cold caches of code that runs once per move): their sum is (inf - inf and
    NaN are NaN), or, where the sum overflowed, each one is."""
    total = sum(values)
    return total - total == 0.0 or all(math.isfinite(v) for v in values)


def fast_floats(name: str, value: Any, n: int, unit: str = "") -> list[float]:
    """:func:`floats` with a shortcut for the common case, a finite float64 array (n,)."""
    if type(value) is np.ndarray and value.dtype is _F64 and value.shape == (n,):
        values: list[float] = value.tolist()
        if all_finite(values):
            return values
    return floats(name, value, n, unit)


def floats(name: str, value: Any, n: int, unit: str = "") -> list[float]:
    """``value`` as ``n`` finite floats (any array-like of n elements, e.g. (n,) or (n, 1))."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.size == n:
        values = value.ravel().tolist()
    else:
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: expected {n} numbers {unit}, got {value!r}") from exc
        if arr.size != n or (arr.ndim > 1 and max(arr.shape) != n):
            raise ValueError(
                f"{name}: expected {n} values of shape ({n},) {unit}, got shape {arr.shape}"
            )
        if np.iscomplexobj(value):
            raise ValueError(f"{name}: expected real numbers {unit}, got {value!r}")
        values = arr.ravel().tolist()
    s = sum(values)
    if s - s != 0.0:  # NaN or infinity somewhere (or an overflowing sum)
        raise ValueError(f"{name}: expected finite values {unit}, got {values}")
    return values


def nonnegative(name: str, value: Any, n: int, unit: str = "") -> list[float]:
    values = floats(name, value, n, unit)
    if min(values) < 0.0:
        raise ValueError(f"{name}: expected values >= 0 {unit}, got {values}")
    return values


def scalar(name: str, value: Any, unit: str = "") -> float:
    return number(name, value, unit)


def nonnegative_scalar(name: str, value: Any, unit: str = "") -> float:
    return number(name, value, unit, low=0.0)


def unit_interval(name: str, value: Any) -> float:
    """A filter coefficient: a number in (0, 1] (1: no filtering)."""
    return number(name, value, low=0.0, low_open=True, high=1.0)


def quaternion(name: str, value: Any) -> list[float]:
    """A unit quaternion (x, y, z, w); within ``QUATERNION_NORM_TOL`` of unit norm it is
    normalised."""
    values = floats(name, value, 4, "(quaternion x, y, z, w)")
    norm = math.sqrt(sum(v * v for v in values))
    if not abs(norm - 1.0) <= QUATERNION_NORM_TOL:
        raise ValueError(f"{name}: expected a unit quaternion (x, y, z, w), got norm {norm}")
    return [v / norm for v in values]


def matrix6(name: str, value: Any, unit: str = "") -> list[float]:
    """A 6x6 symmetric positive semi-definite matrix, row-major."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a 6x6 matrix {unit}, got {value!r}") from exc
    if arr.shape != (6, 6):
        raise ValueError(f"{name}: expected shape (6, 6) {unit}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: expected finite values {unit}, got {arr.tolist()}")
    if not np.allclose(arr, arr.T, rtol=0.0, atol=1e-9 * max(1.0, float(abs(arr).max()))):
        raise ValueError(f"{name}: expected a symmetric matrix {unit}, got {arr.tolist()}")
    if np.linalg.eigvalsh(arr).min() < -1e-9 * max(1.0, float(abs(arr).max())):
        raise ValueError(f"{name}: expected a positive semi-definite matrix {unit}")
    return arr.ravel().tolist()


def rigid_errors(T: Any) -> NDArray[np.float64]:
    """The largest deviation [-] of each 4x4 of ``T`` ((4, 4) or (N, 4, 4), finite) from a
    rigid transform (see :data:`RIGID_TOL`): one value, or one per matrix."""
    try:
        a = np.asarray(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"T: expected 4x4 transforms, got {T!r}") from exc
    if a.shape[-2:] != (4, 4) or a.ndim not in (2, 3):
        raise ValueError(f"T: expected shape (4, 4) or (N, 4, 4), got shape {a.shape}")
    m = a.reshape(-1, 4, 4)
    if len(m) <= 8:  # a move's few targets: in scalars, a tenth of the vectorised cost
        err = np.array([rigid_error(rows) for rows in m.tolist()])
        return err if a.ndim == 3 else err.reshape(())
    x, y, z = m[:, :3, 0], m[:, :3, 1], m[:, :3, 2]
    err = np.stack(
        [
            np.abs((x * x).sum(axis=1) - 1.0),
            np.abs((y * y).sum(axis=1) - 1.0),
            np.abs((x * y).sum(axis=1)),
            np.abs(np.cross(x, y) - z).max(axis=1),
            np.abs(m[:, 3, :3]).max(axis=1),
            np.abs(m[:, 3, 3] - 1.0),
        ]
    ).max(axis=0)
    return err if a.ndim == 3 else err.reshape(())


def rigid_error(rows: list[list[float]]) -> float:
    """:func:`rigid_errors` of one 4x4 given as rows of floats (the same six terms)."""
    (x0, y0, z0, _), (x1, y1, z1, _), (x2, y2, z2, _), last = rows
    cx, cy, cz = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0  # x cross y
    return max(
        abs(x0 * x0 + x1 * x1 + x2 * x2 - 1.0),
        abs(y0 * y0 + y1 * y1 + y2 * y2 - 1.0),
        abs(x0 * y0 + x1 * y1 + x2 * y2),
        abs(cx - z0), abs(cy - z1), abs(cz - z2),
        abs(last[0]), abs(last[1]), abs(last[2]),
        abs(last[3] - 1.0),
    )  # fmt: skip


def rigid_message(name: str, deviation: float, index: int | None = None) -> str:
    """The message for a matrix that is finite but not a rigid transform."""
    where = "" if index is None else f" (batch index {index})"
    return (
        f"{name}: expected a rigid transform (orthonormal rotation with det +1, last row "
        f"0 0 0 1, tolerance {RIGID_TOL}){where}; largest deviation {deviation:.3g}"
    )
