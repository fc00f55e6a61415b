"""Time-optimal Cartesian trajectories through poses (panda-py's CartesianTrajectory).

The path lives in R^6: position ``p`` [m] and a developed rotation coordinate ``φ`` [rad]
with ``φ_0 = 0`` and ``φ_{i+1} = φ_i + log(Q_i^-1 Q_{i+1})``, the body-frame rotation
vector from waypoint i to i+1 (shortest way round). It is a Kunz-Stilman path through the
points ``[p_i; φ_i]``; the orientation at a point of the path is ``Q_c exp(φ - φ_c)`` in the
chart of a waypoint c: the segment's first waypoint on a line (there it is exactly the
slerp between the waypoints), the rounded waypoint on a blend. Both charts agree on the
lines, so the orientation is continuous with continuous angular velocity.

Bounds (the robot's, each scaled by ``speed_factor``): ``|ṗ| <= v_t``, ``|p̈| <= a_t``
and ``|ω| <= v_r``, ``|ω̇| <= a_r`` (Euclidean norms, as Franka specifies its Cartesian
limits). On a line ``ω = φ̇`` and ``ω̇ = φ̈`` exactly. On a blend ``|ω| <= |φ̇|`` (the
right Jacobian of SO(3) has singular values <= 1) and ``ω̇`` gains a term bounded by
``k(θ) |φ̇|²`` (θ: distance from the chart's waypoint), which the blend speed accounts for.
"""

from __future__ import annotations

import math
import time as _time
from typing import Any, NamedTuple, Protocol, overload

import numpy as np

from panda_py import checks
from panda_py.checks import QUATERNION_NORM_TOL
from panda_py.motion import _checks
from panda_py.motion import rotation as rot
from panda_py.motion._path import (
    Array,
    Piece,
    build_path,
    check_deadline,
    max_norm_on_arc,
    piece_points,
    piece_tangents,
)
from panda_py.motion._profile import (
    ARC_SPEED_FRACTION,
    ARC_STRETCH_ANGLE,
    Profile,
    arc_stretches,
    stretch_bounds,
)
from panda_py.robots.params import RobotKind, RobotSpec, get_robot

# [-] |‖q‖ - 1| above this is an error, below it normalised (one tolerance everywhere)
QUATERNION_NORM_TOLERANCE = QUATERNION_NORM_TOL
DUPLICATE_TOLERANCE = 1e-12  # [m, rad] consecutive poses closer than this are merged


class CartesianSamples(NamedTuple):
    """End-effector states at many times; arrays of shape ``times.shape + (3,)`` or ``(4,)``."""

    positions: Array  # [m]
    orientations: Array  # unit quaternions x, y, z, w
    velocities: Array  # [m/s]
    accelerations: Array  # [m/s^2]
    angular_velocities: Array  # [rad/s], in the base frame


def _blend_rotation_gain(theta: float) -> float:
    """Upper bound k(θ) of ``|d/dt J_r(x)| |ẋ| / |ẋ|²`` for ``|x| <= θ <= π`` [-]
    (series bound of the SO(3) right Jacobian's derivative, checked numerically in the
    tests, with 1 % margin)."""
    return 1.01 * (theta / 6.0 + theta * theta / 12.0 + theta**3 / 60.0)


class JointMap(Protocol):
    """The arm's joints along a Cartesian path, given by the caller (the kinematics are
    not this module's): how fast they turn for an end-effector twist at a pose, and the
    bounds they keep."""

    velocity: Array  # (7,) [rad/s]
    acceleration: Array  # (7,) [rad/s^2]

    def rates(self, poses: Array, twists: Array) -> Array:
        """Joint velocities (N, 7) that move the end effector at each pose (N, 4, 4) with
        the twist (N, 6: linear, angular, base frame); NaN rows where it cannot reach."""
        ...


# the joints' bounds are taken on stretches at most JOINT_STRETCH long [path units: m and
# rad], from their rates at points JOINT_STEP apart at most (their change between points:
# the rates' derivative along the path)
JOINT_STRETCH = 0.01
JOINT_STEP = 2.5e-3
# a stretch's top speed is at most this fraction of the speed at which the joints' rates'
# change (q'' ṡ²) takes all of a joint's acceleration: half of it is left to speed up and
# slow down with (the constant bound holds from standstill to the top speed)
JOINT_SPEED_FRACTION = math.sqrt(0.5)


