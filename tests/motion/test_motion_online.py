"""The online generator: from any state to a target (or to rest) within the velocity,
acceleration and jerk limits, continuous, reaching the target exactly; the pose variant
keeps its twist consistent with its orientation."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import jit
from panda_py.fci import PERIOD
from panda_py.jit import LOADED
from panda_py.motion import rotation
from panda_py.motion.online import OnlineGenerator, OnlineLimits, OnlinePose
from panda_py.robots.params import get_robot

ONLINE_JIT = "panda_py.motion._online_jit"  # the compiled steps (jit.LOADED)
FER = get_robot("fer")


def run(gen: OnlineGenerator, ticks: int = 20_000) -> np.ndarray:
    states = [np.concatenate([gen.position, gen.velocity, gen.acceleration])]
    for _ in range(ticks):
        done = gen.step()
        states.append(np.concatenate([gen.position, gen.velocity, gen.acceleration]))
        if done:
            break
    else:
        raise AssertionError("the generator never finished")
    return np.array(states)


@pytest.mark.parametrize("seed", range(20))
def test_from_any_state_within_the_limits_to_the_target(seed: int) -> None:
    rng = np.random.default_rng(seed)
    limits = OnlineLimits.joints(FER, float(rng.uniform(0.1, 1.0)))
    v, a, j = (np.array(x) for x in (limits.velocity, limits.acceleration, limits.jerk))
    gen = OnlineGenerator(limits)
    gen.reset(rng.uniform(-1, 1, 7), rng.uniform(-0.9, 0.9, 7) * v, rng.uniform(-0.5, 0.5, 7) * a)
    target = rng.uniform(-1, 1, 7)
    gen.set_target(target)
    s = run(gen)
    p, dq, ddq = s[:, :7], s[:, 7:14], s[:, 14:]
    np.testing.assert_allclose(p[-1], target, atol=1e-9)
    np.testing.assert_allclose(dq[-1], 0.0, atol=1e-9)
    tol = 1 + 1e-6
    assert np.all(np.abs(dq) <= v * tol) and np.all(np.abs(ddq) <= a * tol)
    assert np.all(np.abs(np.diff(ddq, axis=0)) <= j * PERIOD * tol)
    # the position integrates the velocity (no jump anywhere)
    np.testing.assert_allclose(np.diff(p, axis=0), 0.5 * (dq[1:] + dq[:-1]) * PERIOD, atol=1e-6)


def test_coming_to_rest_from_full_speed_stays_within_the_limits() -> None:
    limits = OnlineLimits.joints(FER, 0.5)
    v, a = np.array(limits.velocity), np.array(limits.acceleration)
    gen = OnlineGenerator(limits)
    gen.reset(np.zeros(7), v, np.zeros(7))
    gen.set_rest()
    s = run(gen)
    dq, ddq = s[:, 7:14], s[:, 14:]
    np.testing.assert_allclose(dq[-1], 0.0, atol=1e-9)
    assert np.all(np.abs(ddq) <= a * (1 + 1e-6))
    assert np.all(np.diff(np.abs(dq), axis=0) <= 1e-9)  # only slower, never back


def test_a_target_state_beyond_the_limits_is_clipped_not_refused() -> None:
    limits = OnlineLimits.joints(FER, 0.2)
    gen = OnlineGenerator(limits)
    gen.reset(np.zeros(7), np.zeros(7), np.zeros(7))
    gen.set_target(np.full(7, 0.5), np.full(7, 10.0), np.full(7, 100.0))
    s = run(gen)
    np.testing.assert_allclose(s[-1, 7:14], limits.velocity, rtol=1e-9)
    assert np.all(np.abs(s[:, 7:14]) <= np.array(limits.velocity) * (1 + 1e-9))


def test_bad_limits_and_states_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="velocity: expected 2 finite limits > 0"):
        OnlineLimits((1.0, 0.0), (1.0, 1.0), (1.0, 1.0))
    with pytest.raises(ValueError, match="jerk: expected 1 finite limits > 0"):
        OnlineLimits((1.0,), (1.0,), (float("nan"),))
    with pytest.raises(ValueError, match=r"speed_factor: expected a number in \(0, 1\]"):
        OnlineLimits.joints(FER, 1.5)
    gen = OnlineGenerator(OnlineLimits.joints(FER, 0.2))
    with pytest.raises(ValueError, match="velocity: expected 7 finite values"):
        gen.reset(np.zeros(7), np.full(7, np.inf), np.zeros(7))


def test_the_pose_reaches_its_target_with_a_twist_that_matches_its_motion() -> None:
    limits = OnlineLimits.cartesian(FER, 0.5)
    gen = OnlinePose(limits)
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    gen.reset(np.array([0.3, 0.0, 0.5]), q0, np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.5]), np.zeros(6))
    target_q = rotation.multiply(q0, rotation.exp(np.array([0.3, -0.2, 1.0])))
    gen.set_target(np.array([0.4, 0.1, 0.4]), target_q)
    prev = gen.orientation.copy()
    prev_p = gen.position.copy()
    worst_w = worst_v = 0.0
    for k in range(20_000):
        done = gen.step()
        # the angular velocity from the orientation's change (mid-tick) and the twist's
        dq = rotation.multiply(gen.orientation, rotation.conjugate(prev))
        w = rotation.log(dq) / PERIOD
        worst_w = max(worst_w, float(np.linalg.norm(w - gen.twist[3:])))
        worst_v = max(
            worst_v, float(np.linalg.norm((gen.position - prev_p) / PERIOD - gen.twist[:3]))
        )
        prev, prev_p = gen.orientation.copy(), gen.position.copy()
        if k == 300:  # a new target mid-way: re-anchored, continuous
            target_q = rotation.multiply(q0, rotation.exp(np.array([-0.5, 0.4, -0.6])))
            gen.set_target(np.array([0.3, -0.1, 0.45]), target_q)
        if done:
            break
    assert done
    np.testing.assert_allclose(gen.position, [0.3, -0.1, 0.45], atol=1e-9)
    assert abs(abs(float(gen.orientation @ target_q)) - 1.0) < 1e-9
    # half a tick of the limits' acceleration is the finite difference's own error
    assert worst_w < 0.02 and worst_v < 0.02
    c = FER.cartesian
    assert np.linalg.norm(gen.twist[:3]) <= 0.5 * c.translation_velocity


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reset_toward_is_reset_then_set_target_in_one(seed: int) -> None:
    """A move's hand-over restarts the pose generator once: the same trajectory, tick for
    tick, as a reset to the state followed by the target; bad states are refused alike."""
    rng = np.random.default_rng(seed)
    limits = OnlineLimits.cartesian(FER, 0.5)
    q0 = rotation.multiply(np.array([1.0, 0.0, 0.0, 0.0]), rotation.exp(rng.normal(size=3)))
    start = (np.array([0.3, 0.0, 0.5]) + rng.normal(scale=0.05, size=3), q0,
             rng.normal(scale=0.2, size=6), rng.normal(scale=1.0, size=6))  # fmt: skip
    target = (np.array([0.4, 0.1, 0.4]), rotation.multiply(q0, rotation.exp(rng.normal(size=3))),
              rng.normal(scale=0.05, size=6), np.zeros(6))  # fmt: skip
    a, b = OnlinePose(limits), OnlinePose(limits)
    a.reset(*start)
    first = (a.position.copy(), a.orientation.copy(), a.twist.copy(), a.accel.copy())
    a.set_target(*target)
    b.reset_toward(*start, *target)
    for x, y in zip(first, (b.position, b.orientation, b.twist, b.accel), strict=True):
        np.testing.assert_allclose(y, x, atol=1e-12)  # the start state, published
    for _ in range(3000):
        done_a, done_b = a.step(), b.step()
        assert done_a == done_b
        np.testing.assert_allclose(b.position, a.position, atol=1e-9)
        np.testing.assert_allclose(b.twist, a.twist, atol=1e-9)
        assert abs(abs(float(a.orientation @ b.orientation)) - 1.0) < 1e-12
        if done_a:
            break
    assert done_a
    with pytest.raises(ValueError, match="twist: expected 6 finite values"):
        b.reset_toward(start[0], q0, np.full(6, np.nan), np.zeros(6), *target[:2])
    for bad in (np.zeros(4), [0.0, np.nan, 0.0, 1.0], [0.0, 0.0, 1.0], [np.inf, 0, 0, 1]):
        with pytest.raises(ValueError, match="orientation: expected a unit quaternion"):
            b.reset_toward(start[0], bad, np.zeros(6), np.zeros(6), *target[:2])
    with pytest.raises(ValueError, match="position: expected 3 finite values"):
        b.reset_toward([0.3, np.inf, 0.5], q0, np.zeros(6), np.zeros(6), *target[:2])
    with pytest.raises(ValueError, match="accel: expected 6 finite values"):
        b.reset_toward(start[0], q0, np.zeros(6), np.zeros(7), *target[:2])
    gen = OnlineGenerator(OnlineLimits.joints(FER, 0.5))  # huge but finite: not refused
    gen.reset(np.full(7, 1e308), np.zeros(7), np.zeros(7))
    with pytest.raises(ValueError, match="position: expected 7 finite values"):
        gen.reset(np.array([1e308, 1e308, np.inf, 0, 0, 0, 0]), np.zeros(7), np.zeros(7))


def test_scaled_limits_refuse_factors_that_are_not_positive() -> None:
    limits = OnlineLimits.cartesian(FER, 0.5)
    assert limits.scaled(0.5, 0.25) == OnlineLimits(
        tuple(0.5 * v for v in limits.velocity), tuple(0.25 * a for a in limits.acceleration),
        tuple(0.25 * j for j in limits.jerk),
    )  # fmt: skip
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="scaled: expected factors > 0"):
            limits.scaled(bad, 1.0)


def test_an_arm_at_rest_with_noise_sized_velocities_is_at_its_target() -> None:
    """ruckig 0.19 cannot synchronize velocities of 1e-14 (it raises): those are rest."""
    gen = OnlineGenerator(OnlineLimits.joints(FER, 1.0))
    q = np.array(FER.joints.q_max) * 0.1
    noise = np.array([5e-15, 9e-16, -2e-15, 1e-15, 7e-14, 2e-15, 1e-14])
    gen.reset(q, noise, np.zeros(7))
    assert gen.step()
    np.testing.assert_allclose(gen.position, q, atol=1e-12)


def test_a_synchronization_ruckig_cannot_solve_falls_back_to_the_next(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from panda_py.motion import online

    monkeypatch.setattr(online, "_REST_VELOCITY", 0.0)  # let the noise through to ruckig
    gen = OnlineGenerator(OnlineLimits.joints(FER, 1.0))
    q = np.array(
        [-6.1e-14, -0.785398163397, -1.1e-14, -2.35619449019, 8e-13, 1.5707963268, 0.78539816]
    )
    noise = np.array([5.07e-15, 9.36e-16, -2.45e-15, 1.42e-15, 6.88e-14, 2.02e-15, 1.04e-14])
    gen.reset(q, noise, np.zeros(7))
    assert gen.step()  # phase synchronization raised inside ruckig; the next one solved it
    np.testing.assert_allclose(gen.position, q, atol=1e-12)


def test_the_scalar_jacobians_equal_the_vectorized_ones() -> None:
    from panda_py.motion import online

    rng = np.random.default_rng(3)
    for scale in (1e-6, 0.3, 2.5):
        for _ in range(20):
            x, y = rng.normal(size=3) * scale, rng.normal(size=3)
            right = rotation.right_jacobian_times(x[None], y[None])[0]
            left = rotation.right_jacobian_times(-x[None], y[None])[0]  # J_l(x) = J_r(-x)
            np.testing.assert_allclose(online._jacobian_times(list(x), list(y), -1.0), right,
                                       atol=1e-12)  # fmt: skip
            np.testing.assert_allclose(online._jacobian_times(list(x), list(y), 1.0), left,
                                       atol=1e-12)  # fmt: skip


def test_the_pose_generators_frames_are_rotations_along_the_motion() -> None:
    from panda_py.motion import online

    rng = np.random.default_rng(5)
    for d in [*rng.normal(size=(50, 3)), np.array([0.0, 0.0, 2.0]), np.array([1e-3, 0.0, 0.0])]:
        F = online._frame(d, np.zeros(3))
        np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
        assert np.linalg.det(F) == pytest.approx(1.0)
        np.testing.assert_allclose(F[:, 0], d / np.linalg.norm(d), atol=1e-12)
    np.testing.assert_allclose(online._frame(np.zeros(3), [0.0, 2.0, 0.0])[:, 0], [0, 1, 0])
    np.testing.assert_array_equal(online._frame(np.zeros(3), np.zeros(3)), np.eye(3))


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_compiled_restart_toward_a_pose_equals_the_python_reference(monkeypatch) -> None:
    """OnlinePose's restart toward a new target (a hand-over's reset_toward, a streamed
    target's set_target: frames, start state and goal) is the same compiled as in NumPy,
    from random states to random targets, rotations small and large, also from rest
    toward where it is (the frames' fallbacks)."""
    from panda_py.motion import online

    kernels = online._compiled()
    assert kernels is not None  # numba comes with the package here
    limits = OnlineLimits.cartesian(get_robot("fr3"), 1.0)
    rng = np.random.default_rng(11)

    def restart(compiled: bool, *args: np.ndarray) -> tuple[np.ndarray, ...]:
        monkeypatch.setitem(LOADED, ONLINE_JIT, kernels if compiled else None)
        gen = OnlinePose(limits)
        gen.reset_toward(*args)
        inp = gen.gen._inp
        return (gen._Ft, gen._Fr, np.array(inp.current_position),
                np.array(inp.current_velocity), np.array(inp.current_acceleration),
                np.array(inp.target_position))  # fmt: skip

    for i in range(300):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        p = rng.uniform(-0.5, 0.5, 3)
        # a rotation of 1e-9 rad has a direction only to ~1e-7 (its quaternion's vector
        # part is a difference of O(1) products): the rotation's frame to 1e-6 there
        tol = 1e-12
        if i % 10 == 0:  # at rest, toward where it is: both frames fall back
            args = (p, quat, np.zeros(6), np.zeros(6), p.copy(), quat.copy())
        else:
            tol = 1e-6 if i % 7 == 0 else 1e-12
            small = rng.normal(0.0, 1e-9 if i % 7 == 0 else 0.5, 3)
            target_q = rotation.multiply(quat, rotation.exp(small))
            args = (p, quat, rng.normal(0.0, 0.3, 6), rng.normal(0.0, 1.0, 6),
                    p + rng.normal(0.0, 0.2, 3), target_q * rng.choice([-1.0, 1.0]))  # fmt: skip
        for want, got in zip(restart(False, *args), restart(True, *args), strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=tol)


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_compiled_pose_output_equals_the_python_reference() -> None:
    """OnlinePose's per-tick output (base-frame position, orientation, twist, acceleration
    from the aligned generator) is the same compiled as in scalar Python, along moves to
    random targets (new anchors and frames) with small and large rotation vectors."""
    from panda_py.motion import online

    assert online._compiled() is not None  # numba comes with the package here
    limits = OnlineLimits.cartesian(get_robot("fr3"), 1.0)
    rng = np.random.default_rng(5)
    gen = OnlinePose(limits)
    gen.reset(np.array([0.3, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(6),
              np.zeros(6))  # fmt: skip
    names = ("position", "orientation", "twist", "accel")
    checked = 0
    for _ in range(6):
        quat = rng.normal(size=4)
        gen.set_target(gen.position + rng.normal(0.0, 0.2, 3), quat / np.linalg.norm(quat))
        for _ in range(150):
            gen.step()  # compiled
            compiled = [getattr(gen, n).copy() for n in names]
            gen._publish_python()
            for n, want in zip(names, compiled, strict=True):
                np.testing.assert_allclose(getattr(gen, n), want, rtol=1e-12, atol=1e-12)
            checked += 1
    assert checked == 900


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_compiled_steps_sample_exactly_what_ruckig_steps_to(monkeypatch) -> None:
    """Compiled, ruckig steps once after each change of the generator's input, and the
    steps after it sample the trajectory it calculated (``_online_jit.sample``); ruckig's
    ``update`` alone steps to the same states, bit for bit, with the same ``finished`` and
    durations: from states beyond the limits (ruckig brakes first), toward new targets
    mid-motion, after new limits, and to rest. The pose generator's outputs likewise."""
    from panda_py.motion import _online_jit, online

    kernels = online._compiled()
    assert kernels is not None  # numba comes with the package here
    assert online._ROW == _online_jit.ROW
    rng = np.random.default_rng(4)

    def both(gens: list, method: str, *args: object) -> list:  # type: ignore[type-arg]
        """``gens[0].method(*args)`` through ruckig's update, ``gens[1]``'s compiled."""
        out = []
        for compiled, gen in zip((False, True), gens, strict=True):
            monkeypatch.setitem(
                LOADED, "panda_py.motion._online_jit", kernels if compiled else None
            )
            out.append(getattr(gen, method)(*args))
        return out

    slow, fast = OnlineLimits.joints(FER, 0.3), OnlineLimits.joints(FER, 1.0)
    names = ("position", "velocity", "acceleration")
    steps = 0
    for _ in range(25):
        q = rng.uniform(-1.0, 1.0, 7)
        v = rng.normal(0.0, 1.5, 7) * np.array(slow.velocity)  # some beyond the limits
        a = rng.normal(0.0, 0.5, 7) * np.array(slow.acceleration)
        gens = [OnlineGenerator(slow), OnlineGenerator(slow)]
        both(gens, "reset", q, v, a)
        for change in range(5):
            if change == 2:
                both(gens, "set_limits", fast)
            if change == 4:
                both(gens, "set_rest")
            else:
                both(gens, "set_target", q + rng.uniform(-0.5, 0.5, 7))
            for _ in range(int(rng.integers(1, 300))):
                want, got = both(gens, "step")
                assert got == want
                assert gens[1].duration == gens[0].duration
                for name in names:
                    np.testing.assert_array_equal(getattr(gens[1], name), getattr(gens[0], name))
                steps += 1
    assert steps > 2_000

    limits = OnlineLimits.cartesian(FER, 0.5)
    poses = [OnlinePose(limits), OnlinePose(limits)]
    both(poses, "reset", np.array([0.3, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0]),
         rng.normal(0.0, 0.1, 6), np.zeros(6))  # fmt: skip
    for change in range(4):
        if change == 3:
            both(poses, "set_rest")
        else:
            quat = rng.normal(size=4)
            both(poses, "set_target", poses[0].position + rng.normal(0.0, 0.2, 3), quat)
        for _ in range(200):
            want, got = both(poses, "step")
            assert got == want
            for name in ("position", "orientation", "twist", "accel"):
                np.testing.assert_allclose(getattr(poses[1], name), getattr(poses[0], name),
                                           rtol=1e-12, atol=1e-12)  # fmt: skip


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_compiled_new_target_equals_the_python_reference(monkeypatch) -> None:
    """OnlinePose.set_target mid-motion (the anchor moved to the current orientation, the
    rotation vector's rates turned by its right Jacobian, then the restart toward the
    target) is the same compiled (``_online_jit.retarget``) as in NumPy: anchors, frames,
    the generator's start and goal, with and without a rotation under way, and with the
    arrival twist and acceleration given."""
    from panda_py.motion import _online_jit, online

    kernels = online._compiled()
    assert kernels is not None  # numba comes with the package here
    assert _online_jit.SMALL_ANGLE == rotation.SMALL_ANGLE
    limits = OnlineLimits.cartesian(get_robot("fr3"), 1.0)
    rng = np.random.default_rng(12)

    def moving(seed: int) -> OnlinePose:
        """A pose generator some ticks into a move (the same for the same seed)."""
        r = np.random.default_rng(seed)
        gen = OnlinePose(limits)
        quat = r.normal(size=4)
        gen.reset(r.uniform(-0.5, 0.5, 3), quat / np.linalg.norm(quat), r.normal(0.0, 0.2, 6),
                  np.zeros(6))  # fmt: skip
        if seed % 5:  # else at rest where it started: no rotation under way
            gen.set_target(
                gen.position + r.normal(0.0, 0.2, 3),
                rotation.multiply(gen.orientation, rotation.exp(r.normal(0, 0.5, 3))),
            )
            for _ in range(int(r.integers(2, 200))):
                gen.step()
        return gen

    for seed in range(60):
        target = rng.uniform(-0.5, 0.5, 3)
        quat = rng.normal(size=4) * rng.uniform(0.5, 2.0)  # any norm
        arrive = (rng.normal(0.0, 0.1, 6), rng.normal(0.0, 0.5, 6)) if seed % 3 == 0 else ()
        got = []
        for compiled in (False, True):
            gen = moving(seed)
            monkeypatch.setitem(
                LOADED, "panda_py.motion._online_jit", kernels if compiled else None
            )
            gen.set_target(target, quat, *arrive)
            inp = gen.gen._inp
            got.append([gen._q0, gen._R0, gen._Ft, gen._Fr, np.array(inp.current_position),
                        np.array(inp.current_velocity), np.array(inp.current_acceleration),
                        np.array(inp.target_position), np.array(inp.target_velocity),
                        np.array(inp.target_acceleration)])  # fmt: skip
            monkeypatch.setitem(LOADED, ONLINE_JIT, kernels)
        for want, have in zip(*got, strict=True):
            np.testing.assert_allclose(have, want, rtol=1e-12, atol=1e-12)


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_compiled_mapped_peaks_equal_ruckigs_own_sampling(monkeypatch) -> None:
    """``mapped_peaks`` (the largest ``|M v|`` and ``|M a|`` along the whole trajectory)
    compiled (``_online_jit.mapped_peaks`` on the packed trajectory) and through ruckig's
    ``at_time``: the same to 1e-9, from states beyond the limits (ruckig brakes first);
    the generator's state is left as it was; and its steps then meet those peaks, never
    more (an acceleration's peak of 2 ms only to within the ticks' sampling)."""
    from panda_py.motion import _online_jit, online

    kernels = online._compiled()
    assert kernels is not None  # numba comes with the package here
    assert online._PEAK_SIZE == _online_jit.PEAK_SIZE
    rng = np.random.default_rng(11)
    limits = OnlineLimits.joints(FER, 0.3)
    for _ in range(20):
        gen = OnlineGenerator(limits)
        v = rng.normal(0.0, 1.5, 7) * np.array(limits.velocity)  # some beyond the limits
        gen.reset(rng.uniform(-1.0, 1.0, 7), v, np.zeros(7))
        gen.set_target(rng.uniform(-1.0, 1.0, 7))
        M = rng.normal(0.0, 1.0, (3, 7))
        before = (gen.position.copy(), gen.velocity.copy(), gen.duration)
        fast = gen.mapped_peaks(M)
        monkeypatch.setitem(LOADED, "panda_py.motion._online_jit", None)
        slow = gen.mapped_peaks(M)
        monkeypatch.setitem(LOADED, "panda_py.motion._online_jit", kernels)
        assert fast is not None and slow is not None
        for a, b in zip(fast, slow, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(gen.position, before[0])
        np.testing.assert_array_equal(gen.velocity, before[1])
        met_v, met_a = np.zeros(3), np.zeros(3)
        while not gen.step():
            met_v = np.maximum(met_v, np.abs(M @ gen.velocity))
            met_a = np.maximum(met_a, np.abs(M @ gen.acceleration))
        assert np.all(met_v <= fast[0] + 1e-9) and np.all(met_a <= fast[1] + 1e-9)
        assert np.all(met_v >= 0.99 * fast[0]) and np.all(met_a >= 0.85 * fast[1])


def test_mapped_peaks_refuse_a_map_of_another_shape_by_name() -> None:
    gen = OnlineGenerator(OnlineLimits.joints(FER, 0.3))
    gen.reset(np.zeros(7), np.zeros(7), np.zeros(7))
    gen.set_target(np.full(7, 0.1))
    for bad in (np.eye(6), np.zeros(7), np.zeros((9, 7)), np.zeros((0, 7))):
        with pytest.raises(ValueError, match=r"M: expected 1 to 8 rows .* 7 coordinates"):
            gen.mapped_peaks(bad)


@pytest.mark.skipif(not jit.enabled(), reason="PANDA_PY_NO_JIT is set: compares the kernels")
def test_the_warmup_loads_every_compiled_step() -> None:
    """``online.warmup()`` (the control process runs it before its loop) compiles or loads
    every kernel the generators call, so none compiles in a tick."""
    from panda_py.motion import _online_jit, online

    assert online._compiled() is not None  # numba comes with the package here
    online.warmup()
    called = ("sample", "sample_pose", "publish_pose", "retarget", "restart_toward",
              "mapped_peaks")  # fmt: skip
    assert set(called) | {"ROW", "aim"} == set(_online_jit.__all__)  # (aim: inside two)
    for name in called:
        kernel = getattr(_online_jit, name)
        assert kernel.signatures, f"{name} was not compiled or loaded by the warm-up"


@pytest.mark.parametrize("compiled", [True, False])
def test_the_acceleration_ahead_is_the_one_the_steps_reach_that_much_later(
    compiled: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """acceleration_ahead(dt) / accel_ahead(dt): where the generator's acceleration will
    be ``dt`` on (what a torque fed forward through the loop's filter aims at), compiled
    and through ruckig's own trajectory, from a state mid-motion toward a new target and
    past the trajectory's end (its last acceleration kept, as ruckig's); before the first
    step after a reset, the state's own."""
    from panda_py.motion import online

    kernels = online._compiled()
    if compiled and kernels is None:
        pytest.skip("PANDA_PY_NO_JIT is set: the compiled sampling is off")
    monkeypatch.setitem(LOADED, ONLINE_JIT, kernels if compiled else None)
    rng = np.random.default_rng(46)
    limits = OnlineLimits.joints(FER, 0.3)
    gen = OnlineGenerator(limits)
    a0 = rng.normal(0.0, 0.3, 7) * np.array(limits.acceleration)
    gen.reset(rng.uniform(-1.0, 1.0, 7), rng.normal(0.0, 0.3, 7) * np.array(limits.velocity), a0)
    np.testing.assert_array_equal(gen.acceleration_ahead(2 * PERIOD), a0)
    gen.set_target(rng.uniform(-1.0, 1.0, 7))
    ahead, reached = [], []
    while not gen.step():
        ahead.append(gen.acceleration_ahead(3 * PERIOD).copy())
        reached.append(gen.acceleration.copy())
    assert np.abs(np.array(reached)).max() > 0.1  # (it moved)
    np.testing.assert_allclose(ahead[:-3], reached[3:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(gen.acceleration_ahead(0.1), gen.acceleration, atol=1e-12)

    pose = OnlinePose(OnlineLimits.cartesian(FER, 0.2))
    pose.reset(np.array([0.3, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(6),
               np.zeros(6))  # fmt: skip
    turn = rotation.multiply(rotation.exp(np.array([0.1, -0.2, 0.05])),
                             np.array([1.0, 0.0, 0.0, 0.0]))  # fmt: skip
    pose.set_target(np.array([0.4, 0.1, 0.45]), turn)
    ahead, reached = [], []
    while not pose.step():
        ahead.append(pose.accel_ahead(2 * PERIOD).copy())
        reached.append(pose.accel.copy())
    assert np.abs(np.array(reached)).max() > 0.5
    # the rotation's in the base frame at the pose of the step (without the compiled
    # kernels: at the pose now, the rotation vector's change over 2 ms left out)
    np.testing.assert_allclose(ahead[:-2], reached[2:], rtol=0, atol=1e-9 if compiled else 1e-6)
    for bad in (-1e-3, float("nan")):
        with pytest.raises(ValueError, match="dt: expected a time >= 0"):
            gen.acceleration_ahead(bad)
        with pytest.raises(ValueError, match="dt: expected a time >= 0"):
            pose.accel_ahead(bad)
