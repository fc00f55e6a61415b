"""The elementary functions the kinematics code calls, as plain Python (``math``'s).

Under the JIT, :mod:`._numba` registers the branch-free versions of :mod:`._nbmath` in
their place, so the solvers' source names one ``atan2`` and one ``sincos`` and each
backend brings its own.
"""

from __future__ import annotations

import math


def atan2(y: float, x: float) -> float:
    """atan2(y, x) [rad] in [-pi, pi]."""
    return math.atan2(y, x)


def sincos(x: float) -> tuple[float, float]:
    """(sin x, cos x)."""
    return math.sin(x), math.cos(x)


def flip(angle: float) -> float:
    """angle + pi, wrapped to (-pi, pi] the way the shoulder flip needs it."""
    return angle - math.pi if angle > 0.0 else angle + math.pi