def joint_grid(piece: Piece) -> tuple[int, int]:
    """The joints' stretches on a piece and the points' intervals in each: (count, per);
    the points are ``linspace(0, length, count * per + 1)``."""
    count = math.ceil(piece.length / JOINT_STRETCH)
    if piece.is_arc:
        count = max(count, math.ceil(piece.angle / ARC_STRETCH_ANGLE))
    count = max(count, 1)
    return count, max(2, math.ceil(piece.length / count / JOINT_STEP))


class CartesianBounds:
    """Norm bounds on translation and rotation (groups 0 and 1 of the 6-D path), and,
    given ``joints`` and their rates along each piece (``rates[k]``: the points' arc
    lengths (:func:`joint_grid`) and the joint rates ``q'`` per unit path length there),
    the joints' own bounds along the path (seven more groups)."""

    def __init__(
        self, v_t: float, a_t: float, v_r: float, a_r: float,
        joints: JointMap | None = None, rates: list[tuple[Array, Array]] | None = None,
    ) -> None:  # fmt: skip
        self.velocity = np.array([v_t, v_r])
        self.acceleration = np.array([a_t, a_r])
        self.joints = joints
        self.rates = rates

    def line(self, direction: Array) -> tuple[float, float]:
        mag = self.line_coefficients(direction)
        with np.errstate(divide="ignore"):
            return float(np.min(self.velocity / mag)), float(np.min(self.acceleration / mag))

    def arc_coefficients(self, piece: Piece, start: Array, stop: Array) -> tuple[Array, Array]:
        r = piece.radius
        xu = (piece.x / r).reshape(2, 3)
        yu = (piece.y / r).reshape(2, 3)
        m1 = max_norm_on_arc(yu, -xu, start, stop)
        m2 = max_norm_on_arc(xu, yu, start, stop) / r
        # every point of the blend is within its reach r tan(α/2) of the chart's waypoint
        reach = min(r * math.tan(0.5 * piece.angle), math.pi)
        m2[:, 1] += _blend_rotation_gain(reach) * m1[:, 1] ** 2
        return m1, m2

    def stretches(self, k: int, piece: Piece) -> tuple[Array, Array, Array]:
        """Piece ``k`` in stretches of constant bounds on its translation, rotation and
        joints: lengths, max path speeds and accelerations (``stretch_bounds``). The joints'
        rates ``q'`` (by path length) at points of each stretch and their change ``q''``
        bound ``q̇ = q' ṡ`` and ``q̈ = q' s̈ + q'' ṡ²`` (an estimate between the points).
        Without joints: one stretch a line, a blend's own (:func:`arc_stretches`)."""
        if self.joints is None or self.rates is None:
            if piece.is_arc:
                return arc_stretches(self, piece)
            v, a = self.line(piece.x)
            return np.array([piece.length]), np.array([v]), np.array([a])
        count, per = joint_grid(piece)
        edges = np.linspace(0.0, piece.length, count + 1)
        if piece.is_arc:
            m1, m2 = self.arc_coefficients(piece, edges[:-1] / piece.radius,
                                           edges[1:] / piece.radius)  # fmt: skip
        else:
            m1 = np.tile(self.line_coefficients(piece.x), (count, 1))
            m2 = np.zeros((count, 2))
        # the joints' rates q' (per path length) at points along the piece, and their
        # change q'': q̇ = q' ṡ and q̈ = q' s̈ + q'' ṡ²
        sigma, rate = self.rates[k]
        change = np.gradient(rate, sigma, axis=0)
        rate, change = np.nan_to_num(np.abs(rate)), np.nan_to_num(np.abs(change))
        # each stretch: its points, both ends included
        idx = np.arange(count)[:, None] * per + np.arange(per + 1)
        speed, accel = stretch_bounds(
            np.hstack([m1, rate[idx].max(axis=1)]), np.hstack([m2, change[idx].max(axis=1)]),
            np.concatenate([self.velocity, self.joints.velocity]),
            np.concatenate([self.acceleration, self.joints.acceleration]),
            np.array([ARC_SPEED_FRACTION] * 2 + [JOINT_SPEED_FRACTION] * rate.shape[1]),
        )  # fmt: skip
        return np.diff(edges), speed, accel

    @staticmethod
    def line_coefficients(direction: Array) -> Array:
        """``|ṗ| / ṡ`` and ``|ω| / ṡ`` on a line of unit ``direction``."""
        return np.array([np.linalg.norm(direction[:3]), np.linalg.norm(direction[3:])])


