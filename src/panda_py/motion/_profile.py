"""Time-optimal velocity profile along a Kunz-Stilman path, in closed form.

Kunz & Stilman (RSS 2012) integrate the phase plane (s, ṡ) numerically: forward at maximum
path acceleration, backward at maximum deceleration, switching where the trajectory meets
the velocity limit curve. On a straight piece the bounds on ṡ and s̈ are constants
(``V = min_i v_i/|u_i|``, ``A = min_i a_i/|u_i|``), so those integrals are parabolas
ṡ² = ṡ0² ± 2A(s - s0) and the switching points are their intersections with each other and
with ṡ = V: a forward pass and a backward pass over the nodes between pieces give the
optimal speed at every node, and each line is a trapezoid or a triangle between them.

On a circular blend the bounds vary with the angle. The blend is cut into short stretches
(at most ARC_STRETCH_ANGLE wide), and on each the largest constant bounds (V, A) are taken
that keep ``|q'| ṡ <= v`` and ``|q'| |s̈| + |q''| ṡ² <= a`` everywhere on the stretch
(closed-form maxima of sinusoids, :func:`~panda_py.motion._path.max_norm_on_arc`), with V
a fixed fraction of the top constant speed so that some acceleration remains. The profile
is then exactly optimal for these piecewise-constant bounds, which lie inside the true ones:
blends are the one place where it is conservative rather than exactly time-optimal.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from panda_py.motion._path import Array, Path, Piece, check_deadline, max_norm_on_arc
from panda_py.motion.errors import TrajectoryError

ARC_STRETCH_ANGLE = math.pi / 32  # [rad] blends are bounded in stretches this wide at most
ARC_SPEED_FRACTION = 0.95  # [-] of a stretch's top constant speed, leaving room to accelerate


class Bounds(Protocol):
    """The robot's bounds on groups of path coordinates (a joint; a translation or a
    rotation): ``|q̇_g| <= velocity[g]``, ``|q̈_g| <= acceleration[g]``. Bounds that vary
    along lines too also have ``stretches(k, piece) -> (lengths, V, A)``: piece ``k`` in
    stretches of constant bounds (the profile then asks them for every piece)."""

    velocity: Array
    acceleration: Array

    def line(self, direction: Array) -> tuple[float, float]:
        """Max path speed and acceleration on a line with unit ``direction``."""
        ...

    def arc_coefficients(self, piece: Piece, start: Array, stop: Array) -> tuple[Array, Array]:
        """For each sub-arc θ in [start_k, stop_k] (shape (K,)) and group g, ``m1[k, g]``
        and ``m2[k, g]`` with ``|q̇_g| <= m1 ṡ`` and ``|q̈_g| <= m1 |s̈| + m2 ṡ²`` there."""
        ...


class BoxBounds:
    """Independent bounds on each coordinate: ``|q̇_i| <= v_i``, ``|q̈_i| <= a_i``."""

    def __init__(self, velocity: Array, acceleration: Array) -> None:
        self.velocity = velocity
        self.acceleration = acceleration

    def line(self, direction: Array) -> tuple[float, float]:
        mag = np.abs(direction)
        with np.errstate(divide="ignore"):
            return float(np.min(self.velocity / mag)), float(np.min(self.acceleration / mag))

    def arc_coefficients(self, piece: Piece, start: Array, stop: Array) -> tuple[Array, Array]:
        r = piece.radius
        xu = (piece.x / r)[:, None]
        yu = (piece.y / r)[:, None]
        # q'(θ) = -sin θ xu + cos θ yu;  q''(θ) = -(cos θ xu + sin θ yu) / r
        m1 = max_norm_on_arc(yu, -xu, start, stop)
        m2 = max_norm_on_arc(xu, yu, start, stop) / r
        return m1, m2


def arc_stretches(bounds: Bounds, piece: Piece) -> tuple[Array, Array, Array]:
    """Split a blend into stretches with constant bounds: lengths, max path speeds ``V``
    and accelerations ``A`` with ``m1 A + m2 V² <= a`` and ``m1 V <= v`` for every group,
    so any motion with ``ṡ <= V``, ``|s̈| <= A`` keeps the robot's bounds on the stretch."""
    count = max(1, math.ceil(piece.angle / ARC_STRETCH_ANGLE))
    edges = np.linspace(0.0, piece.angle, count + 1)
    m1, m2 = bounds.arc_coefficients(piece, edges[:-1], edges[1:])
    with np.errstate(divide="ignore"):
        top = np.minimum(
            np.min(bounds.velocity / m1, axis=1), np.sqrt(np.min(bounds.acceleration / m2, axis=1))
        )
        speed = ARC_SPEED_FRACTION * top
        accel = np.min((bounds.acceleration - m2 * (speed * speed)[:, None]) / m1, axis=1)
    return np.diff(edges) * piece.radius, speed, accel


