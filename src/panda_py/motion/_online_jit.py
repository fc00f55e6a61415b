""":class:`panda_py.motion.online.OnlinePose`'s per-tick output, compiled by numba: the
generator's aligned coordinates turned into the base frame's position, orientation, twist
and acceleration in one call of about a microsecond, where the same scalar Python
(``OnlinePose._publish_python``, the reference: tests hold them together) takes 8-10 us.

Imported on first use unless ``PANDA_PY_NO_JIT=1`` or numba is missing; compiled once
per machine and cached on disk under a key over this file (:mod:`panda_py.jitcache`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from panda_py import jitcache

__all__ = ["publish_pose"]

# the compile cache's key: the kernels compile this file alone (panda_py.jitcache)
KEY = jitcache.source_key([Path(__file__)])


@jitcache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _mv(A, x, i0, out, o0):  # type: ignore[no-untyped-def,unused-ignore]
    """``out[o0:o0+3] = A x[i0:i0+3]`` for a 3x3 ``A``."""
    x0, x1, x2 = x[i0], x[i0 + 1], x[i0 + 2]
    for r in range(3):
        out[o0 + r] = A[r, 0] * x0 + A[r, 1] * x1 + A[r, 2] * x2


@jitcache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _left_jacobian_times(x, y, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``J_l(x) y``: ``y + a (x × y) + b x × (x × y)`` (the rotation vector's left
    Jacobian, series expansions near 0 as the Python reference)."""
    x0, x1, x2 = x[0], x[1], x[2]
    y0, y1, y2 = y[0], y[1], y[2]
    th2 = x0 * x0 + x1 * x1 + x2 * x2
    if th2 < 1e-8:
        a, b = 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    else:
        th = math.sqrt(th2)
        a, b = (1.0 - math.cos(th)) / th2, (th - math.sin(th)) / (th2 * th)
    c0, c1, c2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
    d0, d1, d2 = x1 * c2 - x2 * c1, x2 * c0 - x0 * c2, x0 * c1 - x1 * c0
    out[0] = y0 + a * c0 + b * d0
    out[1] = y1 + a * c1 + b * d1
    out[2] = y2 + a * c2 + b * d2


@jitcache.keyed_jit(KEY, nogil=True, error_model="numpy")
def publish_pose(p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel):  # type: ignore[no-untyped-def,unused-ignore]
    """From the generator's position ``p``, velocity ``v`` and acceleration ``a`` (6,
    translation in frame ``Ft``, rotation vector about the anchor ``q0``/``R0`` in frame
    ``Fr``): ``position`` (3,), ``orientation`` (4, x y z w), ``twist`` and ``accel``
    (6,) in the base frame, in place."""
    xs = np.empty(3)
    _mv(Fr, p, 3, xs, 0)
    x0, x1, x2 = xs[0], xs[1], xs[2]
    th2 = x0 * x0 + x1 * x1 + x2 * x2
    th = math.sqrt(th2)
    if th < 1e-4:
        k, c = 0.5 - th2 / 48.0, 1.0 - th2 / 8.0
    else:
        k, c = math.sin(0.5 * th) / th, math.cos(0.5 * th)
    ex, ey, ez, ew = k * x0, k * x1, k * x2, c
    qx, qy, qz, qw = q0[0], q0[1], q0[2], q0[3]
    orientation[0] = qw * ex + qx * ew + qy * ez - qz * ey
    orientation[1] = qw * ey - qx * ez + qy * ew + qz * ex
    orientation[2] = qw * ez + qx * ey - qy * ex + qz * ew
    orientation[3] = qw * ew - qx * ex - qy * ey - qz * ez
    _mv(Ft, p, 0, position, 0)
    scratch = np.empty(6)
    _rates(v, twist, Ft, Fr, R0, xs, scratch)
    _rates(a, accel, Ft, Fr, R0, xs, scratch)


@jitcache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _rates(src, dst, Ft, Fr, R0, xs, scratch):  # type: ignore[no-untyped-def,unused-ignore]
    """A velocity or acceleration ``src`` (6, aligned frames) into ``dst`` (6, base
    frame): the angular part's world rate is ``R0 J_l(x) xd`` (without the Jacobian's
    rate, small for the small ``x`` the re-anchoring keeps)."""
    _mv(Ft, src, 0, dst, 0)
    rates, world = scratch[:3], scratch[3:]
    _mv(Fr, src, 3, rates, 0)
    _left_jacobian_times(xs, rates, world)
    _mv(R0, world, 0, dst, 3)
