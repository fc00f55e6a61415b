"""Input checks shared by the kinematics API: every bad argument is a ValueError that names
the argument, what was expected and what was given."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from panda_py import checks
from panda_py.checks import QUATERNION_NORM_TOL
from panda_py.kinematics import _backend, _ik
from panda_py.kinematics._ik import ROTATION_TOL

__all__ = ["ROTATION_TOL"]
# A quaternion's norm may differ from 1 by this much [-]; it is normalised (the one
# tolerance of every entry point that takes quaternions).
QUATERNION_TOL = QUATERNION_NORM_TOL


def _describe(x: object) -> str:
    a = np.asarray(x) if not isinstance(x, np.ndarray) else x
    if a.dtype == object:
        return f"{type(x).__name__} {x!r:.60}"
    return f"array of shape {a.shape} and dtype {a.dtype}"


def as_float_array(name: str, x: object) -> NDArray[np.float64]:
    """x as float64; a ValueError for anything else, complex numbers included (NumPy
    would drop their imaginary part with a warning)."""
    if np.iscomplexobj(x):  # type: ignore[arg-type]
        raise ValueError(f"{name}: expected real numbers, got complex values: {_describe(x)}")
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected an array of real numbers, got {_describe(x)}") from exc
    return a


def check_finite(name: str, a: NDArray[np.float64], item_ndim: int | None = None) -> None:
    """All of a finite; in a batch (``a.ndim > item_ndim``) the message names the first
    item with a NaN or infinity."""
    if not np.all(np.isfinite(a)):
        where = ""
        if item_ndim is not None and a.ndim > item_ndim:
            bad = ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
            where = f" (batch index {int(np.flatnonzero(bad)[0])})"
        raise ValueError(
            f"{name}: expected finite values, got NaN or infinity{where} in {a!r:.200}"
        )


def joints(name: str, x: object, *, check: bool = True) -> NDArray[np.float64]:
    """(7,) or (N, 7) joint positions [rad]; a (7, 1) column is taken as (7,). With
    ``check=False`` the values are not tested for being finite (a kernel does that)."""
    a = as_float_array(name, x)
    if a.shape == (7, 1):
        a = a[:, 0]
    if a.ndim not in (1, 2) or a.shape[-1] != 7:
        raise ValueError(
            f"{name}: expected 7 joint positions [rad] as shape (7,) or a batch (N, 7), "
            f"got {_describe(x)}"
        )
    if check:
        check_finite(name, a, 1)
    return a


def transforms(name: str, x: object, *, check: bool = True) -> NDArray[np.float64]:
    """(4, 4) or (N, 4, 4) homogeneous transforms, checked to be finite and rigid (unless
    ``check=False``: the ik kernels test each pose themselves, see ``_ik.ik_range``)."""
    a = as_float_array(name, x)
    if a.ndim not in (2, 3) or a.shape[-2:] != (4, 4):
        raise ValueError(
            f"{name}: expected a 4x4 homogeneous transform or a batch (N, 4, 4), got {_describe(x)}"
        )
    if check:
        check_rigid(name, a)
    return a


def check_rigid(name: str, a: NDArray[np.float64]) -> None:
    """ValueError unless every 4x4 in a ((4, 4) or (N, 4, 4)) is finite and rigid (the
    kernels' own test, ``_ik.rigid_error``); a batch names its first bad item."""
    check_finite(name, a, 2)
    if a.ndim == 2:  # one matrix: no need to load the JIT for it
        err = np.array([_ik.rigid_error(*a.ravel().tolist())])
    else:
        err = _backend.rigid_errors(np.ascontiguousarray(a, dtype=np.float64))
    bad = ~(err <= ROTATION_TOL)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(rigid_message(name, float(err[i]), i if a.ndim == 3 else None))


rigid_message = checks.rigid_message


def position_orientation(position: object, orientation: object) -> NDArray[np.float64]:
    """(3,) position [m] and (4,) quaternion (x, y, z, w), or batches (N, 3) and (N, 4), as
    (4, 4) / (N, 4, 4) transforms."""
    p = as_float_array("position", position)
    o = as_float_array("orientation", orientation)
    if p.ndim not in (1, 2) or p.shape[-1] != 3:
        raise ValueError(f"position: expected shape (3,) or (N, 3) [m], got {_describe(position)}")
    if o.ndim not in (1, 2) or o.shape[-1] != 4:
        raise ValueError(
            "orientation: expected a quaternion (x, y, z, w) of shape (4,) or (N, 4), "
            f"got {_describe(orientation)}"
        )
    if p.shape[:-1] != o.shape[:-1]:
        raise ValueError(
            f"position, orientation: batch sizes differ, got shapes {p.shape} and {o.shape}"
        )
    check_finite("position", p, 1)
    check_finite("orientation", o, 1)
    norm = np.linalg.norm(o, axis=-1)
    if np.any(np.abs(norm - 1.0) > QUATERNION_TOL):
        raise ValueError(
            f"orientation: expected a unit quaternion (|q| = 1 within {QUATERNION_TOL}), "
            f"got norm {np.atleast_1d(norm).flat[0]:.9g}"
        )
    x, y, z, w = np.moveaxis(o / norm[..., None], -1, 0)
    T = np.zeros((*p.shape[:-1], 4, 4))
    T[..., 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    T[..., 0, 1] = 2.0 * (x * y - z * w)
    T[..., 0, 2] = 2.0 * (x * z + y * w)
    T[..., 1, 0] = 2.0 * (x * y + z * w)
    T[..., 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    T[..., 1, 2] = 2.0 * (y * z - x * w)
    T[..., 2, 0] = 2.0 * (x * z - y * w)
    T[..., 2, 1] = 2.0 * (y * z + x * w)
    T[..., 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def scalar_or_batch(
    name: str, x: object, n: int | None, unit: str, *, check: bool = True
) -> NDArray[np.float64]:
    """A float, or (N,) matching a batch of n (finite unless ``check=False``)."""
    a = as_float_array(name, x)
    if a.ndim == 0 or (a.ndim == 1 and n is not None and a.shape[0] == n):
        if check:
            check_finite(name, a, 0)
        return a
    want = "a number" if n is None else f"a number or shape ({n},)"
    raise ValueError(f"{name}: expected {want} [{unit}], got {_describe(x)}")


def nonnegative(name: str, x: object, unit: str) -> float:
    try:
        v = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a number >= 0 [{unit}], got {x!r}") from exc
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name}: expected a finite number >= 0 [{unit}], got {x!r}")
    return v