def stretch_bounds(
    m1: Array, m2: Array, velocity: Array, acceleration: Array,
    fraction: Array,
) -> tuple[Array, Array]:  # fmt: skip
    """Per stretch k (rows of ``m1``, ``m2``: shape (K, G)) the max path speed ``V`` and
    acceleration ``A`` with ``m1 A + m2 V² <= a`` and ``m1 V <= v`` for every group, so
    any motion with ``ṡ <= V``, ``|s̈| <= A`` keeps the bounds on the stretch. ``V`` is at
    most ``fraction[g]`` of the speed at which ``m2 V²`` takes all of group g's
    acceleration, leaving ``1 - fraction[g]²`` of it to speed up and slow down with."""
    with np.errstate(divide="ignore", invalid="ignore"):
        top = np.min(velocity / m1, axis=1)
        speed = np.minimum(top, np.min(fraction * np.sqrt(acceleration / m2), axis=1))
        accel = np.min((acceleration - m2 * (speed * speed)[:, None]) / m1, axis=1)
    return speed, accel


# One constant-acceleration stretch of the profile:
# (t0, σ0, ṡ0, s̈, start, x, y, 1/radius (0 on a line), piece index)
Segment = tuple[float, float, float, float, Array, Array, Array, float, int]


class Profile:
    """The time parametrisation of a path; evaluates q, q̇, q̈ at any time [s]."""

    def __init__(
        self,
        path: Path,
        bounds: Bounds,
        first: Array,
        last: Array,
        deadline: float,
        timeout: float,
    ) -> None:
        self.path = path
        self.first = first
        self.last = last
        pieces = path.pieces
        # stretches of constant bounds: (piece, σ offset, length, V, A); stop at its end?
        stretches: list[tuple[int, float, float, float, float]] = []
        stop_after: list[bool] = []
        split = getattr(bounds, "stretches", None)  # bounds that vary along lines too
        for k, piece in enumerate(pieces):
            check_deadline(deadline, timeout)
            if split is not None:
                lengths, speeds, accels = split(k, piece)
                offset = 0.0
                for i, (length, v, a) in enumerate(
                    zip(lengths.tolist(), speeds.tolist(), accels.tolist(), strict=True)
                ):
                    stretches.append((k, offset, length, v, a))
                    final = i == len(lengths) - 1
                    stop_after.append(final and not piece.is_arc and path.stop[k + 1])
                    offset += length
            elif piece.is_arc:
                lengths, speeds, accels = arc_stretches(bounds, piece)
                offset = 0.0
                for length, v, a in zip(
                    lengths.tolist(), speeds.tolist(), accels.tolist(), strict=True
                ):
                    stretches.append((k, offset, length, v, a))
                    stop_after.append(False)
                    offset += length
            else:
                v, a = bounds.line(piece.x)
                stretches.append((k, 0.0, piece.length, v, a))
                stop_after.append(path.stop[k + 1])
        n = len(stretches)

        # speed at each node between stretches: caps, then the max-acceleration forward and
        # max-deceleration backward integrations (the switching-point search, closed form)
        speed = [0.0] * (n + 1)
        for j in range(1, n):
            speed[j] = 0.0 if stop_after[j - 1] else min(stretches[j - 1][3], stretches[j][3])
        gain = [2.0 * st[4] * st[2] for st in stretches]
        for j in range(n):
            speed[j + 1] = min(speed[j + 1], math.sqrt(speed[j] ** 2 + gain[j]))
        for j in range(n - 1, -1, -1):
            speed[j] = min(speed[j], math.sqrt(speed[j + 1] ** 2 + gain[j]))

        segments: list[Segment] = []
        t = 0.0
        for j, (k, offset, length, vmax, amax) in enumerate(stretches):
            check_deadline(deadline, timeout)
            piece = pieces[k]
            geo = (piece.start, piece.x, piece.y, 1.0 / piece.radius, k)
            for sigma0, v0, acc, dur in _line_profile(length, speed[j], speed[j + 1], vmax, amax):
                segments.append((t, offset + sigma0, v0, acc, *geo))
                t += dur
        self.duration = t
        self.segments = segments
        self._t0 = [s[0] for s in segments]
        # the same, as arrays, for vectorised sampling
        self._seg_arr = np.array([s[:4] for s in segments], dtype=float).reshape(-1, 4)
        self._seg_piece = np.array([s[8] for s in segments], dtype=np.intp)
        dim = len(first)
        self._start = np.array([p.start for p in pieces]).reshape(-1, dim)
        self._x = np.array([p.x for p in pieces]).reshape(-1, dim)
        self._y = np.array([p.y for p in pieces]).reshape(-1, dim)
        self._inv_r = np.array([1.0 / p.radius for p in pieces])  # 0 on lines

    # -- scalar evaluation: the hot path, Python floats and two small numpy operations --

    def position(self, time: float) -> Array:
        t = float(time)
        if 0.0 <= t < self.duration:
            t0, s0, v0, acc, start, x, y, inv_r, _ = self.segments[bisect_right(self._t0, t) - 1]
            dt = t - t0
            s = s0 + dt * (v0 + 0.5 * acc * dt)
            if inv_r == 0.0:
                return start + x * s
            th = s * inv_r
            h = math.sin(0.5 * th)
            return start + x * (-2.0 * h * h) + y * math.sin(th)
        return self._outside(t, False)

    def velocity(self, time: float) -> Array:
        t = float(time)
        if 0.0 <= t < self.duration:
            t0, s0, v0, acc, _, x, y, inv_r, _ = self.segments[bisect_right(self._t0, t) - 1]
            dt = t - t0
            sd = v0 + acc * dt
            if inv_r == 0.0:
                return x * sd
            th = (s0 + dt * (v0 + 0.5 * acc * dt)) * inv_r
            return x * (-math.sin(th) * inv_r * sd) + y * (math.cos(th) * inv_r * sd)
        return self._outside(t, True)

    def acceleration(self, time: float) -> Array:
        t = float(time)
        if 0.0 <= t < self.duration:
            t0, s0, v0, acc, _, x, y, inv_r, _ = self.segments[bisect_right(self._t0, t) - 1]
            if inv_r == 0.0:
                return x * acc
            dt = t - t0
            s = s0 + dt * (v0 + 0.5 * acc * dt)
            sd = v0 + acc * dt
            th = s * inv_r
            c, sn = math.cos(th), math.sin(th)
            k2 = inv_r * inv_r * sd * sd
            return x * (-sn * inv_r * acc - c * k2) + y * (c * inv_r * acc - sn * k2)
        return self._outside(t, True)

    def locate(self, time: float) -> tuple[int, float, float, float] | None:
        """(piece index, σ, σ̇, σ̈) at ``time``, or None outside [0, duration)."""
        t = float(time)
        if 0.0 <= t < self.duration:
            t0, s0, v0, acc, *_, k = self.segments[bisect_right(self._t0, t) - 1]
            dt = t - t0
            return k, s0 + dt * (v0 + 0.5 * acc * dt), v0 + acc * dt, acc
        if t != t:
            raise ValueError(f"time: expected a finite number [s], got {time!r}")
        return None

    def _outside(self, t: float, derivative: bool) -> Array:
        """At rest on the first waypoint before the start and on the last one from the end
        on (a derivative is then zero); NaN is an error."""
        if t != t:
            raise ValueError(f"time: expected a finite number [s], got {t!r}")
        if derivative:
            return np.zeros_like(self.first)
        return (self.first if t < 0.0 else self.last).copy()

    # -- vectorised evaluation --

    def evaluate(self, times: object) -> tuple[Array, Array, Array, NDArray[np.intp]]:
        """q, q̇, q̈ at every time in ``times`` (any shape S) as arrays of shape S + (n,), and
        the index of the piece each time falls in (-1 before the start and from the end)."""
        t = np.asarray(times, dtype=float)
        if not np.all(np.isfinite(t)):
            raise ValueError("times: expected finite numbers [s], got NaN or infinity")
        shape = t.shape
        t = t.reshape(-1)
        dim = len(self.first)
        pos = np.empty((t.size, dim))
        vel = np.zeros((t.size, dim))
        acc = np.zeros((t.size, dim))
        piece = np.full(t.size, -1, dtype=np.intp)
        inside = (t >= 0.0) & (t < self.duration)
        pos[t < 0.0] = self.first
        pos[t >= self.duration] = self.last
        if np.any(inside):
            ti = t[inside]
            seg = np.searchsorted(self._seg_arr[:, 0], ti, side="right") - 1
            t0, s0, v0, a = self._seg_arr[seg].T
            dt = ti - t0
            s = s0 + dt * (v0 + 0.5 * a * dt)
            sd = v0 + a * dt
            k = self._seg_piece[seg]
            ir = self._inv_r[k]
            arc = ir > 0.0
            th = s * ir
            sn, c = np.sin(th), np.cos(th)
            # q = start + x f + y g, derivatives by σ: (f', g'), (f'', g'')
            f = np.where(arc, -2.0 * np.sin(0.5 * th) ** 2, s)
            fd = np.where(arc, -sn * ir, 1.0)
            gd = c * ir
            fdd = -c * ir * ir
            gdd = -sn * ir * ir
            x, y = self._x[k], self._y[k]
            tangent = x * fd[:, None] + y * gd[:, None]
            pos[inside] = self._start[k] + x * f[:, None] + y * sn[:, None]
            vel[inside] = tangent * sd[:, None]
            acc[inside] = (
                tangent * a[:, None] + (x * fdd[:, None] + y * gdd[:, None]) * (sd * sd)[:, None]
            )
            piece[inside] = k
        return (
            pos.reshape(*shape, dim),
            vel.reshape(*shape, dim),
            acc.reshape(*shape, dim),
            piece.reshape(shape),
        )


