"""Branch-free ``atan2`` and ``sincos`` for the numba kernels, within 3 ulp of libm's.

Plain (numba-compatible) Python: :mod:`._numba` compiles them in place of
:mod:`._scalar`'s ``atan2`` and ``sincos`` (which call libm, the faster choice when Python
runs the kernels' source plain).

The kernels spend most of their time in the C library's ``atan2``, ``sin`` and ``cos``:
function calls with argument-dependent branches, which random poses mispredict. These
versions take one predictable branch (to the C library for NaN, infinity, both
arguments zero, or |x| >= 1e5 for sincos, so special values follow libm exactly) and
otherwise evaluate a short exact reduction and a series:

* :func:`atan2`: ``a = min(|x|, |y|) / max(|x|, |y|)`` in [0, 1] is split as
  ``atan(a) = atan(c) + atan((a - c) / (1 + a c))`` with ``c`` the nearest sixteenth,
  so the remaining argument is below 1/32 and five odd Taylor terms leave less than
  1e-19; the octant follows from the signs and which of |x|, |y| is larger, with pi and
  pi/2 added in two parts.
* :func:`sincos`: Cody-Waite reduction by the nearest multiple k of pi/2 (pi/2 in three
  parts, the first two short enough that k times them is exact), Taylor series on
  [-pi/4, pi/4] through r^17 and r^18 (truncation below 1e-19), then the quadrant.

Compiled with fused multiply-adds allowed (fastmath "contract" alone). Tests hold both
within 3 ulp of ``math`` over random and special arguments.
"""

from __future__ import annotations

import math
from decimal import Decimal
from fractions import Fraction

import numpy as np

# pi to 50 digits; the splits below are computed exactly from it.
_PI_EXACT = Fraction(Decimal("3.14159265358979323846264338327950288419716939937510"))


def _split(value: Fraction, bits: int) -> tuple[float, Fraction]:
    """value's leading ``bits`` bits as a float, and the exact remainder."""
    e = math.frexp(float(value))[1]
    scale = Fraction(2) ** (bits - e)
    head = Fraction(round(value * scale)) / scale
    return float(head), value - head


_PIO2_1, _rest = _split(_PI_EXACT / 2, 33)
_PIO2_2, _rest = _split(_rest, 33)
_PIO2_3 = float(_rest)
_PI_HI = float(_PI_EXACT)
_PI_LO = float(_PI_EXACT - Fraction(_PI_HI))
_PIO2_HI = float(_PI_EXACT / 2)
_PIO2_LO = float(_PI_EXACT / 2 - Fraction(_PIO2_HI))
_TWO_OVER_PI = float(2 / _PI_EXACT)
# atan(i / 16), i = 0..16, from the C library
_ATAN16 = np.array([math.atan(i / 16.0) for i in range(17)])
# Taylor coefficients (-1)^k / (2k+1)! for k = 1..8 and (-1)^k / (2k)! for k = 1..9
_S = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(1, 9))
_C = tuple((-1) ** k / math.factorial(2 * k) for k in range(1, 10))
# Up to this |x| [rad] the reduction's products are exact (k < 2^20); beyond it, libm.
SINCOS_MAX = 1e5
_BIG = 1.7976931348623157e308  # the largest finite float


def atan2(y: float, x: float) -> float:
    """atan2(y, x) [rad] in [-pi, pi], within 3 ulp of ``math.atan2``."""
    ax, ay = abs(x), abs(y)
    if not (ax <= _BIG and ay <= _BIG) or (ax == 0.0 and ay == 0.0):
        return math.atan2(y, x)  # NaN, infinity, (+-0, +-0): the C library's conventions
    a = min(ax, ay) / max(ax, ay)
    i = int(a * 16.0 + 0.5)
    c = i * 0.0625
    t = (a - c) / (1.0 + a * c)
    t2 = t * t
    p = t2 * (1.0 / 3.0 - t2 * (0.2 - t2 * (1.0 / 7.0 - t2 * (1.0 / 9.0 - t2 * (1.0 / 11.0)))))
    r = _ATAN16[i] + (t - t * p)  # atan(a), in [0, pi/4]
    # The octant by selects, not branches: |y| <= |x|: r (x >= 0) or pi - r (x < 0);
    # |y| > |x|: pi/2 - r (x >= 0) or pi/2 + r (x < 0).
    swap = ay > ax
    neg = x < 0.0
    hi = _PIO2_HI if swap else (_PI_HI if neg else 0.0)
    lo = _PIO2_LO if swap else (_PI_LO if neg else 0.0)
    r = (hi + (r if swap == neg else -r)) + lo
    return math.copysign(r, y)


def sincos(x: float) -> tuple[float, float]:
    """(sin x, cos x), each within 3 ulp of ``math.sin``/``math.cos``."""
    if not abs(x) < SINCOS_MAX:
        return math.sin(x), math.cos(x)  # large, infinite or NaN: the C library
    k = math.floor(x * _TWO_OVER_PI + 0.5)
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    r2 = r * r
    ps = _S[7]
    for j in range(6, -1, -1):
        ps = _S[j] + r2 * ps
    pc = _C[8]
    for j in range(7, -1, -1):
        pc = _C[j] + r2 * pc
    s = r + r * r2 * ps
    c = 1.0 + r2 * pc
    # (sin, cos) of r + k pi/2: (s, c), (c, -s), (-s, -c), (-c, s), by selects
    q = int(k) & 3
    odd = (q & 1) == 1
    sv = c if odd else s
    cv = s if odd else c
    return (-sv if q & 2 else sv), (-cv if (q + 1) & 2 else cv)