class CartesianTrajectory:
    """The time-optimal end-effector motion through poses, under the robot's Cartesian
    translation and rotation velocity and acceleration limits, each scaled by
    ``speed_factor`` (as panda-py does).

    Either ``CartesianTrajectory(positions, orientations, ...)`` with positions [m]
    (N 3-vectors) and unit quaternions (N 4-vectors, x, y, z, w), or
    ``CartesianTrajectory(poses, ...)`` with N 4x4 homogeneous transforms (as panda-py).

    :param speed_factor: fraction of the Cartesian velocity and acceleration limits, in (0, 1].
    :param max_deviation: how far blends may cut corners, >= 0 (bounds both the position
        [m] and the orientation [rad] deviation); 0 stops exactly at every waypoint.
    :param timeout: planning time budget [s]; :class:`~panda_py.motion.PlanningTimeoutError`
        past it.
    :param robot: whose limits apply: ``"fer"`` (default, as panda-py), ``"fr3"``,
        ``"fr3-pre-5.9"`` or a :class:`~panda_py.robots.params.RobotSpec`.
    :param joints: beyond panda-py: the arm's joints along the path and their bounds (a
        :class:`JointMap`); the motion keeps those too (the Cartesian limits alone can ask
        a joint for more than its own).
    """

    @overload
    def __init__(
        self,
        positions: object,
        orientations: object,
        speed_factor: float = 0.2,
        max_deviation: float = 0.0,
        timeout: float = 30.0,
        *,
        robot: str | RobotKind | RobotSpec = "fer",
        joints: JointMap | None = None,
    ) -> None: ...

    @overload
    def __init__(
        self,
        poses: object,
        speed_factor: float = 0.2,
        max_deviation: float = 0.0,
        timeout: float = 30.0,
        *,
        robot: str | RobotKind | RobotSpec = "fer",
        joints: JointMap | None = None,
    ) -> None: ...

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        binder = _bind_poses if _is_poses_call(args, kwargs) else _bind_positions
        positions, quats, speed_factor, max_deviation, timeout, robot, joints = binder(
            *args, **kwargs
        )
        plan_timeout = _checks.timeout(timeout)
        deadline = _time.perf_counter() + plan_timeout
        self.speed_factor = _checks.speed_factor(speed_factor)
        self.max_deviation = _checks.max_deviation(max_deviation)
        self.robot = get_robot(robot)  # type: ignore[arg-type]  # get_robot validates
        if joints is not None and not callable(getattr(joints, "rates", None)):
            raise ValueError(
                "joints: expected a JointMap (rates(poses, twists), velocity, acceleration), "
                f"got {type(joints).__name__}"
            )
        c = self.robot.cartesian
        sf = self.speed_factor
        #: the bounds kept: [m/s], [m/s^2], [rad/s], [rad/s^2]
        self.max_translation_velocity = sf * c.translation_velocity
        self.max_translation_acceleration = sf * c.translation_acceleration
        self.max_rotation_velocity = sf * c.rotation_velocity
        self.max_rotation_acceleration = sf * c.rotation_acceleration

        # sign-continuous quaternions, then the developed rotation coordinate φ
        n = len(positions)
        for i in range(1, n):
            if quats[i] @ quats[i - 1] < 0.0:
                quats[i] = -quats[i]
        phi = np.zeros((n, 3))
        for i in range(1, n):
            phi[i] = phi[i - 1] + rot.log(rot.multiply(rot.conjugate(quats[i - 1]), quats[i]))
        check_deadline(deadline, plan_timeout)
        points = np.hstack([positions, phi])
        step = np.linalg.norm(np.diff(points, axis=0), axis=1)
        kept = np.flatnonzero(np.concatenate(([True], step > DUPLICATE_TOLERANCE)))
        self.positions = positions
        self.orientations = quats.copy()  # as used: normalised, sign-continuous
        points, quats, phi = points[kept], quats[kept], phi[kept]
        path = build_path(points, self.max_deviation, deadline, plan_timeout)
        # per piece: left-multiplication matrix of its chart's quaternion and the chart's φ
        self._chart_L = np.array([rot.left_matrix(quats[p.corner]) for p in path.pieces])
        self._chart_phi = np.array([phi[p.corner] for p in path.pieces]).reshape(-1, 3)
        bounds = CartesianBounds(
            self.max_translation_velocity,
            self.max_translation_acceleration,
            self.max_rotation_velocity,
            self.max_rotation_acceleration,
            joints,
            None if joints is None else self._joint_rates(path.pieces, joints),
        )
        self._profile = Profile(path, bounds, points[0], points[-1], deadline, plan_timeout)
        self._duration = self._profile.duration
        self._q_first = quats[0].copy()
        self._q_last = quats[-1].copy()

    def _joint_rates(self, pieces: list[Piece], joints: JointMap) -> list[tuple[Array, Array]]:
        """Per piece: the arc lengths of its points (:func:`joint_grid`) and the joints'
        rates there (``joints.rates`` of the poses and the twists of the path's unit
        tangents, base frame), all pieces in one call."""
        sigmas, points, tangents, chart = [], [], [], []
        for k, piece in enumerate(pieces):
            count, per = joint_grid(piece)
            sigma = np.linspace(0.0, piece.length, count * per + 1)
            sigmas.append(sigma)
            points.append(piece_points(piece, sigma))
            tangents.append(piece_tangents(piece, sigma))
            chart.append(np.full(len(sigma), k))
        pts, tan, kk = np.vstack(points), np.vstack(tangents), np.concatenate(chart)
        x = pts[:, 3:] - self._chart_phi[kk]
        quat = np.einsum("nij,nj->ni", self._chart_L[kk], rot.exp_many(x))
        poses = rot.transforms(pts[:, :3], quat)
        omega = rot.rotate_many(quat, rot.right_jacobian_times(x, tan[:, 3:]))
        rates = np.asarray(joints.rates(poses, np.hstack([tan[:, :3], omega])), dtype=float)
        width = len(joints.velocity)
        if rates.shape != (len(pts), width) or len(joints.acceleration) != width:
            raise ValueError(
                f"joints: expected rates of shape ({len(pts)}, {width}) (one row per pose, "
                f"one column per joint of velocity and acceleration), got shape {rates.shape} "
                f"and {len(joints.acceleration)} accelerations"
            )
        bounds = np.cumsum([len(sg) for sg in sigmas])[:-1]
        return list(zip(sigmas, np.split(rates, bounds), strict=True))

    def get_duration(self) -> float:
        """Duration of the motion [s]."""
        return self._duration

    def get_position(self, time: float) -> Array:
        """End-effector position at ``time`` [s], shape (3,) [m]."""
        return self._profile.position(time)[:3]

    def get_orientation(self, time: float) -> Array:
        """End-effector orientation at ``time`` [s]: unit quaternion (x, y, z, w), shape (4,)."""
        return self._orientation(time, None)

    def get_pose(self, time: float) -> Array:
        """End-effector pose at ``time`` [s]: 4x4 homogeneous transform [m]."""
        q6 = self._profile.position(time)
        pose = np.eye(4)
        pose[:3, :3] = rot.to_matrix(self._orientation(time, q6))
        pose[:3, 3] = q6[:3]
        return pose

    def _orientation(self, time: float, q6: Array | None) -> Array:
        loc = self._profile.locate(time)
        if loc is None:
            return (self._q_first if float(time) < 0.0 else self._q_last).copy()
        k = loc[0]
        if q6 is None:
            q6 = self._profile.position(time)
        return self._chart_L[k] @ rot.exp(q6[3:] - self._chart_phi[k])

    def sample(self, times: object) -> CartesianSamples:
        """The end-effector state at all of ``times`` [s] at once (array of any shape).
        Beyond panda-py's API."""
        pos, vel, acc, piece = self._profile.evaluate(times)
        shape = pos.shape[:-1]
        pos, vel, acc, piece = (
            pos.reshape(-1, 6),
            vel.reshape(-1, 6),
            acc.reshape(-1, 6),
            piece.reshape(-1),
        )
        quat = np.empty((len(pos), 4))
        omega = np.zeros((len(pos), 3))
        inside = piece >= 0
        before = ~inside & (np.asarray(times, dtype=float).reshape(-1) < 0.0)
        quat[before] = self._q_first
        quat[~inside & ~before] = self._q_last
        if np.any(inside):
            k = piece[inside]
            x = pos[inside, 3:] - self._chart_phi[k]
            q = np.einsum("nij,nj->ni", self._chart_L[k], rot.exp_many(x))
            quat[inside] = q
            omega_body = rot.right_jacobian_times(x, vel[inside, 3:])
            omega[inside] = rot.rotate_many(q, omega_body)
        return CartesianSamples(
            pos[:, :3].reshape(*shape, 3),
            quat.reshape(*shape, 4),
            vel[:, :3].reshape(*shape, 3),
            acc[:, :3].reshape(*shape, 3),
            omega.reshape(*shape, 3),
        )

    def __repr__(self) -> str:
        return (
            f"CartesianTrajectory({len(self.positions)} waypoints, robot={self.robot.name!r}, "
            f"speed_factor={self.speed_factor}, duration={self._duration:.4f} s)"
        )


