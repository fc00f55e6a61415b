"""Client-side rate limiter and low-pass filter: limits honoured, fast path = reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.libfranka import _fast
from panda_py.libfranka import limits as lm
from panda_py.libfranka._commander import Commander
from panda_py.robots import FER, FR3, position_based_velocity_limits

DT = 1e-3
SLACK = 1e-6  # [relative] float round-off allowed on a limit


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T.reshape(16, order="F")


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_limited_joint_positions_respect_velocity_acceleration_and_jerk(robot):
    """Closed loop as on the robot: the state echoes each limited command as q_d/dq_d/ddq_d."""
    rng = np.random.default_rng(1)
    lim = lm.RateLimits.for_robot(robot)
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    dq = np.zeros(7)
    ddq = np.zeros(7)
    target = q.copy()
    for k in range(3000):
        if k % 500 == 0:  # wild steps: the limiter must make them feasible
            target = q + rng.uniform(-0.8, 0.8, 7)
        upper, lower = lim.joint_velocity_limits(q)
        q_new = lm.limit_rate_joint_positions(
            upper, lower, lim.max_joint_acceleration, lim.max_joint_jerk, target, q, dq, ddq
        )
        dq_new = (q_new - q) / DT
        ddq_new = (dq_new - dq) / DT
        jerk = (ddq_new - ddq) / DT
        # A velocity above the limit (the FR3's limit shrinks as the joint moves) is driven
        # back: its excess shrinks by (1 - jerk/acc * dt) or by acc * dt per tick.
        shrink = 1.0 - lim.max_joint_jerk / lim.max_joint_acceleration * DT
        step = lim.max_joint_acceleration * DT
        for excess, new in ((dq - upper, dq_new - upper), (lower - dq, lower - dq_new)):
            bound = np.maximum(0.0, np.maximum(shrink * excess, excess - step))
            assert np.all(new <= bound + 1e-9)
        assert np.all(np.abs(ddq_new) <= lim.max_joint_acceleration * (1 + SLACK) + 1e-9)
        if not lim.position_based:  # a shrinking FR3 limit can clamp faster (as libfranka)
            assert np.all(np.abs(jerk) <= lim.max_joint_jerk * (1 + SLACK) + 1e-6)
        q, dq, ddq = q_new, dq_new, ddq_new


def test_a_feasible_smooth_motion_passes_the_limiter_unchanged():
    lim = lm.RateLimits.for_robot("fer")
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    q, dq, ddq = q0.copy(), np.zeros(7), np.zeros(7)
    for k in range(1, 1001):  # 0.2 rad in 1 s, cosine profile: far inside every limit
        target = q0 + 0.1 * (1 - np.cos(np.pi * k / 1000))
        upper, lower = lim.joint_velocity_limits(q)
        out = lm.limit_rate_joint_positions(
            upper, lower, lim.max_joint_acceleration, lim.max_joint_jerk, target, q, dq, ddq
        )
        np.testing.assert_allclose(out, target, atol=1e-12)
        dq_new = (out - q) / DT
        q, dq, ddq = out, dq_new, (dq_new - dq) / DT


def test_fer_limits_are_libfranka_0_9s_constants():
    lim = lm.RateLimits.for_robot("fer")
    # kMaxJointVelocity = 2.175 - kLimitEps - 3 packets * 1 ms * (15 - kLimitEps)
    assert lim.max_joint_velocity[0] == pytest.approx(2.175 - 1e-3 - 3e-3 * (15 - 1e-3))
    assert lim.max_joint_jerk[1] == pytest.approx(3750 - 1e-3)
    assert lim.translation[0] == pytest.approx(1.7 - 1e-3 - 3e-3 * (13 - 1e-3))
    assert lf.MAX_TORQUE_RATE == pytest.approx([1000 - 1e-3] * 7)


def test_fr3_velocity_limits_follow_the_position():
    lim = lm.RateLimits.for_robot("fr3")
    rng = np.random.default_rng(2)
    for _ in range(50):
        q = rng.uniform(FR3.joints.q_min, FR3.joints.q_max)
        up, lo = position_based_velocity_limits(FR3, q)
        upper, lower = lim.joint_velocity_limits(q)
        np.testing.assert_allclose(upper, np.array(up) - lm.LIMIT_EPS, atol=1e-12)
        np.testing.assert_allclose(lower, np.array(lo) + lm.LIMIT_EPS, atol=1e-12)


def test_torque_rate_limit_and_lowpass_gain():
    last = np.zeros(7)
    out = lf.limit_rate(np.full(7, 1000.0), np.array([5, -5, 0.5, 0, 0, 0, 0.0]), last)
    np.testing.assert_allclose(out, [1, -1, 0.5, 0, 0, 0, 0])
    gain = DT / (DT + 1 / (2 * math.pi * 100.0))
    assert lf.lowpass_filter(DT, 1.0, 0.0, 100.0) == pytest.approx(gain)
    with pytest.raises(ValueError, match="cutoff_frequency"):
        lf.lowpass_filter(DT, 1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="infinite or NaN"):
        lf.limit_rate(np.full(7, 1000.0), np.full(7, np.nan), last)


def test_cartesian_lowpass_moves_along_the_shortest_arc():
    rng = np.random.default_rng(3)
    for _ in range(20):
        R0, R1 = _random_rotation(rng), _random_rotation(rng)
        T0, T1 = _pose(R0, rng.normal(size=3)), _pose(R1, rng.normal(size=3))
        out = lf.cartesian_lowpass_filter(DT, T1, T0, 50.0)
        gain = DT / (DT + 1 / (2 * math.pi * 50.0))
        R = out.reshape(4, 4, order="F")[:3, :3]
        angle_total = np.arccos(np.clip((np.trace(R0.T @ R1) - 1) / 2, -1, 1))
        angle_step = np.arccos(np.clip((np.trace(R0.T @ R) - 1) / 2, -1, 1))
        assert angle_step == pytest.approx(gain * angle_total, abs=1e-9)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(out[12:15], T0[12:15] + gain * (T1[12:15] - T0[12:15]))


def test_limited_cartesian_pose_respects_the_twist_limits():
    rng = np.random.default_rng(4)
    lim = lm.RateLimits.for_robot("fr3")
    T = _pose(np.eye(3), np.array([0.3, 0.0, 0.5]))
    v = np.zeros(6)
    a = np.zeros(6)
    goal = _pose(_random_rotation(rng), np.array([0.6, 0.3, 0.2]))
    for _ in range(2000):
        T_new = lm.limit_rate_cartesian_pose(lim.translation, lim.rotation, goal, T, v, a)
        assert lf.is_homogeneous_transformation(T_new)
        v_new = np.empty(6)
        v_new[:3] = (T_new[12:15] - T[12:15]) / DT
        R_prev, R_cur = T.reshape(4, 4, order="F")[:3, :3], T_new.reshape(4, 4, order="F")[:3, :3]
        v_new[3:] = lm._log(R_cur @ R_prev.T) / DT
        assert np.linalg.norm(v_new[:3]) <= lim.translation[0] * (1 + SLACK)
        assert np.linalg.norm(v_new[3:]) <= 0.99 * lim.rotation[0] * (1 + 1e-6)
        a_new = (v_new - v) / DT
        assert np.linalg.norm(a_new[:3]) <= lim.translation[1] * (1 + 1e-6) + 1e-6
        T, v, a = T_new, v_new, a_new


def test_fast_math_equals_the_numpy_reference():
    rng = np.random.default_rng(5)
    lim = lm.RateLimits.for_robot("fr3")
    for _ in range(200):
        q_last = rng.uniform(FR3.joints.q_min, FR3.joints.q_max)
        dq, ddq = rng.normal(0, 1, 7), rng.normal(0, 5, 7)
        q = q_last + rng.normal(0, 0.01, 7)
        up, lo = lim.joint_velocity_limits(q_last)
        ref = lm.limit_rate_joint_positions(
            up, lo, lim.max_joint_acceleration, lim.max_joint_jerk, q, q_last, dq, ddq
        )
        fast = _fast.joint_positions(
            up.tolist(), lo.tolist(), lim.max_joint_acceleration.tolist(),
            lim.max_joint_jerk.tolist(), q.tolist(), q_last.tolist(), dq.tolist(), ddq.tolist(),
        )  # fmt: skip
        np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-12)
        T_last = _pose(_random_rotation(rng), rng.normal(size=3))
        R_step = lm._exp(rng.normal(0, 0.01, 3))
        T = _pose(R_step @ T_last.reshape(4, 4, order="F")[:3, :3], T_last[12:15] + 0.001)
        v, a = rng.normal(0, 0.5, 6), rng.normal(0, 2, 6)
        ref_T = lm.limit_rate_cartesian_pose(lim.translation, lim.rotation, T, T_last, v, a)
        rot = [0.99 * x for x in lim.rotation]
        fast_T = _fast.pose_limit(lim.translation, rot, T.tolist(), T_last.tolist(), v, a)
        np.testing.assert_allclose(fast_T, ref_T, atol=1e-12)
        ref_f = lf.cartesian_lowpass_filter(DT, T, T_last, 30.0)
        gain = lm._gain(DT, 30.0)
        np.testing.assert_allclose(_fast.pose_lowpass(gain, T, T_last), ref_f, atol=1e-12)
        # filter and limiter in one pass, for steps up to large rotations and gains near 1
        for angle, cutoff in ((0.01, 30.0), (1.0, 300.0), (3.0, 999.0)):
            T_far = _pose(lm._exp(rng.normal(0, angle, 3)) @ R_step, T_last[12:15] + 0.01)
            ref_f = lf.cartesian_lowpass_filter(DT, T_far, T_last, cutoff)
            ref_fl = lm.limit_rate_cartesian_pose(lim.translation, lim.rotation, ref_f, T_last,
                                                  v, a)  # fmt: skip
            fast_fl = _fast.pose_lowpass_limit(
                lm._gain(DT, cutoff), lim.translation, rot, T_far.tolist(), T_last.tolist(), v, a
            )
            np.testing.assert_allclose(fast_fl, ref_fl, atol=1e-12)
    # a rotation by (almost) pi: the log map's special branch
    R = lm._exp(np.array([0.0, math.pi - 1e-9, 0.0]))
    np.testing.assert_allclose(_fast.log_so3(tuple(R.reshape(9))), lm._log(R), atol=1e-6)
    np.testing.assert_allclose(np.abs(lm._log(R)), [0, math.pi, 0], atol=1e-6)


def test_commander_filters_and_limits_torques_against_tau_J_d():
    d = fci.dialect(5)
    c = Commander(d, lm.RateLimits.for_robot(FER), True, 100.0)
    state = d.new_state()
    state["tau_J_d"] = np.arange(7.0)
    data = d.encode_state(state)
    c.torques(lf.Torques(np.arange(7.0) + 50.0), data)
    gain = lm._gain(DT, 100.0)
    step = min(gain * 50.0, 1.0 - 1e-6)  # limited to (1000 - eps) Nm/s * 1 ms
    np.testing.assert_allclose(c.record["tau_J_d"], np.arange(7.0) + step, rtol=1e-12)
    assert bytes(c.buffer) == d.encode_command(c.record)  # the record views the datagram
    again = lf.Torques(np.arange(7.0) + 50.0)
    c.torques(again, data)
    first = bytes(c.buffer)
    c.torques(again, data)  # the same object returned twice: the same command
    assert bytes(c.buffer) == first
    np.testing.assert_array_equal(again.tau_J, np.arange(7.0) + 50.0)  # not filtered in place
    off = Commander(d, lm.RateLimits.for_robot(FER), False, 1000.0)  # both disabled
    off.torques(lf.Torques(np.full(7, 50.0)), data)
    np.testing.assert_array_equal(off.record["tau_J_d"], np.full(7, 50.0))
    bad = lf.Torques(np.zeros(7))
    bad.tau_J[2] = np.nan  # mutated after construction: still caught
    with pytest.raises(ValueError, match="infinite or NaN"):
        c.torques(bad, data)
    bad.tau_J = np.zeros(8)  # replaced by a wrong shape: a clear error, not a struct one
    with pytest.raises(ValueError, match="expected 7 numbers"):
        c.torques(bad, data)
    with pytest.raises(ValueError, match="expected it to return Torques"):
        c.torques(lf.JointPositions(np.zeros(7)), data)
    pose = lf.CartesianPose(np.eye(4))
    pose.O_T_EE[0] = 2.0  # no longer a rotation
    with pytest.raises(ValueError, match="invalid transformation"):
        c.cartesian_pose(pose, data)


def _reference_command(
    kind: type, lim: lm.RateLimits, limit: bool, cutoff: float, out, rec, first: bool
) -> dict[str, np.ndarray]:
    """What the Commander must write, from the NumPy reference of :mod:`limits`."""
    f = lambda name: np.array(rec[name], dtype=np.float64)  # noqa: E731
    filt = cutoff < lm.MAX_CUTOFF_FREQUENCY
    if kind is lf.Torques:
        tau = out.tau_J
        if filt:
            tau = lm.lowpass_filter(DT, tau, f("tau_J_d"), cutoff)
        if limit:
            tau = lm.limit_rate(lim.max_torque_rate, tau, f("tau_J_d"))
        return {"tau_J_d": tau}
    if kind is lf.JointPositions or kind is lf.JointVelocities:
        up, lo = lim.joint_velocity_limits(f("q_d"))
        acc, jerk = lim.max_joint_acceleration, lim.max_joint_jerk
        if kind is lf.JointPositions:
            q = out.q
            if filt and not first:
                q = lm.lowpass_filter(DT, q, f("q_d"), cutoff)
            if limit:
                q = lm.limit_rate_joint_positions(
                    up, lo, acc, jerk, q, f("q_d"), f("dq_d"), f("ddq_d")
                )
            return {"q_c": q}
        dq = out.dq
        if filt:
            dq = lm.lowpass_filter(DT, dq, f("dq_d"), cutoff)
        if limit:
            dq = lm.limit_rate_joint_velocities(up, lo, acc, jerk, dq, f("dq_d"), f("ddq_d"))
        return {"dq_c": dq}
    e0, sign = out.elbow
    last_e = f("elbow_c")[0]
    if kind is lf.CartesianPose:
        T = out.O_T_EE
        if filt and not first:
            T = lm.cartesian_lowpass_filter(DT, T, f("O_T_EE_c"), cutoff)
            e0 = lm.lowpass_filter(DT, e0, last_e, cutoff)
        if limit:
            T = lm.limit_rate_cartesian_pose(
                lim.translation, lim.rotation, T, f("O_T_EE_c"), f("O_dP_EE_c"),
                f("O_ddP_EE_c"),
            )  # fmt: skip
        value = {"O_T_EE_c": T}
    else:
        v = out.O_dP_EE
        if filt:
            v = lm.lowpass_filter(DT, v, f("O_dP_EE_c"), cutoff)
            e0 = lm.lowpass_filter(DT, e0, last_e, cutoff)
        if limit:
            v = lm.limit_rate_cartesian_velocity(
                lim.translation, lim.rotation, v, f("O_dP_EE_c"), f("O_ddP_EE_c")
            )
        value = {"O_dP_EE_c": v}
    if limit:
        e0 = lm.limit_rate_position(lim.elbow, e0, last_e, f("delbow_c")[0], f("ddelbow_c")[0])
    value["elbow_c"] = np.array([e0, sign])
    return value


@pytest.mark.parametrize("version", [5, 10])  # float64 and float32 states
@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_commander_equals_the_numpy_reference_on_random_states(version, robot):
    """The per-tick path (struct reads of the state datagram, float math, a packed
    datagram) writes what the NumPy reference computes, to 1e-12, for every command type,
    with and without filter and rate limiter."""
    rng = np.random.default_rng(version * 10 + len(robot))
    d = fci.dialect(version)
    spec = FER if robot == "fer" else FR3
    lim = lm.RateLimits.for_robot(robot)
    kinds = [lf.Torques, lf.JointPositions, lf.JointVelocities, lf.CartesianPose,
             lf.CartesianVelocities]  # fmt: skip
    convert = {lf.Torques: "torques", lf.JointPositions: "joint_positions",
               lf.JointVelocities: "joint_velocities", lf.CartesianPose: "cartesian_pose",
               lf.CartesianVelocities: "cartesian_velocities"}  # fmt: skip
    for i in range(150):
        state = d.new_state()
        q_d = rng.uniform(spec.joints.q_min, spec.joints.q_max)
        state["q_d"], state["dq_d"], state["ddq_d"] = q_d, rng.normal(0, 1, 7), rng.normal(0, 5, 7)
        state["tau_J_d"] = rng.normal(0, 5, 7)
        T_last = _pose(_random_rotation(rng), rng.normal(0, 0.5, 3))
        state["O_T_EE_c"] = T_last
        state["O_dP_EE_c"], state["O_ddP_EE_c"] = rng.normal(0, 0.3, 6), rng.normal(0, 3, 6)
        state["elbow_c"] = [rng.uniform(-2, 2), 1.0]
        state["delbow_c"], state["ddelbow_c"] = rng.normal(0, 0.5, 2), rng.normal(0, 3, 2)
        data = d.encode_state(state)
        rec = d.decode_state(data)  # float32 fields in v10: the reference reads the same
        T_now = np.array(rec["O_T_EE_c"], dtype=np.float64).reshape(4, 4, order="F")
        small = 10.0 ** rng.uniform(-6, -2)  # within and far beyond the limits
        R = lm._exp(rng.normal(0, small, 3)) @ T_now[:3, :3]
        commands = {
            lf.Torques: lf.Torques(rec["tau_J_d"] + rng.normal(0, 100 * small, 7)),
            lf.JointPositions: lf.JointPositions(rec["q_d"] + rng.normal(0, small, 7)),
            lf.JointVelocities: lf.JointVelocities(rec["dq_d"] + rng.normal(0, 100 * small, 7)),
            lf.CartesianPose: lf.CartesianPose(
                _pose(R, T_now[:3, 3] + rng.normal(0, small, 3)),
                [rec["elbow_c"][0] + rng.normal(0, small), -1.0],
            ),
            lf.CartesianVelocities: lf.CartesianVelocities(
                rec["O_dP_EE_c"] + rng.normal(0, 100 * small, 6),
                [rec["elbow_c"][0] + rng.normal(0, small), 1.0],
            ),
        }
        limit = bool(i % 4 != 3)
        cutoff = (1000.0, 100.0, 30.0)[i % 3]
        for kind in kinds:
            c = Commander(d, lim, limit, cutoff)
            c.initialized = bool(i % 2)  # position filters skip the first command
            first = not c.initialized
            getattr(c, convert[kind])(commands[kind], data)
            expected = _reference_command(kind, lim, limit, cutoff, commands[kind], rec, first)
            for name, value in expected.items():
                np.testing.assert_allclose(c.record[name], value, rtol=0, atol=1e-12,
                                           err_msg=f"{kind.__name__} {name} case {i}")  # fmt: skip
            if kind in (lf.CartesianPose, lf.CartesianVelocities):
                assert bool(c.record["valid_elbow"])
