"""The control loop runs libfranka's torque path with the low-pass filter and without the
rate limiter, because its own saturation already holds libfranka's bound: for every torque
the loop can hand over (within 1 Nm of the last command ``tau_J_d``), the command with the
limiter on is the command with it off, bit for bit. The filter itself runs in the loop's
compiled finalize: what it sends is what libfranka's filter would have sent."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.controllers import laws
from panda_py.controllers.finalize import CUTOFF_FREQUENCY, FILTER_GAIN
from panda_py.libfranka import Torques
from panda_py.libfranka._commander import Commander
from panda_py.libfranka.limits import RateLimits
from panda_py.robots.params import get_robot
from panda_py.rt import child


@pytest.mark.parametrize("version", [5, 10])
def test_the_rate_limiter_cannot_bind_after_the_loops_saturation(version: int) -> None:
    assert child.LIMIT_RATE is False and CUTOFF_FREQUENCY == 100.0
    dialect = fci.dialect(version)
    limits = RateLimits.for_robot(get_robot("fr3" if version >= 6 else "fer"))
    on = Commander(dialect, limits, True, CUTOFF_FREQUENCY)
    off = Commander(dialect, limits, False, CUTOFF_FREQUENCY)
    assert np.allclose(limits.max_torque_rate * 1e-3, laws.DTAU_MAX_PER_TICK)
    rng = np.random.default_rng(version)
    rec = np.zeros((), dialect.state_dtype)
    for _ in range(2000):
        tau_J_d = rng.uniform(-80.0, 80.0, 7)
        rec["tau_J_d"] = tau_J_d
        state = dialect.encode_state(rec)
        wanted = tau_J_d + rng.normal(scale=50.0, size=7)  # far beyond one tick's step
        tau = laws.saturate_torque_rate(wanted, np.asarray(rec["tau_J_d"], dtype=np.float64))
        on.torques(Torques(tau), state)
        off.torques(Torques(tau), state)
        assert bytes(on.buffer) == bytes(off.buffer)


@pytest.mark.parametrize("version", [5, 10])
def test_the_loops_filter_is_libfrankas(version: int) -> None:
    from panda_py.libfranka.limits import MAX_CUTOFF_FREQUENCY

    dialect = fci.dialect(version)
    limits = RateLimits.for_robot(get_robot("fr3" if version >= 6 else "fer"))
    libfranka_filters = Commander(dialect, limits, False, CUTOFF_FREQUENCY)
    unfiltered = Commander(dialect, limits, False, MAX_CUTOFF_FREQUENCY)
    tau_max = np.array([87.0] * 4 + [12.0] * 3)
    walls = laws.JointWalls(np.full(7, -3.0), np.full(7, 3.0))  # far: no wall torque
    rng = np.random.default_rng(version)
    rec = np.zeros((), dialect.state_dtype)
    z = np.zeros(7)
    raw, filtered = np.empty(7), np.empty(7)
    for _ in range(500):
        rec["tau_J_d"] = rng.uniform(-10.0, 10.0, 7)
        state = dialect.encode_state(rec)
        tau_J_d = lf.RobotState(dialect, state).tau_J_d  # as the loop reads it (v10: float32)
        tau = tau_J_d + rng.normal(scale=2.0, size=7)
        assert walls.finalize(tau, z, z, tau_J_d, tau_max, raw)
        assert walls.finalize(tau, z, z, tau_J_d, tau_max, filtered, FILTER_GAIN)
        libfranka_filters.torques(Torques(raw), state)
        unfiltered.torques(Torques(filtered), state)
        got = unfiltered.record["tau_J_d"]
        np.testing.assert_allclose(got, libfranka_filters.record["tau_J_d"], rtol=0, atol=1e-12)
        assert not np.allclose(filtered, raw)  # (the filter did something)
