"""CartesianTrajectory: norm bounds at 1 kHz, waypoints, closed-form optima, errors."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from panda_py.motion import CartesianTrajectory
from panda_py.motion import rotation as rot
from panda_py.motion.cartesian import _blend_rotation_gain
from panda_py.robots.params import FER, FR3, RobotSpec

DT = 1e-3  # [s]
P0 = np.array([0.4, 0.0, 0.4])  # [m]
Q0 = np.array([1.0, 0.0, 0.0, 0.0])  # flange pointing down (x, y, z, w)


def closed_form_duration(distance: float, vmax: float, amax: float) -> float:
    if distance >= vmax * vmax / amax:
        return distance / vmax + vmax / amax
    return 2.0 * math.sqrt(distance / amax)


def random_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def random_poses(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    positions = P0 + rng.uniform(-0.3, 0.3, size=(n, 3))
    quats = np.array([rot.multiply(Q0, rot.exp(rng.uniform(-1.0, 1.0, 3))) for _ in range(n)])
    return positions, quats


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Geodesic angle between rows of unit quaternions [rad]."""
    return 2.0 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=-1)), 0.0, 1.0))


@pytest.mark.parametrize("spec", [FER, FR3], ids=["fer", "fr3"])
@pytest.mark.parametrize("speed_factor", [0.1, 1.0])
def test_straight_moves_are_the_closed_form_optimum(spec: RobotSpec, speed_factor: float) -> None:
    rng = np.random.default_rng(4)
    c = spec.cartesian
    v_t, a_t = speed_factor * c.translation_velocity, speed_factor * c.translation_acceleration
    v_r, a_r = speed_factor * c.rotation_velocity, speed_factor * c.rotation_acceleration
    for distance in (0.003, 0.05, 0.6):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)  # any direction: the bound is on |v|
        traj = CartesianTrajectory(
            [P0, P0 + distance * direction], [Q0, Q0], speed_factor, robot=spec
        )
        assert traj.get_duration() == pytest.approx(closed_form_duration(distance, v_t, a_t))
    for angle in (0.01, 0.3, 2.5):
        axis = rng.normal(size=3)
        q1 = rot.multiply(Q0, rot.exp(angle * axis / np.linalg.norm(axis)))
        traj = CartesianTrajectory([P0, P0], [Q0, q1], speed_factor=speed_factor, robot=spec)
        assert traj.get_duration() == pytest.approx(closed_form_duration(angle, v_r, a_r))
    # both at once: one line in [p; φ], bounded by whichever part binds
    d, angle = 0.2, 0.4
    q1 = rot.multiply(Q0, rot.exp(np.array([0.0, 0.0, angle])))
    p1 = P0 + np.array([d, 0.0, 0.0])
    traj = CartesianTrajectory([P0, p1], [Q0, q1], speed_factor=speed_factor, robot=spec)
    length = math.hypot(d, angle)
    v = min(v_t * length / d, v_r * length / angle)
    a = min(a_t * length / d, a_r * length / angle)
    assert traj.get_duration() == pytest.approx(closed_form_duration(length, v, a))


