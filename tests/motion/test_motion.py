"""JointTrajectory: bounds at 1 kHz, waypoints, closed-form optima, errors."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import panda_py
from panda_py.motion import JointTrajectory, PlanningTimeoutError, TrajectoryError
from panda_py.robots.params import FER, FR3, START_POSE, RobotSpec

DT = 1e-3  # [s] the robot's control period
REL = 1e-9  # [-] rounding allowance on analytic velocities/accelerations


def limits(spec: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    return np.array(spec.joints.q_min), np.array(spec.joints.q_max)


def random_waypoints(rng: np.random.Generator, spec: RobotSpec, n: int) -> np.ndarray:
    lo, hi = limits(spec)
    return rng.uniform(lo, hi, size=(n, 7))


def closed_form_duration(distance: float, vmax: float, amax: float) -> float:
    """Rest-to-rest time-optimal duration of a straight move: triangle or trapezoid."""
    if distance >= vmax * vmax / amax:
        return distance / vmax + vmax / amax
    return 2.0 * math.sqrt(distance / amax)


def sample_1khz(traj: JointTrajectory) -> tuple[np.ndarray, ...]:
    times = np.arange(0.0, traj.get_duration() + DT, DT)
    return times, *traj.sample(times)


def polyline_distance(points: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
    """Distance of each point to the polyline through the waypoints."""
    best = np.full(len(points), np.inf)
    for a, b in itertools.pairwise(waypoints):
        d = b - a
        u = np.clip((points - a) @ d / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + u[:, None] * d), axis=1))
    return best


def test_panda_py_reexports_the_classes() -> None:
    assert panda_py.JointTrajectory is JointTrajectory
    assert panda_py.CartesianTrajectory.__module__ == "panda_py.motion.cartesian"


@pytest.mark.parametrize("spec", [FER, FR3], ids=["fer", "fr3"])
@pytest.mark.parametrize("speed_factor", [0.05, 0.2, 1.0])
@pytest.mark.parametrize("distance", [0.005, 0.1, 1.5])
def test_single_joint_move_is_the_closed_form_optimum(
    spec: RobotSpec, speed_factor: float, distance: float
) -> None:
    for j in range(7):
        q0 = np.array(START_POSE)
        q1 = q0.copy()
        q1[j] += distance if q0[j] + distance <= spec.joints.q_max[j] else -distance
        traj = JointTrajectory([q0, q1], speed_factor=speed_factor, robot=spec.name)
        expected = closed_form_duration(
            distance, speed_factor * spec.joints.dq_max[j], speed_factor * spec.joints.ddq_max[j]
        )
        assert traj.get_duration() == pytest.approx(expected, rel=1e-9)


def test_diagonal_move_is_limited_by_the_slowest_joint() -> None:
    q0 = np.array(START_POSE)
    step = np.full(7, 0.3)
    traj = JointTrajectory([q0, q0 + step], speed_factor=0.5)
    # each joint moves 0.3 rad; the slowest joint's own optimum is the path's optimum
    per_joint = [
        closed_form_duration(0.3, 0.5 * FER.joints.dq_max[j], 0.5 * FER.joints.ddq_max[j])
        for j in range(7)
    ]
    assert traj.get_duration() == pytest.approx(max(per_joint), rel=1e-9)


def test_stopping_path_takes_the_sum_of_its_segments() -> None:
    rng = np.random.default_rng(3)
    w = random_waypoints(rng, FER, 4)
    total = JointTrajectory(w).get_duration()
    parts = sum(JointTrajectory(w[i : i + 2]).get_duration() for i in range(3))
    assert total == pytest.approx(parts, rel=1e-12)


@pytest.mark.parametrize("spec", [FER, FR3], ids=["fer", "fr3"])
@pytest.mark.parametrize("max_deviation", [0.0, 0.02, 0.2])
def test_bounds_hold_at_1khz(spec: RobotSpec, max_deviation: float) -> None:
    rng = np.random.default_rng(11)
    lo, hi = limits(spec)
    for _ in range(8):
        sf = float(rng.uniform(0.05, 1.0))
        w = random_waypoints(rng, spec, int(rng.integers(2, 7)))
        traj = JointTrajectory(w, speed_factor=sf, max_deviation=max_deviation, robot=spec)
        vmax = sf * np.array(spec.joints.dq_max)
        amax = sf * np.array(spec.joints.ddq_max)
        np.testing.assert_allclose(traj.max_velocity, vmax)
        _, q, dq, ddq = sample_1khz(traj)
        assert np.all(np.isfinite(q))
        assert np.all(q >= lo) and np.all(q <= hi)
        assert np.all(np.abs(dq) <= vmax * (1 + REL))
        assert np.all(np.abs(ddq) <= amax * (1 + REL))
        # what a robot sees: differences of the commanded positions
        assert np.all(np.abs(np.diff(q, axis=0)) / DT <= vmax * (1 + REL) + 1e-9)
        assert np.all(np.abs(np.diff(q, 2, axis=0)) / DT**2 <= amax + 1e-6)
        # the analytic derivatives are the derivatives of the positions
        mid = 0.5 * (dq[1:] + dq[:-1])
        np.testing.assert_allclose(np.diff(q, axis=0) / DT, mid, atol=amax.max() * DT)


def test_starts_and_ends_at_rest_exactly_on_the_waypoints() -> None:
    rng = np.random.default_rng(5)
    for dev in (0.0, 0.1):
        w = random_waypoints(rng, FER, 5)
        traj = JointTrajectory(w, max_deviation=dev)
        end = traj.get_duration()
        assert np.array_equal(traj.get_joint_positions(0.0), w[0])
        assert np.array_equal(traj.get_joint_positions(end), w[-1])
        for t in (0.0, end):
            assert np.all(traj.get_joint_velocities(t) == 0.0)
        assert np.linalg.norm(traj.get_joint_velocities(end - 1e-9)) < 1e-6
        np.testing.assert_allclose(traj.get_joint_positions(end - 1e-9), w[-1], atol=1e-12)
        # before and after: at rest on the ends
        assert np.array_equal(traj.get_joint_positions(-1.0), w[0])
        assert np.array_equal(traj.get_joint_positions(end + 5.0), w[-1])
        assert np.all(traj.get_joint_accelerations(end + 5.0) == 0.0)
        assert np.all(traj.get_joint_velocities(-1.0) == 0.0)


def test_without_deviation_every_waypoint_is_visited_at_rest() -> None:
    rng = np.random.default_rng(7)
    for _ in range(10):
        w = random_waypoints(rng, FER, 6)
        traj = JointTrajectory(w, speed_factor=1.0)
        _, q, dq, _ = sample_1khz(traj)
        # between two 1 kHz samples a stopped joint moves at most a_max dt² / 2
        reach = 0.5 * np.linalg.norm(FER.joints.ddq_max) * DT**2
        for wp in w:
            dist = np.linalg.norm(q - wp, axis=1)
            k = int(np.argmin(dist))
            assert dist[k] <= reach
            assert np.linalg.norm(dq[k]) <= np.linalg.norm(FER.joints.ddq_max) * DT


def test_with_deviation_the_path_stays_within_it() -> None:
    rng = np.random.default_rng(8)
    blended = stopping = 0.0
    for dev in (0.01, 0.05, 0.3):
        for _ in range(5):
            w = random_waypoints(rng, FER, 5)
            traj = JointTrajectory(w, max_deviation=dev)
            _, q, _, _ = sample_1khz(traj)
            assert polyline_distance(q, w).max() <= dev + 1e-9
            # every interior waypoint is passed within the deviation
            for wp in w[1:-1]:
                assert np.linalg.norm(q - wp, axis=1).min() <= dev + 1e-3
            blended += traj.get_duration()
            stopping += JointTrajectory(w).get_duration()
    # cutting corners instead of stopping saves time overall (a blend at a near-reversal
    # can be slightly slower than stopping: it adds a slow arc)
    assert blended < 0.99 * stopping


def test_thousand_random_sets_plan_without_nan() -> None:
    rng = np.random.default_rng(2024)
    for i in range(1000):
        spec = FER if i % 2 else FR3
        w = random_waypoints(rng, spec, int(rng.integers(2, 8)))
        dev = float(rng.choice([0.0, 0.01, 0.1, 0.5]))
        sf = float(rng.uniform(0.01, 1.0))
        traj = JointTrajectory(w, speed_factor=sf, max_deviation=dev, robot=spec)
        duration = traj.get_duration()
        assert math.isfinite(duration) and duration > 0.0
        q, dq, ddq = traj.sample(np.linspace(0.0, duration, 40))
        assert np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.all(np.isfinite(ddq))


def test_vectorised_sampling_equals_scalar_getters() -> None:
    rng = np.random.default_rng(9)
    traj = JointTrajectory(random_waypoints(rng, FER, 5), max_deviation=0.1)
    times = rng.uniform(-0.5, traj.get_duration() + 0.5, size=300)
    q, dq, ddq = traj.sample(times)
    for t, qi, dqi, ddqi in zip(times, q, dq, ddq, strict=True):
        np.testing.assert_allclose(traj.get_joint_positions(t), qi, rtol=0, atol=1e-12)
        np.testing.assert_allclose(traj.get_joint_velocities(t), dqi, rtol=0, atol=1e-12)
        np.testing.assert_allclose(traj.get_joint_accelerations(t), ddqi, rtol=0, atol=1e-10)
    assert traj.sample(np.zeros((2, 3))).positions.shape == (2, 3, 7)


def test_single_or_repeated_waypoint_is_a_motionless_trajectory() -> None:
    q = np.array(START_POSE)
    for waypoints in ([q], [q, q, q]):
        traj = JointTrajectory(waypoints)
        assert traj.get_duration() == 0.0
        assert np.array_equal(traj.get_joint_positions(0.0), q)
        assert np.all(traj.get_joint_velocities(0.3) == 0.0)
    # a repeated waypoint inside a path is passed once
    other = q + 0.2
    assert JointTrajectory([q, other, other, q]).get_duration() == pytest.approx(
        JointTrajectory([q, other, q]).get_duration()
    )


def test_accepts_panda_py_column_vectors_and_arrays() -> None:
    q = np.array(START_POSE)
    a = JointTrajectory([q.reshape(7, 1), (q + 0.1).reshape(7, 1)])
    b = JointTrajectory(np.stack([q, q + 0.1]))
    c = JointTrajectory([list(q), list(q + 0.1)], 0.2, 0.0, 30.0)
    assert a.get_duration() == b.get_duration() == c.get_duration()


def test_fr3_limits_differ_from_the_fer() -> None:
    q = np.array(START_POSE)
    w = [q, q + np.array([0.0, 0.0, 0.0, 0.0, 0.8, 0.0, 0.0])]
    # joint 5: FER 2.61 rad/s, 15 rad/s²; FR3 5.26 rad/s, 10 rad/s²
    fer = JointTrajectory(w, speed_factor=1.0).get_duration()
    fr3 = JointTrajectory(w, speed_factor=1.0, robot="fr3").get_duration()
    assert fer == pytest.approx(closed_form_duration(0.8, 2.61, 15.0))
    assert fr3 == pytest.approx(closed_form_duration(0.8, 5.26, 10.0))


@pytest.mark.parametrize(
    ("waypoints", "match"),
    [
        ([], "at least one"),
        (np.zeros((0, 7)), "at least one"),
        (np.array(START_POSE), r"shape \(N, 7\)"),
        (np.zeros((2, 6)), r"shape \(N, 7\)"),
        ([[0.0] * 7, [0.0] * 6], "numeric array"),
        ("abc", r"shape|numeric"),
        ([START_POSE, [math.nan, *START_POSE[1:]]], r"waypoints\[1\]\[0\].*finite"),
        ([START_POSE, [math.inf, *START_POSE[1:]]], "finite"),
        ([[3.0, *START_POSE[1:]]], r"waypoints\[0\]\[0\].*joint 1.*outside"),
    ],
)
def test_bad_waypoints_are_rejected(waypoints: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        JointTrajectory(waypoints)


def test_waypoint_outside_fr3_limits_but_inside_fer_limits() -> None:
    q = list(START_POSE)
    q[5] = 0.2  # FER allows down to -0.0175 rad, FR3 only to 0.4398 rad
    JointTrajectory([q])
    with pytest.raises(ValueError, match=r"joint 6.*fr3"):
        JointTrajectory([q], robot="fr3")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"speed_factor": 0.0}, "speed_factor"),
        ({"speed_factor": 1.01}, "speed_factor"),
        ({"speed_factor": -0.5}, "speed_factor"),
        ({"speed_factor": math.nan}, "speed_factor"),
        ({"speed_factor": "fast"}, "speed_factor"),
        ({"max_deviation": -0.1}, "max_deviation"),
        ({"max_deviation": math.inf}, "max_deviation"),
        ({"timeout": 0.0}, "timeout"),
        ({"timeout": math.nan}, "timeout"),
        ({"robot": "ur5"}, "robot"),
    ],
)
def test_bad_arguments_are_rejected(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        JointTrajectory([START_POSE, np.array(START_POSE) + 0.1], **kwargs)  # type: ignore[arg-type]


def test_planning_past_the_timeout_raises() -> None:
    rng = np.random.default_rng(1)
    w = random_waypoints(rng, FER, 2000)
    with pytest.raises(PlanningTimeoutError, match="timeout"):
        JointTrajectory(w, max_deviation=0.1, timeout=1e-4)
    assert issubclass(PlanningTimeoutError, TrajectoryError)
    assert issubclass(PlanningTimeoutError, RuntimeError)  # what panda-py raises
    JointTrajectory(w, max_deviation=0.1, timeout=30.0)


def test_nan_time_is_rejected() -> None:
    traj = JointTrajectory([START_POSE, np.array(START_POSE) + 0.1])
    with pytest.raises(ValueError, match="time"):
        traj.get_joint_positions(math.nan)
    with pytest.raises(ValueError, match="times"):
        traj.sample([0.0, math.nan])


def test_motion_all_is_honest() -> None:
    import panda_py.motion as motion

    assert all(hasattr(motion, name) for name in motion.__all__)
    assert {"JointTrajectory", "CartesianTrajectory"} <= set(motion.__all__)