# -- argument parsing: panda-py's two overloads --

_Bound = tuple[Array, Array, object, object, object, object, Any]


def _is_poses_call(args: tuple[Any, ...], kwargs: dict[str, Any]) -> bool:
    if "poses" in kwargs:
        return True
    if "positions" in kwargs or "orientations" in kwargs or not args:
        return False
    try:
        first = np.asarray(args[0], dtype=float)
    except (TypeError, ValueError):
        return False
    return first.ndim == 3 and first.shape[1:] == (4, 4)


def _bind_poses(
    poses: object,
    speed_factor: object = 0.2,
    max_deviation: object = 0.0,
    timeout: object = 30.0,
    *,
    robot: object = "fer",
    joints: object = None,
) -> _Bound:
    positions, quats = parse_poses(poses)
    return positions, quats, speed_factor, max_deviation, timeout, robot, joints


def _bind_positions(
    positions: object,
    orientations: object,
    speed_factor: object = 0.2,
    max_deviation: object = 0.0,
    timeout: object = 30.0,
    *,
    robot: object = "fer",
    joints: object = None,
) -> _Bound:
    p = stack_rows("positions", positions, 3, "[m]")
    q = stack_rows("orientations", orientations, 4, "(unit quaternions x, y, z, w)")
    if len(p) != len(q):
        raise ValueError(
            f"orientations: expected one per position ({len(p)}), got {len(q)} orientations"
        )
    norms = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_NORM_TOLERANCE)
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"orientations[{i}]: expected a unit quaternion (x, y, z, w), got norm {norms[i]:.6g}"
        )
    return p, q / norms[:, None], speed_factor, max_deviation, timeout, robot, joints


