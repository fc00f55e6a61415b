"""Geometry of a Kunz-Stilman path: straight segments through the waypoints, joined by
circular blends whose deviation from the corner is bounded.

Reference: T. Kunz and M. Stilman, "Time-Optimal Trajectory Generation for Path Following
with Bounded Acceleration and Velocity", Robotics: Science and Systems VIII, 2012, section
III (path with circular blends). The path lives in R^n; every piece is written as

    q(σ) = start + x * f(σ) + y * g(σ),   σ in [0, length]  (arc length within the piece)

with ``f = σ, g = 0`` on a line (``x`` is its unit direction) and
``f = cos(σ/r) - 1, g = sin(σ/r)`` on an arc of radius ``r`` (``x`` is ``r`` times the unit
vector from the arc's centre to its start, ``y`` is ``r`` times the start tangent). Writing
the arc about its start rather than its centre keeps nearly straight blends (huge ``r``)
free of cancellation.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from panda_py.motion.errors import PlanningTimeoutError

DUPLICATE_TOLERANCE = 1e-12  # [path units] consecutive waypoints closer than this are merged
STRAIGHT_TOLERANCE = 1e-9  # [rad] smaller turns are passed straight through, no blend
REVERSAL_TOLERANCE = 1e-6  # [rad] turns closer than this to pi stop instead of blending

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Piece:
    """One line or circular arc of the path (see the module docstring for the formula)."""

    start: Array  # q at σ = 0
    x: Array  # line: unit direction; arc: r * unit vector centre -> start
    y: Array  # line: zeros; arc: r * unit tangent at the start
    length: float  # arc length of the piece
    radius: float  # math.inf on a line
    angle: float  # arc: the turn angle [rad]; line: 0
    corner: int  # arc: index of the waypoint it rounds; line: index of its first waypoint

    @property
    def is_arc(self) -> bool:
        return self.radius < math.inf


@dataclass(frozen=True)
class Path:
    """The pieces of a path and, for each node between pieces (and the two ends), whether
    the motion has to stop there (a corner that is not blended)."""

    pieces: list[Piece]
    stop: list[bool]  # len(pieces) + 1 entries


def check_deadline(deadline: float, timeout: float) -> None:
    """Raise :class:`PlanningTimeoutError` once ``time.perf_counter()`` passes ``deadline``."""
    if time.perf_counter() > deadline:
        raise PlanningTimeoutError(f"trajectory planning took longer than timeout={timeout} s")


def merge_duplicates(points: Array) -> NDArray[np.intp]:
    """Indices of the waypoints kept when consecutive (near-)duplicates are merged."""
    if len(points) < 2:
        return np.arange(len(points))
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    keep = np.concatenate(([True], step > DUPLICATE_TOLERANCE))
    return np.flatnonzero(keep)


def build_path(points: Array, max_deviation: float, deadline: float, timeout: float) -> Path:
    """Lines through ``points`` (shape (M, n), no consecutive duplicates), blended with
    circular arcs at the corners when ``max_deviation > 0``.

    At each corner the blend starts and ends ``ell`` before and after the waypoint, with
    ``ell = min(L_prev / 2, L_next / 2, δ sin(α/2) / (1 - cos(α/2)))`` for turn angle ``α``,
    so the arc passes within ``δ = max_deviation`` of the waypoint and blends never overlap
    (Kunz & Stilman 2012, eq. 3-5). The arc's radius is ``ell / tan(α/2)``.
    """
    m = len(points)
    if m < 2:
        return Path([], [True])
    deltas = np.diff(points, axis=0)
    lengths = np.linalg.norm(deltas, axis=1)
    units = deltas / lengths[:, None]
    # turn angle at each interior waypoint, atan2 form: exact for tiny and near-pi turns
    cos_turn = np.einsum("ij,ij->i", units[:-1], units[1:])
    perp = units[1:] - cos_turn[:, None] * units[:-1]
    sin_turn = np.linalg.norm(perp, axis=1)
    turns = np.arctan2(sin_turn, cos_turn)

    ell = np.zeros(m)  # blend reach at each waypoint (0: no blend)
    stop = np.zeros(m, dtype=bool)  # corner without a blend
    stop[0] = stop[-1] = True
    for i in range(1, m - 1):
        alpha = float(turns[i - 1])
        if alpha <= STRAIGHT_TOLERANCE:
            continue
        if max_deviation <= 0.0 or alpha >= math.pi - REVERSAL_TOLERANCE:
            stop[i] = True
            continue
        half = 0.5 * alpha
        # 1 - cos(α/2) = 2 sin²(α/4), exact for small α
        reach = max_deviation * math.sin(half) / (2.0 * math.sin(0.5 * half) ** 2)
        ell[i] = min(0.5 * float(lengths[i - 1]), 0.5 * float(lengths[i]), reach)

    pieces: list[Piece] = []
    node_stop: list[bool] = [True]
    zeros = np.zeros(points.shape[1])
    for i in range(m - 1):
        check_deadline(deadline, timeout)
        u = units[i]
        line_len = float(lengths[i]) - ell[i] - ell[i + 1]
        if line_len > DUPLICATE_TOLERANCE:
            pieces.append(Piece(points[i] + ell[i] * u, u, zeros, line_len, math.inf, 0.0, i))
            node_stop.append(bool(stop[i + 1]))
        if ell[i + 1] > 0.0:
            alpha = float(turns[i])
            radius = ell[i + 1] / math.tan(0.5 * alpha)
            normal = perp[i] / sin_turn[i]  # in-plane unit normal towards the centre
            start = points[i + 1] - ell[i + 1] * u
            pieces.append(
                Piece(start, -radius * normal, radius * u, radius * alpha, radius, alpha, i + 1)
            )
            node_stop.append(False)
    node_stop[-1] = True
    return Path(pieces, node_stop)


def piece_points(piece: Piece, sigma: Array) -> Array:
    """The points ``q(σ)`` of a piece at arc lengths ``sigma`` (shape (N,)) -> (N, n)."""
    if not piece.is_arc:
        return piece.start + sigma[:, None] * piece.x
    th = sigma / piece.radius
    return piece.start + np.outer(np.cos(th) - 1.0, piece.x) + np.outer(np.sin(th), piece.y)


def piece_tangents(piece: Piece, sigma: Array) -> Array:
    """The unit tangents ``q'(σ)`` of a piece at arc lengths ``sigma`` -> (N, n)."""
    if not piece.is_arc:
        return np.tile(piece.x, (len(sigma), 1))
    th = sigma / piece.radius
    return (np.outer(-np.sin(th), piece.x) + np.outer(np.cos(th), piece.y)) / piece.radius