def _line_profile(
    length: float, v_in: float, v_out: float, vmax: float, amax: float
) -> list[tuple[float, float, float, float]]:
    """Time-optimal motion along a stretch with constant bounds from speed ``v_in`` to
    ``v_out``: accelerate at ``amax``, cruise at ``vmax`` if it is reached, decelerate at
    ``amax``. Returns ``(σ0, ṡ0, s̈, duration)`` per non-empty phase."""
    if amax <= 0.0:  # no acceleration possible: the passes made v_in == v_out
        v = 0.5 * (v_in + v_out)
        if v <= 0.0:
            raise TrajectoryError("a stretch of the path can be traversed at zero speed only")
        return [(0.0, v, 0.0, length / v)]
    peak_sq = amax * length + 0.5 * (v_in * v_in + v_out * v_out)
    peak = vmax if peak_sq > vmax * vmax else math.sqrt(peak_sq)
    peak = max(peak, v_in, v_out)
    d_acc = (peak * peak - v_in * v_in) / (2.0 * amax)
    d_dec = (peak * peak - v_out * v_out) / (2.0 * amax)
    cruise = max(length - d_acc - d_dec, 0.0)
    phases = []
    t_acc = (peak - v_in) / amax
    if t_acc > 0.0:
        phases.append((0.0, v_in, amax, t_acc))
    if cruise > 0.0 and peak > 0.0:
        phases.append((d_acc, peak, 0.0, cruise / peak))
    t_dec = (peak - v_out) / amax
    if t_dec > 0.0:
        phases.append((length - d_dec, peak, -amax, t_dec))
    return phases
