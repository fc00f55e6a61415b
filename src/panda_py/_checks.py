"""Argument checks shared by every package area (client, simulator, math): each raises a
``ValueError`` naming the argument, the expected shape or range with its unit, and what
was given, before anything is sent or changed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_TIMEOUT", "QUATERNION_NORM_TOL", "number", "timeout", "vector"]

#: The longest wait a caller may ask for [s]: finite, and small enough for every socket
#: and ``select`` (which reject, e.g., infinity or 1e300 with an ``OverflowError``).
MAX_TIMEOUT = 86400.0
# One tolerance for a quaternion's norm wherever one is given (move_to_pose,
# CartesianImpedance.set_control, CartesianTrajectory, ik): within it the quaternion is
# normalised, beyond it refused. Hand-typed four-decimal quaternions (0.7071, 0.7071, 0, 0)
# are 3e-5 off; a forgotten normalisation is percents off.
QUATERNION_NORM_TOL = 1e-3  # [-] |norm - 1|


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