@pytest.mark.parametrize("max_deviation", [0.0, 0.02, 0.15])
def test_bounds_hold_at_1khz(max_deviation: float) -> None:
    rng = np.random.default_rng(21)
    for i in range(6):
        spec = FER if i % 2 else FR3
        sf = float(rng.uniform(0.1, 1.0))
        positions, quats = random_poses(rng, int(rng.integers(2, 6)))
        traj = CartesianTrajectory(
            positions, quats, speed_factor=sf, max_deviation=max_deviation, robot=spec
        )
        c = spec.cartesian
        v_t, a_t = sf * c.translation_velocity, sf * c.translation_acceleration
        v_r, a_r = sf * c.rotation_velocity, sf * c.rotation_acceleration
        times = np.arange(0.0, traj.get_duration() + DT, DT)
        s = traj.sample(times)
        assert np.all(np.isfinite(s.positions)) and np.all(np.isfinite(s.orientations))
        np.testing.assert_allclose(np.linalg.norm(s.orientations, axis=1), 1.0, atol=1e-12)
        speed = np.linalg.norm(np.diff(s.positions, axis=0), axis=1) / DT
        assert speed.max() <= v_t * (1 + 1e-9)
        assert np.linalg.norm(s.velocities, axis=1).max() <= v_t * (1 + 1e-9)
        accel = np.linalg.norm(np.diff(s.positions, 2, axis=0), axis=1) / DT**2
        assert accel.max() <= a_t + 1e-6
        assert np.linalg.norm(s.accelerations, axis=1).max() <= a_t * (1 + 1e-9)
        turn = angle_between(s.orientations[1:], s.orientations[:-1]) / DT
        assert turn.max() <= v_r * (1 + 1e-6)
        omega = s.angular_velocities
        assert np.linalg.norm(omega, axis=1).max() <= v_r * (1 + 1e-9)
        # the analytic angular velocity is the derivative of the orientation ...
        mid = rot.multiply  # (readability) compare with the finite-difference rotation
        increments = np.array(
            [
                rot.log(mid(b, rot.conjugate(a)))
                for a, b in zip(s.orientations[:-1], s.orientations[1:], strict=True)
            ]
        )
        np.testing.assert_allclose(
            increments / DT, 0.5 * (omega[1:] + omega[:-1]), atol=a_r * DT + 1e-6
        )
        # ... and its change per period stays within the angular acceleration bound
        alpha = np.linalg.norm(np.diff(omega, axis=0), axis=1) / DT
        assert alpha.max() <= a_r * (1 + 1e-6) + 1e-6


def test_starts_and_ends_at_rest_on_the_waypoints() -> None:
    rng = np.random.default_rng(5)
    for dev in (0.0, 0.05):
        positions, quats = random_poses(rng, 4)
        traj = CartesianTrajectory(positions, quats, max_deviation=dev)
        end = traj.get_duration()
        assert np.array_equal(traj.get_position(0.0), positions[0])
        assert np.array_equal(traj.get_position(end), positions[-1])
        np.testing.assert_allclose(traj.get_orientation(0.0), quats[0], atol=1e-15)
        assert angle_between(traj.get_orientation(end), quats[-1]) < 1e-7
        assert angle_between(traj.get_orientation(end - 1e-9), quats[-1]) < 1e-7
        s = traj.sample([0.0, end, end + 1.0, -1.0])
        assert np.all(s.velocities[1:] == 0.0) and np.all(s.angular_velocities[1:] == 0.0)
        pose = traj.get_pose(0.5 * end)
        np.testing.assert_allclose(pose[:3, 3], traj.get_position(0.5 * end))
        np.testing.assert_allclose(pose[:3, :3], rot.to_matrix(traj.get_orientation(0.5 * end)))
        np.testing.assert_array_equal(pose[3], [0, 0, 0, 1])


def test_without_deviation_every_pose_is_visited() -> None:
    rng = np.random.default_rng(6)
    positions, quats = random_poses(rng, 5)
    traj = CartesianTrajectory(positions, quats, speed_factor=1.0)
    s = traj.sample(np.arange(0.0, traj.get_duration() + DT, DT))
    for p, q in zip(positions, quats, strict=True):
        k = int(np.argmin(np.linalg.norm(s.positions - p, axis=1)))
        assert (
            np.linalg.norm(s.positions[k] - p)
            <= 0.5 * FER.cartesian.translation_acceleration * DT**2
        )
        assert (
            angle_between(s.orientations[k], q) <= 0.5 * FER.cartesian.rotation_acceleration * DT**2
        )


