"""The control loop runs libfranka's torque path with the low-pass filter and without the
rate limiter, because its own saturation already holds libfranka's bound: for every torque
the loop can hand over (within 1 Nm of the last command ``tau_J_d``), the command with the
limiter on is the command with it off, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import fci
from panda_py.controllers import laws
from panda_py.libfranka import Torques
from panda_py.libfranka._commander import Commander
from panda_py.libfranka.limits import RateLimits
from panda_py.robots.params import get_robot
from panda_py.rt import child


@pytest.mark.parametrize("version", [5, 10])
def test_the_rate_limiter_cannot_bind_after_the_loops_saturation(version: int) -> None:
    assert child.LIMIT_RATE is False and child.CUTOFF_FREQUENCY == 100.0
    dialect = fci.dialect(version)
    limits = RateLimits.for_robot(get_robot("fr3" if version >= 6 else "fer"))
    on = Commander(dialect, limits, True, child.CUTOFF_FREQUENCY)
    off = Commander(dialect, limits, False, child.CUTOFF_FREQUENCY)
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