def stack_rows(name: str, value: object, width: int, unit: str) -> Array:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{name}: expected a sequence of {width}-vectors {unit}, got {type(value).__name__}"
        ) from exc
    if arr.size == 0:
        raise ValueError(f"{name}: expected at least one waypoint, got none")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]  # panda-py style column vectors
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"{name}: expected shape (N, {width}) {unit}, got shape {arr.shape}")
    _check_finite(name, arr)
    return arr


def _check_finite(name: str, arr: Array) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        where = "".join(f"[{i}]" for i in idx)
        raise ValueError(f"{name}{where}: expected a finite number, got {arr[idx]}")


def parse_poses(poses: object) -> tuple[Array, Array]:
    """``(positions (N, 3), unit quaternions (N, 4))`` of 4x4 homogeneous transforms
    (N, 4, 4), each finite and rigid (:func:`panda_py.checks.rigid_errors`)."""
    if type(poses) is np.ndarray and poses.dtype == np.float64 and poses.shape == (1, 4, 4):
        one = _one_pose(poses[0].tolist())
        if one is not None:
            return one
    try:
        arr = np.array(poses, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"poses: expected a sequence of 4x4 homogeneous transforms, got {type(poses).__name__}"
        ) from exc
    if arr.size == 0:
        raise ValueError("poses: expected at least one pose, got none")
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"poses: expected shape (N, 4, 4), got shape {arr.shape}")
    _check_finite("poses", arr)
    err = checks.rigid_errors(arr)  # the package's one rigid-transform test
    bad = np.flatnonzero(~(err <= checks.RIGID_TOL))
    if bad.size:
        i = int(bad[0])
        raise ValueError(checks.rigid_message(f"poses[{i}]", float(err[i])))
    rots = arr[:, :3, :3]
    quats = np.array([rot.from_matrix(r) for r in rots])
    return arr[:, :3, 3].copy(), quats


def _one_pose(rows: list[list[float]]) -> tuple[Array, Array] | None:
    """:func:`parse_poses` of a single pose (its rows) in scalars, or None where it is not
    finite and rigid (the general path words the error). A move's one target is parsed
    where it is given, on the way to the robot: in NumPy calls it cost 20 us, and 250 us
    on the cold caches of a caller that slept in between (a policy's, between targets)."""
    (m00, m01, m02, px), (m10, m11, m12, py), (m20, m21, m22, pz), last = rows
    total = m00 + m01 + m02 + px + m10 + m11 + m12 + py + m20 + m21 + m22 + pz + sum(last)
    if total - total != 0.0 or not checks.rigid_error(rows) <= checks.RIGID_TOL:
        return None  # (not finite: inf - inf and NaN are NaN)
    quat = rot.quaternion_of(m00, m01, m02, m10, m11, m12, m20, m21, m22)
    return np.array([[px, py, pz]]), np.array([quat])