def test_with_deviation_the_position_stays_within_it() -> None:
    rng = np.random.default_rng(12)
    for dev in (0.01, 0.05):
        positions, _ = random_poses(rng, 5)
        quats = np.tile(Q0, (5, 1))
        traj = CartesianTrajectory(positions, quats, max_deviation=dev)
        s = traj.sample(np.arange(0.0, traj.get_duration(), DT))
        best = np.full(len(s.positions), np.inf)
        for a, b in itertools.pairwise(positions):
            d = b - a
            u = np.clip((s.positions - a) @ d / (d @ d), 0.0, 1.0)
            best = np.minimum(best, np.linalg.norm(s.positions - (a + u[:, None] * d), axis=1))
        assert best.max() <= dev + 1e-9
        assert angle_between(s.orientations, Q0).max() < 1e-9


def test_poses_overload_equals_positions_and_orientations() -> None:
    rng = np.random.default_rng(13)
    positions, quats = random_poses(rng, 4)
    poses = np.tile(np.eye(4), (4, 1, 1))
    poses[:, :3, :3] = [rot.to_matrix(q) for q in quats]
    poses[:, :3, 3] = positions
    a = CartesianTrajectory(positions, quats, 0.3, 0.02)
    b = CartesianTrajectory(poses, 0.3, 0.02)
    c = CartesianTrajectory(poses=list(poses), speed_factor=0.3, max_deviation=0.02)
    d = CartesianTrajectory(
        [p.reshape(3, 1) for p in positions], [-q.reshape(4, 1) for q in quats], 0.3, 0.02
    )
    for other in (b, c, d):
        assert other.get_duration() == pytest.approx(a.get_duration(), rel=1e-9)
        t = 0.37 * a.get_duration()
        np.testing.assert_allclose(other.get_pose(t), a.get_pose(t), atol=1e-9)


def test_a_quaternion_and_its_negative_are_the_same_orientation() -> None:
    q1 = rot.multiply(Q0, rot.exp(np.array([0.0, 0.0, 0.5])))
    a = CartesianTrajectory([P0, P0], [Q0, q1])
    b = CartesianTrajectory([P0, P0], [Q0, -q1])
    assert a.get_duration() == b.get_duration() == pytest.approx(1.1)  # 0.5 rad, 0.2 speed


