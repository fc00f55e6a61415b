"""Rigid-body dynamics of the arm: mass matrix, Coriolis and gravity torques.

The model is the serial chain of :mod:`panda_py.robots.params` (modified-DH link frames,
link inertials in those frames) with an optional *load* rigidly attached to the flange:
a body of mass ``m_load`` [kg] whose centre of mass ``F_x_Cload`` [m] is given in the
flange frame and whose inertia ``I_load`` [kg m^2] is about that centre of mass, in
flange-frame axes. This is libfranka's model: its ``Model.mass/coriolis/gravity`` pass the
end effector plus payload as that load (``m_total``, ``F_x_Ctotal``, ``I_total``).

Everything is computed by the recursive Newton-Euler algorithm (RNEA) on plain Python
floats, which for seven links is several times faster than NumPy on 3-vectors; the mass
matrix uses the composite-rigid-body algorithm on the same recursion. Sign convention as
libfranka: :func:`gravity` returns the joint torques that *hold* the arm against gravity
(``tau = M ddq + c + g``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panda_py import checks, jit
from panda_py.robots.params import GRAVITY, RobotSpec, get_robot

__all__ = [
    "LoadedArm",
    "compiled_kernels",
    "coriolis",
    "gravity",
    "inverse_dynamics",
    "mass_matrix",
]

Vec3 = tuple[float, float, float]
Mat3 = tuple[float, float, float, float, float, float, float, float, float]  # row-major

_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_ZERO_I: Mat3 = (0.0,) * 9
_N = 7


@dataclass(frozen=True)
class _Body:
    """Inertial parameters about a frame's origin, in that frame's axes."""

    mass: float  # [kg]
    h: Vec3  # first moment of mass m * c [kg m]
    inertia: Mat3  # about the frame origin [kg m^2]


@dataclass(frozen=True)
class _Chain:
    """Per-robot constants of the recursion (computed once per RobotSpec)."""

    cos_alpha: tuple[float, ...]
    sin_alpha: tuple[float, ...]
    origin: tuple[Vec3, ...]  # origin of frame Ji in frame J(i-1) [m]
    bodies: tuple[_Body, ...]  # links 1..7 (link 7 without load)
    flange_d: float  # [m]


def _about_origin(mass: float, com: Sequence[float], inertia_com: Mat3) -> _Body:
    """Shift an inertia about the centre of mass to the frame origin (parallel axes)."""
    cx, cy, cz = com
    c2 = cx * cx + cy * cy + cz * cz
    c = (cx, cy, cz)
    shifted = tuple(
        inertia_com[3 * r + k] + mass * ((c2 if r == k else 0.0) - c[r] * c[k])
        for r in range(3)
        for k in range(3)
    )
    return _Body(mass, (mass * cx, mass * cy, mass * cz), shifted)  # type: ignore[arg-type]


def _inertia_matrix(ixx: float, iyy: float, izz: float, ixy: float, ixz: float, iyz: float) -> Mat3:
    return (ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz)


@functools.lru_cache(maxsize=16)
def _chain(spec: RobotSpec) -> _Chain:
    dh = spec.dh
    ca = tuple(math.cos(a) for a in dh.alpha)
    sa = tuple(math.sin(a) for a in dh.alpha)
    # RotX(alpha) TransX(a) RotZ(q) TransZ(d): the origin lands at RotX(alpha) (a, 0, d).
    origin = tuple((dh.a[i], -sa[i] * dh.d[i], ca[i] * dh.d[i]) for i in range(_N))
    bodies = tuple(
        _about_origin(link.mass, link.com, _inertia_matrix(*link.inertia))
        for link in spec.links[1 : _N + 1]
    )
    return _Chain(ca, sa, origin, bodies, dh.flange_d)


# ---- small 3-vector helpers on tuples (plain floats: fast for 7 links) -------------------


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _mv(m: Sequence[float], v: Sequence[float]) -> Vec3:
    return (
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    )


def _mtv(m: Sequence[float], v: Sequence[float]) -> Vec3:
    return (
        m[0] * v[0] + m[3] * v[1] + m[6] * v[2],
        m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
        m[2] * v[0] + m[5] * v[1] + m[8] * v[2],
    )


def _rotations(ch: _Chain, q: Sequence[float]) -> list[Mat3]:
    """R_{i-1,i} = RotX(alpha_i) RotZ(q_i), row-major, i = 1..7."""
    out = []
    for i in range(_N):
        cq, sq = math.cos(q[i]), math.sin(q[i])
        ca, sa = ch.cos_alpha[i], ch.sin_alpha[i]
        out.append((cq, -sq, 0.0, ca * sq, ca * cq, -sa, sa * sq, sa * cq, ca))
    return out


def _link7_with_load(ch: _Chain, m_load: float, F_x_C: Vec3, I_load: Mat3) -> _Body:
    """Link 7 plus the load; the flange frame is frame J7 shifted by flange_d along z."""
    link7 = ch.bodies[-1]
    if m_load == 0.0 and not any(I_load):
        return link7
    load = _about_origin(m_load, (F_x_C[0], F_x_C[1], F_x_C[2] + ch.flange_d), I_load)
    return _Body(
        link7.mass + load.mass,
        (link7.h[0] + load.h[0], link7.h[1] + load.h[1], link7.h[2] + load.h[2]),
        tuple(a + b for a, b in zip(link7.inertia, load.inertia, strict=True)),  # type: ignore[arg-type]
    )


def _rnea(
    ch: _Chain,
    rot: list[Mat3],
    bodies: Sequence[_Body],
    dq: Sequence[float],
    ddq: Sequence[float],
    a_base: Vec3,
) -> list[float]:
    """Recursive Newton-Euler: joint torques for (dq, ddq) with base acceleration a_base
    (``-gravity``). Quantities of link i are in frame Ji; moments about its origin."""
    w, wd, a = _ZERO3, _ZERO3, a_base
    wrench: list[tuple[Vec3, Vec3]] = []
    for i in range(_N):
        p = ch.origin[i]
        # linear acceleration of the new origin, still in parent coordinates
        a_par = _cross(wd, p)
        wxp = _cross(w, p)
        wwp = _cross(w, wxp)
        a = _mtv(
            rot[i], (a[0] + a_par[0] + wwp[0], a[1] + a_par[1] + wwp[1], a[2] + a_par[2] + wwp[2])
        )
        w_par = _mtv(rot[i], w)
        wd_par = _mtv(rot[i], wd)
        w = (w_par[0], w_par[1], w_par[2] + dq[i])
        # alpha_i = R^T alpha + (R^T w) x (dq_i z) + ddq_i z
        wd = (wd_par[0] + w_par[1] * dq[i], wd_par[1] - w_par[0] * dq[i], wd_par[2] + ddq[i])
        b = bodies[i]
        I = b.inertia
        h = b.h
        wxh = _cross(w, h)
        wwh = _cross(w, wxh)
        axh = _cross(wd, h)
        f = (
            b.mass * a[0] + axh[0] + wwh[0],
            b.mass * a[1] + axh[1] + wwh[1],
            b.mass * a[2] + axh[2] + wwh[2],
        )
        Iwd = _mv(I, wd)
        wIw = _cross(w, _mv(I, w))
        hxa = _cross(h, a)
        n = (Iwd[0] + wIw[0] + hxa[0], Iwd[1] + wIw[1] + hxa[1], Iwd[2] + wIw[2] + hxa[2])
        wrench.append((f, n))
    tau = [0.0] * _N
    f, n = wrench[-1]
    tau[-1] = n[2]
    for i in range(_N - 2, -1, -1):
        # carry the child's wrench (frame J(i+1)) into frame Ji and add link i's own
        fc = _mv(rot[i + 1], f)
        nc = _mv(rot[i + 1], n)
        pxf = _cross(ch.origin[i + 1], fc)
        fi, ni = wrench[i]
        f = (fi[0] + fc[0], fi[1] + fc[1], fi[2] + fc[2])
        n = (ni[0] + nc[0] + pxf[0], ni[1] + nc[1] + pxf[1], ni[2] + nc[2] + pxf[2])
        tau[i] = n[2]
    return tau


def _crba(ch: _Chain, rot: list[Mat3], bodies: Sequence[_Body]) -> list[list[float]]:
    """Composite-rigid-body algorithm: the joint-space mass matrix."""
    M = [[0.0] * _N for _ in range(_N)]
    composite: list[_Body] = [bodies[-1]]
    for i in range(_N - 2, -1, -1):
        # express the composite of links i+2.. (about origin J(i+1)) about origin Ji
        c = composite[0]
        R, p = rot[i + 1], ch.origin[i + 1]
        h_r = _mv(R, c.h)
        # R I R^T
        RI = [_mv(R, (c.inertia[k], c.inertia[3 + k], c.inertia[6 + k])) for k in range(3)]
        I_r = [_mv(R, (RI[0][r], RI[1][r], RI[2][r])) for r in range(3)]
        m = c.mass
        p2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
        ph = 2.0 * (p[0] * h_r[0] + p[1] * h_r[1] + p[2] * h_r[2])
        body = bodies[i]
        inertia = tuple(
            body.inertia[3 * r + k]
            + I_r[r][k]
            + m * ((p2 if r == k else 0.0) - p[r] * p[k])
            + ((ph if r == k else 0.0) - p[r] * h_r[k] - h_r[r] * p[k])
            for r in range(3)
            for k in range(3)
        )
        h = (
            body.h[0] + h_r[0] + m * p[0],
            body.h[1] + h_r[1] + m * p[1],
            body.h[2] + h_r[2] + m * p[2],
        )
        composite.insert(0, _Body(body.mass + m, h, inertia))  # type: ignore[arg-type]
    for j in range(_N):
        c = composite[j]
        # wrench at origin Jj that accelerates the composite with ddq_j = 1
        f: Vec3 = (-c.h[1], c.h[0], 0.0)  # z x h
        n: Vec3 = (c.inertia[2], c.inertia[5], c.inertia[8])  # I z
        M[j][j] = n[2]
        for i in range(j - 1, -1, -1):
            fc = _mv(rot[i + 1], f)
            nc = _mv(rot[i + 1], n)
            pxf = _cross(ch.origin[i + 1], fc)
            f = fc
            n = (nc[0] + pxf[0], nc[1] + pxf[1], nc[2] + pxf[2])
            M[i][j] = M[j][i] = n[2]
    return M


# ---- input validation --------------------------------------------------------------------


def _vector(name: str, value: ArrayLike, n: int, unit: str) -> list[float]:
    values: list[float] = checks.vector(name, value, n, unit).tolist()
    return values


def _load(
    m_load: float, F_x_Cload: ArrayLike, I_load: ArrayLike | None
) -> tuple[float, Vec3, Mat3]:
    m = checks.number("m_load", m_load, "[kg]", low=0.0)
    c = _vector("F_x_Cload", F_x_Cload, 3, "[m]")
    if I_load is None:
        return m, (c[0], c[1], c[2]), _ZERO_I
    try:
        arr = np.asarray(I_load, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"I_load: expected a 3x3 inertia [kg m^2], got {I_load!r}") from exc
    if arr.shape == (9,):  # libfranka's column-major std::array<double, 9>
        arr = arr.reshape(3, 3, order="F")
    if arr.shape != (3, 3):
        raise ValueError(
            f"I_load: expected shape (3, 3) or (9,) (column-major) [kg m^2], got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"I_load: expected finite values [kg m^2], got {arr.tolist()}")
    return m, (c[0], c[1], c[2]), tuple(arr.ravel().tolist())


def _setup(
    robot: str | RobotSpec,
    q: ArrayLike,
    m_load: float,
    F_x_Cload: ArrayLike,
    I_load: ArrayLike | None,
) -> tuple[_Chain, list[Mat3], list[_Body]]:
    ch = _chain(get_robot(robot))
    qs = _vector("q", q, _N, "[rad]")
    m, c, inertia = _load(m_load, F_x_Cload, I_load)
    bodies = [*ch.bodies[:-1], _link7_with_load(ch, m, c, inertia)]
    return ch, _rotations(ch, qs), bodies


# ---- public API --------------------------------------------------------------------------


def inverse_dynamics(
    q: ArrayLike,
    dq: ArrayLike,
    ddq: ArrayLike,
    *,
    m_load: float = 0.0,
    F_x_Cload: ArrayLike = _ZERO3,
    I_load: ArrayLike | None = None,
    gravity: ArrayLike = GRAVITY,
    robot: str | RobotSpec = "fer",
) -> NDArray[np.float64]:
    """Joint torques ``tau = M(q) ddq + C(q, dq) dq + g(q)`` [Nm] (RNEA).

    ``q`` [rad], ``dq`` [rad/s], ``ddq`` [rad/s^2]: 7 values each. The load (``m_load``
    [kg], ``F_x_Cload`` [m] in the flange frame, ``I_load`` [kg m^2] 3x3 about its centre
    of mass in flange axes, or 9 values column-major) is rigidly attached to the flange.
    ``gravity`` is the gravitational acceleration in the base frame [m/s^2].
    """
    ch, rot, bodies = _setup(robot, q, m_load, F_x_Cload, I_load)
    dqs = _vector("dq", dq, _N, "[rad/s]")
    ddqs = _vector("ddq", ddq, _N, "[rad/s^2]")
    g = _vector("gravity", gravity, 3, "[m/s^2]")
    return np.array(_rnea(ch, rot, bodies, dqs, ddqs, (-g[0], -g[1], -g[2])))


def mass_matrix(
    q: ArrayLike,
    *,
    m_load: float = 0.0,
    F_x_Cload: ArrayLike = _ZERO3,
    I_load: ArrayLike | None = None,
    robot: str | RobotSpec = "fer",
) -> NDArray[np.float64]:
    """The 7x7 joint-space mass matrix M(q) [kg m^2] at ``q`` [rad], including the load
    (see :func:`inverse_dynamics` for the load arguments)."""
    ch, rot, bodies = _setup(robot, q, m_load, F_x_Cload, I_load)
    return np.array(_crba(ch, rot, bodies))


def coriolis(
    q: ArrayLike,
    dq: ArrayLike,
    *,
    m_load: float = 0.0,
    F_x_Cload: ArrayLike = _ZERO3,
    I_load: ArrayLike | None = None,
    robot: str | RobotSpec = "fer",
) -> NDArray[np.float64]:
    """The Coriolis and centrifugal torques ``C(q, dq) dq`` [Nm] at ``q`` [rad],
    ``dq`` [rad/s], including the load (see :func:`inverse_dynamics`)."""
    ch, rot, bodies = _setup(robot, q, m_load, F_x_Cload, I_load)
    dqs = _vector("dq", dq, _N, "[rad/s]")
    return np.array(_rnea(ch, rot, bodies, dqs, [0.0] * _N, _ZERO3))


def gravity(
    q: ArrayLike,
    *,
    m_load: float = 0.0,
    F_x_Cload: ArrayLike = _ZERO3,
    gravity: ArrayLike = GRAVITY,
    robot: str | RobotSpec = "fer",
) -> NDArray[np.float64]:
    """The joint torques [Nm] that hold the arm (and the load of ``m_load`` [kg] at
    ``F_x_Cload`` [m] in the flange frame) still at ``q`` [rad] against ``gravity``
    [m/s^2] in the base frame (libfranka's default ``O_ddP_O`` = (0, 0, -9.81))."""
    ch, rot, bodies = _setup(robot, q, m_load, F_x_Cload, None)
    g = _vector("gravity", gravity, 3, "[m/s^2]")
    zero = [0.0] * _N
    return np.array(_rnea(ch, rot, bodies, zero, zero, (-g[0], -g[1], -g[2])))


def _jit() -> Any:
    """The compiled recursion (:mod:`panda_py.dynamics._compiled`), or None (numba missing, or
    ``PANDA_PY_NO_JIT=1``): imported, and its kernels compiled or loaded, on first use."""
    return jit.optional("panda_py.dynamics._compiled", warm="warmup")


def compiled_kernels() -> Any:
    """The compiled recursion (numba: ``rnea``, ``crba`` on :attr:`LoadedArm.arrays`),
    loaded or compiled on first use, or None where the dynamics run as plain Python (numba
    missing, ``PANDA_PY_NO_JIT=1``): for a compiled loop that calls it itself."""
    return _jit()


def _floats(values: ArrayLike) -> list[float]:
    out: list[float] = np.asarray(values, dtype=np.float64).reshape(-1).tolist()
    return out


class LoadedArm:
    """One arm with one load, prepared once: ``coriolis``, ``gravity`` and ``mass_matrix``
    for a control loop, without the per-call checks and the load combination of the
    functions above, compiled by numba where it is installed (about 2 us a call; the
    plain-Python recursion takes 40-110 us). The caller guarantees 7 finite values per
    argument, as a loop that checked its state does."""

    def __init__(
        self,
        robot: str | RobotSpec = "fer",
        *,
        m_load: float = 0.0,
        F_x_Cload: ArrayLike = _ZERO3,
        I_load: ArrayLike | None = None,
    ) -> None:
        self._chain, _, self._bodies = _setup(robot, np.zeros(_N), m_load, F_x_Cload, I_load)
        ch, bodies = self._chain, self._bodies
        self._kernels = _jit()
        self._arrays = (
            np.array(ch.origin, dtype=np.float64),
            np.array(ch.cos_alpha, dtype=np.float64),
            np.array(ch.sin_alpha, dtype=np.float64),
            np.array([b.mass for b in bodies], dtype=np.float64),
            np.array([b.h for b in bodies], dtype=np.float64),
            np.array([b.inertia for b in bodies], dtype=np.float64).reshape(_N, 3, 3),
        )
        self._zero = np.zeros(_N)
        self._zero3 = np.zeros(3)

    @property
    def arrays(self) -> tuple[NDArray[np.float64], ...]:
        """The arm's parameters as the compiled recursion takes them (see
        :func:`compiled_kernels`): frame origins (7, 3), cos and sin of the twists (7,),
        the links' masses (7,) with the load in the last, first moments (7, 3) and
        inertias about the frame origins (7, 3, 3)."""
        return self._arrays

    def coriolis(self, q: ArrayLike, dq: ArrayLike) -> NDArray[np.float64]:
        """``C(q, dq) dq`` [Nm] at ``q`` [rad], ``dq`` [rad/s]."""
        k = self._kernels
        if k is None:
            rot = _rotations(self._chain, _floats(q))
            tau = _rnea(self._chain, rot, self._bodies, _floats(dq), [0.0] * _N, _ZERO3)
            return np.array(tau, dtype=np.float64)
        out = np.empty(_N)
        k.rnea(*self._arrays, np.asarray(q, dtype=np.float64),
               np.asarray(dq, dtype=np.float64), self._zero, self._zero3, out)  # fmt: skip
        return out

    def gravity(self, q: ArrayLike, gravity: Vec3 = GRAVITY) -> NDArray[np.float64]:
        """Torques [Nm] holding the arm and load against ``gravity`` [m/s^2] at ``q``."""
        a = (-gravity[0], -gravity[1], -gravity[2])
        k = self._kernels
        if k is None:
            rot = _rotations(self._chain, _floats(q))
            zero = [0.0] * _N
            return np.array(_rnea(self._chain, rot, self._bodies, zero, zero, a), dtype=np.float64)
        out = np.empty(_N)
        k.rnea(*self._arrays, np.asarray(q, dtype=np.float64), self._zero, self._zero,
               np.array(a, dtype=np.float64), out)  # fmt: skip
        return out

    def motion_torques(self, q: ArrayLike, dq: ArrayLike, ddq: ArrayLike) -> NDArray[np.float64]:
        """``M(q) ddq + C(q, dq) dq`` [Nm] (N, 7) at each row of ``q``, ``dq``, ``ddq`` (N, 7)
        [rad, rad/s, rad/s^2]: the torques of a motion along a trajectory, gravity left out
        (the robot compensates it), in one compiled call where numba is installed."""
        Q, dQ, ddQ = (np.ascontiguousarray(a, dtype=np.float64) for a in (q, dq, ddq))
        for name, a in (("q", Q), ("dq", dQ), ("ddq", ddQ)):
            if a.ndim != 2 or a.shape[1] != _N:
                raise ValueError(
                    f"{name}: expected rows of {_N} joints (N, {_N}), got shape {a.shape}"
                )
        if not len(Q) == len(dQ) == len(ddQ):
            raise ValueError(
                f"q, dq, ddq: expected as many rows each, got {len(Q)}, {len(dQ)}, {len(ddQ)}"
            )
        out = np.empty((len(Q), _N))
        k = self._kernels
        if k is None:
            for i in range(len(Q)):
                rot = _rotations(self._chain, _floats(Q[i]))
                out[i] = _rnea(self._chain, rot, self._bodies, _floats(dQ[i]), _floats(ddQ[i]),
                               _ZERO3)  # fmt: skip
            return out
        k.rnea_along(*self._arrays, Q, dQ, ddQ, self._zero3, out)
        return out

    def mass_matrix(self, q: ArrayLike) -> NDArray[np.float64]:
        """The 7x7 joint-space mass matrix [kg m^2] at ``q``."""
        k = self._kernels
        if k is None:
            rows = _crba(self._chain, _rotations(self._chain, _floats(q)), self._bodies)
            return np.array(rows, dtype=np.float64)
        M = np.empty((_N, _N))
        k.crba(*self._arrays, np.asarray(q, dtype=np.float64), M)
        return M