def max_norm_on_arc(a: Array, b: Array, start: Array, stop: Array) -> Array:
    """``max over θ in [start_k, stop_k]`` of ``|a_g cos θ + b_g sin θ|``, for each
    sub-interval k and each group g; result shape (K, G).

    ``a`` and ``b`` have shape (G, d): G independent vectors of dimension d (d = 1 for a
    single joint); ``start``, ``stop`` shape (K,), each interval shorter than π. Rotated to
    start at 0, the squared norm is ``m + R cos(2θ - ψ)``, so the maximum lies at
    ``θ* = ψ/2 (mod π)`` when that is inside the interval, else at an end.
    """
    c0, s0 = np.cos(start)[:, None, None], np.sin(start)[:, None, None]
    a0 = a * c0 + b * s0  # shape (K, G, d): the sub-interval rotated to start at 0
    b0 = b * c0 - a * s0
    aa = np.einsum("kgd,kgd->kg", a0, a0)
    bb = np.einsum("kgd,kgd->kg", b0, b0)
    ab = np.einsum("kgd,kgd->kg", a0, b0)
    half_diff = 0.5 * (aa - bb)
    amplitude = np.hypot(half_diff, ab)
    theta_star = np.mod(0.5 * np.arctan2(ab, half_diff), math.pi)
    width = (stop - start)[:, None]
    end = a0 * np.cos(width)[..., None] + b0 * np.sin(width)[..., None]
    end_sq = np.einsum("kgd,kgd->kg", end, end)
    best = np.where(theta_star <= width, 0.5 * (aa + bb) + amplitude, np.maximum(aa, end_sq))
    return np.sqrt(np.maximum(best, 0.0))
