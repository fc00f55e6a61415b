"""The simulator's compiled tick (``sim/_tick_jit.py`` through ``sim/fastpath.py``)
equals its NumPy reference: the same state buffer bit for bit on generated states of every
motion generator, the same verdicts of the command and measured-state checks (NaN,
infinities and values exactly at a limit included), the same commanded joint signal and
flags over random command sequences; and without the JIT the robot runs the reference."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from panda_py.fci import MotionGeneratorMode
from panda_py.kinematics import _backend
from panda_py.robots import FER, FR3, START_POSE
from panda_py.sim.physics import Physics
from panda_py.sim.robot import RobotCore

pytestmark = [
    pytest.mark.timeout(300),
    pytest.mark.skipif(_backend.jit() is None, reason="no JIT (numba missing or disabled)"),
]


@pytest.fixture(scope="module", params=[FR3, FER], ids=["fr3", "fer"])
def core(request: pytest.FixtureRequest) -> RobotCore:
    spec = request.param
    return RobotCore(spec, Physics(spec), np.array(START_POSE))


def _randomise(core: RobotCore, rng: np.random.Generator) -> None:
    """A generated state: joints within their limits (moved in MuJoCo, so the links'
    rotations follow), and every value the fill reads set at random."""
    ph = core.physics
    lo, hi = np.asarray(core.spec.joints.q_min), np.asarray(core.spec.joints.q_max)
    ph.data.qpos[ph.q0 : ph.q0 + 7] = rng.uniform(lo, hi)
    ph.data.qvel[ph.v0 : ph.v0 + 7] = rng.normal(size=7)
    mujoco.mj_forward(ph.model, ph.data)
    ph.dq_before[:] = rng.normal(size=7)  # (tau_J: the rotor inertia's share)
    ph.tau_applied[:] = rng.normal(size=7) * 10
    core.tau_ext[:] = rng.normal(size=7) if rng.random() < 0.5 else 0.0
    core.contact_active = bool(core.tau_ext.any())
    core.tau_J_d[:] = rng.normal(size=7)
    core.joint.reset(rng.uniform(lo, hi))
    core.joint.dq[:] = rng.normal(size=7)
    core.joint.ddq[:] = rng.normal(size=7)
    core.q_hold = rng.uniform(lo, hi)
    T = np.eye(4)
    T[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    T[:3, 3] = rng.normal(size=3)
    core.cart.reset(T)
    core.cart.v[:] = rng.normal(size=6)
    core.cart.a[:] = rng.normal(size=6)
    core.elbow_c[:] = rng.normal(size=2)
    core.delbow_c[:] = rng.normal(size=2)
    core.ddelbow_c[:] = rng.normal(size=2)


@pytest.mark.parametrize("mode", list(MotionGeneratorMode))
def test_fill_state_equals_the_reference(core: RobotCore, mode: MotionGeneratorMode) -> None:
    assert core._fast is not None
    rng = np.random.default_rng(int(mode))
    for trial in range(30):
        _randomise(core, rng)
        core.mg_mode = mode
        # the last fill's generator: the same (held zeros stand) or another (written)
        previous = mode if trial % 2 else None
        before = rng.normal(size=core.state_buffer.size)
        # (a generated pose may touch the table or itself: the contact estimate runs too)
        tau_ext, active = core.tau_ext.copy(), core.contact_active
        core.state_buffer[:] = before
        core._filled_mode = previous
        assert core._fast.fill(core)
        fast = core.state_buffer.copy()
        assert core._filled_mode is mode
        core.state_buffer[:] = before
        core._filled_mode = previous
        core.tau_ext[:], core.contact_active = tau_ext, active
        core._fill_state_reference()
        np.testing.assert_array_equal(fast, core.state_buffer)


def test_fill_state_leaves_a_tool_frame_to_the_reference(core: RobotCore) -> None:
    saved = core.NE_T_EE.copy()
    try:
        core.NE_T_EE = np.eye(4)
        core.NE_T_EE[2, 3] = 0.05
        core._fill_static()
        assert core._fast is not None and not core._fast.fill(core)
        core._fill_state()  # the reference writes it
        expected = core._kin.fk(core.physics.q) @ core.NE_T_EE
        np.testing.assert_array_equal(core.state["O_T_EE"].reshape(4, 4).T, expected)
    finally:
        core.NE_T_EE = saved
        core._fill_static()
        core._fill_state()


_SPECIAL = (np.nan, np.inf, -np.inf, 0.0)


def _vectors(rng: np.random.Generator, limit: np.ndarray, n: int) -> list[np.ndarray]:
    """Vectors around ``limit``: well inside, exactly at it, just beyond, and with a
    special value on one joint."""
    out = []
    for _ in range(n):
        v = limit * rng.uniform(-1.2, 1.2, size=7)
        v[rng.integers(7)] = limit[0] * rng.choice((-1.0, 1.0))  # exactly at a limit
        out.append(v)
    for j, x in itertools.product(range(7), _SPECIAL):
        v = limit * 0.5
        v = v.copy()
        v[j] = x
        out.append(v)
    return out


def test_torque_check_equals_the_reference(core: RobotCore) -> None:
    assert core._fast is not None
    rng = np.random.default_rng(7)
    tau_max, step = core._tau_max, core._dtau_step
    fast = core._fast
    verdicts = set()
    for tau in _vectors(rng, tau_max, 300):
        for prev in (tau - step * rng.uniform(-1.5, 1.5, 7), tau.copy(), np.zeros(7)):
            expected = bool((np.abs(tau) <= tau_max).all() and (np.abs(tau - prev) <= step).all())
            assert fast.torque_in_limits(tau, prev, tau_max, step) == expected
            verdicts.add(expected)
    assert verdicts == {True, False}


def test_measured_check_equals_the_reference(core: RobotCore) -> None:
    assert core._fast is not None
    rng = np.random.default_rng(8)
    lo, hi, dq_hi = core._q_lo, core._q_hi, core._dq_hi
    verdicts = set()
    for q, dq in zip(_vectors(rng, hi, 300), _vectors(rng, dq_hi, 300), strict=True):
        q = np.clip(q, lo - 0.1, None) if rng.random() < 0.5 else q
        expected = not ((q < lo).any() or (q > hi).any() or (np.abs(dq) > dq_hi).any())
        assert core._fast.measured_in_limits(q, dq, lo, hi, dq_hi) == expected
        verdicts.add(expected)
    assert verdicts == {True, False}


def test_the_command_views_use_the_warm_kernels(core: RobotCore) -> None:
    """A command datagram's read-only (maybe unaligned) view compiles nothing new in the
    loop: it was compiled when the robot was built."""
    from panda_py import fci
    from panda_py.sim import _tick_jit
    from panda_py.sim.wire import CommandWire

    kernels = (_tick_jit.torque_in_limits, _tick_jit.all_finite, _tick_jit.joint_push)
    before = [len(k.signatures) for k in kernels]
    z = np.zeros(7)
    signal = [np.zeros(7) for _ in range(4)]
    assert core._fast is not None
    for version in fci.SUPPORTED_VERSIONS:
        c = CommandWire(fci.dialect(version)).command
        assert core._fast.torque_in_limits(c.tau_J_d, z, core._tau_max, core._dtau_step)
        for x in (c.q_c, c.dq_c):
            assert core._fast.all_finite(x)
            _tick_jit.joint_push(*signal, x, _tick_jit.PUSH_POSITION, 1e-3)
    assert [len(k.signatures) for k in kernels] == before


def test_joint_controller_equals_the_reference(core: RobotCore) -> None:
    """The robot's joint impedance controller (holding, a Desk drive, a motion
    generator's tracking) against ``Physics.joint_tracking_torque``: equal to rounding
    (the mass matrix's product sums in its own order), moving joints and joints at rest
    (their friction comes from the push) alike, at any stiffness the client set; and the
    loop's arrays compile nothing new."""
    from panda_py.sim import _tick_jit

    assert core._fast is not None
    before = len(_tick_jit.joint_tracking.signatures)
    rng = np.random.default_rng(7)
    ph = core.physics
    default = np.asarray(core.spec.default_K_theta)
    for k in range(300):
        _randomise(core, rng)
        if k % 3 == 0:
            ph.data.qvel[ph.v0 : ph.v0 + 7] = 0.0  # at rest: the clipped push
        q_d = core.joint.q + rng.normal(scale=0.05, size=7)
        dq_d, ddq_d = rng.normal(size=7), rng.normal(scale=3.0, size=7)
        K = default * rng.uniform(0.0, 2.0, size=7)  # 0: the 1e-3 floor
        got = core._fast.joint_tracking(ph, q_d, dq_d, ddq_d, K, default).copy()
        want = ph.joint_tracking_torque(q_d, dq_d, ddq_d, np.maximum(K / default, 1e-3))
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)
    core._hold_torque()  # the held joints' zeros
    assert len(_tick_jit.joint_tracking.signatures) == before


