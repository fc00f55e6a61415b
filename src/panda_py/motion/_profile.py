"""Time-optimal velocity profile along a Kunz-Stilman path, in closed form.

Kunz & Stilman (RSS 2012) integrate the phase plane (s, ṡ) numerically: forward at maximum
path acceleration, backward at maximum deceleration, switching where the trajectory meets
the velocity limit curve. On a straight piece the bounds on ṡ and s̈ are constants
(``V = min_i v_i/|u_i|``, ``A = min_i a_i/|u_i|``), so those integrals are parabolas
ṡ² = ṡ0² ± 2A(s - s0) and the switching points are their intersections with each other and
with ṡ = V: a forward pass and a backward pass over the nodes between pieces give the
optimal speed at every node, and each line is a trapezoid or a triangle between them.

A circular blend is traversed at constant speed: the highest speed whose velocity and
centripetal acceleration stay within the bounds over the whole arc (a closed-form maximum,
see :func:`~panda_py.motion._path.max_norm_on_arc`). This is the one place where the
profile is conservative rather than exactly optimal; blends are short, so the cost is small.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from typing import Protocol

import numpy as np

from panda_py.motion._path import Array, Path, Piece, check_deadline, max_norm_on_arc


class Bounds(Protocol):
    """Translates the robot's bounds into bounds on the path speed and acceleration."""

    def line(self, direction: Array) -> tuple[float, float]:
        """Max path speed and acceleration on a line with unit ``direction``."""
        ...

    def arc(self, piece: Piece) -> float:
        """Max constant path speed along the arc ``piece``."""
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

    def arc(self, piece: Piece) -> float:
        r = piece.radius
        xu = (piece.x / r)[:, None]
        yu = (piece.y / r)[:, None]
        # q'(θ) = -sin θ xu + cos θ yu;  q''(θ) = -(cos θ xu + sin θ yu) / r
        dq = max_norm_on_arc(yu, -xu, piece.angle)
        ddq = max_norm_on_arc(xu, yu, piece.angle) / r
        with np.errstate(divide="ignore"):
            return min(
                float(np.min(self.velocity / dq)), math.sqrt(float(np.min(self.acceleration / ddq)))
            )


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
        n_pieces = len(pieces)
        vmax = np.empty(n_pieces)
        amax = np.empty(n_pieces)
        for k, piece in enumerate(pieces):
            check_deadline(deadline, timeout)
            if piece.is_arc:
                vmax[k], amax[k] = bounds.arc(piece), math.inf
            else:
                vmax[k], amax[k] = bounds.line(piece.x)
        lengths = [p.length for p in pieces]
        arcs = [p.is_arc for p in pieces]

        # speed at each node: caps, then max-acceleration forward and max-deceleration
        # backward integration (the switching-point search, in closed form)
        speed = [0.0] * (n_pieces + 1)
        for k in range(1, n_pieces):
            speed[k] = 0.0 if path.stop[k] else min(float(vmax[k - 1]), float(vmax[k]))
        gain = [0.0 if arcs[k] else 2.0 * amax[k] * lengths[k] for k in range(n_pieces)]
        for k in range(n_pieces):  # an arc keeps its speed: gain 0
            speed[k + 1] = min(speed[k + 1], math.sqrt(speed[k] ** 2 + gain[k]))
        for k in range(n_pieces - 1, -1, -1):
            speed[k] = min(speed[k], math.sqrt(speed[k + 1] ** 2 + gain[k]))
        self.node_speeds = speed

        segments: list[Segment] = []
        node_times = [0.0]
        t = 0.0
        for k, piece in enumerate(pieces):
            check_deadline(deadline, timeout)
            inv_r = 1.0 / piece.radius if piece.is_arc else 0.0
            geo = (piece.start, piece.x, piece.y, inv_r, k)
            length = lengths[k]
            if arcs[k]:
                w = speed[k]
                segments.append((t, 0.0, w, 0.0, *geo))
                t += length / w
            else:
                for sigma0, v0, acc, dur in _line_profile(
                    length, speed[k], speed[k + 1], float(vmax[k]), float(amax[k])
                ):
                    segments.append((t, sigma0, v0, acc, *geo))
                    t += dur
            node_times.append(t)
        self.duration = t
        self.node_times = node_times
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

    def evaluate(self, times: object) -> tuple[Array, Array, Array]:
        """q, q̇, q̈ at every time in ``times`` (any shape S) as arrays of shape S + (n,)."""
        t = np.asarray(times, dtype=float)
        if not np.all(np.isfinite(t)):
            raise ValueError("times: expected finite numbers [s], got NaN or infinity")
        shape = t.shape
        t = t.reshape(-1)
        dim = len(self.first)
        pos = np.empty((t.size, dim))
        vel = np.zeros((t.size, dim))
        acc = np.zeros((t.size, dim))
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
            f = np.where(arc, -2.0 * np.sin(0.5 * th) ** 2, s)
            fd = np.where(arc, -sn * ir, 1.0)
            gd = c * ir
            fdd = -c * ir * ir
            gdd = -sn * ir * ir
            x, y = self._x[k], self._y[k]
            pos[inside] = self._start[k] + x * f[:, None] + y * sn[:, None]
            vel[inside] = (x * fd[:, None] + y * gd[:, None]) * sd[:, None]
            acc[inside] = (x * fd[:, None] + y * gd[:, None]) * a[:, None] + (
                x * fdd[:, None] + y * gdd[:, None]
            ) * (sd * sd)[:, None]
        out = (pos, vel, acc)
        return tuple(v.reshape(*shape, dim) for v in out)  # type: ignore[return-value]


def _line_profile(
    length: float, v_in: float, v_out: float, vmax: float, amax: float
) -> list[tuple[float, float, float, float]]:
    """Time-optimal motion along a line from speed ``v_in`` to ``v_out``: accelerate at
    ``amax``, cruise at ``vmax`` if it is reached, decelerate at ``amax``. Returns
    ``(σ0, ṡ0, s̈, duration)`` per non-empty phase."""
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
