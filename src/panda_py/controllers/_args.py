"""Argument checks for controller inputs and parameters, in the user's process.

Every check names the argument, what it expects and what it got, and returns plain
Python floats (cheap to pack into shared memory). Scalars go through the package's
:func:`panda_py._checks.number`; vectors come back as lists for the fast path. Nothing
reaches the control process unchecked: a robot is never sent a non-finite value.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py._checks import QUATERNION_NORM_TOL, number

__all__ = [
    "matrix6",
    "nonnegative",
    "quaternion",
    "unit_interval",
    "vector",
]


_F64 = np.dtype(np.float64)


def fast_vector(name: str, value: Any, n: int, unit: str = "") -> list[float]:
    """:func:`vector` with a shortcut for the common case, a finite float64 array (n,)."""
    if type(value) is np.ndarray and value.dtype is _F64 and value.shape == (n,):
        values: list[float] = value.tolist()
        s = sum(values)
        if s - s == 0.0:
            return values
    return vector(name, value, n, unit)


def vector(name: str, value: Any, n: int, unit: str = "") -> list[float]:
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
    values = vector(name, value, n, unit)
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
    values = vector(name, value, 4, "(quaternion x, y, z, w)")
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