def test_blend_rotation_gain_bounds_the_jacobian_derivative() -> None:
    """The bound on d/dt J_r(x) ẋ that the blends rely on (finite differences)."""

    def right_jacobian(x: np.ndarray) -> np.ndarray:
        return np.stack([rot.right_jacobian_times(x[None], e[None])[0] for e in np.eye(3)], 1)

    rng = np.random.default_rng(14)
    for _ in range(300):
        theta = rng.uniform(0.0, math.pi)
        x = rng.normal(size=3)
        x *= theta / np.linalg.norm(x)
        xd = rng.normal(size=3)
        xd /= np.linalg.norm(xd)
        h = 1e-6
        deriv = (right_jacobian(x + h * xd) - right_jacobian(x - h * xd)) / (2 * h) @ xd
        assert np.linalg.norm(deriv) <= _blend_rotation_gain(theta) + 1e-7


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (([], []), {}, "at least one"),
        (([P0, P0], [Q0]), {}, "one per position"),
        (([P0[:2]], [Q0]), {}, r"positions: expected shape \(N, 3\)"),
        (([P0], [Q0[:3]]), {}, r"orientations: expected shape \(N, 4\)"),
        (([P0], [2 * Q0]), {}, r"orientations\[0\].*unit quaternion"),
        (([P0], [np.zeros(4)]), {}, "unit quaternion"),
        (([[math.nan, 0, 0]], [Q0]), {}, r"positions\[0\]\[0\].*finite"),
        (([P0], [Q0]), {"speed_factor": 0.0}, "speed_factor"),
        (([P0], [Q0]), {"max_deviation": -1.0}, "max_deviation"),
        (([P0], [Q0]), {"timeout": -1.0}, "timeout"),
        (([P0], [Q0]), {"robot": "kuka"}, "robot"),
    ],
)
def test_bad_positions_and_orientations_are_rejected(
    args: tuple[object, ...], kwargs: dict[str, object], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        CartesianTrajectory(*args, **kwargs)


def test_bad_poses_are_rejected() -> None:
    good = np.eye(4)
    bottom = good.copy()
    bottom[3, 0] = 0.1
    skew = good.copy()
    skew[0, 1] = 0.1
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    nan = good.copy()
    nan[0, 3] = math.nan
    for pose, match in [
        (bottom, r"poses\[1\].*last row"),
        (skew, r"poses\[1\].*rotation"),
        (mirror, r"poses\[1\].*det"),
        (nan, r"poses\[1\]\[0\]\[3\].*finite"),
    ]:
        with pytest.raises(ValueError, match=match):
            CartesianTrajectory([good, pose])
    with pytest.raises(ValueError, match="speed_factor"):
        CartesianTrajectory([good], 1.5)


class ArmAtStart:
    """A JointMap: the FER's joints near the start pose (``J^+`` at the IK configuration),
    bounded by half their limits."""

    def __init__(self) -> None:
        from panda_py.kinematics import get_kinematics

        self.kin = get_kinematics("fer")
        self.q0 = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
        self.velocity = 0.5 * np.array(FER.joints.dq_max)
        self.acceleration = 0.5 * np.array(FER.joints.ddq_max)
        self.start = self.kin.fk(self.q0)

    def rates(self, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
        q = self.kin.ik(poses, self.q0, float(self.q0[6]))
        return np.array([np.linalg.pinv(self.kin.zero_jacobian(qi)) @ t
                         for qi, t in zip(q, twists, strict=True)])  # fmt: skip


def test_a_joint_map_bounds_the_joints_at_every_sample_as_well() -> None:
    """Beyond panda-py: with ``joints`` the path keeps the joints' bounds too (where the
    Cartesian ones alone would ask a joint for more), on lines and blends alike."""
    arm = ArmAtStart()
    rng = np.random.default_rng(3)
    slower = 0
    for _ in range(6):
        poses = [arm.start]
        for _ in range(int(rng.integers(1, 4))):
            pose = arm.start.copy()
            pose[:3, 3] += rng.uniform(-0.15, 0.15, 3)
            poses.append(pose)
        sf = float(rng.uniform(0.1, 1.0))
        traj = CartesianTrajectory(np.stack(poses), sf, 0.02, joints=arm)
        s = traj.sample(np.arange(0.0, traj.get_duration() + DT, DT))
        poses = rot.transforms(s.positions, s.orientations)
        dq = arm.rates(poses, np.hstack([s.velocities, s.angular_velocities]))
        assert np.isfinite(dq).all()
        assert (np.abs(dq) / arm.velocity).max() <= 1.0 + 1e-3
        assert (np.abs(np.diff(dq, axis=0)) / DT / arm.acceleration).max() <= 1.0 + 1e-3
        v_t = sf * FER.cartesian.translation_velocity
        assert np.linalg.norm(s.velocities, axis=1).max() <= v_t * (1 + 1e-9)
        np.testing.assert_allclose(s.positions[-1], poses[-1][:3, 3], atol=1e-9)
        free = CartesianTrajectory(np.stack(poses), sf, 0.02).get_duration()
        slower += traj.get_duration() > free * 1.01
    assert slower >= 3  # at half their limits the joints held most of these paths back


def test_a_joint_map_must_be_one() -> None:
    with pytest.raises(ValueError, match="joints: expected a JointMap"):
        CartesianTrajectory([P0, P0 + 0.1], [Q0, Q0], joints=object())

    class Short(ArmAtStart):
        def rates(self, poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
            return super().rates(poses, twists)[:, :6]

    arm = Short()
    with pytest.raises(ValueError, match=r"joints: expected rates of shape \(\d+, 7\)"):
        CartesianTrajectory(np.stack([arm.start, arm.start @ _shifted(0.05)]), joints=arm)


def _shifted(dx: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = dx
    return T