def test_without_the_jit_the_robot_runs_the_reference() -> None:
    probe = (
        "import numpy as np\n"
        "from panda_py.robots import FR3, START_POSE\n"
        "from panda_py.sim.physics import Physics\n"
        "from panda_py.sim.robot import RobotCore\n"
        "import sys\n"
        "core = RobotCore(FR3, Physics(FR3), np.array(START_POSE))\n"
        "core.tick(None)\n"
        "print(core._fast is None, 'panda_py.sim._tick_jit' in sys.modules,"
        " float(core.state['q'][0]) == float(core.physics.q[0]))\n"
    )
    env = {**os.environ, "PANDA_PY_NO_JIT": "1"}
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "False", "True"]


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # NaN, inf
@pytest.mark.parametrize("cartesian", [False, True])
def test_joint_signal_equals_the_reference(core: RobotCore, cartesian: bool) -> None:
    """Positions, velocities and lost commands in random order, some beyond the limits or
    not finite: the compiled signal keeps the reference's values and flags bit for bit."""
    from panda_py.sim import _tick_jit
    from panda_py.sim.safety import JointSignal

    assert core._fast is not None and core._fast.kernels is _tick_jit
    rng = np.random.default_rng(9 + cartesian)
    j = core.spec.joints
    fast, ref = JointSignal(_tick_jit), JointSignal()
    start = np.array(START_POSE)
    fast.reset(start)
    ref.reset(start)
    flagged = set()
    for step in range(3000):
        if step % 500 == 0:  # start over now and then, so the values stay near the limits
            fast.reset(start)
            ref.reset(start)
        kind = rng.integers(3)
        scale = rng.choice((1e-4, 1e-3, 1e-2))  # most steps smooth, some far too fast
        if kind == 0:
            x = ref.q + rng.normal(size=7) * scale
            if rng.random() < 0.01:
                x[rng.integers(7)] = rng.choice(_SPECIAL)
            fast.push_position(x)
            ref.push_position(x)
        elif kind == 1:
            x = ref.dq + rng.normal(size=7) * scale * np.asarray(j.dq_max)
            fast.push_velocity(x)
            ref.push_velocity(x)
        else:
            fast.extrapolate()
            ref.extrapolate()
        for a, b in ((fast.q, ref.q), (fast.dq, ref.dq), (fast.ddq, ref.ddq),
                     (fast.dddq, ref.dddq)):  # fmt: skip
            np.testing.assert_array_equal(a, b)
        flags = fast.violations(core.spec, cartesian=cartesian)
        assert flags == ref.violations(core.spec, cartesian=cartesian)
        flagged.update(flags)
    assert len(flagged) >= 3  # the limits were hit, not only passed


def test_finite_check_equals_the_reference(core: RobotCore) -> None:
    from panda_py.sim.safety import all_finite

    assert core._fast is not None
    rng = np.random.default_rng(10)
    for v in _vectors(rng, np.ones(7), 50):
        assert core._fast.all_finite(v) == all_finite(v)
